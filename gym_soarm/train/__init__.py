"""``python -m gym_soarm.train``: the RL trainer's command line (:mod:`gym_soarm.cli.train`).

Importing this package runs nothing; the work itself is :func:`gym_soarm.rl.training.train`.
"""
