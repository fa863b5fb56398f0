"""``python -m gym_soarm.bench.grasp_hold``: the grasp benchmark.

The program is :func:`gym_soarm.cli.grasp_hold.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

from gym_soarm.cli.grasp_hold import main

if __name__ == "__main__":
    main()
