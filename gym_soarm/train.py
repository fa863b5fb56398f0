"""``python -m gym_soarm.train``: the program's ``-m`` name (also ``gym-soarm-train`` and
``python -m gym_soarm train``).

The program is :func:`gym_soarm.cli.train.main`; importing this module runs nothing.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.train import main

__all__ = ["main"]

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
