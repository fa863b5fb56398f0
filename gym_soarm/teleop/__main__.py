"""``python -m gym_soarm.teleop``: the teleoperation window (also ``gym-soarm-teleop``)."""

from __future__ import annotations

import sys

from gym_soarm.cli.teleop import main

if __name__ == "__main__":
    sys.exit(main())
