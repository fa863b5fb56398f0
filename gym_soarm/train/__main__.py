"""``python -m gym_soarm.train``: the RL trainer (also ``gym-soarm-train``).

The program is :func:`gym_soarm.cli.train.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.train import main

if __name__ == "__main__":  # worker processes that import this file again run nothing
    sys.exit(main())
