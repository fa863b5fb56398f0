"""Scripted experts that pick the cube up, lift it and place it on the pad.

``make_expert(env)`` returns a policy for the environment's task. It reads the
simulation state (never pixels), so it works with every ``obs_type``::

    env = gym.make("SoArm-v0")
    expert = gym_soarm.make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset()
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        if terminated or truncated:
            break

The expert moves through named phases: approach above the cube with the jaws open and
aligned with the cube's yaw (modulo 90 degrees), descend, close, lift and then, for the
lift task, hold, or, for pick and place, carry, lower onto the pad, release and retreat.
Joint targets come from inverse kinematics on the MJCF model itself: damped least
squares on the MuJoCo Jacobian of the ``grasp_center`` site (position first, the jaws'
orientation within the freedom left), joint limits respected, computed on a private
``mujoco.MjData`` so the environment's state is never touched. Targets follow a
minimum-jerk profile so that the stiff 50 Hz position servos move smoothly. A grasp that
closes on nothing, or a cube that falls out, is retried.

Run ``python -m gym_soarm.expert --task pick_and_place`` to measure the success rate
over every grid cell, seed yaw and three seeds (the README's table).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.physics import SoArmPhysics
from gym_soarm.units import RADIANS, JointUnits, joint_units

_QUARTER_TURN_RAD = math.pi / 2
# Keeps the null-space projector of the position Jacobian finite at a singular pose
# while leaving it exact (to ~1e-8) everywhere else.
_NULLSPACE_REGULARISATION = 1e-10 * np.eye(3)
# Inverse kinematics stops within these of the target: a tenth of a millimetre, and an
# angle that moves the jaw tips (10 cm from the wrist) by a third of a millimetre.
POSITION_TOLERANCE_M = 1e-4
ROTATION_TOLERANCE_RAD = 3e-3


@dataclasses.dataclass(frozen=True)
class ExpertConfig:
    """Figures of the scripted motion: heights in metres, durations in control steps."""

    hover_height_m: float = 0.05
    """Height of the ``grasp_center`` site above the table while approaching."""
    grasp_height_m: float = 0.018
    """Height of the ``grasp_center`` site when closing: jaw tips just clear the table."""
    fixed_jaw_clearance_m: float = 0.004
    """Gap left between the fixed jaw and the cube while descending; closing closes it."""
    carry_height_m: float = 0.075
    """Height of the cube's centre while carrying it (and of the lift target)."""
    lift_reach_m: tuple[float, float] = (0.13, 0.20)
    """While lifting, the cube also moves to this range of horizontal distances from the
    shoulder pan axis, where the arm holds it high with the jaws still vertical."""
    place_clearance_m: float = 0.003
    """Height of the cube's bottom above the pad when the jaws release it."""
    retreat_height_m: float = 0.10
    """Height of the ``grasp_center`` site after the release."""
    gripper_open_rad: float = 0.6
    """Gripper target while approaching: about 45 mm between the pads."""
    gripper_closed_rad: float = -0.17453
    """Gripper target while holding: the closed end of its range, the servo's torque limit
    sets the grip force."""
    approach_steps: int = 55
    """Longest approach; a shorter joint move takes ``approach_speed_rad_per_step``."""
    approach_speed_rad_per_step: float = 0.03
    descend_steps: int = 35
    close_steps: int = 15
    lift_steps: int = 35
    carry_steps: int = 60
    lower_steps: int = 35
    release_steps: int = 12
    retreat_steps: int = 25
    hold_steps: int = 25
    """Lift task: how long to hold the cube up after the lift."""
    rise_steps: int = 20
    """Before a new grasp: open the jaws and rise to the hover height."""
    max_regrasps: int = 2

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if field.name.endswith("_steps") and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1
            ):
                raise ValueError(
                    f"{field.name} must be an int >= 1 (control steps); got {value!r}."
                )
        if isinstance(self.max_regrasps, bool) or not isinstance(self.max_regrasps, int):
            raise ValueError(f"max_regrasps must be an int >= 0; got {self.max_regrasps!r}.")
        if self.max_regrasps < 0:
            raise ValueError(f"max_regrasps must be an int >= 0; got {self.max_regrasps!r}.")
        low, high = self.lift_reach_m
        if not 0.0 < low <= high:
            raise ValueError(
                f"lift_reach_m must be (min, max) metres with 0 < min <= max; got {self.lift_reach_m!r}."
            )
        if not self.approach_speed_rad_per_step > 0.0:
            raise ValueError(
                "approach_speed_rad_per_step must be > 0; "
                f"got {self.approach_speed_rad_per_step!r}."
            )


