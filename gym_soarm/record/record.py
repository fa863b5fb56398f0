"""Record the scripted expert as a LeRobotDataset v3.0, without LeRobot or torch.

Run ``python -m gym_soarm.record --help``. For example, 50 lift demonstrations with the
front and wrist cameras at 480 x 640, in LeRobot's follower units::

    python -m gym_soarm.record --task LiftCube-v0 --episodes 50 --seed 0 \\
        --root datasets/soarm_lift --repo-id local/soarm_lift

Each frame holds the observation before a step and the action sent at that step:
``observation.state`` (the six joints in the chosen units, named ``shoulder_pan.pos`` ...
``gripper.pos``), ``action`` (the expert's action in the chosen control mode: by default
its six joint targets, same units; see :mod:`gym_soarm.envs.control`), one
``observation.images.<camera>`` video per camera (or ``observation.environment_state``
when recording without cameras), and ``next.reward``, ``next.success``, ``next.done`` of
the step. Each episode's task sentence is the environment's ``task_description`` after its reset
(the instruction tasks with a choice draw at reset).

With ``--dart-noise SIGMA`` the arm executes the expert's action plus Gaussian noise of
standard deviation SIGMA radians on every joint, while the dataset keeps the expert's
clean action as the label (DART): the demonstrations then visit the states a slightly
imperfect policy reaches, and show how the expert recovers from them.

The expert computes its joint targets in radians from the simulation state; the
environment's control mode turns them into its action
(``env.unwrapped.control.action_for_targets``): joint targets in the recording's units
(:mod:`gym_soarm.real.units`), their changes, or the jaws' pose or its change.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.data import LeRobotDatasetWriter
from gym_soarm.envs.control import action_names
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.real.units import FEATURE_NAMES, joint_units
from gym_soarm.record.attempt import AttemptPlan, record_here
from gym_soarm.tasks import get_task, lift_cube
from gym_soarm.tasks.suites import (
    SelectedTask,
    distinct_tasks,
    resolve_selection,
    shared_state_names,
)
from gym_soarm.validation import ArgumentTypeError, check_int, parse_size, resolve_camera_config

CAMERA_CONFIG_NONE = "none"
CAMERA_CONFIG_CHOICES: tuple[str, ...] = (*constants.CAMERA_CONFIGS, CAMERA_CONFIG_NONE)
KEEP_CHOICES: tuple[str, ...] = ("success", "all")
START_METHODS: tuple[str, ...] = ("forkserver", "spawn")
VARIATION_KEYWORDS: tuple[str, ...] = (
    "visual_randomization",
    "physics_randomization",
    "servo_model",
    "object_placement",
    "distractors",
)
SETTINGS_PATH = "meta/gym_soarm.json"
"""What a gym_soarm recording's joint values mean: units, wrist offset, calibration, mode."""
DEFAULT_RECORD_TASK = lift_cube.SPEC.name
"""The recorder's default task: lifting the cube, the shortest demonstration."""


def robot_type_for(units: str) -> str:
    """The dataset's ``robot_type``: the real follower's in LeRobot's units, else gym_soarm."""
    return "gym_soarm" if units == "radians" else "so101_follower"


def default_root(repo_id: str) -> Path:
    """Where LeRobot looks for ``repo_id`` when no root is given (``$HF_LEROBOT_HOME/<repo_id>``)."""
    home = os.environ.get("HF_LEROBOT_HOME")
    if home is None:
        hf_home = os.environ.get("HF_HOME")
        if hf_home is None:
            cache = os.environ.get("XDG_CACHE_HOME", os.path.join("~", ".cache"))
            hf_home = os.path.join(cache, "huggingface")
        home = os.path.join(hf_home, "lerobot")
    return Path(home).expanduser() / repo_id


