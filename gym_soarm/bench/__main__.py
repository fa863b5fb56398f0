"""``python -m gym_soarm.bench``: the speed benchmark (also ``gym-soarm-bench``).

The program is :func:`gym_soarm.cli.bench.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.bench import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
