"""Replaying a LeRobot SO-101 dataset's actions in the simulation, and how well it tracks.

:func:`replay` reads a LeRobotDataset v3.0 folder (written by the real follower with
``lerobot-record``, by LeRobot's ``LeRobotDataset`` API or by ``python -m gym_soarm.record``)
with pyarrow alone, no LeRobot and no torch. Per episode it places the simulated arm at
the episode's first recorded ``observation.state``, sends the recorded ``action`` frame by
frame as joint targets, and compares the simulated ``agent_pos`` with the recorded
``observation.state`` of the following frames: the tracking error per joint, in the
dataset's units.

**What the dataset must hold.** ``action`` and ``observation.state``, six values each
named as LeRobot's SO-101 follower names them (``shoulder_pan.pos`` ... ``gripper.pos``):
absolute joint targets, as ``lerobot-record`` and the recorder's default
``control_mode="joint_pos"`` write them.

**Units.** A gym_soarm recording says how it was written (``meta/gym_soarm.json``: units,
wrist offset, calibration file); otherwise ``robot_type`` ``"gym_soarm"`` means radians
and any other means LeRobot's units, degrees by default (``"lerobot"``, the follower's
default since LeRobot 0.4.4). Arguments given to :func:`replay` win over both. Datasets recorded in LeRobot's older -100..100
convention need ``units="lerobot_range"``; a real arm's calibration file
(``calibration``, see :mod:`gym_soarm.real.calibration`) and ``wrist_roll_offset_deg`` apply
as in ``gym.make``.

**Time.** The simulation steps at its ``control_hz`` (50 by default; pass
``control_hz=30`` for a 30 fps recording). At another frame rate each control step sends
the action of the frame in force at the step's start (the follower, too, holds its last
goal until the next), and the simulated joints are interpolated linearly to each recorded
frame's time (``frame / fps``). When the rates agree every frame is one step and nothing
is interpolated.

**The scene.** :data:`REPLAY_TASK` by default: the arm and a target ball that collides
with nothing, so no simulated object is in the way of a real arm's motion. A real
gripper that closed on an object stops at the object, the simulated one closes further:
expect the gripper's error to show the grasps. A dataset recorded by
``python -m gym_soarm.record`` lists each episode's task and reset seed
(``meta/variation.jsonl``): each episode is replayed in its own task, reset with its own
seed, so the objects are where they were.
Giving ``task`` replays every episode in that scene, episode ``k`` reset with
``seed + k``.

**The recording's settings.** A gym_soarm recording stores the environment settings it
was made with (``meta/gym_soarm.json``, see :class:`gym_soarm.envs.settings.EnvSettings`).
The replay moves the arm as the recording did: with its ``dynamics``, ``servo_model``
and ``control_hz`` (:data:`ARM_SETTINGS`); replaying each episode in its own task and seed
it also takes the scene's randomisation, placement and distractors
(:data:`SCENE_SETTINGS`), so every reset draws what the recording's drew. Arguments
given win over the recording's.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm import constants
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.real.dataset import KEYS as KEYS  # the features a replay reads
from gym_soarm.real.dataset import ReplayDataset, read_replay_dataset
from gym_soarm.real.dynamics import load_dynamics
from gym_soarm.real.units import FEATURE_NAMES, UNITS, joint_units
from gym_soarm.tasks import get_task, reach_target
from gym_soarm.validation import check_choice, check_int

REPLAY_TASK = reach_target.SPEC.name
"""The default scene: the arm and a target ball that collides with nothing."""
SIM_FPS = constants.RENDER_FPS
"""The simulation's step rate (Hz)."""
FIGURES: tuple[str, ...] = ("mean_abs", "rms", "max_abs")
"""The error figures of each joint: mean absolute, root mean square, largest absolute."""
UNIT_LABELS: dict[str, str] = {
    "radians": "rad",
    "lerobot": "deg (gripper 0-100)",
    "lerobot_range": "-100..100 (gripper 0-100)",
}


def _figures(error: np.ndarray) -> dict[str, dict[str, float]]:
    """Per joint (feature name): mean absolute, RMS and largest absolute error."""
    magnitude = np.abs(error)
    return {
        name: {
            "mean_abs": float(magnitude[:, j].mean()),
            "rms": float(np.sqrt(np.mean(error[:, j] ** 2))),
            "max_abs": float(magnitude[:, j].max()),
        }
        for j, name in enumerate(FEATURE_NAMES)
    }


