"""Command-line programs of gym_soarm: each is one module here, with its ``main``.

The console scripts (``gym-soarm-<name>``) call it, and so does ``python -m
gym_soarm.<name>`` through ``gym_soarm/<name>/__main__.py`` (``bench_vector`` and
``docs`` run as ``python -m gym_soarm.bench.bench_vector`` and ``python -m gym_soarm.tools.docs``). Library modules hold no
``__main__`` block; ``tests/test_architecture.py`` checks it.
"""
