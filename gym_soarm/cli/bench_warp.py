"""``python -m gym_soarm.bench.bench_warp``: MuJoCo Warp on a GPU.

What it measures: :mod:`gym_soarm.bench.bench_warp`.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from typing import Any

from gym_soarm.bench import bench_warp as bench


def _ints(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers of worlds separated by commas (e.g. 256,1024); got {text!r}"
        ) from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected numbers of worlds >= 1; got {text!r}")
    return values


def main(argv: Sequence[str] | None = None) -> None:
    """Measure and print the table (``--json``: and save the report after each row)."""
    parser = argparse.ArgumentParser(
        prog="python -m gym_soarm.bench.bench_warp", description=bench.__doc__.splitlines()[0]
    )
    parser.add_argument("--env-id", default=bench.DEFAULT_ENV_ID)
    parser.add_argument("--worlds", type=_ints, default=[256, 1024, 4096])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--env-worlds-max", type=int, default=1024)
    parser.add_argument("--batched-worlds-max", type=int, default=256)
    parser.add_argument("--json", help="write the report here too")
    args = parser.parse_args(argv)
    from gym_soarm.sim.warp_backend import check_device

    device = check_device(args.device)

    def save(report: dict[str, Any]) -> None:
        if args.json:
            with open(args.json, "w") as f:
                json.dump(report, f, indent=1)

    report = bench.measure(
        args.env_id,
        args.worlds,
        device,
        args.seconds,
        args.repeats,
        args.env_worlds_max,
        args.batched_worlds_max,
        on_row=save,
    )
    print(bench.format_table(report))


if __name__ == "__main__":
    main()
