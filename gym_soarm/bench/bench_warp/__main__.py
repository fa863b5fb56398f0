"""``python -m gym_soarm.bench.bench_warp``: MuJoCo Warp on a GPU.

The program is :func:`gym_soarm.cli.bench_warp.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

from gym_soarm.cli.bench_warp import main

if __name__ == "__main__":
    main()
