"""``python -m gym_soarm.record``: the recorder's command line (also ``gym-soarm-record``).

The recording itself is :func:`gym_soarm.data.record.record`.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.record import main

if __name__ == "__main__":
    sys.exit(main())
