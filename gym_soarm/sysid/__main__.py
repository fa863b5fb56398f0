"""``python -m gym_soarm.sysid``: fit the simulation to a LeRobot dataset (also ``gym-soarm-sysid``).

The program is :func:`gym_soarm.cli.sysid.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.sysid import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
