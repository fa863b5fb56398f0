"""``python -m gym_soarm.record``: the recorder (also ``gym-soarm-record``).

The program is :func:`gym_soarm.cli.record.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.record import main

if __name__ == "__main__":  # spawn and forkserver workers import this file again: run nothing
    sys.exit(main())
