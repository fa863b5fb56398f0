"""``python -m gym_soarm.bench``: the speed benchmark's command line (:mod:`gym_soarm.cli.bench`).

Importing this package runs nothing; the work itself is :mod:`gym_soarm.bench.bench`;
:mod:`~gym_soarm.bench.bench_vector` (vector envs' scaling),
:mod:`~gym_soarm.bench.bench_warp` (MuJoCo Warp on a GPU) and
:mod:`~gym_soarm.bench.grasp_hold` (friction-only lift-and-carry) are benchmarks of
their own, each with its ``python -m`` name.
"""
