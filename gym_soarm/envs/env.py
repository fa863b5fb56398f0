"""The Gymnasium environment of the SO-101 arm: a thin adapter over physics and task."""

from __future__ import annotations

import copy
import dataclasses
import os
import reprlib
import warnings
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gym_soarm import constants
from gym_soarm.envs import snapshot as snapshots
from gym_soarm.envs.control import ControlMode, ServoChain, make_control
from gym_soarm.envs.core import StepCore
from gym_soarm.envs.settings import IMAGE_MODALITIES as IMAGE_MODALITIES
from gym_soarm.envs.settings import OBS_TYPES as OBS_TYPES
from gym_soarm.envs.settings import PLACEMENTS as PLACEMENTS
from gym_soarm.envs.settings import REWARD_TYPES as REWARD_TYPES
from gym_soarm.envs.settings import STATE_OBS_TYPES, EnvSettings
from gym_soarm.envs.snapshot import Snapshot
from gym_soarm.real.dynamics import apply_dynamics, load_dynamics
from gym_soarm.real.units import JointUnits, joint_units
from gym_soarm.render.camera import CameraRenderer
from gym_soarm.sim.arrays import SimArrays, item
from gym_soarm.sim.backends import MjDataBackend
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.sim.randomization import STS3215, Randomizer, Sts3215Servo
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ, control_timing
from gym_soarm.tasks import DEFAULT_TASK, get_task
from gym_soarm.tasks.base import Task, TaskSpec
from gym_soarm.tasks.distractors import place_distractors, with_distractors
from gym_soarm.validation import (
    ArgumentTypeError,
    check_choice,
    check_image_size,
    choices,
)

_DEFAULTS: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(EnvSettings)}


def _keywords(scope: Mapping[str, Any]) -> dict[str, Any]:
    """The ``gym.make`` keywords of ``SoArmEnv.__init__``'s local scope."""
    return {name: scope[name] for name in _DEFAULTS}


# LeRobot's evaluation (lerobot >= 0.6) marks the start of every rollout with this reset
# option; it is accepted and has no effect.
LEROBOT_ROLLOUT_OPTION = "lerobot_new_rollout"
STATE_OPTION = "state"
"""The reset option that restores a :class:`~gym_soarm.envs.snapshot.Snapshot`."""


def _differs(value: Any, default: Any) -> bool:
    try:
        return bool(value != default)
    except (TypeError, ValueError):  # e.g. an array compared with a str
        return True


