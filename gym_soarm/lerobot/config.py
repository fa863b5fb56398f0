"""The ``soarm`` EnvConfig: how LeRobot builds and reads gym_soarm environments."""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig

import gym_soarm  # noqa: F401  (registers gym_soarm/<task> wherever this config is unpickled)
from gym_soarm import constants
from gym_soarm.envs.control import CONTROL_MODES
from gym_soarm.real.dynamics import load_dynamics
from gym_soarm.real.units import UNITS, check_wrist_roll_offset, joint_units
from gym_soarm.sim.randomization import LEVELS, SERVO_MODELS
from gym_soarm.sim.timing import check_control_hz
from gym_soarm.tasks import DEFAULT_TASK, get_task
from gym_soarm.tasks.distractors import MAX_DISTRACTORS
from gym_soarm.tasks.suites import (
    TASK_GROUP,
    SelectedTask,
    resolve_selection,
    shared_state_names,
)
from gym_soarm.validation import check_choice, check_int, parse_cameras

ACTION = "action"
OBS_STATE = "observation.state"
OBS_ENV_STATE = "observation.environment_state"
OBS_IMAGES = "observation.images"
OBS_TYPES: tuple[str, ...] = ("pixels_agent_pos", "environment_state_agent_pos", "pixels")
LEROBOT_BUILDS_SUITES = hasattr(EnvConfig, "create_envs")
"""Whether this LeRobot's ``make_env`` asks the config for its envs (LeRobot >= 0.6); older
ones make ``gym_id`` alone, so they can evaluate one task without a suite's settings."""
PACKAGE_VECTOR_ENVS: tuple[str, ...] = ("batched", "processes", "warp")
"""gym_soarm's own vector envs, by the names of ``gym.make_vec``'s ``vector_env`` (see
:func:`gym_soarm.vector.make_vector_env`) and the trainer's ``--vector-env``."""
VECTOR_ENVS: tuple[str, ...] = ("auto", *PACKAGE_VECTOR_ENVS, "async", "sync")
"""Values of ``vector_env``: how ``create_envs`` batches ``n_envs`` environments."""
DEPRECATED_VECTOR_ENVS: tuple[str, ...] = ("native",)
"""Earlier values of ``vector_env``, still taken with a ``FutureWarning``: ``"native"``,
gym_soarm's vector env picked as ``"auto"`` picks it for several environments (now
``"batched"`` or ``"processes"``)."""


def check_task(task: object) -> str:
    """The registered name of ``task`` (a name, an alias or a gym id); ValueError if unknown."""
    return get_task(task).name


def check_selection(task: object) -> str:
    """``task`` as the config keeps it: one task's registered name, or the selection.

    Raises:
        ValueError: an unknown task or suite (see
            :func:`gym_soarm.tasks.suites.resolve_selection`).
    """
    selected = resolve_selection(task)  # type: ignore[arg-type]
    parts = [part.strip() for part in str(task).split(",") if part.strip()]
    if len(parts) == 1 and selected[0].group == TASK_GROUP:
        return selected[0].task
    return ",".join(parts)


def make_task_env(env_id: str, disable_env_checker: bool, kwargs: dict[str, Any]) -> gym.Env:
    """``gym.make(env_id, **kwargs)``: one environment of a Gymnasium vector env."""
    return gym.make(env_id, disable_env_checker=disable_env_checker, **kwargs)


