"""``python -m gym_soarm.sysid``: fit the simulation's servos and joints to a LeRobot dataset.

The fit itself is :func:`gym_soarm.real.sysid.fit_dynamics`; this module parses the
command line, checks where the results go before fitting, prints the per-joint tracking
error before and after and writes the dynamics file and the plot.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from gym_soarm import constants
from gym_soarm.cli.options import (
    add_dataset_scene_arguments,
    dataset_scene_keywords,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.real.dynamics import write_dynamics
from gym_soarm.real.sysid import DELAYS, FIT_ITERATIONS, SYSID_SETTINGS, fit_dynamics, plot_fit

DESCRIPTION = (
    "Replay a LeRobot SO-101 dataset's actions in the simulation and fit, per "
    "joint, the servo gains (kp, kv) and the joint's damping, armature and friction loss, "
    "and the control delay, to its recorded observation.state. Writes a "
    "gym_soarm.dynamics/1 file for dynamics=PATH / --dynamics."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("sysid", DESCRIPTION)
    add_dataset_scene_arguments(parser, SYSID_SETTINGS)
    parser.add_argument(
        "--episodes",
        type=int,
        nargs="+",
        default=None,
        metavar="K",
        help="the episode indices to fit to (default: every episode)",
    )
    parser.add_argument(
        "--out", required=True, metavar="FILE.json", help="the dynamics file to write"
    )
    parser.add_argument(
        "--plot",
        default=None,
        metavar="PATH.png",
        help="draw recorded vs simulated joints, before and after the fit (needs matplotlib)",
    )
    parser.add_argument(
        "--delays",
        type=int,
        nargs="+",
        default=list(DELAYS),
        metavar="STEPS",
        help="the control delays (20 ms steps) to try (default: 0 1 2 3)",
    )
    parser.add_argument(
        "--iterations",
        type=int,
        default=FIT_ITERATIONS,
        help=f"at most this many iterations of the final fit (default {FIT_ITERATIONS})",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.out.lower().endswith(".json"):
        parser.error(f"--out must name a .json file; got {args.out!r}.")
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        parser.error(f"--plot must name a .png file; got {args.plot!r}.")
    for flag, path in (("--out", args.out), ("--plot", args.plot)):
        if path is not None and not Path(path).resolve().parent.is_dir():
            parser.error(f"{flag}: the folder of {path!r} does not exist; create it first.")
    if args.plot is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            parser.error("--plot needs matplotlib: pip install matplotlib.")
    try:
        result = fit_dynamics(
            args.root,
            episodes=args.episodes,
            delays=args.delays,
            iterations=args.iterations,
            **dataset_scene_keywords(args),
        )
    except (ValueError, TypeError, ImportError) as exc:
        parser.error(str(exc))
    report = result.report
    print(
        f"fitted to {report['frames_compared']} frames ({report['seconds']} s) of "
        f"{len(report['episodes'])} episode(s) in {report['fit_seconds']} s"
    )
    print(f"control delay: {result.dynamics.delay_steps} step(s) of 20 ms")
    print(f"{'joint':<16}{'rms before':>12}{'rms after':>12}   (deg)")
    for name in constants.JOINT_NAMES:
        before, after = report["rms_before_deg"][name], report["rms_after_deg"][name]
        print(f"{name:<16}{before:>12.4g}{after:>12.4g}")
    overall_before, overall_after = (
        report["overall_rms_before_deg"],
        report["overall_rms_after_deg"],
    )
    print(f"{'all':<16}{overall_before:>12.4g}{overall_after:>12.4g}")
    if report.get("kept_model_values"):
        print("no fit improved on the model's own figures: they are kept (and no delay)")
    try:
        write_dynamics(result.dynamics, args.out)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"dynamics written to {args.out}")
    if args.plot is not None:
        try:
            plot_fit(result, args.plot)
        except ValueError as exc:
            parser.error(str(exc))
        print(f"plot written to {args.plot}")
    return 0
