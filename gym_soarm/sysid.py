"""``python -m gym_soarm.sysid``: the program's ``-m`` name (also ``gym-soarm-sysid`` and
``python -m gym_soarm sysid``).

The program is :func:`gym_soarm.cli.sysid.main`; importing this module runs nothing.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.sysid import main

__all__ = ["main"]

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