DEFAULT_CONFIG = ExpertConfig()

# Elbow up, wrist bent down (arm joints, rad): where inverse kinematics starts from,
# turned towards the target by the shoulder pan.
READY_POSTURE_RAD = np.array([0.0, 0.0, 0.6, 1.1, 0.0])


def minimum_jerk(fraction: float) -> float:
    """Minimum-jerk progress (0 to 1, zero velocity and acceleration at both ends)."""
    s = min(max(fraction, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _downward_rotation(yaw_rad: float) -> np.ndarray:
    """World rotation of the ``grasp_center`` site with the jaws pointing straight down.

    The gripper frame's jaws extend along its -z axis and close along its x axis, so z
    points up and x lies horizontal at ``yaw_rad``.
    """
    cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
    # Columns: x = (cos, sin, 0), y = z cross x = (-sin, cos, 0), z = (0, 0, 1).
    return np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])


def _rotation_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Small-angle rotation vector (rad, world frame) turning ``current`` to ``target``.

    Half the sum of the cross products of matching axes, computed as the axial vector
    of ``target @ current.T`` (the cross products themselves are slow in numpy).
    """
    turn = target @ current.T
    return 0.5 * np.array(
        [turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]]
    )


def cube_yaw(physics: SoArmPhysics) -> float:
    """Yaw (rad) of the cube's x axis about the world z axis."""
    w, x, y, z = physics.cube_quaternion()
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class ArmKinematics:
    """Inverse kinematics of the five arm joints on a private copy of the model's data.

    Damped least squares on the ``grasp_center`` site Jacobian (``mujoco.mj_jacSite``)
    with two priorities: the site's position first, its orientation in what freedom the
    position leaves. Where the wrist cannot point the jaws straight down (high above the
    far cells) the jaws tilt, but the site still follows its path. A joint at a limit that
    the step would push further is held there. Forward kinematics come from
    ``mujoco.mj_kinematics`` on the same private data, never from the environment's.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        damping: float = 0.005,
        rotation_damping: float = 0.05,
        max_iterations: int = 50,
    ) -> None:
        self._model = model
        self._data = mujoco.MjData(model)
        self._site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, constants.GRASP_SITE)
        joint_ids = [model.joint(name).id for name in constants.ARM_JOINT_NAMES]
        self._qpos_adr = model.jnt_qposadr[joint_ids]
        self._dof_adr = model.jnt_dofadr[joint_ids]
        self.lower, self.upper = model.jnt_range[joint_ids].T.copy()
        self._damping = damping**2 * np.eye(3)
        self._rotation_damping = rotation_damping**2 * np.eye(3)
        self._max_iterations = max_iterations
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        # The shoulder pan's axis and the direction the arm points at zero pan.
        pan = joint_ids[constants.ARM_JOINT_NAMES.index("shoulder_pan")]
        self._set(np.zeros(len(joint_ids)))
        self._pan_anchor = self._data.xanchor[pan].copy()
        self._pan_axis = self._data.xaxis[pan].copy()
        self._pan_zero = self._data.site_xpos[self._site] - self._pan_anchor

    def within_reach(self, position: np.ndarray, reach: tuple[float, float]) -> np.ndarray:
        """``position`` moved along its bearing from the shoulder pan axis so that its
        distance from the axis lies within ``reach`` (min, max) metres."""
        radius = min(max(self.radius(position), reach[0]), reach[1])
        return self.cylindrical_point(radius, self.bearing(position), float(position[2]))

    def radius(self, position: np.ndarray) -> float:
        """Horizontal distance (m) of ``position`` from the shoulder pan axis."""
        return float(np.hypot(*(np.asarray(position)[:2] - self._pan_anchor[:2])))

    def bearing(self, position: np.ndarray) -> float:
        """Direction (rad, about the world z axis) of ``position`` from the pan axis."""
        offset = np.asarray(position)[:2] - self._pan_anchor[:2]
        return math.atan2(offset[1], offset[0])

    def cylindrical_point(self, radius: float, bearing: float, height: float) -> np.ndarray:
        """The world point at ``radius`` and ``bearing`` from the pan axis, at ``height``."""
        x = self._pan_anchor[0] + radius * math.cos(bearing)
        y = self._pan_anchor[1] + radius * math.sin(bearing)
        return np.array([x, y, height])

    def pan_towards(self, position: np.ndarray) -> float:
        """Shoulder pan angle (rad) that turns the arm towards ``position``."""
        target = np.asarray(position) - self._pan_anchor
        sine = float(self._pan_axis @ np.cross(self._pan_zero, target))
        return math.atan2(sine, float(self._pan_zero[:2] @ target[:2]))

    def _set(self, arm_q: np.ndarray) -> None:
        self._data.qpos[self._qpos_adr] = arm_q
        mujoco.mj_kinematics(self._model, self._data)

    def site_pose(self, arm_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation of ``grasp_center`` for five arm joint angles."""
        self._set(arm_q)
        return (
            self._data.site_xpos[self._site].copy(),
            self._data.site_xmat[self._site].reshape(3, 3).copy(),
        )

    def _step(
        self, jacp: np.ndarray, jacr: np.ndarray, dp: np.ndarray, dr: np.ndarray
    ) -> np.ndarray:
        """One prioritised damped-least-squares step: position, then orientation."""
        step = jacp.T @ np.linalg.solve(jacp @ jacp.T + self._damping, dp)
        # Orientation moves only within the exact null space of the position Jacobian,
        # and more heavily damped: where the jaws cannot point down, they tilt quietly.
        nullspace = np.eye(jacp.shape[1]) - jacp.T @ np.linalg.solve(
            jacp @ jacp.T + _NULLSPACE_REGULARISATION, jacp
        )
        jacr_null = jacr @ nullspace
        secondary = jacr_null.T @ np.linalg.solve(
            jacr_null @ jacr_null.T + self._rotation_damping, dr - jacr @ step
        )
        return step + nullspace @ secondary

    def solve(
        self, start: np.ndarray, position: np.ndarray, rotation: np.ndarray
    ) -> tuple[np.ndarray, float, float]:
        """Joint angles placing ``grasp_center`` at ``position``, turned towards ``rotation``.

        Args:
            start: five arm joint angles (rad) to start the iteration from.
            position: target site position (m, world frame).
            rotation: target site rotation matrix (3, 3, world frame).

        Returns:
            The five joint angles (within their limits), the remaining position error
            (m) and the remaining rotation error (rad).
        """
        q = np.clip(np.asarray(start, dtype=np.float64), self.lower, self.upper)
        model, data, site = self._model, self._data, self._site
        position_error = rotation_error = math.inf
        for _ in range(self._max_iterations):
            self._set(q)
            current = data.site_xmat[site].reshape(3, 3)
            dp = position - data.site_xpos[site]
            dr = _rotation_error(current, rotation)
            position_error = float(np.linalg.norm(dp))
            rotation_error = float(np.linalg.norm(dr))
            if position_error < POSITION_TOLERANCE_M and rotation_error < ROTATION_TOLERANCE_RAD:
                break
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, self._jacp, self._jacr, site)
            jacp = self._jacp[:, self._dof_adr]
            jacr = self._jacr[:, self._dof_adr]
            step = self._step(jacp, jacr, dp, dr)
            # Hold the joints that sit at a limit and would be pushed past it.
            blocked = ((q <= self.lower) & (step < 0)) | ((q >= self.upper) & (step > 0))
            if blocked.any():
                free = (~blocked).astype(np.float64)
                step = self._step(jacp * free, jacr * free, dp, dr) * free
            q = np.clip(q + step, self.lower, self.upper)
            if float(np.abs(step).max()) < 1e-7:
                break
        return q, position_error, rotation_error