@dataclasses.dataclass(frozen=True)
class RecordSummary:
    """What a recording produced."""

    root: Path
    episodes: int
    frames: int
    attempts: int
    successes: int
    seconds: float
    bytes_on_disk: int
    interrupted: bool = False
    tasks: tuple[str, ...] = ()
    """The recorded tasks, in recording order (``episodes`` of each were asked for)."""

    @property
    def success_rate(self) -> float:
        """Successful attempts / attempts (every attempt, kept or not)."""
        return self.successes / self.attempts if self.attempts else 0.0

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def text(self) -> str:
        mb = self.bytes_on_disk / 1024**2
        per_episode = mb / self.episodes if self.episodes else 0.0
        state = "interrupted: " if self.interrupted else ""
        return (
            f"{state}{self.episodes} episodes, {self.frames} frames, expert success "
            f"{self.successes}/{self.attempts} = {100 * self.success_rate:.1f} %, "
            f"{mb:.1f} MB on disk ({per_episode:.2f} MB/episode), {self.seconds:.1f} s "
            f"({self.frames_per_second:.0f} frames/s) -> {self.root}"
        )


def dataset_features(
    cameras: Sequence[str],
    height: int,
    width: int,
    environment_state: Sequence[str] | None,
    control_mode: str = "joint_pos",
) -> dict[str, dict[str, Any]]:
    """The LeRobot features of a gym_soarm recording.

    Args:
        cameras: one video feature per camera.
        height: image height.
        width: image width.
        environment_state: the names of ``observation.environment_state``'s values
            (the env's ``state_names``), or None to record no environment state.
        control_mode: names the ``action`` values (``shoulder_pan.pos`` ... for
            ``joint_pos``, ``ee.x`` ... for ``ee_pose``; see
            :func:`gym_soarm.envs.control.action_names`).
    """
    names = list(FEATURE_NAMES)
    actions = list(action_names(control_mode))
    features: dict[str, dict[str, Any]] = {
        "action": {"dtype": "float32", "shape": (len(actions),), "names": actions},
        "observation.state": {"dtype": "float32", "shape": (len(names),), "names": names},
    }
    for camera in cameras:
        features[f"observation.images.{camera}"] = {
            "dtype": "video",
            "shape": (height, width, 3),
            "names": ["height", "width", "channels"],
        }
    if environment_state is not None:
        features["observation.environment_state"] = {
            "dtype": "float32",
            "shape": (len(environment_state),),
            "names": list(environment_state),
        }
    features["next.reward"] = {"dtype": "float32", "shape": (1,), "names": None}
    features["next.success"] = {"dtype": "bool", "shape": (1,), "names": None}
    features["next.done"] = {"dtype": "bool", "shape": (1,), "names": None}
    return features


def write_recording_settings(root: str | os.PathLike[str], settings: EnvSettings) -> None:
    """Write ``meta/gym_soarm.json``: the environment settings the dataset was recorded
    with (``"env"``, :meth:`~gym_soarm.envs.settings.EnvSettings.to_dict`, file paths made
    absolute) and, as before, how to read its joint values back (units, wrist offset,
    calibration, control mode, dynamics). :func:`gym_soarm.real.replay.replay` and
    :func:`gym_soarm.real.sysid.fit_dynamics` read it."""
    paths = {
        name: os.path.abspath(value)
        for name in ("calibration", "dynamics")
        if (value := getattr(settings, name)) is not None
    }
    stored = settings.replace(**paths) if paths else settings
    content = {
        "units": stored.units,
        "wrist_roll_offset_deg": stored.wrist_roll_offset_deg,
        "calibration": stored.calibration,
        "control_mode": stored.control_mode,
        "dynamics": stored.dynamics,
        "env": stored.to_dict(),
    }
    path = Path(root) / SETTINGS_PATH
    path.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")


