"""``python -m gym_soarm.expert``: each task's scripted expert success rate (also ``gym-soarm-expert``).

The program is :func:`gym_soarm.cli.expert.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.expert import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
