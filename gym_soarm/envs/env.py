"""The Gymnasium environment of the SO-101 arm: a thin adapter over physics and task."""

from __future__ import annotations

import copy
import operator
import os
import warnings
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.envs import snapshot as snapshots
from gym_soarm.envs.checks import LEROBOT_ROLLOUT_OPTION as LEROBOT_ROLLOUT_OPTION
from gym_soarm.envs.checks import STATE_OPTION, check_action, check_reset_options
from gym_soarm.envs.observations import Observer
from gym_soarm.envs.settings import IMAGE_MODALITIES as IMAGE_MODALITIES
from gym_soarm.envs.settings import OBS_TYPES as OBS_TYPES
from gym_soarm.envs.settings import PLACEMENTS as PLACEMENTS
from gym_soarm.envs.settings import REWARD_TYPES as REWARD_TYPES
from gym_soarm.envs.settings import EnvSettings, resolve_settings, setting_property
from gym_soarm.envs.snapshot import Snapshot
from gym_soarm.envs.spaces import observation_space
from gym_soarm.envs.world import World
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ
from gym_soarm.tasks import DEFAULT_TASK


def _reads(path: str, doc: str) -> property:
    """A read-only attribute of the environment: its ``path`` (dotted), documented ``doc``."""
    return property(operator.attrgetter(path), doc=doc)


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

    **Observations** by ``obs_type`` (all described in :mod:`gym_soarm.envs.spaces`, with the
    ``image_modalities`` and ``agent_pos``'s units): ``"pixels"`` (``{camera: uint8 (H, W,
    3)}``), ``"pixels_agent_pos"`` (default: ``{"pixels": {...}, "agent_pos": float64 (6,)}``),
    ``"environment_state_agent_pos"`` (``agent_pos`` and the task's ``environment_state``:
    :attr:`state_layout`) or ``"state"`` (one flat float32 vector: :attr:`observation_names`);
    the last two render nothing.

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
        task, obs_type, ...: the fields of :class:`~gym_soarm.envs.settings.EnvSettings`,
            which says what each does (``docs/keywords.md``: their values and flags); each
            is also an attribute, read-only but ``reward_type`` and ``render_camera``.
        settings: all of them at once, as one ``EnvSettings`` (then no other keyword).
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
        settings = resolve_settings(locals(), settings, unknown)
        self.render_mode = settings.render_mode
        self._world = world = World.build(settings)  # the world owns the settings
        self.timing = world.timing
        # Videos, datasets and windows show one frame a control step.
        self.metadata = {**type(self).metadata, "render_fps": self.control_hz}
        self._observer = Observer(world)
        self._variation: dict[str, Any] = world.first_variation()
        self._viewer, self._closed, self._step_count = None, False, 0
        self._needs_reset, self._no_episode_reason = True, "the episode has not started"
        self.action_space = world.control.action_space
        self.observation_space = observation_space(self._observer)
        if self.render_mode == "human":
            from gym_soarm.render.viewer import HumanViewer

            self._viewer = HumanViewer(self)

    # --- the settings, as attributes (a setting that may change says so) --------------
    task = setting_property("task")
    obs_type = setting_property("obs_type")
    camera_config = setting_property("camera_config")
    observation_height = setting_property("observation_height")
    observation_width = setting_property("observation_width")
    render_camera = setting_property("render_camera", settable=True)
    render_quality = setting_property("render_quality")
    reward_type = setting_property("reward_type", settable=True)
    units = setting_property("units")
    wrist_roll_offset_deg = setting_property("wrist_roll_offset_deg")
    image_modalities = setting_property("image_modalities")
    visual_randomization = setting_property("visual_randomization")
    physics_randomization = setting_property("physics_randomization")
    servo_model = setting_property("servo_model")
    distractors = setting_property("distractors")
    control_mode = setting_property("control_mode")
    calibration = setting_property("calibration")
    dynamics = setting_property("dynamics")
    normalize_actions = setting_property("normalize_actions")

    @property
    def settings(self) -> EnvSettings:
        """Every keyword this environment was made with, checked and normalised (see
        :class:`gym_soarm.envs.settings.EnvSettings`); ``gym.make(id, settings=...)`` takes it."""
        return self._world.settings

    # --- the world, as attributes (the objects it is made of) ---------------------------
    physics = _reads("_world.physics", "The dm_control physics (for experts, tests and tools).")
    joint_units = _reads("_world.units", "The conversion between radians and the action's units.")
    task_logic = _reads("_world.task", "The task object that holds the episode's logic.")
    task_spec = _reads("_world.spec", "The registered declaration of this environment's task.")
    task_description = _reads("_world.task.instruction", "The episode's instruction.")
    state_layout = _reads("_world.task.state_layout", "``environment_state``'s field sizes.")
    state_names = _reads("_world.task.state_names", "The names of ``environment_state``'s values.")
    observation_names = _reads("_world.core.state_observer.names", "The state vector's names.")
    object_placement = _reads("_world.placement", "How objects start (or the task's default).")
    control = _reads("_world.control", "The control mode: what an action means, its conversions.")
    servo_chain = _reads("_world.chain", "The control mode, delay and servo model of the servos.")
    cameras = _reads("_observer.cameras", "The cameras of pixel observations (none for state).")
    control_hz = _reads("timing.control_hz", "Control steps a second (the ``control_hz`` setting).")
    dt = _reads("timing.control_timestep_s", "One control step (s): ``1 / control_hz``.")
    viewer = _reads("_viewer", "The ``render_mode='human'`` window (a ``HumanViewer``), or None.")

    # --- Gymnasium API -------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        self._check_open("reset")
        options = check_reset_options(options, self._world)
        super().reset(seed=seed)
        if STATE_OPTION in options:  # the episode of a snapshot, drawing nothing
            restored = snapshots.restore(self._world, options[STATE_OPTION])
            self._variation, self._step_count, self.np_random = restored
        else:
            self._world.start_episode(self.np_random, options, self._variation)
            self._step_count = 0
        self._needs_reset = False
        obs, info = self._observer.observation(), self._observer.info()
        if self._world.reports_variation:
            info["variation"] = copy.deepcopy(self._variation)
        if self._viewer is not None:
            self._viewer.show(info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self._check_open("step")
        world = self._world
        array = check_action(action, self.action_space.shape, self.control_mode, world.control)
        if self._needs_reset:
            raise RuntimeError(f"call reset() before step(): {self._no_episode_reason}.")
        self._step_count += 1
        sparse = self.reward_type == "sparse"
        targets = world.chain.targets(array)
        result = world.core.step(targets, self._step_count, self.step_limit, sparse)
        if result.diverged:  # truncated with copies of the last sound observation and info
            reason = result.diverged[0]
            obs, info = self._observer.diverged(reason)  # warns
            self.end_episode(
                f"the previous step truncated the episode because the physics diverged ({reason})"
            )
            return obs, 0.0, False, True, info
        obs = self._observer.observation(result.sim)
        info = self._observer.info(result.sim, result.evaluation, result.terms)
        if self._viewer is not None:
            self._viewer.show(info)
        return obs, result.reward, result.success, False, info

    def render(self) -> np.ndarray | None:
        """The ``render_camera`` frame (``rgb_array``), or draw the window (``human``).

        With ``render_mode=None`` there is nothing to render: it warns and returns None.
        """
        self._check_open("render")
        if self.render_mode is None:
            env_id = self.spec.id if self.spec is not None else self._world.spec.env_id
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

    def render_camera_image(
        self, camera: str, height: int | None = None, width: int | None = None
    ) -> np.ndarray:
        """Render one camera now as a fresh uint8 (H, W, 3) array.

        ``height``/``width`` default to the observation size; another size gets a
        renderer of its own (created once, reused).
        """
        self._check_open("render_camera_image")
        return self._observer.image(camera, height, width)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        self._observer.close()

    def _check_open(self, method: str) -> None:
        if self._closed:
            raise RuntimeError(
                f"{method}() was called after close(): this environment was closed and its GL "
                "contexts and windows freed. Create a new one with gym.make(...)."
            )

    # --- snapshots -----------------------------------------------------------------------
    def save_state(self) -> Snapshot:
        """A picklable snapshot of everything the next step depends on.

        ``env.reset(options={"state": snapshot})`` restores it, here or in an environment
        with the same simulation settings; the same actions then give bit for bit the same
        observations, rewards, terminations and infos (see :mod:`gym_soarm.envs.snapshot`:
        what it holds, which settings may differ, what a restoring reset does).

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
        return snapshots.save(self._world, self._step_count, self._variation, self.np_random)

    # --- episode and control ------------------------------------------------------------
    @property
    def variation(self) -> dict[str, Any]:
        """What the last reset drew (``info["variation"]``); empty without randomisation."""
        return copy.deepcopy(self._variation)

    @property
    def step_count(self) -> int:
        """The steps of this episode so far (the success reward counts from it)."""
        return self._step_count

    @step_count.setter
    def step_count(self, value: int) -> None:
        # A vector env that steps this environment's simulation in a batch keeps it.
        self._step_count = int(value)

    @property
    def step_limit(self) -> int:
        """The episode's step limit: the id's ``max_episode_steps``, else the task's."""
        spec = self.spec
        if spec is not None and spec.max_episode_steps:
            return int(spec.max_episode_steps)
        return int(self._world.spec.max_episode_steps)

    def end_episode(self, reason: str) -> None:
        """Refuse further steps until ``reset()``, saying ``reason`` (a vector env whose
        batch found this simulation diverged ends its episode as ``step`` would)."""
        self._needs_reset = True
        self._no_episode_reason = reason

    def observation(self) -> Any:
        """The observation of the current state (pixel observations render now)."""
        return self._observer.observation()

    @property
    def commanded_targets(self) -> np.ndarray:
        """The six servo targets (rad) the last step set, or the reset's: the targets
        that ``joint_delta`` and ``ee_delta`` actions change (a copy)."""
        return self._world.chain.commanded.copy()

    def hold_servo_targets(self, targets: np.ndarray) -> None:
        """Make the servos hold ``targets`` (rad, six) from now until the first actions
        reach them (through the control delay, if any): for a replay that places the arm
        after ``reset``. Call it between ``reset`` and the first ``step``."""
        self._world.hold_targets(np.asarray(targets, dtype=np.float64))

    @property
    def segmentation_ids(self) -> dict[str, int]:
        """Ids of segmentation images: ``"background"`` 0 (floor and sky), ``"table"`` 1,
        ``"robot"`` 2, then the scene's objects and fixtures (pick-and-place: cube 3, goal 4)."""
        return self._world.physics.segmentation_ids()