def read_recording_settings(root: str | os.PathLike[str]) -> EnvSettings | None:
    """The environment settings ``meta/gym_soarm.json`` of a recording stores; None for
    a dataset without them (not a gym_soarm recording, or an older one).

    Raises:
        ValueError: the file cannot be read or holds bad settings.
    """
    path = Path(root) / SETTINGS_PATH
    if not path.is_file():
        return None
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path} cannot be read ({exc}); check the file.") from exc
    if not isinstance(content, dict) or "env" not in content:
        return None
    try:
        return EnvSettings.from_dict(content["env"])
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path} holds bad environment settings: {exc}") from exc


_RECORD_DEFAULTS: dict[str, Any] = {
    "units": "lerobot",
    "wrist_roll_offset_deg": 0.0,
    "control_mode": "joint_pos",
    "calibration": None,
    "dynamics": None,
}


_NOT_RECORDED = ("render_mode", "image_modalities", "normalize_actions")
"""Settings the recorder leaves at their defaults (the dataset could not hold them)."""


def _recording_settings(
    settings: EnvSettings | None,
    task: str,
    variation: Mapping[str, Any] | None,
    **keywords: Any,
) -> EnvSettings:
    """The settings of a recording: ``settings`` as given (then ``keywords`` and
    ``variation`` must be the recorder's defaults), else built from them."""
    variation = dict(variation or {})
    unknown = sorted(set(variation) - set(VARIATION_KEYWORDS))
    if unknown:
        raise ValueError(
            f"variation takes the keywords {', '.join(VARIATION_KEYWORDS)}; got {unknown}."
        )
    keywords.update(variation)
    if settings is None:
        kwargs = {k: v for k, v in keywords.items() if v is not None or k in _RECORD_DEFAULTS}
        if kwargs.get("calibration") is not None:
            kwargs["calibration"] = os.fspath(kwargs["calibration"])
        return EnvSettings.from_kwargs(task=task, **kwargs)
    if not isinstance(settings, EnvSettings):
        raise ArgumentTypeError(
            f"settings must be a gym_soarm.envs.settings.EnvSettings or None; got "
            f"{type(settings).__name__}. Build one with EnvSettings(...)."
        )
    unfit = {k: v for k, v in settings.changed().items() if k in _NOT_RECORDED}
    if unfit:
        raise ValueError(
            f"the recorder cannot record with {unfit}: it writes RGB videos of the control "
            f"mode's own actions, without a window. Leave {', '.join(sorted(unfit))} at "
            "their defaults."
        )
    given = sorted(
        k
        for k, v in keywords.items()
        if (v != _RECORD_DEFAULTS[k] if k in _RECORD_DEFAULTS else True)
    )
    if given:
        raise ValueError(
            f"pass either settings or the keywords {given}, not both. Put them in the "
            f"settings: settings.replace({'=..., '.join(given)}=...)."
        )
    return settings.replace(task=task)


