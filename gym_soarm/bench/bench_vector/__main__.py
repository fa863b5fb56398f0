"""``python -m gym_soarm.bench.bench_vector``: the scaling of vector environments alone.

The program is :func:`gym_soarm.cli.bench_vector.main`; this file only gives it its ``-m``
name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.bench_vector import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
