"""``python -m gym_soarm.record``: the recorder's command line (:mod:`gym_soarm.cli.record`).

Importing this package runs nothing; the work itself is :func:`gym_soarm.record.record.record`.
"""