@dataclasses.dataclass(frozen=True)
class _Phase:
    """One segment of the script: its name, its length in steps and what starts it."""

    name: str
    steps: int
    begin: Callable[[], None]


class ScriptedExpert:
    """State-reading scripted policy for one SO-101 environment (base of both tasks).

    Call :meth:`reset` after every ``env.reset(...)`` (the expert also restarts by itself
    when it sees the simulation clock go back) and ``expert(obs, info)`` for each action.
    Observations are not used: the expert reads ``env.unwrapped.physics``.

    Each phase moves the servo targets from where the previous phase left them along a
    minimum-jerk profile: in joint space for the approach, round the shoulder pan axis
    for the carry, and in a straight line of the ``grasp_center`` site for every other
    arm motion. When a grasp fails (the jaws closed on nothing, or the cube fell) the
    expert opens, rises and tries again, at most ``config.max_regrasps`` times.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        self.env = env.unwrapped
        self.config = config
        conversion = getattr(self.env, "joint_units", None)
        if not isinstance(conversion, JointUnits):
            conversion = joint_units(getattr(self.env, "units", RADIANS))
        self._units = conversion
        physics: SoArmPhysics = self.env.physics
        self._kinematics = ArmKinematics(physics.model.ptr)
        self._n_arm = len(constants.ARM_JOINT_NAMES)
        self._roll = constants.ARM_JOINT_NAMES.index("wrist_roll")
        self._plan: list[_Phase] = []
        self._phase_index = 0
        self._phase_step = 0
        self._phase_length = 1
        self._time = -math.inf
        self._regrasps = 0
        self._command = np.zeros(len(constants.JOINT_NAMES))
        self._segment: Callable[[float], np.ndarray] | None = None
        self._gripper_from = self._gripper_to = 0.0
        self._yaw = 0.0
        self._grasp_point = np.zeros(3)
        self._cube_offset = np.zeros(3)

    # --- public API ------------------------------------------------------------------
    @property
    def phase(self) -> str:
        """Name of the phase the next action belongs to (``"done"`` after the script)."""
        if self._phase_index >= len(self._plan):
            return "done"
        return self._plan[self._phase_index].name

    @property
    def regrasps(self) -> int:
        """How many times this episode's grasp has been retried."""
        return self._regrasps

    def reset(self) -> None:
        """Start the script again from the environment's current (just reset) state."""
        physics = self.env.physics
        self._time = physics.data.time
        self._command = physics.joint_angles()
        self._regrasps = 0
        self._plan = self._grasp_phases() + self._after_grasp_phases()
        self._phase_index = 0
        self._begin_phase()

    def __call__(self, obs: Any = None, info: dict[str, Any] | None = None) -> np.ndarray:
        """The next action (float32): six servo targets in the environment's ``units``."""
        return self._units.from_radians(self.next_targets_radians()).astype(np.float32)

    def next_targets_radians(self) -> np.ndarray:
        """The next six servo targets in radians (float64), gripper last.

        This advances the script like a call does; use one or the other per step.
        """
        now = self.env.physics.data.time
        if not self._plan or now < self._time:
            self.reset()
        self._time = now
        if self._phase_index < len(self._plan):
            self._phase_step += 1
            fraction = minimum_jerk(self._phase_step / self._phase_length)
            if self._segment is not None:
                self._command[: self._n_arm] = self._segment(fraction)
            gripper = self._gripper_from + fraction * (self._gripper_to - self._gripper_from)
            self._command[self._n_arm] = gripper
            if self._phase_step >= self._phase_length:
                self._phase_index += 1
                self._begin_phase()
        return self._command.copy()

    # --- the script ----------------------------------------------------------------------
    def _grasp_phases(self) -> list[_Phase]:
        c = self.config
        return [
            _Phase("approach", c.approach_steps, self._begin_approach),
            _Phase("descend", c.descend_steps, self._begin_descend),
            _Phase("close", c.close_steps, self._begin_close),
        ]

    def _after_grasp_phases(self) -> list[_Phase]:
        raise NotImplementedError

    def _begin_phase(self) -> None:
        self._phase_step = 0
        if self._phase_index < len(self._plan):
            phase = self._plan[self._phase_index]
            self._phase_length = phase.steps
            phase.begin()

    def _holding(self) -> bool:
        """False if the cube is not in the jaws and a new grasp has been scheduled instead.

        Once ``config.max_regrasps`` retries are used up the script carries on regardless.
        """
        if self.env.physics.cube_grasped() or self._regrasps >= self.config.max_regrasps:
            return True
        self._regrasps += 1
        # Start over from a grasp: rise, approach, descend, close, then lift and the rest.
        rise = _Phase("rise", self.config.rise_steps, self._begin_rise)
        self._plan[self._phase_index :] = [
            rise,
            *self._grasp_phases(),
            *self._after_grasp_phases(),
        ]
        self._begin_phase()
        return False

    # --- motions --------------------------------------------------------------------------
    def _gripper(self, target: float) -> None:
        self._gripper_from = float(self._command[self._n_arm])
        self._gripper_to = target

    def _hold_arm(self) -> None:
        self._segment = None

    def _joint_move(self, target: np.ndarray) -> None:
        """Move the arm in joint space from the current targets to ``target``."""
        start = self._command[: self._n_arm].copy()
        self._segment = lambda s: start + s * (target - start)

    def _path_move(self, path: Callable[[float], tuple[np.ndarray, float]]) -> None:
        """Move ``grasp_center`` along ``path(s) -> (position, yaw)`` for s from 0 to 1.

        The jaws point down wherever the wrist allows it, turned to the path's yaw about
        the vertical. Each solve starts from the previous one, so the joints move smoothly.
        """
        guess = [self._command[: self._n_arm].copy()]

        def segment(s: float) -> np.ndarray:
            position, yaw = path(s)
            q, _, _ = self._kinematics.solve(guess[0], position, _downward_rotation(yaw))
            guess[0] = q
            return q

        self._segment = segment

    def _line_move(self, position: np.ndarray, yaw: float) -> None:
        """Move ``grasp_center`` in a straight line to ``position``, turning to ``yaw``."""
        start, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        start_yaw, self._yaw = self._yaw, yaw
        self._path_move(
            lambda s: (start + s * (position - start), start_yaw + s * (yaw - start_yaw))
        )

    def _arc_move(self, position: np.ndarray) -> None:
        """Carry ``grasp_center`` to ``position`` round the shoulder pan axis.

        Distance from the axis, bearing and height change linearly, so the path keeps
        clear of the base, and the jaws turn with the bearing so that the wrist roll
        stays where it is.
        """
        kinematics = self._kinematics
        start, _ = kinematics.site_pose(self._command[: self._n_arm])
        r0, r1 = kinematics.radius(start), kinematics.radius(position)
        b0 = kinematics.bearing(start)
        turn = math.remainder(kinematics.bearing(position) - b0, math.tau)
        z0, z1 = start[2], position[2]
        start_yaw = self._yaw
        self._yaw = start_yaw + turn

        def path(s: float) -> tuple[np.ndarray, float]:
            return kinematics.cylindrical_point(
                r0 + s * (r1 - r0), b0 + s * turn, z0 + s * (z1 - z0)
            ), start_yaw + s * turn

        self._path_move(path)

    def _seed_towards(self, position: np.ndarray) -> np.ndarray:
        """An elbow-up, wrist-down posture turned towards ``position``: the IK start."""
        seed = READY_POSTURE_RAD.copy()
        seed[0] = self._kinematics.pan_towards(position)
        return seed

    def _choose_grasp_yaw(self, position: np.ndarray) -> float:
        """Of the cube's four face directions, the one the jaws reach with least roll."""
        base = cube_yaw(self.env.physics)
        best_yaw, best_cost = base, math.inf
        seed = self._seed_towards(position)
        for quarter in range(4):
            yaw = base + quarter * _QUARTER_TURN_RAD
            q, position_error, rotation_error = self._kinematics.solve(
                seed, position, _downward_rotation(yaw)
            )
            cost = abs(q[self._roll]) + 100.0 * (position_error + rotation_error)
            if cost < best_cost:
                best_yaw, best_cost = yaw, cost
        return best_yaw

    # --- phases ---------------------------------------------------------------------------
    def _begin_approach(self) -> None:
        config = self.config
        grasp = self.env.physics.cube_position()
        grasp[2] = config.grasp_height_m
        self._yaw = self._choose_grasp_yaw(grasp)
        # The jaws descend with the fixed jaw clear of the cube (shifted along the
        # gripper's -x axis, away from the moving jaw); closing pushes the cube onto it.
        closing_axis = _downward_rotation(self._yaw)[:, 0]
        self._grasp_point = grasp - config.fixed_jaw_clearance_m * closing_axis
        hover = self._grasp_point.copy()
        hover[2] = config.hover_height_m
        target, _, _ = self._kinematics.solve(
            self._seed_towards(hover), hover, _downward_rotation(self._yaw)
        )
        # Short moves (a second attempt) take less time; the longest take approach_steps.
        distance = float(np.abs(target - self._command[: self._n_arm]).max())
        steps = math.ceil(distance / config.approach_speed_rad_per_step)
        self._phase_length = min(max(steps, config.rise_steps), config.approach_steps)
        self._joint_move(target)
        self._gripper(config.gripper_open_rad)

    def _begin_descend(self) -> None:
        self._line_move(self._grasp_point, self._yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_close(self) -> None:
        self._hold_arm()
        self._gripper(self.config.gripper_closed_rad)

    def _begin_rise(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[2] = max(site[2], self.config.hover_height_m)
        self._line_move(site, self._yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_lift(self) -> None:
        if not self._holding():
            return
        physics = self.env.physics
        # Where the held cube sits relative to the site, to put it down precisely later.
        self._cube_offset = physics.cube_position() - physics.grasp_center()
        target = self._kinematics.within_reach(physics.grasp_center(), self.config.lift_reach_m)
        target[2] = self.config.carry_height_m - self._cube_offset[2]
        self._line_move(target, self._yaw)
        self._gripper(self.config.gripper_closed_rad)


class LiftExpert(ScriptedExpert):
    """Approach, descend, close and lift the cube 2.5 cm above the 5 cm line, then hold."""

    def _after_grasp_phases(self) -> list[_Phase]:
        c = self.config
        return [
            _Phase("lift", c.lift_steps, self._begin_lift),
            _Phase("hold", c.hold_steps, self._begin_hold),
        ]

    def _begin_hold(self) -> None:
        if self._holding():
            self._hold_arm()


class PickAndPlaceExpert(ScriptedExpert):
    """Lift the cube, carry it over the pad, lower it, release it and move away."""

    def _after_grasp_phases(self) -> list[_Phase]:
        c = self.config
        return [
            _Phase("lift", c.lift_steps, self._begin_lift),
            _Phase("carry", c.carry_steps, self._begin_carry),
            _Phase("lower", c.lower_steps, self._begin_lower),
            _Phase("release", c.release_steps, self._begin_release),
            _Phase("retreat", c.retreat_steps, self._begin_retreat),
        ]

    def _site_target(self, cube_centre: np.ndarray) -> np.ndarray:
        """Where ``grasp_center`` goes to bring the held cube's centre to ``cube_centre``."""
        physics = self.env.physics
        self._cube_offset = physics.cube_position() - physics.grasp_center()
        return cube_centre - self._cube_offset

    def _begin_carry(self) -> None:
        if not self._holding():
            return
        goal = self.env.physics.goal_position()
        cube = np.array([goal[0], goal[1], self.config.carry_height_m])
        self._arc_move(self._site_target(cube))

    def _begin_lower(self) -> None:
        if not self._holding():
            return
        goal = self.env.physics.goal_position()
        resting_height = constants.TABLE_TOP_Z_M + constants.CUBE_HALF_M
        cube = np.array([goal[0], goal[1], resting_height + self.config.place_clearance_m])
        self._line_move(self._site_target(cube), self._yaw)

    def _begin_release(self) -> None:
        self._hold_arm()
        self._gripper(self.config.gripper_open_rad)

    def _begin_retreat(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        # Slide the fixed jaw off the cube's face, then rise.
        closing_axis = _downward_rotation(self._yaw)[:, 0]
        target = site - self.config.fixed_jaw_clearance_m * 2.5 * closing_axis
        target[2] = self.config.retreat_height_m
        self._line_move(target, self._yaw)


EXPERTS: dict[str, type[ScriptedExpert]] = {
    "PickAndPlaceCube-v0": PickAndPlaceExpert,
    "LiftCube-v0": LiftExpert,
}


def make_expert(env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> ScriptedExpert:
    """A scripted expert for the task of ``env`` (what ``gym.make`` returns, or its env).

    Args:
        env: a gym_soarm environment, wrapped or not.
        config: heights and phase durations of the scripted motion.

    Returns:
        A policy: call ``expert.reset()`` after each ``env.reset(...)`` and
        ``expert(obs, info)`` for each action.

    Raises:
        TypeError: ``env`` is not a gym_soarm environment, or ``config`` is not an
            :class:`ExpertConfig`.
    """
    from gym_soarm.env import SoArmEnv

    base = getattr(env, "unwrapped", None)
    if not isinstance(base, SoArmEnv):
        raise TypeError(
            "make_expert expects an environment made by gym.make('SoArm-v0') or another "
            f"gym_soarm id; got {type(env).__name__}."
        )
    if not isinstance(config, ExpertConfig):
        raise TypeError(
            "config must be a gym_soarm.expert.ExpertConfig (e.g. "
            f"ExpertConfig(carry_steps=80)); got {type(config).__name__}."
        )
    return EXPERTS[base.task](env, config)


# --- measurement -----------------------------------------------------------------------------
TASK_ENV_IDS = {"pick_and_place": "gym_soarm/PickAndPlaceCube-v0", "lift": "gym_soarm/LiftCube-v0"}
EVALUATION_SEEDS: tuple[int, ...] = (0, 1, 2)


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """Outcome of one evaluated episode."""

    cell: int
    yaw_deg: float
    seed: int
    success: bool
    steps: int


def evaluation_resets(seeds: Sequence[int] = EVALUATION_SEEDS) -> list[tuple[int, dict]]:
    """The (seed, options) of every evaluation episode: 9 cells x 4 yaws x seeds."""
    return [
        (seed, {"cube_grid_position": cell, "cube_rotation_deg": yaw})
        for cell in range(constants.NUM_GRID_CELLS)
        for yaw in constants.CUBE_YAWS_DEG
        for seed in seeds
    ]


def run_episode(
    env: gym.Env, policy: Callable[[Any, dict], np.ndarray], seed: int, options: dict
) -> EpisodeResult:
    """Run one episode of ``policy`` (an expert or any callable) until it ends."""
    obs, info = env.reset(seed=seed, options=options)
    reset = getattr(policy, "reset", None)
    if reset is not None:
        reset()
    steps = 0
    while True:
        obs, _reward, terminated, truncated, info = env.step(policy(obs, info))
        steps += 1
        if terminated or truncated:
            break
    return EpisodeResult(
        info["cube_grid_position"], info["cube_rotation_deg"], seed, info["is_success"], steps
    )


def evaluate(task: str, seeds: Sequence[int] = EVALUATION_SEEDS) -> list[EpisodeResult]:
    """Run the expert of ``task`` over every grid cell, seed yaw and seed (state obs)."""
    env = gym.make(TASK_ENV_IDS[task], obs_type="environment_state_agent_pos")
    try:
        expert = make_expert(env)
        return [run_episode(env, expert, seed, opts) for seed, opts in evaluation_resets(seeds)]
    finally:
        env.close()


if __name__ == "__main__":
    from gym_soarm.cli.expert import main

    main()
