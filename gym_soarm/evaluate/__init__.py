"""``python -m gym_soarm.evaluate``: a policy scored on the protocol (:mod:`gym_soarm.cli.evaluate`).

Importing this package runs nothing; the work itself is :func:`gym_soarm.rl.evaluation.score`.
"""
