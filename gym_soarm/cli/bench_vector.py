"""``python -m gym_soarm.bench.bench_vector``: the scaling of vector environments alone.

Parses the command line, runs :func:`gym_soarm.bench.bench_vector.measure` and prints its
table (``python -m gym_soarm.bench --vector-scaling`` measures the same in the benchmark).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from gym_soarm.bench import bench_vector


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints a table (and writes JSON with ``--json``)."""
    parser = argparse.ArgumentParser(prog="python -m gym_soarm.bench.bench_vector")
    parser.add_argument("--env-id", default=bench_vector.DEFAULT_ENV_ID)
    parser.add_argument("--num-envs", default="1,2,4,8,16", help="counts, comma-separated")
    parser.add_argument("--obs", default="state", help="'state' or a camera config")
    parser.add_argument("--size", default="96x128", help="image HEIGHTxWIDTH for pixels")
    parser.add_argument(
        "--modes", default=",".join(bench_vector.VECTOR_MODES), help="vector envs measured"
    )
    parser.add_argument("--seconds", type=float, default=1.0, help="seconds per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (medians)")
    parser.add_argument(
        "--processes", type=int, default=None, help="native env's processes (default: CPUs)"
    )
    parser.add_argument("--json", default=None, help="write the figures to this file")
    args = parser.parse_args(argv)
    try:
        counts = [int(c) for c in args.num_envs.split(",") if c.strip()]
        height, width = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(
            f"--num-envs must be comma-separated ints and --size HEIGHTxWIDTH; got "
            f"{args.num_envs!r} and {args.size!r}"
        )
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    try:
        report = bench_vector.measure(
            args.env_id,
            counts,
            args.obs,
            (height, width),
            args.seconds,
            args.rounds,
            args.processes,
            modes,
        )
    except ValueError as exc:
        parser.error(str(exc))
    sys.stdout.write(bench_vector.title(report) + "\n" + bench_vector.format_table(report) + "\n")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as file:
            json.dump(report, file, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