def record(
    root: str | os.PathLike[str],
    task: str = DEFAULT_RECORD_TASK,
    episodes: int = 10,
    seed: int = 0,
    camera_config: str | Sequence[str] = "front_wrist",
    size: tuple[int, int] = (480, 640),
    units: str = "lerobot",
    wrist_roll_offset_deg: float = 0.0,
    keep: str = "success",
    dart_noise: float = 0.0,
    overwrite: bool = False,
    max_attempts: int | None = None,
    progress: bool = False,
    workers: int = 1,
    start_method: str | None = None,
    ray_address: str | None = None,
    variation: Mapping[str, Any] | None = None,
    control_mode: str = "joint_pos",
    calibration: str | os.PathLike[str] | None = None,
    dynamics: str | os.PathLike[str] | None = None,
    settings: EnvSettings | None = None,
) -> RecordSummary:
    """Record ``episodes`` episodes of the scripted expert into a dataset folder.

    Attempt ``k`` resets the environment with ``seed + k``, so the same arguments give
    the same actions and states.

    Args:
        root: the dataset folder (new or empty, or an old dataset with ``overwrite``).
        task: a registered task's name (see :func:`gym_soarm.tasks.task_names`), an
            alias (``"lift"``), a suite (``"soarm_core"``) or a comma list of them (see
            :mod:`gym_soarm.tasks.suites`). Several tasks go into one dataset, one task
            after the other, each episode with its own instruction; a suite's settings
            (``soarm_robust``'s randomisation) override ``variation``. Without cameras
            the tasks must share one environment-state layout.
        episodes: episodes to keep per task. Task ``i``'s attempt ``k`` resets with
            ``seed + k``, as a recording of that task alone would.
        seed: seed of the first attempt.
        camera_config: ``"front_only"``, ``"front_wrist"``, ``"all"``, camera names, or
            ``"none"`` (no video; ``observation.environment_state`` is recorded instead).
        size: image (height, width), both even.
        units: joint units of states and actions, one of :data:`gym_soarm.real.units.UNITS`.
        wrist_roll_offset_deg: with LeRobot units, the real arm's wrist_roll reading
            (degrees) when the model's wrist_roll is at 0 rad (see :mod:`gym_soarm.real.units`).
        keep: ``"success"`` keeps only successful episodes (failed attempts are dropped
            and another attempt is made); ``"all"`` keeps every attempt.
        dart_noise: standard deviation (rad) of the Gaussian noise added to the executed
            action on every joint; the recorded action stays the expert's. 0 disables it.
        overwrite: replace an existing dataset in ``root``.
        max_attempts: give up on a task after this many of its attempts (default
            ``3 * episodes + 10``).
        progress: show a progress bar on stderr.
        workers: record the attempts in this many processes: this one and
            ``workers - 1`` worker processes (each sends its episodes as shards; this
            process plays attempts itself while no worker is free and merges everything
            in attempt order; see :mod:`gym_soarm.record.parallel`). The dataset is the
            same, frame for frame, for every worker count; a worker that dies
            mid-episode costs a retry of that attempt.
        start_method: how workers start: ``"forkserver"`` (default where available) or
            ``"spawn"``.
        ray_address: run the attempts as Ray tasks instead (``pip install
            "gym-soarm[ray]"``): a cluster address (``"auto"``, ``"host:6379"``,
            ``"ray://host:10001"``) or ``"local"`` for a local cluster; ``workers`` > 1
            then caps the tasks in flight (default: the cluster's CPUs). The dataset is
            the same as with one process.
        variation: keywords of ``gym.make`` that vary the scene: ``visual_randomization``,
            ``physics_randomization``, ``servo_model``, ``object_placement``,
            ``distractors``. What each kept episode's reset drew (``info["variation"]``)
            is written to ``meta/variation.jsonl``, one line per kept episode (with
            its task and reset seed, also when nothing varies).
        control_mode: the environment's control mode (one of
            :data:`gym_soarm.envs.control.CONTROL_MODES`): what the recorded ``action`` holds.
        calibration: with LeRobot units, a real SO-101 follower's LeRobot calibration
            JSON: states and actions are then that arm's values (see
            :mod:`gym_soarm.real.calibration`).
        dynamics: a ``gym_soarm.dynamics/1`` file (servo gains, joint figures, control
            delay; see :mod:`gym_soarm.real.dynamics`) the simulated arm moves with.
        settings: every environment keyword at once (a
            :class:`gym_soarm.envs.settings.EnvSettings`), instead of ``units``,
            ``wrist_roll_offset_deg``, ``calibration``, ``control_mode``, ``dynamics``
            and ``variation`` (leave those at their defaults then); its ``task``,
            ``obs_type``, ``camera_config`` and image size are the recorder's own
            (``task``, ``camera_config`` and ``size``). It is stored in the dataset
            (``meta/gym_soarm.json``), where replay and sysid read it back.

    Raises:
        ValueError: a bad argument; nothing is written then.
        TypeError: ``wrist_roll_offset_deg`` is not a number; nothing is written then.
    """
    selected = distinct_tasks(resolve_selection(task))
    episodes = check_int("episodes", episodes, 1)
    seed = check_int("seed", seed, 0)
    settings = _recording_settings(
        settings,
        selected[0].task,
        variation,
        units=units,
        wrist_roll_offset_deg=wrist_roll_offset_deg,
        control_mode=control_mode,
        calibration=calibration,
        dynamics=dynamics,
    )
    units, wrist_roll_offset_deg = settings.units, settings.wrist_roll_offset_deg
    joint_units(units, wrist_roll_offset_deg, settings.calibration)  # checks units, offset, file
    _check_keep_and_noise(keep, dart_noise)
    height, width = parse_size(f"{size[0]}x{size[1]}")
    state_only = camera_config == CAMERA_CONFIG_NONE
    cameras = () if state_only else resolve_camera_config(camera_config)
    run = _Run.checked(episodes, max_attempts, workers, start_method, ray_address)
    settings = _observed(settings, None if state_only else cameras, height, width)
    started = time.perf_counter()
    plans = _attempt_plans(
        selected,
        settings,
        (height, width),
        robot_type=robot_type_for(units),
        seed=seed,
        dart_noise=float(dart_noise),
        keep=keep,
        units=units,
        wrist_roll_offset_deg=wrist_roll_offset_deg,
        cameras=tuple(cameras),
        state_only=state_only,
    )
    writer = LeRobotDatasetWriter.create(
        root,
        settings.control_hz,
        plans[0].features,
        robot_type=plans[0].robot_type,
        overwrite=overwrite,
    )
    write_recording_settings(root, settings)
    attempts, successes, interrupted = _record_plans(root, writer, plans, run, progress)
    return RecordSummary(
        root=Path(root),
        episodes=writer.num_episodes,
        frames=writer.num_frames,
        attempts=attempts,
        successes=successes,
        seconds=time.perf_counter() - started,
        bytes_on_disk=sum(p.stat().st_size for p in Path(root).rglob("*") if p.is_file()),
        interrupted=interrupted,
        tasks=tuple(plan.spec.name for plan in plans),
    )


