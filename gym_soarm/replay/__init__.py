"""``python -m gym_soarm.replay``: the replay's command line (:mod:`gym_soarm.cli.replay`).

Importing this package runs nothing; the work itself is :func:`gym_soarm.data.replay.replay`.
"""
