"""The ``soarm`` EnvConfig: how LeRobot builds and reads gym_soarm environments."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig

import gym_soarm  # noqa: F401  (registers gym_soarm/<task> wherever this config is unpickled)
from gym_soarm import constants
from gym_soarm.control import CONTROL_MODES
from gym_soarm.sim.randomization import LEVELS, SERVO_MODELS
from gym_soarm.tasks import DEFAULT_TASK, get_task
from gym_soarm.tasks.distractors import MAX_DISTRACTORS
from gym_soarm.units import UNITS, check_wrist_roll_offset
from gym_soarm.validation import check_choice, check_int, parse_cameras

ACTION = "action"
OBS_STATE = "observation.state"
OBS_ENV_STATE = "observation.environment_state"
OBS_IMAGES = "observation.images"
OBS_TYPES: tuple[str, ...] = ("pixels_agent_pos", "environment_state_agent_pos", "pixels")


def check_task(task: object) -> str:
    """The registered name of ``task`` (a name, an alias or a gym id); ValueError if unknown."""
    return get_task(task).name


@EnvConfig.register_subclass("soarm")
@dataclass
class SoArmEnvConfig(EnvConfig):
    """gym_soarm's SO-101 tasks for LeRobot (``--env.type=soarm``).

    The gym id is ``gym_soarm/<task>``. Observations reach policies as
    ``observation.state`` (the six joints, in ``units``), ``observation.images.<camera>``
    per camera and, for ``obs_type="environment_state_agent_pos"``,
    ``observation.environment_state`` (the task's layout, read from the task itself:
    ``env.unwrapped.state_layout``). ``obs_type="pixels"`` gives policies the cameras only.

    Attributes:
        task: a registered task (``gym_soarm.task_names()``), e.g. ``"LiftCube-v0"``.
        fps: control rate (the environment steps at 50 Hz).
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
            when the model's wrist_roll is at 0 rad (see :mod:`gym_soarm.units`).
        visual_randomization: ``"none"``, ``"light"`` or ``"heavy"``.
        physics_randomization: ``"none"``, ``"light"`` or ``"heavy"``.
        servo_model: ``"ideal"`` or ``"sts3215"``.
        object_placement: ``"grid"`` or ``"uniform"``; None for the task's default.
        distractors: extra objects on the table, 0 to 4.
        control_mode: what the policy's action means: ``"joint_pos"``,
            ``"joint_delta"``, ``"ee_delta"`` or ``"ee_pose"`` (see
            :mod:`gym_soarm.control`); six values in every mode.
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
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.task = check_task(self.task)
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
        get_task(self.task).make_task(self.object_placement)  # refuses an unsupported placement
        self.distractors = check_int("distractors", self.distractors, 0, MAX_DISTRACTORS)
        check_choice("control_mode", self.control_mode, CONTROL_MODES)
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
            layout = get_task(self.task).make_task(self.object_placement).state_layout
            features["environment_state"] = PolicyFeature(
                type=FeatureType.ENV, shape=(sum(size for _, size in layout),)
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
        }
        if self.episode_length is not None:
            kwargs["max_episode_steps"] = self.episode_length
        return kwargs
