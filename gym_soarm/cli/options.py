"""Command-line options shared by gym_soarm's programs (recorder, teleop, expert)."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from gym_soarm import constants
from gym_soarm.control import CONTROL_MODES
from gym_soarm.data.replay import REPLAY_TASK
from gym_soarm.tasks import task_names, task_spellings
from gym_soarm.tasks.suites import resolve_selection
from gym_soarm.units import UNITS


def task_selection(text: str) -> str:
    """argparse type of ``--task``: a task, a suite or a comma list of them, checked."""
    try:
        resolve_selection(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def int_at_least(minimum: int) -> Callable[[str], int]:
    """argparse type of an int option that must be ``minimum`` or more (``--steps``)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected an int >= {minimum}; got {text!r}"
            ) from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected an int >= {minimum}; got {value}")
        return value

    return parse


def add_dataset_action_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--units``, ``--wrist-roll-offset-deg``, ``--calibration`` and ``--control-mode``:
    what the recorded states and actions hold."""
    parser.add_argument(
        "--units", choices=UNITS, default="lerobot", help="joint units (default lerobot)"
    )
    parser.add_argument(
        "--wrist-roll-offset-deg",
        type=float,
        default=0.0,
        metavar="DEG",
        help="with LeRobot units: the real arm's wrist_roll reading when the model's is at "
        "0 rad, e.g. -90 (default 0)",
    )
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="PATH",
        help="with LeRobot units: a real SO-101 follower's LeRobot calibration JSON; states "
        "and actions are then that arm's values",
    )
    parser.add_argument(
        "--control-mode",
        choices=CONTROL_MODES,
        default="joint_pos",
        help="what the recorded action is: joint targets (joint_pos), their changes "
        "(joint_delta), the jaws' pose in the robot's base frame (ee_pose) or its changes "
        "(ee_delta) (default joint_pos)",
    )


def add_dataset_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """How a dataset's joints and scenes are read back (replay and sysid): ``--units``,
    ``--calibration``, ``--wrist-roll-offset-deg``, ``--task`` and ``--seed``."""
    parser.add_argument(
        "--units",
        choices=UNITS,
        default=None,
        help="the dataset's joint units (default: a gym_soarm recording's own, else from robot_type: gym_soarm = radians, "
        "else lerobot; use lerobot_range for LeRobot's older -100..100 datasets)",
    )
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="PATH",
        help="the recording arm's LeRobot calibration JSON (LeRobot units)",
    )
    parser.add_argument(
        "--wrist-roll-offset-deg",
        type=float,
        default=None,
        metavar="DEG",
        help="the arm's wrist_roll reading when the model's is at 0 rad (default: the "
        "recording's own, else 0)",
    )
    parser.add_argument(
        "--task",
        choices=task_spellings(),
        default=None,
        metavar="TASK",
        help=f"the scene of every episode: {', '.join(task_names())} (default: each "
        f"episode's recorded task in gym_soarm recordings, else {REPLAY_TASK}: no object "
        "in the way)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="episode K resets the scene with SEED + K, as the recorder did (default 0)",
    )


def add_dynamics_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--dynamics``: a fitted arm's servo and joint figures (gym_soarm.dynamics)."""
    parser.add_argument(
        "--dynamics",
        default=None,
        metavar="PATH",
        help="a gym_soarm.dynamics/1 JSON file (python -m gym_soarm.sysid fits one to a real "
        "arm's dataset): the simulated servos and joints move with its figures",
    )


def camera_config_argument(text: str) -> str | list[str]:
    """``--camera-config`` as the recorder takes it: a config name (``front_wrist``,
    ``none`` ...) as is, camera names (``front_camera,wrist_camera``) as a list."""
    if "," in text or text in constants.CAMERA_NAMES:
        return [name.strip() for name in text.split(",") if name.strip()]
    return text
