"""``python -m gym_soarm.teleop`` (``gym-soarm-teleop``): drive the jaws, record episodes.

The window and its loop are :class:`gym_soarm.teleop.session.TeleopSession`; this module
parses the command line, makes the environment, the dataset writer and the gamepad, and
prints one line per event (reset, start, gripper, save, discard, exit) on stdout.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

from gym_soarm.cli.options import (
    add_settings_arguments,
    camera_config_argument,
    settings_from_args,
    task_name,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.data import LeRobotDatasetWriter
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.record.record import (
    CAMERA_CONFIG_CHOICES,
    CAMERA_CONFIG_NONE,
    DEFAULT_RECORD_TASK,
    dataset_features,
    default_root,
    robot_type_for,
    write_recording_settings,
)
from gym_soarm.render.display import window_support_problem
from gym_soarm.tasks import get_task, task_names
from gym_soarm.teleop.gamepad import Gamepad, import_pygame
from gym_soarm.teleop.input import KEY_HELP, MAX_SPEED_M_S, MAX_TURN_SPEED_RAD_S, TeleopSpeeds
from gym_soarm.teleop.session import KEEP_CHOICES, TeleopSession
from gym_soarm.validation import check_int, parse_size, resolve_camera_config

DEFAULT_SIZE = "240x320"
DEFAULT_MAX_STEPS = 1500
DEFAULT_REPO_ID = "local/soarm_teleop"
SHOWN_WITHOUT_CAMERAS: tuple[str, ...] = ("front_camera", "wrist_camera")


TELEOP_EXCLUDES: tuple[str, ...] = (
    "task",  # --task
    "obs_type",  # images with --camera-config, the task state with --camera-config none
    "camera_config",  # --camera-config, which also takes 'none'
    "observation_height",  # --size
    "observation_width",  # --size
    "render_quality",  # --quality (also --render-quality)
    "render_mode",  # the session's own window shows the cameras
    "render_camera",
    "image_modalities",  # the window and LeRobot's videos show RGB
    "normalize_actions",  # the session sends the control mode's own values
)
"""The environment settings the teleop sets itself (the reason beside each)."""


def _key_map_text() -> str:
    width = max(len(keys) for keys, _ in KEY_HELP)
    return "\n".join(f"  {keys:<{width}}  {what}" for keys, what in KEY_HELP)


def _add_dataset_arguments(parser: argparse.ArgumentParser) -> None:
    """The task, the episodes and the dataset they are recorded into."""
    parser.add_argument(
        "--task",
        type=task_name,
        default=DEFAULT_RECORD_TASK,
        metavar="TASK",
        help=f"a task, by name, alias or gym id: {', '.join(task_names())} "
        f"(default {DEFAULT_RECORD_TASK})",
    )
    parser.add_argument(
        "--episodes", type=int, default=10, help="stop after saving N episodes (default 10)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode's reset")
    parser.add_argument(
        "--root",
        default=None,
        help="record into this dataset folder (default with --repo-id: "
        "$HF_LEROBOT_HOME/<repo-id>; without either nothing is recorded)",
    )
    parser.add_argument(
        "--repo-id",
        default=None,
        help=f"dataset name as LeRobot sees it, owner/name (default {DEFAULT_REPO_ID})",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace an existing dataset in --root"
    )
    parser.add_argument(
        "--camera-config",
        default="front_wrist",
        help=f"one of {', '.join(CAMERA_CONFIG_CHOICES)} or comma-separated camera names: "
        "the cameras shown and recorded; 'none' records observation.environment_state and "
        "shows the front and wrist cameras (default front_wrist)",
    )
    parser.add_argument(
        "--size", default=DEFAULT_SIZE, help=f"image HEIGHTxWIDTH (default {DEFAULT_SIZE})"
    )
    parser.add_argument(
        "--keep",
        choices=KEEP_CHOICES,
        default="all",
        help="'all': save every ended episode; 'success': only those where the task succeeded",
    )
    parser.add_argument(
        "--max-steps",
        type=int,
        default=DEFAULT_MAX_STEPS,
        metavar="N",
        help=f"an episode ends after N steps (default {DEFAULT_MAX_STEPS}: 30 s)",
    )


def _add_driving_arguments(parser: argparse.ArgumentParser) -> None:
    """How the jaws move: the speeds of the keys, the gamepad and the render quality."""
    parser.add_argument(
        "--speed",
        type=float,
        default=0.1,
        metavar="M_S",
        help="jaw centre speed while a key is held, m/s of simulated time, up to 0.5 (default 0.1)",
    )
    parser.add_argument(
        "--turn-speed",
        type=float,
        default=1.0,
        metavar="RAD_S",
        help="pitch and roll speed while a key is held, rad/s, up to 5 (default 1)",
    )
    parser.add_argument(
        "--gamepad",
        nargs="?",
        type=int,
        const=0,
        default=None,
        metavar="INDEX",
        help="also drive with gamepad INDEX (default 0): left stick x/y, right stick z/roll, "
        "shoulder buttons pitch, A gripper, Start save, Back discard; needs pip install pygame",
    )
    parser.add_argument(
        "--quality",
        "--render-quality",
        dest="render_quality",
        choices=("fast", "high"),
        default="fast",
        help="render quality (default fast)",
    )


DESCRIPTION = (
    "Drive the SO-101's jaw centre in the robot's base frame from the keyboard "
    "(or a gamepad) in a window that shows the cameras, and record the episodes as a "
    "LeRobotDataset v3.0 (with --root or --repo-id; without them it only drives). The "
    "simulation waits for the first key of each episode, then runs in real time (50 Hz, "
    "or as fast as rendering allows: the default 240x320 images keep it quick)."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser(
        "teleop",
        DESCRIPTION,
        epilog="keys (with the window focused):\n" + _key_map_text() + "\n\nAn episode ends "
        "when you save it, when the task succeeds, or at --max-steps; a recording saves it "
        "then (--keep success: only if the task succeeded). Each saved episode holds its "
        "instruction and next.success per frame; Ctrl-C, Esc/Q and closing the window keep "
        "every saved episode.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_dataset_arguments(parser)
    _add_driving_arguments(parser)
    add_settings_arguments(
        parser,
        exclude=TELEOP_EXCLUDES,
        defaults={"units": "lerobot"},
        description="gym.make keywords of the driven environment (see docs/keywords.md)",
    )
    return parser


def env_settings(args: argparse.Namespace) -> EnvSettings:
    """The environment settings the flags ask for (checked)."""
    camera_config = camera_config_argument(args.camera_config)
    height, width = parse_size(args.size)
    fixed: dict[str, Any] = {
        "task": get_task(args.task).name,
        "render_quality": args.render_quality,
        "observation_height": height,
        "observation_width": width,
    }
    if camera_config == CAMERA_CONFIG_NONE:
        fixed["obs_type"] = "environment_state_agent_pos"
    else:
        fixed.update(
            obs_type="pixels_agent_pos", camera_config=resolve_camera_config(camera_config)
        )
    return settings_from_args(args, **fixed)


def _check_arguments(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> tuple[EnvSettings, tuple[str, ...]]:
    """The environment settings and the cameras shown and recorded (a usage error if the
    flags are not valid)."""
    camera_config = camera_config_argument(args.camera_config)
    try:
        get_task(args.task)
        parse_size(args.size)
        cameras = (
            () if camera_config == CAMERA_CONFIG_NONE else resolve_camera_config(camera_config)
        )
        check_int("--episodes", args.episodes, 1)
        check_int("--max-steps", args.max_steps, 1)
        check_int("--seed", args.seed, 0)
        settings = env_settings(args)
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))
    return settings, tuple(cameras)


def _speeds(
    parser: argparse.ArgumentParser, args: argparse.Namespace, control_hz: int
) -> TeleopSpeeds:
    """The keys' speeds of ``--speed`` and ``--turn-speed`` (checked: a usage error if not)."""
    for flag, value, limit, unit in (
        ("--speed", args.speed, MAX_SPEED_M_S, "m/s"),
        ("--turn-speed", args.turn_speed, MAX_TURN_SPEED_RAD_S, "rad/s"),
    ):
        if not 0.0 < value <= limit:
            parser.error(f"{flag} must be above 0 and at most {limit:g} {unit}; got {value}.")
    return TeleopSpeeds(args.speed, args.turn_speed, 1.0 / control_hz)


