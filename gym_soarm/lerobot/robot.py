"""The simulated SO-101 as a LeRobot ``Robot``: drive it with a real leader arm.

Importing :mod:`gym_soarm.lerobot` registers :class:`SimSoArmFollowerConfig` as the robot
type ``sim_soarm_follower``. LeRobot's own programs then drive the simulation as they
would drive the real follower::

    lerobot-teleoperate \\
        --robot.discover_packages_path=gym_soarm.lerobot --robot.type=sim_soarm_follower \\
        --teleop.type=so101_leader --teleop.port=/dev/ttyACM0 --teleop.id=my_leader \\
        --display_data=true

The robot speaks the follower's ``<motor>.pos`` values (body joints in degrees, gripper
0 to 100; :mod:`gym_soarm.real.units`), so a calibrated leader's actions go straight in, and
its observation holds the same six values plus one image per simulated camera. Each
action advances the simulation by the wall-clock time since the previous one, in 20 ms
steps, so the arm moves at the leader's pace whatever the loop's rate.
"""

from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from lerobot.robots.config import RobotConfig
from lerobot.robots.robot import Robot
from lerobot.utils.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.lerobot.config import check_task
from gym_soarm.real.units import FEATURE_NAMES, LEROBOT, UNITS, check_wrist_roll_offset
from gym_soarm.render.backend import RENDER_QUALITIES
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ, check_control_hz
from gym_soarm.tasks import DEFAULT_TASK
from gym_soarm.validation import check_choice, check_image_size, parse_cameras

logger = logging.getLogger(__name__)

NO_CAMERAS = "none"
MAX_STEPS_PER_ACTION = 10  # after a long pause the arm does not race to catch up


@RobotConfig.register_subclass("sim_soarm_follower")
@dataclass(kw_only=True)
class SimSoArmFollowerConfig(RobotConfig):
    """The simulated SO-101 follower (``--robot.type=sim_soarm_follower``).

    Attributes:
        task: the scene's task, a registered name such as ``"PickAndPlaceCube-v0"``.
        camera_config: ``"front_wrist"``, ``"front_only"``, ``"all"``, comma-separated
            camera names, or ``"none"`` (joint positions only).
        observation_height: image height in pixels.
        observation_width: image width in pixels.
        units: ``"lerobot"`` (body degrees, gripper 0 to 100, what a leader calibrated
            by LeRobot >= 0.4.4 sends), ``"lerobot_range"`` (-100 to 100) or ``"radians"``.
        wrist_roll_offset_deg: the leader's wrist_roll reading when the model's wrist_roll
            is at 0 rad (see :mod:`gym_soarm.real.units`).
        steps_per_action: control steps (of ``1 / control_hz`` s) per action; 0 follows
            the wall clock (the time since the previous action, 1 to 10 steps).
        seed: seed of the scene's first reset (where the task's objects start); None draws one.
        render_quality: ``"fast"`` or ``"high"``.
        control_hz: the simulation's control rate (50; 30 as LeRobot records).
    """

    task: str = DEFAULT_TASK
    camera_config: str = "front_wrist"
    observation_height: int = 480
    observation_width: int = 640
    units: str = LEROBOT
    wrist_roll_offset_deg: float = 0.0
    steps_per_action: int = 0
    seed: int | None = 0
    render_quality: str = "fast"
    control_hz: int = DEFAULT_CONTROL_HZ

    def __post_init__(self) -> None:
        super().__post_init__()
        self.task = check_task(self.task)
        self.control_hz = check_control_hz("control_hz", self.control_hz)
        if self.units not in UNITS:
            raise ValueError(f"units must be one of {', '.join(UNITS)}; got {self.units!r}.")
        self.wrist_roll_offset_deg = check_wrist_roll_offset(self.units, self.wrist_roll_offset_deg)
        steps = self.steps_per_action
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
            raise ValueError(
                f"steps_per_action must be an int >= 0 (0 follows the wall clock); got {steps!r}."
            )
        seed = self.seed
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            raise ValueError(f"seed must be None or an int >= 0; got {seed!r}.")
        # The environment's own checks, so that a bad value fails here, not at connect.
        check_choice("render_quality", self.render_quality, RENDER_QUALITIES)
        check_image_size("observation_height", self.observation_height)
        check_image_size("observation_width", self.observation_width)
        self.cameras_in_use()  # a bad camera_config fails here, not at connect

    def cameras_in_use(self) -> tuple[str, ...]:
        """The simulated cameras of the observation (none for ``"none"``)."""
        if self.camera_config.strip().lower() == NO_CAMERAS:
            return ()
        return parse_cameras(self.camera_config)