class SoArmEnv(gym.Env):
    """The SO-ARM101 on a table with one registered task, on MuJoCo through dm_control.

    The arm stands at (0, 0.15, 0) facing +y across a 64 x 45 cm table. The task (see
    :mod:`gym_soarm.tasks`) owns the episode: its objects and fixtures, where they
    start, the environment state, the reward terms, success and the instruction
    (``task_description``). This class adapts it to Gymnasium: it checks arguments,
    builds the spaces, steps the physics and renders the cameras.

    **Actions** ``Box((6,), float32)``; values outside the bounds are clipped. With the
    default ``control_mode="joint_pos"``: absolute servo targets in radians, in the
    order of the table below. The other modes (changes of the targets, the jaws' pose
    in the robot's base frame or changes of it) are described in
    :mod:`gym_soarm.envs.control`.

    ===  ===============  ==================  =====
    idx  joint/actuator   range (rad)         note
    ===  ===============  ==================  =====
    0    shoulder_pan     -1.91986 .. 1.91986
    1    shoulder_lift    -1.74533 .. 1.74533
    2    elbow_flex       -1.69 .. 1.69
    3    wrist_flex       -1.65806 .. 1.65806
    4    wrist_roll       -2.74385 .. 2.84121
    5    gripper          -0.17453 .. 1.74533  closes towards the lower bound
    ===  ===============  ==================  =====

    **Observations** by ``obs_type``:

    * ``"pixels"``: ``{camera: uint8 (H, W, 3)}`` for the configured cameras.
    * ``"pixels_agent_pos"`` (default): ``{"pixels": {...}, "agent_pos": float64 (6,)}``.
    * ``"environment_state_agent_pos"``: ``{"agent_pos": (6,), "environment_state": (N,)}``
      where ``environment_state`` follows the task's :attr:`state_layout` (pick-and-place:
      cube position (3, m), cube quaternion (w, x, y, z), ``gripperframe`` site position
      (3, m) and goal position (3, m)). Renders nothing.
    * ``"state"``: one flat ``float32 (N,)`` vector for state policies: joint angles and
      velocities, the commanded servo targets, the jaws' centre, the task's environment
      state and the vectors from the jaws to each object and from each object to its
      goal, in radians and metres; :attr:`observation_names` names every value (see
      :mod:`gym_soarm.tasks.state_observation`). Renders nothing.

    With ``image_modalities`` beyond ``("rgb",)``, pixel observations hold one dict of
    cameras per modality, keyed ``"pixels"`` (uint8 (H, W, 3), when ``"rgb"`` is asked),
    ``"depth"`` (float32 (H, W), metres along the camera axis, up to the far plane) and
    ``"segmentation"`` (int32 (H, W), ids of :attr:`segmentation_ids`): ``"pixels"``
    observations become ``{"pixels": {...}, "depth": {...}, ...}`` and
    ``"pixels_agent_pos"`` ones gain the keys beside ``"pixels"`` and ``"agent_pos"``.

    ``agent_pos`` holds the six joint positions in the units of the action: radians by
    default; with ``units="lerobot"`` the body joints in degrees and the gripper in 0 to
    100 (0 = closed), as LeRobot's SO-101 follower; with ``units="lerobot_range"`` the
    body joints in -100 to 100 (see :mod:`gym_soarm.real.units`). The action bounds follow.

    **Reward** (``reward_type="dense"``): the task's named terms (``info["reward_terms"]``,
    each in [0, 1]) weighted to a total in [0, 1]; the step that succeeds (and ends the
    episode) pays 1 plus 1 for every step left until the step limit, what the rest of
    the episode could have earned at the most, so reaching success always pays more
    than hovering short of it. ``"sparse"``: 1.0 on the success step, else 0.0.

    **Snapshots**: ``s = env.unwrapped.save_state()`` is a picklable
    :class:`~gym_soarm.envs.snapshot.Snapshot` of everything the next step depends on, and
    ``env.reset(options={"state": s})`` restores it (see :meth:`save_state`).

    **Diverging physics**: when a step leaves the simulation with NaN/inf, raises a
    MuJoCo instability warning, throws an object more than 5 m or turns a joint past
    +-pi, ``step`` warns (``RuntimeWarning``) and returns ``truncated=True``, reward 0,
    ``info["physics_unstable"] = True`` and copies of the previous step's observation
    and info (finite, inside the observation space; ``is_success`` False and every
    reward term 0). The next ``step`` raises until ``reset()`` starts a clean episode.

    Args:
        task: a registered task's name (``"PickAndPlaceCube-v0"``, ``"LiftCube-v0"``, ...;
            see :func:`gym_soarm.tasks.task_names`) or one of its aliases.
        obs_type: one of :data:`OBS_TYPES`.
        camera_config: ``"front_only"``, ``"front_wrist"``, ``"all"`` or camera names.
        observation_height: image height in pixels (16 to 2048).
        observation_width: image width in pixels (16 to 2048).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        render_camera: camera returned by ``render()`` in ``rgb_array`` mode.
        render_quality: ``"fast"`` (simplified visual meshes; no shadows, reflections or
            multisampling) or ``"high"`` (full-detail meshes, shadows, reflections and
            4x multisampling). The physics is the same for both.
        reward_type: ``"dense"`` (weighted named terms in [0, 1]) or ``"sparse"``.
        units: joint units of actions and ``agent_pos``: ``"radians"``, ``"lerobot"``
            or ``"lerobot_range"``.
        wrist_roll_offset_deg: with LeRobot units, the real arm's wrist_roll reading
            (degrees, -180 to 180) when the model's wrist_roll is at 0 rad; wrist_roll
            values are shifted by it and wrapped to a turn (see :mod:`gym_soarm.real.units`).
        calibration: with LeRobot units, the path of a real SO-101 follower's LeRobot
            calibration JSON: actions, ``agent_pos`` and their bounds are then that arm's
            values, as LeRobot's motor bus normalises them (see
            :mod:`gym_soarm.real.calibration`). None: the fixed maps of :mod:`gym_soarm.real.units`.
        dynamics: the path of a ``gym_soarm.dynamics/1`` JSON file (fitted to a real arm
            by ``python -m gym_soarm.sysid``): its servo gains, joint damping, armature,
            friction loss and control delay replace the model's on this environment's
            own model copy; with ``physics_randomization`` the draws centre on them (see
            :mod:`gym_soarm.real.dynamics`). None: the model's own.
        image_modalities: images of each camera in pixel observations: a tuple of
            ``"rgb"``, ``"depth"`` and ``"segmentation"`` (see above); only these are
            rendered.
        visual_randomization: ``"none"``, ``"light"`` or ``"heavy"``: lights, table,
            floor and object colours and the cameras drawn anew at every reset (see
            :mod:`gym_soarm.sim.randomization`); the reset's ``info["variation"]`` says
            what was drawn.
        physics_randomization: ``"none"``, ``"light"`` or ``"heavy"``: object mass and
            friction, servo gains and joint damping (+-10 % or +-30 %), and with
            ``"heavy"`` a control delay of 0 or 1 steps, drawn at every reset.
        servo_model: ``"ideal"`` (the servo targets are the actions) or ``"sts3215"``
            (the follower's Feetech STS3215: speed-limited, quantised targets with
            backlash and its stall torque as force range; see
            :class:`gym_soarm.sim.randomization.Sts3215Servo`).
        control_mode: what an action means: ``"joint_pos"`` (absolute servo targets),
            ``"joint_delta"`` (changes of the servo targets), ``"ee_delta"`` (changes of
            the jaws' pose) or ``"ee_pose"`` (the jaws' pose); see
            :mod:`gym_soarm.envs.control`. The ee modes add ``ik_error_m`` and
            ``ik_error_rad`` to ``info``.
        normalize_actions: ``True``: actions are ``Box(-1, 1, (6,), float32)``, mapped
            linearly onto the control mode's own Box (-1 to its low bound, +1 to its
            high bound), for every control mode; the RL recipes use it.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": constants.RENDER_FPS}

    def __init__(
        self,
        task: str = DEFAULT_TASK,
        obs_type: str = "pixels_agent_pos",
        camera_config: str | Sequence[str] = constants.DEFAULT_CAMERA_CONFIG,
        observation_height: int = 480,
        observation_width: int = 640,
        render_mode: str | None = None,
        render_camera: str = constants.DEFAULT_RENDER_CAMERA,
        render_quality: str = "fast",
        reward_type: str = "dense",
        units: str = "radians",
        wrist_roll_offset_deg: float = 0.0,
        image_modalities: Sequence[str] = ("rgb",),
        visual_randomization: str = "none",
        physics_randomization: str = "none",
        servo_model: str = "ideal",
        object_placement: str | None = None,
        distractors: int = 0,
        control_mode: str = "joint_pos",
        calibration: str | os.PathLike[str] | None = None,
        dynamics: str | os.PathLike[str] | None = None,
        normalize_actions: bool = False,
        control_hz: int = DEFAULT_CONTROL_HZ,
        settings: EnvSettings | None = None,
        **unknown: Any,
    ) -> None:
        keywords = _keywords(locals())
        if unknown:  # an error naming the closest keywords, before anything is built
            EnvSettings.from_kwargs(**keywords, **unknown)
        if settings is not None:
            if not isinstance(settings, EnvSettings):
                raise ArgumentTypeError(
                    f"settings must be a gym_soarm.envs.settings.EnvSettings; got "
                    f"{type(settings).__name__}. Build one with EnvSettings(...) or "
                    "EnvSettings.from_kwargs(...)."
                )
            given = {k: v for k, v in keywords.items() if _differs(v, _DEFAULTS[k])}
            # A registered id passes its own task: fine when the settings name it too.
            if "task" in given and get_task(given["task"]).name == settings.task:
                del given["task"]
            if given:
                raise TypeError(
                    f"pass either settings or keywords, not both; got settings and "
                    f"{sorted(given)}. Use settings.replace({'=..., '.join(sorted(given))}=...)."
                )
        else:
            # Every argument is checked once, before anything is built.
            settings = EnvSettings.from_kwargs(**keywords)
        self._settings = settings
        s = settings
        spec = get_task(s.task)
        joint_conversion = joint_units(s.units, s.wrist_roll_offset_deg, s.calibration)  # reads
        fitted = None if s.dynamics is None else load_dynamics(s.dynamics)  # reads the file
        task_logic: Task = spec.make_task(s.object_placement)
        cameras = s.camera_config
        modalities = s.image_modalities
        render_mode, obs_type = s.render_mode, s.obs_type
        render_quality, servo_model, distractors = s.render_quality, s.servo_model, s.distractors
        visual_randomization = s.visual_randomization
        physics_randomization = s.physics_randomization

        self.render_mode = render_mode
        self.obs_type = obs_type
        self.cameras = cameras if obs_type not in STATE_OBS_TYPES else ()
        self.camera_config = cameras
        self.observation_height = s.observation_height
        self.observation_width = s.observation_width
        self.render_camera = s.render_camera
        self.render_quality = render_quality
        self.reward_type = s.reward_type
        self.units = s.units
        self.wrist_roll_offset_deg = s.wrist_roll_offset_deg
        self.control_mode = s.control_mode
        self.normalize_actions = s.normalize_actions
        self.calibration = s.calibration
        self.dynamics = s.dynamics
        self._units = joint_conversion
        self.image_modalities = modalities
        self._rgb = "rgb" in modalities
        self._depth = "depth" in modalities
        self._segmentation = "segmentation" in modalities
        self.visual_randomization = visual_randomization
        self.physics_randomization = physics_randomization
        self.servo_model = servo_model
        self.object_placement = task_logic.placement
        self.distractors = distractors

        # The render quality picks the visual meshes; the physics is the same for both.
        self._spec = spec
        scene, label = spec.scene, spec.name
        if distractors:
            scene, label = with_distractors(scene, distractors), f"{spec.name}+{distractors}d"
        self._physics = SoArmPhysics.from_scene(scene, render_quality, label)
        self.timing = control_timing(s.control_hz)
        self._physics.model.opt.timestep = self.timing.timestep_s
        # Videos, datasets and windows show one frame a control step.
        self.metadata = {**type(self).metadata, "render_fps": self.control_hz}
        self._scene_label = label
        self._task = task_logic
        self.task = spec.name
        self._options: dict[str, Any] = {}
        self._camera_ids = {
            name: self._physics.model.name2id(name, "camera") for name in constants.CAMERA_NAMES
        }
        self._renderers: dict[tuple[int, int], CameraRenderer] = {}
        self._segment_of_geom = self._physics.geom_segments() if self._segmentation else None
        self._servo: Sts3215Servo | None = None
        if servo_model == "sts3215":
            self._physics.set_servo_force_limit(STS3215.stall_torque_nm)
            self._servo = Sts3215Servo(self.timing.control_timestep_s)
        if fitted is not None:  # before the randomiser saves the values it draws around
            apply_dynamics(self._physics.model.ptr, fitted.joints)
        # A fitted delay is counted in steps of the rate fits run at (the default): the
        # same time at this rate.
        self._fitted_delay_steps = (
            0
            if fitted is None
            else round(fitted.delay_steps * self.control_hz / DEFAULT_CONTROL_HZ)
        )
        randomized = visual_randomization != "none" or physics_randomization != "none"
        self._randomizer = Randomizer(self._physics) if randomized else None
        self._report_variation = (
            randomized
            or servo_model != "ideal"
            or distractors > 0
            or self.object_placement != spec.default_placement
        )
        self._variation: dict[str, Any] = {}
        if self._report_variation:
            self._variation = {
                "visual_randomization": visual_randomization,
                "visual": {},
                "physics_randomization": physics_randomization,
                "physics": {},
                "servo_model": servo_model,
                "object_placement": self.object_placement,
                "distractors": [],
            }
        self._viewer = None
        self._closed = False
        self._needs_reset = True
        self._no_episode_reason = "the episode has not started"
        self._step_count = 0
        self._last_obs: Any = None
        self._last_info: dict[str, Any] = {}

        # The control mode turns an action into servo targets (clipped in radians).
        self._control = make_control(
            s.control_mode, self._physics, self._units, normalize=s.normalize_actions
        )
        self._chain = ServoChain(self._control, self._servo, self._fitted_delay_steps)
        self._chain.commanded = self._physics.joint_targets().copy()
        # The step, written once (gym_soarm.envs.core), over this environment's MjData.
        physics = self._physics
        hook = None
        if type(task_logic).before_step is not Task.before_step:
            hook = lambda targets: task_logic.before_step(targets, physics)  # noqa: E731
        self._core = StepCore(task_logic, MjDataBackend(physics), None, hook, self.timing.substeps)
        self.action_space = self._control.action_space
        self.observation_space = self._make_observation_space()

        if render_mode == "human":
            from gym_soarm.render.viewer import HumanViewer

            self._viewer = HumanViewer(self)

    # --- spaces ------------------------------------------------------------------------
    def _make_observation_space(self) -> spaces.Dict:
        image = spaces.Box(
            0, 255, (self.observation_height, self.observation_width, 3), dtype=np.uint8
        )
        # Joint limits never come near +-pi rad (wrist_roll's range is the widest).
        n_joints = len(constants.JOINT_NAMES)
        agent_pos = spaces.Box(
            *self._units.bounds(np.full(n_joints, -np.pi), np.full(n_joints, np.pi)),
            dtype=np.float64,
        )
        # OrderedDict keeps our key order; Gymnasium sorts the keys of a plain dict.
        pixels = spaces.Dict(OrderedDict((name, image) for name in self.cameras))
        if self.obs_type == "pixels" and self.image_modalities == ("rgb",):
            return pixels
        if self.obs_type in ("pixels", "pixels_agent_pos"):
            size = (self.observation_height, self.observation_width)
            far = float(
                np.float32(self._physics.model.vis.map.zfar * self._physics.model.stat.extent)
            )
            depth = spaces.Box(0.0, far, size, dtype=np.float32)
            n_segments = len(self.segmentation_ids)
            segmentation = spaces.Box(0, n_segments - 1, size, dtype=np.int32)
            layout: OrderedDict[str, spaces.Space] = OrderedDict()
            if self._rgb:
                layout["pixels"] = pixels
            if self._depth:
                layout["depth"] = spaces.Dict(OrderedDict((n, depth) for n in self.cameras))
            if self._segmentation:
                layout["segmentation"] = spaces.Dict(
                    OrderedDict((n, segmentation) for n in self.cameras)
                )
            if self.obs_type == "pixels_agent_pos":
                layout["agent_pos"] = agent_pos
            return spaces.Dict(layout)
        if self.obs_type == "state":
            return self._core.state_observer.space
        env_state = spaces.Box(*self._task.state_bounds(), dtype=np.float64)
        return spaces.Dict(OrderedDict(agent_pos=agent_pos, environment_state=env_state))

    # --- physics access --------------------------------------------------------------
    @property
    def settings(self) -> EnvSettings:
        """Every keyword this environment was made with, checked and normalised (see
        :class:`gym_soarm.envs.settings.EnvSettings`); ``gym.make(id, settings=...)`` takes it."""
        return self._settings

    @property
    def physics(self) -> SoArmPhysics:
        """The dm_control physics of this environment (for experts, tests and tools)."""
        return self._physics

    @property
    def joint_units(self) -> JointUnits:
        """The conversion between radians and the units of actions and ``agent_pos``."""
        return self._units

    @property
    def control(self) -> ControlMode:
        """The control mode: the action's meaning, names and conversions (e.g. the
        expert's ``control.action_for_targets(targets_rad, env.commanded_targets)``)."""
        return self._control

    @property
    def commanded_targets(self) -> np.ndarray:
        """The six servo targets (rad) the last step set, or the reset's: the targets
        that ``joint_delta`` and ``ee_delta`` actions change (a copy)."""
        return self._chain.commanded.copy()

    @property
    def servo_chain(self) -> ServoChain:
        """The control mode, delay and servo model between an action and the servos
        (:class:`~gym_soarm.envs.control.ServoChain`)."""
        return self._chain

    @property
    def step_count(self) -> int:
        """The steps of this episode so far (the success reward counts from it)."""
        return self._step_count

    @step_count.setter
    def step_count(self, value: int) -> None:
        # A vector env that steps this environment's simulation in a batch keeps it.
        self._step_count = int(value)

    def end_episode(self, reason: str) -> None:
        """Refuse further steps until ``reset()``, saying ``reason`` (a vector env whose
        batch found this simulation diverged ends its episode as ``step`` would)."""
        self._needs_reset = True
        self._no_episode_reason = reason

    def observation(self) -> Any:
        """The observation of the current state (pixel observations render now)."""
        return self._observation()

    def hold_servo_targets(self, targets: np.ndarray) -> None:
        """Make the servos hold ``targets`` (rad, six) from now until the first actions
        reach them (through the control delay, if any): for a replay that places the arm
        after ``reset``. Call it between ``reset`` and the first ``step``."""
        targets = np.asarray(targets, dtype=np.float64)
        self._physics.set_joint_targets(targets)
        self._chain.hold(targets)

    @property
    def task_logic(self) -> Task:
        """The task object holding this environment's episode logic."""
        return self._task

    @property
    def task_spec(self) -> TaskSpec:
        """The registered declaration of this environment's task."""
        return self._spec

    @property
    def task_description(self) -> str:
        """The episode's instruction, e.g. "Pick up the blue cube and place it on the green pad."."""
        return self._task.instruction

    @property
    def state_layout(self) -> tuple[tuple[str, int], ...]:
        """The ``environment_state`` layout: ordered (field, size) pairs of the task."""
        return self._task.state_layout

    @property
    def state_names(self) -> tuple[str, ...]:
        """The name of each ``environment_state`` value (for datasets), in order."""
        return self._task.state_names

    @property
    def observation_names(self) -> tuple[str, ...]:
        """The name of every value of an ``obs_type="state"`` observation, in order
        (see :mod:`gym_soarm.tasks.state_observation`); the same for every obs type."""
        return self._core.state_observer.names

    @property
    def segmentation_ids(self) -> dict[str, int]:
        """Ids of segmentation images: ``"background"`` 0 (floor and sky), ``"table"`` 1,
        ``"robot"`` 2, then each object and fixture of the task's scene in declaration
        order, objects first (e.g. ``{"cube": 3, "goal": 4}`` for pick-and-place).
        """
        return self._physics.segmentation_ids()

    @property
    def viewer(self) -> Any:
        """The ``render_mode='human'`` window (a ``HumanViewer``), or None."""
        return self._viewer

    # --- validation --------------------------------------------------------------------
    def _validate_action(self, action: Any) -> np.ndarray:
        if (
            type(action) is np.ndarray
            and action.dtype.kind == "f"
            and action.shape == self.action_space.shape
        ):
            array = action  # the common case, already known to be a real array of the right shape
        else:
            array = self._check_action_array(action)
        array = array.astype(np.float64)  # our own copy, which the control mode may modify
        if not np.isfinite(array).all():
            names = self._control.action_names
            bad = [names[i] for i in np.flatnonzero(~np.isfinite(array))]
            raise ValueError(
                f"action must be finite; got {array.tolist()!r} with NaN/inf for {bad}. "
                "The simulation was not stepped; check the policy's output (e.g. its "
                "normalisation statistics) before stepping."
            )
        return array

    def _check_action_array(self, action: Any) -> np.ndarray:
        try:
            array = np.asarray(action)
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"action must be an array of shape {self.action_space.shape} in "
                f"control_mode={self.control_mode!r}: {self._control.description}; got "
                f"{action!r} ({exc}). Pass e.g. env.action_space.sample()."
            ) from None
        if array.dtype == np.bool_ or not np.issubdtype(array.dtype, np.number):
            raise ValueError(
                f"action must hold real numbers (float or int); got {reprlib.repr(action)} "
                f"with dtype {array.dtype}. Pass e.g. np.asarray(action, dtype=np.float32)."
            )
        if np.issubdtype(array.dtype, np.complexfloating):
            raise ValueError(
                f"action must be real-valued; got dtype {array.dtype}. "
                "Pass the real part, e.g. np.real(action).astype(np.float32)."
            )
        if array.shape != self.action_space.shape:
            raise ValueError(
                f"action must have shape {self.action_space.shape} in control_mode="
                f"{self.control_mode!r}: {self._control.description}; got shape "
                f"{array.shape}. Pass e.g. env.action_space.sample()."
            )
        return array

    def _validate_options(self, options: Mapping[str, Any] | None) -> dict[str, Any]:
        """The task's checked options, or ``{"state": snapshot}`` for a restore."""
        keys = self._task.option_keys
        example = f"options={{{keys[0]!r}: ...}}" if keys else "options=None"
        if options is None:
            return {}
        if not isinstance(options, Mapping):
            raise ArgumentTypeError(
                f"options must be a dict with keys from {choices(keys) or 'none'} (or "
                f'"state"); got {options!r}. Pass e.g. {example}.'
            )
        unknown = sorted(set(options) - {*keys, STATE_OPTION, LEROBOT_ROLLOUT_OPTION}, key=repr)
        if unknown:
            raise ValueError(
                f"unknown reset option(s) {unknown!r}: options must have keys from "
                f"{choices(keys) or 'none (this task takes no options)'} for {self.task}, or "
                f'"state" (a snapshot to restore); got {list(options)!r}. Remove the others.'
            )
        if STATE_OPTION in options:
            others = sorted(set(options) & set(keys), key=repr)
            if others:
                raise ValueError(
                    f'reset option "state" restores a snapshot, which holds the whole '
                    f"episode; it cannot be combined with the task's options {others!r}. "
                    'Pass options={"state": snapshot} alone.'
                )
            snapshot = snapshots.check_snapshot(
                options[STATE_OPTION], self._simulation_settings(), f"this {self.task} environment"
            )
            snapshots.check_model_fields(self._physics.model.ptr, snapshot.model)
            if len(snapshot.physics) != len(
                snapshots.physics_state(self._physics.model.ptr, self._physics.data.ptr)
            ):
                raise ValueError(
                    "the snapshot's physics state does not fit this environment's model; "
                    "restore it into an environment made with the same settings."
                )
            return {STATE_OPTION: snapshot}
        return self._task.validate_options({k: v for k, v in options.items() if k in keys})

    # --- snapshots -------------------------------------------------------------------------
    def _simulation_settings(self) -> dict[str, Any]:
        return {
            "task": self.task,
            "scene": self._scene_label,
            "distractors": self.distractors,
            "object_placement": self.object_placement,
            "servo_model": self.servo_model,
            "dynamics": self.dynamics,
            "physics_randomization": self.physics_randomization,
            "visual_randomization": self.visual_randomization,
        }

    def save_state(self) -> Snapshot:
        """A picklable snapshot of everything the next step depends on.

        ``env.reset(options={"state": snapshot})`` restores it, in this environment or in
        another made with the same simulation settings (task, ``distractors``,
        ``object_placement``, ``servo_model``, ``dynamics``, ``physics_randomization``
        and ``visual_randomization``; a snapshot of other settings is refused with a
        ``ValueError`` naming both values). The same actions then give bit for bit the
        same observations, rewards, terminations and infos as this environment would.

        The snapshot holds the MuJoCo state (``mjSTATE_INTEGRATION``), the model fields
        that resets write (fixture poses, randomised lights, colours, cameras, masses,
        friction, gains and damping), the commanded servo targets, the control delay's
        queue, the STS3215 servo model's state, the control mode's state, the task's
        episode variables, the step count, the reset's variation and the state of
        ``np_random`` (see :class:`gym_soarm.envs.snapshot.Snapshot`).

        The settings that do not change the simulation (``obs_type``, ``control_mode``,
        ``normalize_actions``, ``units``, ``reward_type``, image size, cameras, render
        quality) may differ: restored into another ``control_mode``, that mode starts
        from its reset state (the ee modes' ``ik_error_*`` at 0) instead.

        ``reset(options={"state": s})`` does not draw a new episode: it runs no task
        placement or randomisation and returns the restored state's observation and
        info (with ``info["variation"]`` of the snapshot's episode, as a reset reports
        it). A ``seed`` given with it is applied and then overwritten by the snapshot's
        random state, which wins; ``"state"`` cannot be combined with the task's own
        options (``ValueError``), and anything but a snapshot raises ``TypeError``. All
        checks run before anything changes. The step count continues from the
        snapshot's (the success reward uses it), but a ``TimeLimit`` wrapper counts its
        steps from the restoring reset, so truncation by the step limit comes that many
        steps later than in the original episode.

        Raises:
            RuntimeError: no episode is running (before the first ``reset``, after a
                diverged step or after ``close``).
        """
        self._check_open("save_state")
        if self._needs_reset:
            raise RuntimeError(
                f"save_state() needs a running episode: {self._no_episode_reason}. "
                "Call reset() first."
            )
        m, d = self._physics.model.ptr, self._physics.data.ptr
        chain = self._chain
        return Snapshot(
            version=snapshots.SNAPSHOT_VERSION,
            settings=self._simulation_settings(),
            physics=snapshots.physics_state(m, d),
            model=snapshots.model_fields(m),
            commanded=chain.commanded.copy(),
            pending_targets=tuple(np.array(t, dtype=np.float64) for t in chain.pending),
            delay_steps=int(chain.delay_steps),
            servo=None if chain.servo is None else chain.servo.state,
            control_mode=self.control_mode,
            control=snapshots.control_state(self._control),
            task_state=snapshots.task_state(self._task),
            step_count=int(self._step_count),
            variation=copy.deepcopy(self._variation),
            rng=copy.deepcopy(self.np_random.bit_generator.state),
        )

    def _restore(self, snapshot: Snapshot) -> tuple[Any, dict[str, Any]]:
        """Write ``snapshot`` (already checked) into this environment; the reset's result."""
        physics = self._physics
        m, d = physics.model.ptr, physics.data.ptr
        snapshots.set_model_fields(m, snapshot.model)
        snapshots.set_physics_state(m, d, snapshot.physics)
        chain = self._chain
        chain.delay_steps = snapshot.delay_steps
        chain.pending = [np.array(t, dtype=np.float64) for t in snapshot.pending_targets]
        if chain.servo is not None and snapshot.servo is not None:
            chain.servo.state = snapshot.servo
        if snapshot.control_mode == self.control_mode:
            snapshots.set_control_state(self._control, snapshot.control)
        else:
            self._control.reset()
        chain.commanded = np.array(snapshot.commanded, dtype=np.float64)
        snapshots.set_task_state(self._task, snapshot.task_state)
        self._variation = copy.deepcopy(snapshot.variation)
        self._step_count = snapshot.step_count
        self.np_random = snapshots.generator_from_state(snapshot.rng)
        self._needs_reset = False
        obs = self._observation()
        info = self._info()
        if self._report_variation:
            info["variation"] = copy.deepcopy(self._variation)
        if self._viewer is not None:
            self._viewer.show(info)
        return obs, info

    # --- Gymnasium API -------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        self._check_open("reset")
        options = self._validate_options(options)
        super().reset(seed=seed)
        if STATE_OPTION in options:
            return self._restore(options[STATE_OPTION])
        with self._physics.reset_context():
            self._task.initialize_episode(self._physics, self.np_random, options)
            placed = place_distractors(self._physics, self.distractors, self.np_random)
            if self._report_variation:
                self._variation["distractors"] = placed
            if self._randomizer is not None:
                # Drawn after the task's placement, so a seed places the objects the
                # same way at every level; applied before the reset's forward pass.
                self._randomize()
        # The servos hold the reset's targets until the first actions reach them.
        self._chain.reset(self._physics.joint_targets())
        self._needs_reset = False
        self._step_count = 0
        obs = self._observation()
        info = self._info()
        if self._report_variation:
            info["variation"] = copy.deepcopy(self._variation)
        if self._viewer is not None:
            self._viewer.show(info)
        return obs, info

    def _randomize(self) -> None:
        assert self._randomizer is not None
        rng = self.np_random
        visual = self._randomizer.visual(self.visual_randomization, rng)
        physical, drawn_delay = self._randomizer.physics(self.physics_randomization, rng)
        self._chain.delay_steps = self._fitted_delay_steps + drawn_delay
        self._variation.update(
            visual_randomization=self.visual_randomization,
            visual=visual,
            physics_randomization=self.physics_randomization,
            physics=physical,
            servo_model=self.servo_model,
        )

    @property
    def variation(self) -> dict[str, Any]:
        """What the last reset drew (``info["variation"]``); empty without randomisation."""
        return copy.deepcopy(self._variation)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self._check_open("step")
        array = self._validate_action(action)
        if self._needs_reset:
            raise RuntimeError(f"call reset() before step(): {self._no_episode_reason}.")
        self._step_count += 1
        result = self._core.step(
            self._chain.targets(array),
            self._step_count,
            self.step_limit,
            self.reward_type == "sparse",
        )
        if result.diverged:
            return self._truncate_diverged_episode(result.diverged[0])
        obs = self._observation(result.sim)
        info = self._info(result.sim, result.evaluation, result.terms)
        if self._viewer is not None:
            self._viewer.show(info)
        return obs, result.reward, result.success, False, info

    @property
    def control_hz(self) -> int:
        """Control steps a second (the ``control_hz`` setting)."""
        return self.timing.control_hz

    @property
    def dt(self) -> float:
        """One control step (s): ``1 / control_hz``."""
        return self.timing.control_timestep_s

    @property
    def step_limit(self) -> int:
        """The episode's step limit: the id's ``max_episode_steps``, else the task's."""
        spec = self.spec
        if spec is not None and spec.max_episode_steps:
            return int(spec.max_episode_steps)
        return int(self._spec.max_episode_steps)

    def render(self) -> np.ndarray | None:
        """The ``render_camera`` frame (``rgb_array``), or draw the window (``human``).

        With ``render_mode=None`` there is nothing to render: it warns and returns None.
        """
        self._check_open("render")
        if self.render_mode is None:
            env_id = self.spec.id if self.spec is not None else self._spec.env_id
            warnings.warn(
                "render() was called on an environment made without a render_mode, so it "
                f'returns None. Make it with e.g. gym.make("{env_id}", render_mode="rgb_array") '
                "to get frames, or read the cameras from pixel observations.",
                UserWarning,
                stacklevel=2,
            )
            return None
        if self.render_mode == "rgb_array":
            return self.render_camera_image(self.render_camera)
        if self.render_mode == "human" and self._viewer is not None:
            self._viewer.show(None)
        return None

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
        self._last_obs = None

    # --- helpers ---------------------------------------------------------------------------
    def _check_open(self, method: str) -> None:
        if self._closed:
            raise RuntimeError(
                f"{method}() was called after close(): this environment was closed and its GL "
                "contexts and windows freed. Create a new one with gym.make(...)."
            )

    def _truncate_diverged_episode(self, reason: str) -> tuple[Any, float, bool, bool, dict]:
        """End the episode after a divergence with the last sound observation and info.

        The observation and info are fresh copies of those of the previous step (the
        diverged state is not observed); the reward and its terms are 0.
        """
        warnings.warn(
            f"The physics diverged ({reason}); the episode is truncated. Call reset() to "
            "start a clean episode.",
            RuntimeWarning,
            stacklevel=3,
        )
        self._needs_reset = True
        self._no_episode_reason = (
            f"the previous step truncated the episode because the physics diverged ({reason})"
        )
        info = copy.deepcopy(self._last_info)
        info.update(
            is_success=False,
            reward_terms=dict.fromkeys(info["reward_terms"], 0.0),
            physics_unstable=True,
        )
        return copy.deepcopy(self._last_obs), 0.0, False, True, info

    def render_camera_image(
        self, camera: str, height: int | None = None, width: int | None = None
    ) -> np.ndarray:
        """Render one camera now as a fresh uint8 (H, W, 3) array.

        ``height``/``width`` default to the observation size; another size gets a
        renderer of its own (created once, reused).
        """
        self._check_open("render_camera_image")
        check_choice("camera", camera, constants.CAMERA_NAMES)
        h = self.observation_height if height is None else check_image_size("height", height)
        w = self.observation_width if width is None else check_image_size("width", width)
        renderer = self._renderer_for(h, w)
        return renderer.render(self._physics.data.ptr, self._camera_ids[camera])

    def _renderer_for(self, height: int, width: int) -> CameraRenderer:
        renderer = self._renderers.get((height, width))
        if renderer is None:
            renderer = CameraRenderer(self._physics.model.ptr, width, height, self.render_quality)
            self._renderers[(height, width)] = renderer
        return renderer

    def _observation(self, sim: SimArrays | None = None) -> Any:
        """The observation now (``sim``: this step's arrays of the simulation, if made)."""
        physics = self._physics
        if self.obs_type == "state":
            sim = self._core.arrays() if sim is None else sim
            obs = self._core.state_observation(sim, self._chain.commanded)
        elif self.obs_type == "environment_state_agent_pos":
            sim = self._core.arrays() if sim is None else sim
            obs = {
                "agent_pos": self._units.from_radians(physics.joint_angles()),
                "environment_state": self._core.environment_state(sim),
            }
        elif self.image_modalities != ("rgb",):
            obs = self._modality_observation()
        else:
            renderer = self._renderer_for(self.observation_height, self.observation_width)
            data = physics.data.ptr
            pixels = {name: renderer.render(data, self._camera_ids[name]) for name in self.cameras}
            if self.obs_type == "pixels":
                obs = pixels
            else:
                obs = {
                    "pixels": pixels,
                    "agent_pos": self._units.from_radians(physics.joint_angles()),
                }
        self._last_obs = obs
        return obs

    def _modality_observation(self) -> dict[str, Any]:
        """A pixel observation with a dict of cameras per asked image modality."""
        renderer = self._renderer_for(self.observation_height, self.observation_width)
        data = self._physics.data.ptr
        images: dict[str, dict[str, np.ndarray]] = {
            key: {} for key, asked in self._modality_keys() if asked
        }
        for name in self.cameras:
            rgb, depth, segmentation = renderer.render_images(
                data, self._camera_ids[name], self._rgb, self._depth, self._segment_of_geom
            )
            for key, image in (("pixels", rgb), ("depth", depth), ("segmentation", segmentation)):
                if image is not None:
                    images[key][name] = image
        obs: dict[str, Any] = dict(images)
        if self.obs_type == "pixels_agent_pos":
            obs["agent_pos"] = self._units.from_radians(self._physics.joint_angles())
        return obs

    def _modality_keys(self) -> tuple[tuple[str, bool], ...]:
        return (("pixels", self._rgb), ("depth", self._depth), ("segmentation", self._segmentation))

    def _info(
        self,
        sim: SimArrays | None = None,
        evaluation: dict[str, Any] | None = None,
        terms: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """The info of a sound state (a diverged step builds its own from the last one).

        ``sim``, ``evaluation`` and ``terms``: the step's arrays, task evaluation and
        reward terms (one environment, unbatched); a reset evaluates the task here, once.
        """
        task = self._task
        if sim is None:
            sim = self._core.arrays()
        if evaluation is None:
            evaluation = task.evaluate(sim)
        if terms is None:
            terms = task.batch_reward_terms(evaluation)
        task_info, gripper = self._core.info_values(sim, evaluation)
        self._last_info = {
            "is_success": bool(evaluation["success"]),
            **{key: item(value) for key, value in task_info.items()},
            "gripper_pos": gripper.copy(),
            "reward_terms": {name: float(value) for name, value in terms.items()},
            "task": self.task_description,
            "physics_unstable": False,
            **self._control.info(),
        }
        return self._last_info