@dataclasses.dataclass(frozen=True)
class _Run:
    """How every task's attempts run: how many, and where (checked)."""

    episodes: int
    max_attempts: int
    workers: int
    start_method: str | None
    ray_address: str | None

    @classmethod
    def checked(
        cls,
        episodes: int,
        max_attempts: Any,
        workers: Any,
        start_method: Any,
        ray_address: Any,
    ) -> _Run:
        """The run of :func:`record`'s arguments; ValueError for a bad one."""
        if max_attempts is None:
            max_attempts = 3 * episodes + 10
        max_attempts = check_int("max_attempts", max_attempts, episodes)
        workers = _check_workers(workers, ray_address, start_method)
        return cls(episodes, max_attempts, workers, start_method, ray_address)


def _observed(
    settings: EnvSettings, cameras: Sequence[str] | None, height: int, width: int
) -> EnvSettings:
    """``settings`` observing what is recorded: ``cameras`` at ``height`` x ``width``
    (images), or the task state (``cameras`` None)."""
    if cameras is None:
        return settings.replace(obs_type="environment_state_agent_pos")
    return settings.replace(
        obs_type="pixels_agent_pos",
        camera_config=tuple(cameras),
        observation_height=height,
        observation_width=width,
    )


def _check_keep_and_noise(keep: Any, dart_noise: Any) -> None:
    """Refuse a ``keep`` that is not a choice and a ``dart_noise`` that is not radians >= 0."""
    if keep not in KEEP_CHOICES:
        raise ValueError(f"keep must be one of {', '.join(KEEP_CHOICES)}; got {keep!r}.")
    if isinstance(dart_noise, bool) or not isinstance(dart_noise, (int, float)):
        raise ValueError(f"dart_noise must be a number of radians >= 0; got {dart_noise!r}.")
    if not np.isfinite(dart_noise) or dart_noise < 0:
        raise ValueError(f"dart_noise must be a finite number of radians >= 0; got {dart_noise!r}.")


