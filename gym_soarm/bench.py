"""``python -m gym_soarm.bench``: the speed benchmark (also ``gym-soarm-bench``).

The benchmark itself is :mod:`gym_soarm.tools.bench`.
"""

from __future__ import annotations

import sys

from gym_soarm.tools.bench import main

if __name__ == "__main__":
    sys.exit(main())