def _open_gamepad(parser: argparse.ArgumentParser, index: int | None) -> Gamepad | None:
    """The gamepad of ``--gamepad`` (None without it); RuntimeError if it failed to open."""
    if index is None:
        return None
    try:
        gamepad = Gamepad(index)
    except ValueError as exc:  # refused input: argparse's usage error, exit 2
        parser.error(f"--gamepad: {exc}")
    print(f"gamepad {gamepad.name!r}", flush=True)
    return gamepad


def _create_writer(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    env: gym.Env,
    root: Path,
    settings: EnvSettings,
    cameras: Sequence[str],
) -> LeRobotDatasetWriter:
    """The dataset the session saves its episodes into, with the recording's settings."""
    height, width = settings.observation_height, settings.observation_width
    state_only = settings.obs_type == "environment_state_agent_pos"
    state_names = env.unwrapped.state_names if state_only else None
    features = dataset_features(cameras, height, width, state_names, settings.control_mode)
    robot_type = robot_type_for(settings.units)
    try:
        writer = LeRobotDatasetWriter.create(
            root,
            settings.control_hz,
            features,
            robot_type=robot_type,
            overwrite=args.overwrite,
        )
    except (ValueError, FileExistsError, ImportError) as exc:
        parser.error(str(exc))
    write_recording_settings(root, settings)
    print(f"recording into {root}", flush=True)
    return writer


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    settings, cameras = _check_arguments(parser, args)
    state_only = settings.obs_type == "environment_state_agent_pos"
    recording = args.root is not None or args.repo_id is not None
    repo_id = args.repo_id or DEFAULT_REPO_ID
    speeds = _speeds(parser, args, settings.control_hz)
    if args.gamepad is not None:
        try:
            import_pygame()
        except ImportError as exc:
            parser.error(f"--gamepad: {exc}")
    problem = window_support_problem()
    if problem is not None:
        print(problem, file=sys.stderr)
        return 1
    try:
        gamepad = _open_gamepad(parser, args.gamepad)
    except RuntimeError as exc:  # the device failed to open
        print(f"--gamepad: {exc}", file=sys.stderr)
        return 1

    writer = None
    root = Path(args.root) if args.root else default_root(repo_id)
    try:
        env = gym.make(
            get_task(args.task).env_id, max_episode_steps=args.max_steps, settings=settings
        )
    except (ValueError, TypeError) as exc:
        if gamepad is not None:
            gamepad.close()
        parser.error(str(exc))
    try:
        if recording:
            writer = _create_writer(parser, args, env, root, settings, cameras)
        session = TeleopSession(
            env,
            writer,
            cameras=SHOWN_WITHOUT_CAMERAS if state_only else cameras,
            episodes=args.episodes,
            seed=args.seed,
            keep=args.keep,
            speeds=speeds,
            gamepad=gamepad,
            report=lambda line: print(line, flush=True),
        )
        summary = session.run()
    finally:
        if writer is not None:
            writer.finalize()
        env.close()
        if gamepad is not None:
            gamepad.close()
    if writer is not None:
        print(
            f"{summary.episodes} episodes, {summary.frames} frames saved in {root}; load it "
            f"with: LeRobotDataset({repo_id!r}, root={str(root)!r})",
            flush=True,
        )
    return 130 if summary.interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
