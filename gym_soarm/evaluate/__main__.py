"""``python -m gym_soarm.evaluate``: score a trained policy or the expert (also
``gym-soarm-evaluate``).

The program is :func:`gym_soarm.cli.evaluate.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

import sys

from gym_soarm.cli.evaluate import main

if __name__ == "__main__":
    sys.exit(main())
