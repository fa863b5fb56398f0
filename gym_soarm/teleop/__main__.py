"""``python -m gym_soarm.teleop``: the teleoperation window (also ``gym-soarm-teleop``).

The program is :func:`gym_soarm.cli.teleop.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.teleop import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