@dataclass(frozen=True)
class EpisodeReplay:
    """One replayed episode.

    Attributes:
        episode_index: the dataset's episode index.
        times_s: the compared frames' times (s), frames 1 to the last.
        recorded: the recorded ``observation.state`` of those frames, (frames - 1, 6).
        simulated: the simulated ``agent_pos`` at those times, same shape and units.
    """

    episode_index: int
    times_s: np.ndarray
    recorded: np.ndarray
    simulated: np.ndarray

    @property
    def error(self) -> np.ndarray:
        """Simulated minus recorded, per frame and joint."""
        return self.simulated - self.recorded

    def figures(self) -> dict[str, dict[str, float]]:
        """Per joint: ``mean_abs``, ``rms`` and ``max_abs`` of the error."""
        return _figures(self.error)


@dataclass(frozen=True)
class ReplayReport:
    """The outcome of :func:`replay`: per-episode tracking errors and how they came about."""

    root: str
    units: str
    fps: int
    robot_type: str | None
    task: str
    episodes: tuple[EpisodeReplay, ...]
    settings: EnvSettings | None = None
    """The environment settings replayed with (the first scene's task)."""

    def figures(self) -> dict[str, dict[str, float]]:
        """Per joint, over every compared frame of every episode."""
        return _figures(np.concatenate([e.error for e in self.episodes]))

    def to_json(self) -> dict[str, Any]:
        """The figures, per episode and overall, with what was replayed."""
        return {
            "root": self.root,
            "units": self.units,
            "fps": self.fps,
            "robot_type": self.robot_type,
            "task": self.task,
            "frames_compared": int(sum(len(e.times_s) for e in self.episodes)),
            "overall": self.figures(),
            "episodes": [
                {
                    "episode_index": e.episode_index,
                    "frames_compared": len(e.times_s),
                    "joints": e.figures(),
                }
                for e in self.episodes
            ],
        }

    def table(self) -> str:
        """The overall figures as a text table, one row per joint."""
        unit = UNIT_LABELS[self.units]
        frames = sum(len(e.times_s) for e in self.episodes)
        lines = [
            f"tracking error over {len(self.episodes)} episode(s), {frames} frames at "
            f"{self.fps} fps, in {unit}",
            f"{'joint':<20}{'mean abs':>12}{'rms':>12}{'max abs':>12}",
        ]
        for name, row in self.figures().items():
            lines.append(
                f"{name:<20}{row['mean_abs']:>12.4g}{row['rms']:>12.4g}{row['max_abs']:>12.4g}"
            )
        return "\n".join(lines)


def resolve_units(
    dataset: ReplayDataset,
    units: str | None = None,
    calibration: str | os.PathLike[str] | None = None,
    wrist_roll_offset_deg: float | None = None,
) -> tuple[str, float, str | os.PathLike[str] | None]:
    """The units, wrist offset and calibration file to read ``dataset``'s joints with.

    Arguments given win; None takes a gym_soarm recording's own settings, else the
    units detected from ``robot_type``, no offset and no calibration. All three are
    checked (the calibration file is read).

    Raises:
        ValueError: a bad unit name, offset or calibration file.
    """
    settings = dataset.settings or {}
    from_settings = units is None and bool(settings)
    chosen_units = units or dataset.units
    if wrist_roll_offset_deg is None:
        wrist_roll_offset_deg = settings.get("wrist_roll_offset_deg", 0.0) if from_settings else 0.0
    if calibration is None and from_settings:
        calibration = settings.get("calibration")
    joint_units(chosen_units, wrist_roll_offset_deg, calibration)  # checks them all first
    return chosen_units, wrist_roll_offset_deg, calibration


def episode_scenes(
    dataset: ReplayDataset, task: str | None = None, seed: int = 0
) -> dict[int, tuple[str, int]]:
    """Episode index -> (task, reset seed) of the scene it is replayed in.

    The episode's recorded task and seed where the dataset lists them and ``task`` is
    None; else ``task`` (default :data:`REPLAY_TASK`) reset with ``seed + index``.
    """
    scenes: dict[int, tuple[str, int]] = {}
    for index in dataset.episodes:
        origin = (dataset.origins or {}).get(index)
        if task is None and origin is not None:
            scenes[index] = (get_task(origin[0]).name, origin[1])
        else:
            scenes[index] = (task or REPLAY_TASK, seed + index)
    return scenes