def _check_workers(workers: Any, ray_address: Any, start_method: Any) -> int:
    """The worker count, once ``workers``, ``ray_address`` and ``start_method`` are checked."""
    workers = check_int("workers", workers, 1)
    if ray_address is not None and (not isinstance(ray_address, str) or not ray_address):
        raise ValueError(
            f"ray_address must be a Ray cluster address such as 'auto' or 'host:6379', or "
            f"'local'; got {ray_address!r}."
        )
    if start_method is not None and start_method not in START_METHODS:
        raise ValueError(
            f"start_method must be one of {', '.join(START_METHODS)} or None; got {start_method!r}."
        )
    return workers


def _attempt_plans(
    selected: Sequence[SelectedTask],
    settings: EnvSettings,
    size: tuple[int, int],
    **fields: Any,
) -> list[AttemptPlan]:
    """Each task's plan, with the dataset's features and ``fields`` common to all. Every
    task's environment is built (and checked) here, before anything is written."""
    common_kwargs = settings.to_kwargs()
    del common_kwargs["task"]  # each task's gym id gives its own
    plans: list[AttemptPlan] = []
    for item in selected:
        spec = get_task(item.task)
        env_kwargs = {**common_kwargs, **item.variation}
        gym.make(spec.env_id, **env_kwargs).close()  # checks every keyword for this task
        plans.append(AttemptPlan(spec=spec, env_kwargs=env_kwargs, features={}, **fields))
    state_only, cameras = fields["state_only"], fields["cameras"]
    names = shared_state_names(tuple(selected), settings.object_placement) if state_only else None
    features = dataset_features(cameras, *size, names, settings.control_mode)
    return [dataclasses.replace(plan, features=features) for plan in plans]


def _record_plans(
    root: str | os.PathLike[str],
    writer: LeRobotDatasetWriter,
    plans: list[AttemptPlan],
    run: _Run,
    progress: bool,
) -> tuple[int, int, bool]:
    """Record every task's episodes, one task after the other, then finalize ``writer``:
    (attempts, successes, interrupted)."""
    attempts = successes = 0
    interrupted = False
    bar = None
    session = contextlib.ExitStack()
    try:
        if run.ray_address is not None and len(plans) > 1:  # one Ray connection for all tasks
            from gym_soarm.record.ray_tasks import ray_session

            session.enter_context(ray_session(run.ray_address))
        if progress:
            from tqdm import tqdm

            bar = tqdm(
                total=run.episodes * len(plans),
                unit="episode",
                file=sys.stderr,
                dynamic_ncols=True,
            )
        for plan in plans:
            if bar is not None and len(plans) > 1:
                bar.set_description(plan.spec.name)
            outcome = _record_task(root, writer, plan, run, bar)
            attempts += outcome[0]
            successes += outcome[1]
            if outcome[2]:
                interrupted = True
                break
    finally:
        if bar is not None:
            bar.close()
        session.close()
        writer.finalize()
    return attempts, successes, interrupted


def _record_task(
    root: str | os.PathLike[str],
    writer: LeRobotDatasetWriter,
    plan: AttemptPlan,
    run: _Run,
    bar: Any,
) -> tuple[int, int, bool]:
    """Record one task's episodes into ``writer``: (attempts, successes, interrupted)."""
    if run.ray_address is not None:
        from gym_soarm.record.ray_tasks import record_with_ray

        return record_with_ray(
            writer,
            plan,
            run.episodes,
            run.max_attempts,
            run.ray_address,
            parallel=run.workers if run.workers > 1 else None,
            bar=bar,
        )
    if run.workers > 1:
        from gym_soarm.record.parallel import record_in_workers

        return record_in_workers(
            writer, plan, run.episodes, run.max_attempts, run.workers, run.start_method, bar
        )

    return record_here(root, writer, plan, run.episodes, run.max_attempts, bar)
