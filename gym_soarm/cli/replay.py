"""``python -m gym_soarm.replay``: drive the simulation with a LeRobot SO-101 dataset's actions.

The replay itself is :func:`gym_soarm.real.replay.replay`; this module parses the command
line, prints the per-joint tracking error and writes the JSON and the plot.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from gym_soarm.cli.options import (
    add_dataset_scene_arguments,
    dataset_scene_keywords,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.real.replay import REPLAY_OVERRIDES, plot_replay, replay

DESCRIPTION = (
    "Replay a LeRobot SO-101 dataset's actions in the simulation and report, "
    "per joint, the error between the simulated and the recorded observation.state."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("replay", DESCRIPTION)
    add_dataset_scene_arguments(parser, REPLAY_OVERRIDES)
    parser.add_argument(
        "--episode",
        type=int,
        action="append",
        default=None,
        metavar="K",
        help="an episode index to replay; repeat for several (default: every episode)",
    )
    parser.add_argument("--json", default=None, metavar="PATH", help="write the figures as JSON")
    parser.add_argument(
        "--plot", default=None, metavar="PATH.png", help="draw recorded vs simulated joints"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        parser.error(f"--plot must name a .png file; got {args.plot!r}.")
    for flag, path in (("--json", args.json), ("--plot", args.plot)):
        if path is not None and not Path(path).resolve().parent.is_dir():
            parser.error(f"{flag}: the folder of {path!r} does not exist; create it first.")
    try:
        report = replay(args.root, episodes=args.episode, **dataset_scene_keywords(args))
    except (ValueError, TypeError, ImportError) as exc:
        parser.error(str(exc))
    print(report.table())
    if args.json is not None:
        try:
            Path(args.json).write_text(json.dumps(report.to_json(), indent=2) + "\n")
        except OSError as exc:
            parser.error(f"--json: cannot write {args.json!r}: {exc}")
        print(f"figures written to {args.json}")
    if args.plot is not None:
        try:
            plot_replay(report, args.plot)
        except ValueError as exc:
            parser.error(str(exc))
        print(f"plot written to {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