def start_episode(env: Any, state: np.ndarray, seed: int) -> None:
    """Reset ``env`` (the unwrapped environment) with ``seed`` and place the arm at a
    recorded ``observation.state`` (dataset units), its servo targets there too."""
    env.reset(seed=seed)
    physics = env.physics
    start = env.joint_units.to_radians(state)
    low, high = physics.control_range()
    start = np.clip(start, low, high)
    physics.set_joint_angles(start)
    env.hold_servo_targets(start)
    physics.forward()


def frame_of_steps(steps: int, frames: int, fps: float, sim_fps: float = SIM_FPS) -> np.ndarray:
    """For each of ``steps`` control steps (``sim_fps`` a second), the frame whose action
    is in force at its start."""
    k = np.arange(steps)
    return np.minimum((k * fps // sim_fps).astype(int), frames - 2)


ARM_SETTINGS: tuple[str, ...] = ("dynamics", "servo_model", "control_hz")
"""Settings of a recording that replay and sysid take beside its units: how the arm moves
(and how often it is told to)."""
SCENE_SETTINGS: tuple[str, ...] = (
    "visual_randomization",
    "physics_randomization",
    "object_placement",
    "distractors",
)
"""Settings of a recording that a replay takes when it replays each episode in its own
recorded task and seed: what is on the table and what its resets draw."""
REPLAY_OVERRIDES: tuple[str, ...] = (*ARM_SETTINGS, *SCENE_SETTINGS)
"""The environment keywords :func:`replay` takes in ``settings`` (its own arguments give
the units, offset, calibration and task)."""


def replay_settings(
    dataset: ReplayDataset,
    task: str | None = None,
    units: str | None = None,
    calibration: str | os.PathLike[str] | None = None,
    wrist_roll_offset_deg: float | None = None,
    overrides: Mapping[str, Any] | None = None,
    taken: Sequence[str] = REPLAY_OVERRIDES,
) -> EnvSettings:
    """The environment settings to replay ``dataset`` with (``task``: the first scene's).

    State observations and joint targets; the units, offset and calibration of
    :func:`resolve_units`; the recording's ``taken`` settings (the arm's always, the
    scene's when each episode is replayed in its recorded task); ``overrides`` win
    over the recording's.

    Raises:
        ValueError: a bad value, or an override :data:`REPLAY_OVERRIDES` does not name.
    """
    overrides = dict(overrides or {})
    unknown = sorted(set(overrides) - set(REPLAY_OVERRIDES))
    if unknown:
        raise ValueError(
            f"settings of a replay may be {', '.join(REPLAY_OVERRIDES)}; got {unknown}. Give "
            "units, calibration, wrist_roll_offset_deg and task as replay's own arguments."
        )
    chosen_units, offset, calibration = resolve_units(
        dataset, units, calibration, wrist_roll_offset_deg
    )
    scenes = episode_scenes(dataset, task)
    own_scenes = task is None and bool(dataset.origins)
    values: dict[str, Any] = {}
    recorded = dataset.recorded
    if recorded is not None:
        wanted = [k for k in taken if k in ARM_SETTINGS or (own_scenes and k in SCENE_SETTINGS)]
        values.update({k: getattr(recorded, k) for k in wanted})
    elif dataset.settings and dataset.settings.get("dynamics") and "dynamics" in taken:
        values["dynamics"] = dataset.settings["dynamics"]  # recordings before the "env" key
    values.update(overrides)
    first = next(iter(scenes.values()))[0] if scenes else (task or REPLAY_TASK)
    return EnvSettings.from_kwargs(
        **values,
        task=first,
        obs_type="environment_state_agent_pos",
        units=chosen_units,
        wrist_roll_offset_deg=offset,
        calibration=None if calibration is None else os.fspath(calibration),
    )


@contextlib.contextmanager
def scene_envs(settings: EnvSettings) -> Iterator[Callable[[str], Any]]:
    """Environments to replay a dataset in, one per scene: ``env_for(task_name)`` makes
    one with ``settings`` (its task replaced) when first asked for it and returns the
    unwrapped env; all are closed when the block ends."""
    import gymnasium as gym

    envs: dict[str, Any] = {}

    def env_for(name: str) -> Any:
        if name not in envs:
            spec = get_task(name)
            envs[name] = gym.make(spec.env_id, settings=settings.replace(task=spec.name))
        return envs[name].unwrapped

    try:
        yield env_for
    finally:
        for env in envs.values():
            env.close()


def replay(
    root: str | os.PathLike[str],
    episodes: Sequence[int] | None = None,
    units: str | None = None,
    calibration: str | os.PathLike[str] | None = None,
    wrist_roll_offset_deg: float | None = None,
    task: str | None = None,
    seed: int = 0,
    dynamics: str | os.PathLike[str] | None = None,
    settings: Mapping[str, Any] | None = None,
) -> ReplayReport:
    """Drive the simulation with a dataset's actions; compare with its recorded states.

    Args:
        root: a LeRobotDataset v3.0 folder (see the module docstring).
        episodes: episode indices to replay; None for all.
        units: the dataset's joint units (one of :data:`gym_soarm.real.units.UNITS`); None to
            read them from a gym_soarm recording's settings, or from ``robot_type``.
        calibration: the recording arm's LeRobot calibration file (LeRobot units only);
            None for the recording's own (gym_soarm recordings) or none.
        wrist_roll_offset_deg: the arm's wrist_roll reading when the model's is at 0 rad;
            None for the recording's own (gym_soarm recordings) or 0.
        task: the scene of every episode (a registered task or alias); None for each
            episode's recorded task where the dataset lists it, else :data:`REPLAY_TASK`.
        seed: with ``task`` (or a dataset that lists no origins), episode ``k`` resets the
            scene with ``seed + k``.
        dynamics: a ``gym_soarm.dynamics/1`` file (servo gains, joint figures, control
            delay; see :mod:`gym_soarm.real.dynamics`) to replay with; None for the
            recording's own (gym_soarm recordings store theirs) or the model's own.
        settings: further ``gym.make`` keywords of :data:`REPLAY_OVERRIDES` (e.g.
            ``{"servo_model": "sts3215"}``) over the recording's own.

    Raises:
        ValueError: a bad argument or dataset (nothing is simulated then).
        ImportError: pyarrow is missing.
    """

    if task is not None:
        task = get_task(task).name
    check_choice("units", units, UNITS, none_ok=True)
    seed = check_int("seed", seed, 0)
    if episodes is not None:
        episodes = [check_int("episode", e, 0) for e in episodes]
    overrides = dict(settings or {})
    if dynamics is not None:
        load_dynamics(dynamics)  # checks the file first
        overrides["dynamics"] = os.fspath(dynamics)
    dataset = read_replay_dataset(root, episodes)
    env_settings = replay_settings(
        dataset, task, units, calibration, wrist_roll_offset_deg, overrides
    )
    if env_settings.dynamics is not None:
        load_dynamics(env_settings.dynamics)  # a recording's file: checked before simulating
    scenes = episode_scenes(dataset, task, seed)
    with scene_envs(env_settings) as env_for:
        replays = []
        for index, (actions, states) in dataset.episodes.items():
            name, episode_seed = scenes[index]
            env = env_for(name)
            replays.append(_replay_episode(env, index, actions, states, dataset.fps, episode_seed))
    label = ",".join(dict.fromkeys(name for name, _ in scenes.values()))
    return ReplayReport(
        str(root),
        env_settings.units,
        dataset.fps,
        dataset.robot_type,
        label,
        tuple(replays),
        env_settings,
    )


def _replay_episode(
    env: Any, index: int, actions: np.ndarray, states: np.ndarray, fps: float, seed: int
) -> EpisodeReplay:
    frames = len(states)
    if frames < 2:
        raise ValueError(
            f"episode {index} has {frames} frame(s); a replay compares the frames after the "
            "first, so it needs at least 2. Leave that episode out."
        )
    start_episode(env, states[0], seed)
    physics = env.physics
    # Control steps until the last frame's time; each sends the frame in force then.
    sim_fps = env.control_hz
    steps = math.ceil((frames - 1) * sim_fps / fps - 1e-9)
    positions = np.empty((steps + 1, len(FEATURE_NAMES)))
    positions[0] = env.joint_units.from_radians(physics.joint_angles())
    for k, frame in enumerate(frame_of_steps(steps, frames, fps, sim_fps)):
        obs, *_ = env.step(actions[frame].astype(np.float32))
        positions[k + 1] = obs["agent_pos"]
    times = np.arange(1, frames) / fps
    if fps == sim_fps:
        simulated = positions[1:frames]
    else:
        sim_times = np.arange(steps + 1) / sim_fps
        simulated = np.stack(
            [np.interp(times, sim_times, positions[:, j]) for j in range(positions.shape[1])],
            axis=1,
        )
    return EpisodeReplay(index, times, states[1:], simulated)


# --- the plot ---------------------------------------------------------------------------------
_RECORDED_BGR = (40, 40, 40)
_SIMULATED_BGR = (30, 120, 230)
_PANEL_W, _PANEL_H, _MARGIN = 560, 240, 48


def plot_replay(report: ReplayReport, path: str | os.PathLike[str]) -> None:
    """Write a PNG: per joint, the recorded and the simulated position over time.

    Six panels (two columns); episodes follow one another along the time axis, split by
    grey lines. Recorded in dark grey, simulated in orange. Drawn with OpenCV.

    Raises:
        ValueError: ``path`` does not end in ``.png`` or cannot be written.
    """
    import cv2

    if not str(path).lower().endswith(".png"):
        raise ValueError(f"plot path must end in .png; got {os.fspath(path)!r}.")
    recorded = np.concatenate([e.recorded for e in report.episodes])
    simulated = np.concatenate([e.simulated for e in report.episodes])
    bounds = np.cumsum([len(e.times_s) for e in report.episodes])[:-1]
    n = len(recorded)
    cols, rows = 2, math.ceil(len(FEATURE_NAMES) / 2)
    width = cols * (_PANEL_W + _MARGIN) + _MARGIN
    height = rows * (_PANEL_H + _MARGIN) + _MARGIN + 24
    image = np.full((height, width, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    title = (
        f"{Path(report.root).name}: recorded (grey) vs simulated (orange), "
        f"{len(report.episodes)} episode(s), {UNIT_LABELS[report.units]}"
    )
    cv2.putText(image, title, (_MARGIN, 28), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, name in enumerate(FEATURE_NAMES):
        x0 = _MARGIN + (j % cols) * (_PANEL_W + _MARGIN)
        y0 = _MARGIN + 24 + (j // cols) * (_PANEL_H + _MARGIN)
        cv2.rectangle(image, (x0, y0), (x0 + _PANEL_W, y0 + _PANEL_H), (180, 180, 180), 1)
        values = np.concatenate([recorded[:, j], simulated[:, j]])
        lo, hi = float(values.min()), float(values.max())
        if hi - lo < 1e-9:
            lo, hi = lo - 1.0, hi + 1.0
        for b in bounds:
            x = x0 + round(float(b) / max(n - 1, 1) * _PANEL_W)
            cv2.line(image, (x, y0), (x, y0 + _PANEL_H), (210, 210, 210), 1)
        for series, colour, thickness in (
            (recorded[:, j], _RECORDED_BGR, 2),
            (simulated[:, j], _SIMULATED_BGR, 1),
        ):
            xs = x0 + np.linspace(0, _PANEL_W, n) if n > 1 else np.array([x0 + _PANEL_W / 2])
            ys = y0 + _PANEL_H - (series - lo) / (hi - lo) * _PANEL_H
            points = np.round(np.stack([xs, ys], axis=1)).astype(np.int32)
            cv2.polylines(image, [points], False, colour, thickness, cv2.LINE_AA)
        cv2.putText(image, name, (x0 + 6, y0 + 18), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for value, y in ((hi, y0 + 14), (lo, y0 + _PANEL_H - 6)):
            label = f"{value:.4g}"
            x = x0 + _PANEL_W - 8 - 7 * len(label)
            cv2.putText(image, label, (x, y), font, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    if not cv2.imwrite(os.fspath(path), image):
        raise ValueError(f"plot path {os.fspath(path)!r} cannot be written; check its folder.")
