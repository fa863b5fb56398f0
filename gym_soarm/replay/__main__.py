"""``python -m gym_soarm.replay``: the replay of a LeRobot dataset (also ``gym-soarm-replay``).

The program is :func:`gym_soarm.cli.replay.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.replay import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
