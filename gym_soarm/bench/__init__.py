"""``python -m gym_soarm.bench``: the speed benchmark's command line (:mod:`gym_soarm.cli.bench`).

Importing this package runs nothing. :func:`gym_soarm.bench.bench.run` runs the
benchmark, one module a measurement: :mod:`~gym_soarm.bench.config` (what is measured),
:mod:`~gym_soarm.bench.single` (one environment against its ceiling, the program
:mod:`~gym_soarm.bench.ceiling` run by its path), :mod:`~gym_soarm.bench.jobs` (what a
worker process runs), :mod:`~gym_soarm.bench.bench_vector` (vector envs' scaling),
:mod:`~gym_soarm.bench.bench_record` (recording throughput) and
:mod:`~gym_soarm.bench.targets` (the floors), in the processes of
:mod:`~gym_soarm.bench.child`. :mod:`~gym_soarm.bench.bench_warp` (MuJoCo Warp on a GPU)
and :mod:`~gym_soarm.bench.grasp_hold` (friction-only lift-and-carry) are benchmarks of
their own, each with its ``python -m`` name.
"""
