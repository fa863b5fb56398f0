"""``python -m gym_soarm <program> [args]``: every program by its name (``--help`` lists them).

The dispatcher is :func:`gym_soarm.cli.programs.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.programs import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
