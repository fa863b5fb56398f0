"""``python -m gym_soarm.replay``: the replay's command line (also ``gym-soarm-replay``).

The replay itself is :func:`gym_soarm.data.replay.replay`.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.replay import main

if __name__ == "__main__":
    sys.exit(main())