@EnvConfig.register_subclass("soarm")
@dataclass
class SoArmEnvConfig(EnvConfig):
    """gym_soarm's SO-101 tasks for LeRobot (``--env.type=soarm``).

    ``task`` is one task, a suite or a comma list of both (see
    :mod:`gym_soarm.tasks.suites`): ``create_envs`` returns
    ``{group: {task_index: VectorEnv}}``, one group per suite (``soarm_core`` ...) and
    the group ``"soarm"`` for tasks named one by one, so ``lerobot-eval`` reports success
    per task, per suite and overall. Evaluate on the protocol: episode ``k`` resets with
    seed ``EVAL_SEED + k`` (1000 + k, ``lerobot-eval``'s default ``--seed``).

    The gym id of a task is ``gym_soarm/<task>``. Observations reach policies as
    ``observation.state`` (the six joints, in ``units``), ``observation.images.<camera>``
    per camera and, for ``obs_type="environment_state_agent_pos"``,
    ``observation.environment_state`` (the task's layout, read from the task itself:
    ``env.unwrapped.state_layout``). ``obs_type="pixels"`` gives policies the cameras only.

    Attributes:
        task: a registered task (``gym_soarm.task_names()``), e.g. ``"LiftCube-v0"``, a
            suite (``"soarm_core"``, ``"soarm_multi"``, ``"soarm_language"``,
            ``"soarm_robust"``, ``"soarm_all"``) or a comma list of them. With
            ``obs_type="environment_state_agent_pos"`` every selected task must have the
            same state layout (one policy reads them all).
        fps: control rate: the environments step (``control_hz``) and their videos play
            at it; 50 by default, 30 as LeRobot records real SO-101 arms.
        episode_length: step limit; ``None`` keeps the task's registered one.
        obs_type: ``"pixels_agent_pos"``, ``"environment_state_agent_pos"`` or ``"pixels"``.
        camera_config: ``"front_only"``, ``"front_wrist"``, ``"all"`` or comma-separated
            camera names (``front_camera,wrist_camera``).
        observation_height: image height in pixels.
        observation_width: image width in pixels.
        render_mode: ``"rgb_array"`` for evaluation videos.
        render_camera: the camera of those videos.
        units: ``"lerobot"`` (body degrees, gripper 0-100, the real follower's units),
            ``"lerobot_range"`` or ``"radians"``.
        wrist_roll_offset_deg: with LeRobot units, the real arm's wrist_roll reading
            when the model's wrist_roll is at 0 rad (see :mod:`gym_soarm.real.units`).
        visual_randomization: ``"none"``, ``"light"`` or ``"heavy"``.
        physics_randomization: ``"none"``, ``"light"`` or ``"heavy"``.
        servo_model: ``"ideal"`` or ``"sts3215"``.
        object_placement: ``"grid"`` or ``"uniform"``; None for the task's default.
        distractors: extra objects on the table, 0 to 4.
        control_mode: what the policy's action means: ``"joint_pos"``,
            ``"joint_delta"``, ``"ee_delta"`` or ``"ee_pose"`` (see
            :mod:`gym_soarm.envs.control`); six values in every mode.
        vector_env: how ``create_envs`` batches ``n_envs`` environments: one of
            gym_soarm's vector envs, by the names ``gym.make_vec`` and the trainer's
            ``--vector-env`` give them: ``"batched"`` (one ``mujoco.batch``, state
            observations), ``"processes"`` (worker processes,
            :class:`gym_soarm.vector.SoArmVectorEnv`) or ``"warp"`` (MuJoCo Warp on a
            GPU); or Gymnasium's ``"async"`` (``AsyncVectorEnv``, one process per
            environment) or ``"sync"`` (``SyncVectorEnv``); or ``"auto"`` (default):
            for several environments batched with state observations and processes
            with cameras (docs/performance.md, "Vector envs and recording at scale": the
            fastest on two cores), sync for one. ``"native"``, the earlier name of
            batched or processes as auto picks them, is deprecated (a ``FutureWarning``).
        calibration: with LeRobot units, the path of a real SO-101 follower's
            calibration JSON, so the env speaks that arm's values (see
            :mod:`gym_soarm.real.calibration`); None for the fixed maps.
        dynamics: the path of a ``gym_soarm.dynamics/1`` file (servo gains, joint
            figures and control delay fitted to a real arm by ``python -m
            gym_soarm.sysid``, see :mod:`gym_soarm.real.dynamics`); None for the model's own.

    A suite's own settings (``soarm_robust``'s randomisation) override the fields above
    for its tasks.
    """

    task: str | None = DEFAULT_TASK
    fps: int = constants.RENDER_FPS
    episode_length: int | None = None
    obs_type: str = "pixels_agent_pos"
    camera_config: str = constants.DEFAULT_CAMERA_CONFIG
    observation_height: int = 480
    observation_width: int = 640
    render_mode: str = "rgb_array"
    render_camera: str = constants.DEFAULT_RENDER_CAMERA
    units: str = "lerobot"
    wrist_roll_offset_deg: float = 0.0
    visual_randomization: str = "none"
    physics_randomization: str = "none"
    servo_model: str = "ideal"
    object_placement: str | None = None
    distractors: int = 0
    control_mode: str = "joint_pos"
    vector_env: str = "auto"
    calibration: str | None = None
    dynamics: str | None = None
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.task = check_selection(self.task)
        selected = resolve_selection(self.task)
        if not LEROBOT_BUILDS_SUITES and (len(selected) > 1 or selected[0].variation):
            raise ValueError(
                f"task {self.task!r} selects several tasks or a suite's settings; this LeRobot "
                "builds one environment per evaluation. Upgrade to LeRobot >= 0.6 (pip install "
                "'lerobot>=0.6'), or name one task."
            )
        if self.obs_type not in OBS_TYPES:
            raise ValueError(
                f"obs_type must be one of {', '.join(OBS_TYPES)}; got {self.obs_type!r}."
            )
        if self.units not in UNITS:
            raise ValueError(f"units must be one of {', '.join(UNITS)}; got {self.units!r}.")
        self.wrist_roll_offset_deg = check_wrist_roll_offset(self.units, self.wrist_roll_offset_deg)
        check_choice("visual_randomization", self.visual_randomization, LEVELS)
        check_choice("physics_randomization", self.physics_randomization, LEVELS)
        check_choice("servo_model", self.servo_model, SERVO_MODELS)
        check_choice("object_placement", self.object_placement, ("grid", "uniform"), none_ok=True)
        for item in selected:  # refuses a placement that a task does not support
            get_task(item.task).make_task(
                item.variation.get("object_placement", self.object_placement)
            )
        self.distractors = check_int("distractors", self.distractors, 0, MAX_DISTRACTORS)
        self.fps = check_control_hz("fps", self.fps)
        check_choice("control_mode", self.control_mode, CONTROL_MODES)
        if self.vector_env in DEPRECATED_VECTOR_ENVS:
            warnings.warn(self._native_warning(selected), FutureWarning, stacklevel=3)
        else:
            check_choice("vector_env", self.vector_env, VECTOR_ENVS)
        if self.calibration is not None:  # reads and checks the file
            joint_units(self.units, self.wrist_roll_offset_deg, self.calibration)
        if self.dynamics is not None:  # reads and checks the file
            load_dynamics(self.dynamics)
        cameras = parse_cameras(self.camera_config)
        n_joints = len(constants.JOINT_NAMES)
        features: dict[str, PolicyFeature] = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(n_joints,))
        }
        features_map = {ACTION: ACTION}
        if self.obs_type != "pixels":
            features["agent_pos"] = PolicyFeature(type=FeatureType.STATE, shape=(n_joints,))
            features_map["agent_pos"] = OBS_STATE
        if self.obs_type == "environment_state_agent_pos":
            features["environment_state"] = PolicyFeature(
                type=FeatureType.ENV,
                shape=(len(shared_state_names(selected, self.object_placement)),),
            )
            features_map["environment_state"] = OBS_ENV_STATE
        else:
            for camera in cameras:
                key = f"pixels/{camera}"
                features[key] = PolicyFeature(
                    type=FeatureType.VISUAL,
                    shape=(self.observation_height, self.observation_width, 3),
                )
                features_map[key] = f"{OBS_IMAGES}.{camera}"
        self.features = features
        self.features_map = features_map

    @property
    def gym_kwargs(self) -> dict[str, Any]:
        # LeRobot reads cameras from the nested "pixels" dict of pixels_agent_pos, so the
        # images-only obs_type is served by that observation too.
        obs_type = "pixels_agent_pos" if self.obs_type == "pixels" else self.obs_type
        kwargs: dict[str, Any] = {
            "obs_type": obs_type,
            "camera_config": list(parse_cameras(self.camera_config)),
            "observation_height": self.observation_height,
            "observation_width": self.observation_width,
            "render_mode": self.render_mode,
            "render_camera": self.render_camera,
            "units": self.units,
            "wrist_roll_offset_deg": self.wrist_roll_offset_deg,
            "visual_randomization": self.visual_randomization,
            "physics_randomization": self.physics_randomization,
            "servo_model": self.servo_model,
            "object_placement": self.object_placement,
            "distractors": self.distractors,
            "control_mode": self.control_mode,
            "control_hz": self.fps,
        }
        if self.episode_length is not None:
            kwargs["max_episode_steps"] = self.episode_length
        if self.calibration is not None:
            kwargs["calibration"] = self.calibration
        if self.dynamics is not None:
            kwargs["dynamics"] = self.dynamics
        return kwargs

    @property
    def gym_id(self) -> str:
        """The gym id of the selection's first task (``create_envs`` makes every task's)."""
        return get_task(resolve_selection(self.task)[0].task).env_id

    def create_envs(
        self, n_envs: int, use_async_envs: bool = False
    ) -> dict[str, dict[int, gym.vector.VectorEnv]]:
        """``{group: {task_index: VectorEnv}}`` of ``n_envs`` environments per selected task.

        With ``vector_env="auto"``: one environment is a ``SyncVectorEnv``; several
        step in gym_soarm's vector env, whatever ``use_async_envs`` says: the batched
        env with state observations (the fastest on two cores), worker processes, one
        per CPU, with cameras (level with ``AsyncVectorEnv`` while starting two
        processes instead of one per environment).
        """
        n_envs = check_int("n_envs", n_envs, 1)
        envs: dict[str, dict[int, gym.vector.VectorEnv]] = {}
        built: list[gym.vector.VectorEnv] = []
        try:
            for item in resolve_selection(self.task):
                vector = self._vector_env(item, n_envs)
                built.append(vector)
                envs.setdefault(item.group, {})[item.index] = vector
        except BaseException:
            for vector in built:
                vector.close()
            raise
        return envs

    def task_kwargs(self, item: SelectedTask) -> dict[str, Any]:
        """The ``gym.make`` keywords of one selected task: the fields, then its suite's."""
        return {**self.gym_kwargs, **item.variation}

    def package_vector_env(self, item: SelectedTask) -> str:
        """The vector env of gym_soarm that ``"auto"`` picks for several environments of
        one selected task: ``"batched"`` with state observations, else ``"processes"``."""
        from gym_soarm.vector.batched import wants_batched

        kwargs = {"task": item.task, **self.task_kwargs(item)}
        return "batched" if wants_batched(kwargs) else "processes"

    def _native_warning(self, selected: tuple[SelectedTask, ...]) -> str:
        picks = sorted({self.package_vector_env(item) for item in selected})
        new = " or ".join(f"vector_env={pick!r}" for pick in picks)
        return (
            f"vector_env='native' is deprecated; pass {new}: gym_soarm's vector envs go by "
            f"the names gym.make_vec's vector_env and the trainer's --vector-env give them "
            f"({', '.join(PACKAGE_VECTOR_ENVS)}). 'native' still picks batched for state "
            "observations and processes with cameras."
        )

    def _vector_env(self, item: SelectedTask, n_envs: int) -> gym.vector.VectorEnv:
        env_id = get_task(item.task).env_id
        kwargs = self.task_kwargs(item)
        mode = self.vector_env
        if mode == "auto":
            mode = "sync" if n_envs == 1 else "native"
        if mode == "native":  # gym_soarm's vector env, as its own "auto" picks it
            mode = self.package_vector_env(item)
        if mode in PACKAGE_VECTOR_ENVS:
            return gym.make_vec(
                env_id,
                num_envs=n_envs,
                vectorization_mode="vector_entry_point",
                autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
                vector_env=mode,
                **kwargs,
            )
        # A module-level function, so that worker processes import gym_soarm (and its ids).
        make_one = functools.partial(make_task_env, env_id, self.disable_env_checker, kwargs)
        if mode == "async" and n_envs > 1:
            return gym.vector.AsyncVectorEnv(
                [make_one] * n_envs,
                autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
                context="forkserver",
            )
        return gym.vector.SyncVectorEnv(
            [make_one] * n_envs, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
        )
