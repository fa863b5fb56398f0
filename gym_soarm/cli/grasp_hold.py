"""``python -m gym_soarm.bench.grasp_hold``: the grasp benchmark.

What it measures: :mod:`gym_soarm.bench.grasp_hold`.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence

from gym_soarm.bench import grasp_hold as bench


def main(argv: Sequence[str] | None = None) -> None:
    """Measure, print a line per shape (``--json``: and save every episode)."""
    parser = argparse.ArgumentParser(
        prog="python -m gym_soarm.bench.grasp_hold", description=bench.__doc__.splitlines()[0]
    )
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the report (with every episode) here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1; got {args.episodes}.")
    report = bench.measure(args.episodes, args.seed)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    for name, summary in {"all": report["all"], **report["shapes"]}.items():
        print(f"{name:9s} {bench.format_summary(summary)}")


if __name__ == "__main__":
    main()