class SimSoArmFollower(Robot):
    """The simulated SO-101 follower arm, driven through LeRobot's ``Robot`` interface."""

    config_class = SimSoArmFollowerConfig
    name = "sim_soarm_follower"

    def __init__(self, config: SimSoArmFollowerConfig) -> None:
        super().__init__(config)
        self.config = config
        self.cameras = config.cameras_in_use()
        self.env: SoArmEnv | None = None
        self.last_info: dict[str, Any] = {}
        self._last_obs: dict[str, Any] = {}
        self._last_action_time: float | None = None
        self._unsimulated_s = 0.0

    # --- what LeRobot reads before connecting ------------------------------------------
    @cached_property
    def observation_features(self) -> dict[str, type | tuple[int, int, int]]:
        features: dict[str, type | tuple[int, int, int]] = dict.fromkeys(FEATURE_NAMES, float)
        size = (self.config.observation_height, self.config.observation_width, 3)
        features.update(dict.fromkeys(self.cameras, size))
        return features

    @cached_property
    def action_features(self) -> dict[str, type]:
        return dict.fromkeys(FEATURE_NAMES, float)

    @property
    def is_connected(self) -> bool:
        return self.env is not None

    @property
    def is_calibrated(self) -> bool:
        return True  # the model's joints need no calibration

    # --- life cycle ----------------------------------------------------------------------
    def connect(self, calibrate: bool = True) -> None:
        """Build the simulation and reset the scene (``calibrate`` has nothing to do)."""
        if self.is_connected:
            raise DeviceAlreadyConnectedError(f"{self} is already connected.")
        config = self.config
        # SoArmEnv itself, not gym.make: a teleoperation session has no step limit. Its
        # steps render nothing; get_observation renders the cameras, once per call.
        env = SoArmEnv(
            task=config.task,
            obs_type="environment_state_agent_pos",
            observation_height=config.observation_height,
            observation_width=config.observation_width,
            render_quality=config.render_quality,
            units=config.units,
            wrist_roll_offset_deg=config.wrist_roll_offset_deg,
            control_hz=config.control_hz,
        )
        try:
            self._start_scene(env, config.seed)
        except BaseException:
            env.close()  # not connected: a later connect() starts afresh
            raise
        self.env = env
        logger.info("%s connected: %s", self, env.task_description)

    def calibrate(self) -> None:
        """Nothing to calibrate in simulation."""

    def configure(self) -> None:
        """Nothing to configure in simulation."""

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """Start a new scene: the arm at home, the task's objects where its reset puts them."""
        self._start_scene(self._connected_env(), seed, options)

    def _start_scene(
        self, env: SoArmEnv, seed: int | None, options: dict[str, Any] | None = None
    ) -> None:
        self._last_obs, self.last_info = env.reset(seed=seed, options=options)
        self._last_action_time = None  # the wall-clock pacing starts again
        self._unsimulated_s = 0.0

    def disconnect(self) -> None:
        env = self._connected_env()
        env.close()
        self.env = None
        logger.info("%s disconnected.", self)

    # --- the control loop ----------------------------------------------------------------
    def get_observation(self) -> dict[str, Any]:
        """The six ``<motor>.pos`` values and one image per camera, rendered now."""
        env = self._connected_env()
        values: dict[str, Any] = dict(
            zip(FEATURE_NAMES, self._last_obs["agent_pos"].tolist(), strict=True)
        )
        for camera in self.cameras:
            values[camera] = env.render_camera_image(camera)
        return values

    def send_action(self, action: dict[str, Any]) -> dict[str, float]:
        """Move the servo targets to ``action`` and advance the simulation.

        Returns:
            The targets the servos got, in the robot's units (clipped to their range).
            If the physics diverged, the scene was reset (with a warning) and these are
            the home pose's targets.

        Raises:
            ValueError: a ``<motor>.pos`` value is missing or not a finite number; the
                simulation is not advanced.
        """
        env = self._connected_env()
        missing = [name for name in FEATURE_NAMES if name not in action]
        if missing:
            raise ValueError(
                f"action must hold {', '.join(FEATURE_NAMES)}; got {sorted(action)!r}, "
                f"missing {missing}. Check the teleoperator's motor names."
            )
        given = {name: action[name] for name in FEATURE_NAMES}
        targets = None
        if not any(isinstance(v, (str, bytes, bool, np.bool_)) for v in given.values()):
            try:
                targets = np.array([float(value) for value in given.values()])
            except (TypeError, ValueError):
                targets = None
        if targets is None or not np.isfinite(targets).all():
            raise ValueError(
                f"action values must be finite numbers in {self.config.units} units; got "
                f"{given!r}. Check the teleoperator's output; the simulation was not advanced."
            )
        for _ in range(self._steps_to_take()):
            obs, _, _, truncated, info = env.step(targets)  # checks finiteness first
            self._last_obs, self.last_info = obs, info
            if truncated:  # the physics diverged: start over rather than stop the session
                warnings.warn("the simulation diverged and was reset", RuntimeWarning, stacklevel=2)
                self.reset()
                break
        sent = env.joint_units.from_radians(env.physics.joint_targets())
        return dict(zip(FEATURE_NAMES, sent.tolist(), strict=True))

    # --- helpers -------------------------------------------------------------------------
    def _connected_env(self) -> SoArmEnv:
        if self.env is None:
            raise DeviceNotConnectedError(f"{self} is not connected; call connect() first.")
        return self.env

    def _steps_to_take(self) -> int:
        if self.config.steps_per_action:
            return self.config.steps_per_action
        now = time.perf_counter()
        if self._last_action_time is not None:
            self._unsimulated_s += now - self._last_action_time
        self._last_action_time = now
        dt = self._connected_env().dt
        steps = int(self._unsimulated_s / dt)
        steps = min(max(steps, 1), MAX_STEPS_PER_ACTION)
        self._unsimulated_s = min(max(self._unsimulated_s - steps * dt, 0.0), dt)
        return steps
