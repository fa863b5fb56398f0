"""``python -m gym_soarm.kernels``: the program's ``-m`` name (also ``gym-soarm-kernels``
and ``python -m gym_soarm kernels``).

The program is :func:`gym_soarm.cli.kernels.main`; importing this module runs nothing.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.kernels import main

__all__ = ["main"]

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
