"""``python -m gym_soarm.bench``: the speed benchmark's command line (:mod:`gym_soarm.cli.bench`).

Importing this package runs nothing; the work itself is :mod:`gym_soarm.bench.bench`.
"""
