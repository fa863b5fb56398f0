"""``python -m gym_soarm.record``: record scripted-expert demonstrations as a LeRobotDataset.

The recording itself is :func:`gym_soarm.record.record.record`; this module parses the command
line and reports on the terminal.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from gym_soarm.cli.options import (
    add_settings_arguments,
    camera_config_argument,
    settings_from_args,
    task_selection,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.record.record import (
    CAMERA_CONFIG_CHOICES,
    DEFAULT_RECORD_TASK,
    KEEP_CHOICES,
    default_root,
    record,
)
from gym_soarm.tasks import task_names
from gym_soarm.tasks.suites import SUITE_NAMES, distinct_tasks, resolve_selection
from gym_soarm.validation import parse_size

RECORD_EXCLUDES: tuple[str, ...] = (
    "task",  # --task: a task, a suite or a list of them
    "obs_type",  # images with --camera-config, the task state with --camera-config none
    "camera_config",  # --camera-config, which also takes 'none'
    "observation_height",  # --size
    "observation_width",  # --size
    "render_mode",  # no window: the recorder writes videos
    "render_camera",  # the cameras recorded are --camera-config's
    "image_modalities",  # LeRobot's videos hold RGB
    "normalize_actions",  # the dataset's actions are the control mode's own values
)
"""The environment settings the recorder sets itself (the reason beside each)."""


def env_settings(args: argparse.Namespace) -> EnvSettings:
    """The environment settings of every attempt (the first task's; each task's own
    ``task`` and the suite's variation apply per task)."""
    first = distinct_tasks(resolve_selection(args.task))[0].task
    return settings_from_args(args, task=first)


def _add_dataset_arguments(parser: argparse.ArgumentParser) -> None:
    """What is recorded and where: tasks, episodes, seed, dataset, cameras and image size."""
    parser.add_argument(
        "--task",
        type=task_selection,
        default=DEFAULT_RECORD_TASK,
        metavar="TASK",
        help=f"a task ({', '.join(task_names())}), a suite ({', '.join(SUITE_NAMES)}) or a "
        f"comma list of them: one dataset, --episodes of each task (default {DEFAULT_RECORD_TASK})",
    )
    parser.add_argument(
        "--episodes", type=int, default=10, help="episodes to keep per task (default 10)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the first attempt")
    parser.add_argument(
        "--repo-id",
        default="local/soarm",
        help="dataset name as LeRobot sees it, owner/name (default local/soarm)",
    )
    parser.add_argument(
        "--root",
        default=None,
        help="dataset folder (default: $HF_LEROBOT_HOME/<repo-id>, where LeRobot looks)",
    )
    parser.add_argument(
        "--camera-config",
        default="front_wrist",
        help=f"one of {', '.join(CAMERA_CONFIG_CHOICES)} or comma-separated camera names; "
        "'none' records observation.environment_state and no video (default front_wrist)",
    )
    parser.add_argument("--size", default="480x640", help="image HEIGHTxWIDTH (default 480x640)")


def _add_attempt_arguments(parser: argparse.ArgumentParser) -> None:
    """How the attempts run: which are kept, the noise, and where they run."""
    parser.add_argument(
        "--keep",
        choices=KEEP_CHOICES,
        default="success",
        help="'success': drop failed attempts and try again; 'all': keep every attempt",
    )
    parser.add_argument(
        "--dart-noise",
        type=float,
        default=0.0,
        metavar="SIGMA",
        help="std (rad) of Gaussian noise on the executed action; labels stay clean (default 0)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace an existing dataset in --root"
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="record attempts in N processes (this one and N - 1 workers); the dataset is the "
        "same for any N (default 1)",
    )
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="run the attempts as Ray tasks on the cluster at ADDRESS ('auto': the running "
        "one), or on a new local cluster without ADDRESS; needs pip install 'gym-soarm[ray]'",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


DESCRIPTION = "Record scripted-expert demonstrations of gym_soarm as a LeRobotDataset v3.0."
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("record", DESCRIPTION)
    _add_dataset_arguments(parser)
    add_settings_arguments(
        parser,
        exclude=RECORD_EXCLUDES,
        defaults={"units": "lerobot"},
        description="gym.make keywords of every attempt's environment (see docs/keywords.md)",
    )
    _add_attempt_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    camera_config = camera_config_argument(args.camera_config)
    root = Path(args.root) if args.root else default_root(args.repo_id)
    try:
        size = parse_size(args.size)
        summary = record(
            root,
            task=args.task,
            episodes=args.episodes,
            seed=args.seed,
            camera_config=camera_config,
            size=size,
            keep=args.keep,
            dart_noise=args.dart_noise,
            overwrite=args.overwrite,
            progress=not args.no_progress,
            workers=args.workers,
            ray_address=args.ray,
            settings=env_settings(args),
        )
    except (ValueError, TypeError, FileExistsError, ImportError) as exc:
        parser.error(str(exc))
    print(summary.text())
    if summary.interrupted:
        return 130
    wanted = args.episodes * len(summary.tasks)
    if summary.episodes < wanted:
        print(
            f"only {summary.episodes} of {wanted} episodes were kept after "
            f"{summary.attempts} attempts",
            file=sys.stderr,
        )
        return 1
    print(
        f"load it with: LeRobotDataset({args.repo_id!r}, root={str(root)!r}) "
        f"or --dataset.repo_id={args.repo_id} --dataset.root={root}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
