"""Control modes: what an action means (``gym.make(id, control_mode=...)``).

Every mode takes a ``Box((6,), float32)`` and turns it into the six servo targets (rad)
that the environment sets before stepping; values outside the Box are clipped.

==============  =====================================================================
mode            action
==============  =====================================================================
``joint_pos``   six absolute servo targets in the env's ``units`` (the default)
``joint_delta`` six changes of the servo targets per step, in the env's ``units``,
                each within +-:data:`JOINT_DELTA_LIMIT_RAD` (0.1 rad: 5 rad/s at 50 Hz)
``ee_delta``    ``[dx, dy, dz, d_pitch, d_roll, gripper]``: moves of the jaw centre in
                the robot's base frame (m, each within +-:data:`EE_DELTA_LIMIT_M`, 1 cm),
                changes of the jaws' pitch and roll (rad, within
                +-:data:`EE_ANGLE_DELTA_LIMIT_RAD`, 0.1 rad), the gripper's absolute target
``ee_pose``     ``[x, y, z, pitch, roll, gripper]``: the jaw centre's position in the
                robot's base frame (m, within :data:`EE_POSITION_LOW_M` ..
                :data:`EE_POSITION_HIGH_M`), the jaws' pitch and roll (rad, -pi .. pi),
                the gripper's absolute target
==============  =====================================================================

**Deltas apply to the targets**, not to the measured joints: the environment keeps the
servo targets it last set (``env.unwrapped.commanded_targets``, radians; after a reset,
the reset's), and a zero ``joint_delta`` or ``ee_delta`` action keeps them where they
are, so the arm holds still and never drifts. ``ee_delta`` reads the jaws' pose of those
targets (forward kinematics) and adds the action to it, so a command beyond reach does
not wind up: the next step starts from where the arm was actually sent.

**Units.** ``joint_pos`` and ``joint_delta`` follow the env's ``units`` (radians, or
LeRobot's degrees and gripper percent: a ``joint_delta`` of 0.1 rad is 5.73 degrees
with ``units="lerobot"``). In the ee modes the five pose values are always metres and
radians; their gripper value is a servo target like ``joint_pos``'s last value, in the
env's ``units``.

**The end effector** is the ``grasp_center`` site: the centre of the jaws, where a held
3 cm cube's centre sits. Its pose has five degrees of freedom, the five arm joints'
(:mod:`gym_soarm.sim.kinematics`, :class:`~gym_soarm.sim.kinematics.JawPose`):

* position in the robot's **base frame**: origin at the base (world (0, 0.15, 0), on
  the table), x forward (world +y, across the table), y to the robot's left (world -x),
  z up: the world point of base (x, y, z) is (-y, 0.15 + x, z).
* ``pitch``: tilt of the jaws from pointing straight down, within the arm's vertical
  plane; positive swings the jaw tips away from the shoulder (pi/2: horizontal,
  pointing outward), negative towards it.
* ``roll``: turn of the jaws about their own axis; 0 with the closing axis horizontal
  and in the arm's plane (along its bearing), positive counter-clockwise seen from above (jaws down).
  It is the wrist roll joint's angle minus 0.0487 rad, so it reaches +-160 degrees.

With the jaws pointing down (pitch 0) the closing axis lies horizontal at yaw =
bearing + roll, ``bearing`` being the direction the arm faces: the shoulder pan's. The
yaw is not a sixth coordinate: five joints give five degrees of freedom, and the arm
must face its jaw centre (within the centre's 7 mm offset from the roll axis), so the
jaws' yaw follows the jaw centre's bearing from the shoulder pan axis. The scripted
expert's ``downward_rotation(yaw)`` is ``pitch = 0, roll = yaw - bearing``.

**Inverse kinematics** is the scripted expert's
:class:`~gym_soarm.sim.kinematics.ArmKinematics` (MuJoCo Jacobians, joint limits
respected) on a private ``MjData``: it never touches the environment's state
(:meth:`~gym_soarm.sim.kinematics.ArmKinematics.solve_pose`). The wrist roll comes
straight from the roll; the other four joints follow damped least squares from the
current targets, position first, at most :data:`IK_MAX_ITERATIONS` iterations per step
of at most 0.2 rad each (a far ``ee_pose`` target is reached over a few steps). A target out of reach, or past a joint limit, moves the jaws
as close as the limits allow, and ``info`` tells how far off the new targets leave the
jaws: ``ik_error_m`` (m, the jaw centre's distance from the commanded position) and
``ik_error_rad`` (rad, the pitch's and roll's errors, root of the sum of squares). Both
are the targets' errors by forward kinematics, not the measured arm's (which lags the
servos); they appear in the ee modes only, 0 at reset.

:meth:`ControlMode.action_for_targets` turns six servo targets in radians (what the
scripted expert computes) into this mode's action: the expert answers in every mode.

**Straight lines in ee_delta.** ``ee_delta`` keeps the commanded pitch while the joints
allow it, with one reserve: holding the pitch must not fold the arm into a corner. Held
on a line from the home pose (jaws level) to a low, near target, the pitch folds the
elbow and bends the wrist back until both sit at their limits, where no small change of
the joints reaches the next point; the only way on is a swing of the whole arm (2 to 3
rad at the wrist) that the servos take half a second over, while the jaws leave the
line. So where the commanded pitch would bring the shoulder lift, elbow flex or wrist
flex nearer than :data:`JOINT_MARGIN_RAD` to a limit (and nearer than it already is),
the pitch yields by the smallest of :data:`PITCH_YIELD_RAD` that keeps them off; an
explicit pitch change (``d_pitch`` not 0) is obeyed wherever it is reachable. Where the
pitch and the new position cannot both be reached at all (a joint pinned at its limit),
the position comes first: the pitch yields by the smallest of :data:`PITCH_YIELD_RAD`
that reaches it, from the current targets or from targets eased towards the middle of
their ranges (:data:`RELAX_SHARES`). ``ik_error_rad`` tells how far the pitch and roll
then are from the commanded ones.

**Normalised actions.** ``normalize_actions=True`` wraps any mode in
:class:`NormalizedControl`: the action becomes ``Box(-1, 1, (6,), float32)``, mapped
linearly onto the mode's own Box (-1 its low bound, +1 its high bound).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from gym_soarm import constants
from gym_soarm.real.units import FEATURE_NAMES, JointUnits
from gym_soarm.sim.kinematics import ArmKinematics, JawPose
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.validation import check_choice

JOINT_POS = "joint_pos"
JOINT_DELTA = "joint_delta"
EE_DELTA = "ee_delta"
EE_POSE = "ee_pose"
CONTROL_MODES: tuple[str, ...] = (JOINT_POS, JOINT_DELTA, EE_DELTA, EE_POSE)
"""Valid values of the ``control_mode`` keyword, the default first."""

JOINT_DELTA_LIMIT_RAD = 0.1
"""Largest change of each servo target per ``joint_delta`` step (rad): 5 rad/s at 50 Hz,
about an STS3215 servo's top speed, and above the scripted expert's fastest moves."""
EE_DELTA_LIMIT_M = 0.01
"""Largest move of the jaw centre along each base axis per ``ee_delta`` step (m)."""
EE_ANGLE_DELTA_LIMIT_RAD = 0.1
"""Largest change of the jaws' pitch and of their roll per ``ee_delta`` step (rad)."""
EE_POSITION_LOW_M: tuple[float, float, float] = (-0.35, -0.45, -0.25)
"""``ee_pose`` position bounds (base frame, m): a box round everything the jaw centre
reaches (0.47 m forward, 0.43 m sideways, 0.52 m up at most)."""
EE_POSITION_HIGH_M: tuple[float, float, float] = (0.50, 0.45, 0.55)

IK_MAX_ITERATIONS = 10
"""Inverse kinematics iterations per step at most (two or three follow a 1 cm move)."""
IK_POSITION_TOLERANCE_M = 1e-5
"""Inverse kinematics stops within 10 micrometres of the commanded position..."""
IK_PITCH_TOLERANCE_RAD = 1e-4
"""... and 0.1 milliradian of the commanded pitch."""
EE_DELTA_YIELD_M = 1e-3
"""``ee_delta``: when the new targets leave the jaw centre further than this from the
commanded position (the commanded pitch is out of reach there), the pitch yields."""
PITCH_YIELD_RAD: tuple[float, ...] = (
    0.05,
    -0.05,
    0.1,
    -0.1,
    0.2,
    -0.2,
    0.4,
    -0.4,
    0.8,
    -0.8,
    1.6,
    -1.6,
)
"""The changes of the commanded pitch that ``ee_delta`` tries, smallest first, until
the position is reached (it keeps the one that comes nearest), or until the joints stay
clear of their limits (:data:`JOINT_MARGIN_RAD`)."""
JOINT_MARGIN_RAD = 0.5
"""``ee_delta`` keeps the shoulder lift, elbow flex and wrist flex targets this far inside
their limits (or no nearer than they already are) by letting a held pitch yield: a
straight line from the home pose to every ``ReachTarget-v0`` target then arrives (280
of 280 seeds tried; without it 1 in 10 stalled in a folded corner)."""
RELAX_SHARES: tuple[float, ...] = (0.3, 0.6)
"""Where no change of the pitch reaches the position from the current targets (joints
pinned at their limits), ``ee_delta`` tries again from targets moved these shares of the
way towards the middle of their ranges."""

EE_POSE_NAMES: tuple[str, ...] = ("ee.x", "ee.y", "ee.z", "ee.pitch", "ee.roll", "gripper.pos")
EE_DELTA_NAMES: tuple[str, ...] = (
    "ee.dx",
    "ee.dy",
    "ee.dz",
    "ee.d_pitch",
    "ee.d_roll",
    "gripper.pos",
)
JOINT_DELTA_NAMES: tuple[str, ...] = tuple(f"{joint}.delta" for joint in constants.JOINT_NAMES)

_N_ARM = len(constants.ARM_JOINT_NAMES)
_GRIPPER = constants.JOINT_NAMES.index(constants.GRIPPER_JOINT_NAME)
# Rounding slack of the clearance test: zero action, whose targets are the current
# ones, never makes the pitch yield.
_CLEARANCE_SLACK_RAD = 1e-6
# The joints that set the pitch: shoulder lift, elbow flex, wrist flex.
_PITCH_JOINTS = slice(
    constants.ARM_JOINT_NAMES.index("shoulder_lift"),
    constants.ARM_JOINT_NAMES.index("wrist_flex") + 1,
)


class ControlMode:
    """How an action becomes the six servo targets; one subclass per control mode.

    Args:
        units: the env's joint units (of ``joint_pos`` and ``joint_delta`` actions, and
            of the ee modes' gripper value).
        low_rad: lower servo target bounds (rad), where targets are clipped.
        high_rad: upper servo target bounds (rad).

    Attributes:
        name: the mode, one of :data:`CONTROL_MODES`.
        action_space: the actions this mode takes.
        action_names: one name per action value (the dataset's ``action`` names).
        description: the action's layout and units, as error messages name them.
    """

    name: ClassVar[str]
    action_names: tuple[str, ...]
    description: str
    action_space: spaces.Box

    def __init__(self, units: JointUnits, low_rad: np.ndarray, high_rad: np.ndarray) -> None:
        self._units = units
        self._low = np.asarray(low_rad, dtype=np.float64)
        self._high = np.asarray(high_rad, dtype=np.float64)

    def _box(self, low: Any, high: Any) -> spaces.Box:
        low32 = np.asarray(low, dtype=np.float32)
        high32 = np.asarray(high, dtype=np.float32)
        return spaces.Box(low32, high32, dtype=np.float32)

    def _clip_targets(self, targets: np.ndarray) -> np.ndarray:
        # In place; the same values as np.clip, with less overhead.
        np.maximum(targets, self._low, out=targets)
        return np.minimum(targets, self._high, out=targets)

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        """The six servo targets (rad, within the servo ranges) that ``action`` sets.

        Args:
            action: a finite float64 array of shape (6,), which this call may modify.
            current_rad: the current servo targets in radians (the environment's
                ``commanded_targets``), which the delta modes change; only read.
        """
        raise NotImplementedError

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        """This mode's action (float32) that sends the servos to ``targets_rad``.

        Delta modes answer relative to the current targets, clipped to their bounds: a
        larger move takes several steps, each asked again from where the last one left
        the targets.

        Args:
            targets_rad: six servo targets in radians, gripper last.
            current_rad: the current servo targets in radians (the environment's
                ``commanded_targets``); only read.
        """
        raise NotImplementedError

    def reset(self) -> None:
        """Forget the last step (called by the environment's reset)."""

    def info(self) -> dict[str, float]:
        """This mode's ``info`` keys after the last step or reset (none for joint modes)."""
        return {}


class JointPositionControl(ControlMode):
    """``joint_pos``: six absolute servo targets in the env's units."""

    name = JOINT_POS
    action_names = FEATURE_NAMES

    def __init__(self, units: JointUnits, low_rad: np.ndarray, high_rad: np.ndarray) -> None:
        super().__init__(units, low_rad, high_rad)
        self.action_space = self._box(*units.bounds(self._low, self._high))
        self.description = (
            f"six absolute servo targets ({', '.join(constants.JOINT_NAMES)}) in {units.name}"
        )
        self._roll = constants.JOINT_NAMES.index("wrist_roll")

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        units = self._units
        if units.wrist_roll_offset_rad:
            # A wrapped wrist_roll value beyond the Box would come back a turn away:
            # clip it to the Box first, as every other joint is clipped.
            roll, space = self._roll, self.action_space
            action[roll] = min(max(action[roll], space.low[roll]), space.high[roll])
        if units.name != "radians":
            action = units.to_radians(action)
        return self._clip_targets(action)

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        return self._units.from_radians(targets_rad).astype(np.float32)


class JointDeltaControl(ControlMode):
    """``joint_delta``: six changes of the servo targets per step, in the env's units."""

    name = JOINT_DELTA
    action_names = JOINT_DELTA_NAMES

    def __init__(self, units: JointUnits, low_rad: np.ndarray, high_rad: np.ndarray) -> None:
        super().__init__(units, low_rad, high_rad)
        # Only the scale applies to a change; offsets (and the wrist_roll offset) cancel.
        # abs: a calibrated joint read in mirrored degrees has a negative scale.
        self._limit = JOINT_DELTA_LIMIT_RAD * np.abs(units.scale)
        self.action_space = self._box(-self._limit, self._limit)
        self.description = (
            f"six changes of the servo targets per step ({', '.join(constants.JOINT_NAMES)}) "
            f"in {units.name}, each within +-{JOINT_DELTA_LIMIT_RAD} rad"
        )

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        change = np.clip(action, -self._limit, self._limit) / self._units.scale
        return self._clip_targets(current_rad + change)

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        change = np.asarray(targets_rad, dtype=np.float64) - current_rad
        change = np.clip(change, -JOINT_DELTA_LIMIT_RAD, JOINT_DELTA_LIMIT_RAD)
        return (change * self._units.scale).astype(np.float32)


class EndEffectorControl(ControlMode):
    """The ee modes' common part: the base frame, the gripper value and the IK.

    Args:
        units: the env's joint units (for the gripper value).
        low_rad: lower servo target bounds (rad).
        high_rad: upper servo target bounds (rad).
        kinematics: the inverse kinematics, on its own private ``MjData``.
    """

    def __init__(
        self,
        units: JointUnits,
        low_rad: np.ndarray,
        high_rad: np.ndarray,
        kinematics: ArmKinematics,
    ) -> None:
        super().__init__(units, low_rad, high_rad)
        self.kinematics = kinematics
        self._origin = kinematics.base_position
        self._rotation = kinematics.base_rotation
        low, high = units.bounds(self._low, self._high)
        self._gripper_bounds = (float(low[_GRIPPER]), float(high[_GRIPPER]))
        self._gripper_scale = float(units.scale[_GRIPPER])
        self._gripper_offset = float(units.offset[_GRIPPER])
        self._errors = (0.0, 0.0)
        pose_low, pose_high = self.pose_bounds
        gripper_low, gripper_high = self._gripper_bounds
        self.action_space = self._box((*pose_low, gripper_low), (*pose_high, gripper_high))
        self._action_low = self.action_space.low.astype(np.float64)
        self._action_high = self.action_space.high.astype(np.float64)
        self.description = f"{self.pose_description}, the gripper's absolute target in {units.name}"

    pose_bounds: tuple[tuple[float, ...], tuple[float, ...]]
    """The lower and upper bounds of the action's five pose values (before the gripper's)."""
    pose_description: str
    """What the action's five pose values are, for :attr:`description`."""

    def pose(self, joints_rad: np.ndarray) -> np.ndarray:
        """``[x, y, z, pitch, roll]`` (m, base frame; rad) of the jaws at these joints.

        Args:
            joints_rad: the five arm joints, or all six, in radians: the servo targets
                (``env.unwrapped.commanded_targets``) or the measured joints
                (``env.unwrapped.physics.joint_angles()``).
        """
        pose = self.kinematics.jaw_pose(np.asarray(joints_rad, dtype=np.float64)[:_N_ARM])
        position = self._rotation.T @ (pose.position - self._origin)
        return np.array([*position, pose.pitch, pose.roll])

    def reset(self) -> None:
        self._errors = (0.0, 0.0)

    def info(self) -> dict[str, float]:
        return {"ik_error_m": self._errors[0], "ik_error_rad": self._errors[1]}

    def _gripper_radians(self, value: float) -> float:
        return (value - self._gripper_offset) / self._gripper_scale

    def _gripper_value(self, radians: float) -> float:
        return radians * self._gripper_scale + self._gripper_offset

    def _solve(self, current: np.ndarray, goal: JawPose, gripper: float) -> np.ndarray:
        """Servo targets for ``goal`` from the current ones; records the IK's errors."""
        arm, position_error, angle_error = self.kinematics.solve_pose(
            current[:_N_ARM],
            goal,
            IK_POSITION_TOLERANCE_M,
            IK_PITCH_TOLERANCE_RAD,
        )
        self._errors = (position_error, angle_error)
        targets = np.empty(len(constants.JOINT_NAMES))
        targets[:_N_ARM] = arm
        targets[_GRIPPER] = self._gripper_radians(gripper)
        return self._clip_targets(targets)


class EndEffectorDeltaControl(EndEffectorControl):
    """``ee_delta``: ``[dx, dy, dz, d_pitch, d_roll, gripper]`` per step."""

    name = EE_DELTA
    action_names = EE_DELTA_NAMES
    pose_bounds = (
        (-EE_DELTA_LIMIT_M,) * 3 + (-EE_ANGLE_DELTA_LIMIT_RAD,) * 2,
        (EE_DELTA_LIMIT_M,) * 3 + (EE_ANGLE_DELTA_LIMIT_RAD,) * 2,
    )
    pose_description = (
        "[dx, dy, dz, d_pitch, d_roll, gripper]: moves of the jaw centre in the robot's "
        f"base frame in metres (each within +-{EE_DELTA_LIMIT_M}), changes of the jaws' pitch "
        f"and roll in radians (within +-{EE_ANGLE_DELTA_LIMIT_RAD})"
    )

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        action = np.minimum(np.maximum(action, self._action_low), self._action_high)
        now = self.kinematics.jaw_pose(current_rad[:_N_ARM])
        goal = JawPose(
            now.position + self._rotation @ action[:3],
            now.pitch + float(action[3]),
            now.roll + float(action[4]),
        )
        gripper = float(action[5])
        targets = self._solve(current_rad, goal, gripper)
        if self._errors[0] <= EE_DELTA_YIELD_M:
            return self._keep_clear(targets, current_rad, goal, gripper, float(action[3]))
        # Position first: the commanded pitch and the position cannot both be reached
        # (a joint at its limit); let the pitch yield by the least that reaches the
        # position, or comes nearest it.
        best, best_error = targets, self._errors[0]
        middle = (self._low + self._high) / 2.0
        starts = [current_rad, *(current_rad + s * (middle - current_rad) for s in RELAX_SHARES)]
        for start in starts:
            for offset in PITCH_YIELD_RAD:
                trial = JawPose(goal.position, goal.pitch + offset, goal.roll)
                candidate = self._solve(start, trial, gripper)
                if self._errors[0] < best_error - IK_POSITION_TOLERANCE_M:
                    best, best_error = candidate, self._errors[0]
                    if best_error <= EE_DELTA_YIELD_M:
                        break
            if best_error <= EE_DELTA_YIELD_M:
                break
        return self._settle(best, best_error, goal)

    def _keep_clear(
        self,
        targets: np.ndarray,
        current_rad: np.ndarray,
        goal: JawPose,
        gripper: float,
        pitch_change: float,
    ) -> np.ndarray:
        """``targets`` reach ``goal``; unless the pitch was asked for (``pitch_change``
        not 0), let a held pitch yield by the least that keeps the pitch joints
        :data:`JOINT_MARGIN_RAD` inside their limits, or no nearer than they are now."""
        errors = self._errors
        need = min(JOINT_MARGIN_RAD, self._clearance(current_rad)) - _CLEARANCE_SLACK_RAD
        if pitch_change != 0.0 or self._clearance(targets) >= need:
            return targets
        for offset in PITCH_YIELD_RAD:
            trial = JawPose(goal.position, goal.pitch + offset, goal.roll)
            candidate = self._solve(current_rad, trial, gripper)
            if self._errors[0] <= EE_DELTA_YIELD_M and self._clearance(candidate) >= need:
                return self._settle(candidate, self._errors[0], goal)
        self._errors = errors  # no yield keeps clear: hold the pitch after all
        return targets

    def _clearance(self, targets: np.ndarray) -> float:
        """How far (rad) the pitch joints' targets are from their nearest limit."""
        low = targets[_PITCH_JOINTS] - self._low[_PITCH_JOINTS]
        high = self._high[_PITCH_JOINTS] - targets[_PITCH_JOINTS]
        return float(min(low.min(), high.min()))

    def _settle(self, targets: np.ndarray, position_error: float, goal: JawPose) -> np.ndarray:
        """Record the errors of ``targets`` whose pitch yielded: the position's, and how
        far the pitch and roll are from ``goal``'s."""
        reached = self.kinematics.jaw_pose(targets[:_N_ARM])
        pitch_error = math.remainder(goal.pitch - reached.pitch, math.tau)
        roll_error = math.remainder(goal.roll - reached.roll, math.tau)
        self._errors = (position_error, math.hypot(pitch_error, roll_error))
        return targets

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        now = self.pose(current_rad)
        goal = self.pose(targets_rad)
        change = goal - now
        change[3:] = [math.remainder(angle, math.tau) for angle in change[3:]]
        action = np.append(change, self._gripper_value(float(targets_rad[_GRIPPER])))
        return np.clip(action, self._action_low, self._action_high).astype(np.float32)


class EndEffectorPoseControl(EndEffectorControl):
    """``ee_pose``: ``[x, y, z, pitch, roll, gripper]``, absolute."""

    name = EE_POSE
    action_names = EE_POSE_NAMES
    pose_bounds = (
        (*EE_POSITION_LOW_M, -math.pi, -math.pi),
        (*EE_POSITION_HIGH_M, math.pi, math.pi),
    )
    pose_description = (
        "[x, y, z, pitch, roll, gripper]: the jaw centre's position in the robot's base "
        "frame in metres, the jaws' pitch and roll in radians (-pi to pi)"
    )

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        action = np.minimum(np.maximum(action, self._action_low), self._action_high)
        goal = JawPose(
            self._origin + self._rotation @ action[:3], float(action[3]), float(action[4])
        )
        return self._solve(current_rad, goal, float(action[5]))

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        action = np.append(
            self.pose(targets_rad), self._gripper_value(float(targets_rad[_GRIPPER]))
        )
        return np.clip(action, self._action_low, self._action_high).astype(np.float32)


class NormalizedControl(ControlMode):
    """``normalize_actions=True``: any mode's actions in ``Box(-1, 1, (6,), float32)``.

    Each value maps linearly onto the mode's own Box: -1 to its low bound, +1 to its high
    bound (0 to the middle: in ``joint_delta`` and ``ee_delta`` a zero change, in
    ``joint_pos`` the middle of each joint's range). Values outside [-1, 1] are clipped.
    The rest of the mode (its names, its ``info``, :meth:`pose` in the ee modes) is the
    wrapped mode's.

    Args:
        mode: the control mode whose actions are rescaled.
    """

    def __init__(self, mode: ControlMode) -> None:
        self.mode = mode
        self.name = mode.name
        self.action_names = mode.action_names
        native = mode.action_space
        self.native_space = native
        self._low = native.low.astype(np.float64)
        self._half_range = (native.high.astype(np.float64) - self._low) / 2.0
        n = native.shape[0]
        self.action_space = spaces.Box(-1.0, 1.0, (n,), dtype=np.float32)
        self.description = (
            f"{n} values in [-1, 1], each mapped linearly onto {mode.name}'s own range "
            f"(-1 its low bound, +1 its high bound): {mode.description}"
        )

    def __getattr__(self, name: str) -> Any:
        # Only reached for attributes this class lacks: the wrapped mode's own (``pose``).
        if name == "mode":
            raise AttributeError(name)
        return getattr(self.mode, name)

    def to_native(self, action: np.ndarray) -> np.ndarray:
        """The wrapped mode's action for a normalised one (clipped to [-1, 1] first)."""
        clipped = np.minimum(np.maximum(action, -1.0), 1.0)
        return self._low + (clipped + 1.0) * self._half_range

    def to_normalized(self, native: np.ndarray) -> np.ndarray:
        """The normalised action (float32, within [-1, 1]) for a wrapped mode's one."""
        scaled = (np.asarray(native, dtype=np.float64) - self._low) / self._half_range - 1.0
        return np.clip(scaled, -1.0, 1.0).astype(np.float32)

    def targets(self, action: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        return self.mode.targets(self.to_native(action), current_rad)

    def action_for_targets(self, targets_rad: np.ndarray, current_rad: np.ndarray) -> np.ndarray:
        return self.to_normalized(self.mode.action_for_targets(targets_rad, current_rad))

    def reset(self) -> None:
        self.mode.reset()

    def info(self) -> dict[str, float]:
        return self.mode.info()


def make_control(
    mode: str, physics: SoArmPhysics, units: JointUnits, normalize: bool = False
) -> ControlMode:
    """The control mode ``mode`` of an environment with ``physics`` and ``units``.

    Args:
        mode: one of :data:`CONTROL_MODES`.
        physics: the environment's physics (servo ranges, the model for the ee modes).
        units: the env's joint units.
        normalize: wrap the mode in :class:`NormalizedControl` (actions in [-1, 1]).

    Raises:
        ValueError: ``mode`` is not one of :data:`CONTROL_MODES`.
    """
    check_choice("control_mode", mode, CONTROL_MODES)
    low, high = physics.control_range()
    if mode == JOINT_POS:
        control: ControlMode = JointPositionControl(units, low, high)
    elif mode == JOINT_DELTA:
        control = JointDeltaControl(units, low, high)
    else:
        kinematics = ArmKinematics(physics.model.ptr, max_iterations=IK_MAX_ITERATIONS)
        if mode == EE_DELTA:
            control = EndEffectorDeltaControl(units, low, high, kinematics)
        else:
            control = EndEffectorPoseControl(units, low, high, kinematics)
    return NormalizedControl(control) if normalize else control


def action_names(mode: str) -> tuple[str, ...]:
    """The names of ``mode``'s six action values (a dataset's ``action`` names).

    Raises:
        ValueError: ``mode`` is not one of :data:`CONTROL_MODES`.
    """
    check_choice("control_mode", mode, CONTROL_MODES)
    return {
        JOINT_POS: FEATURE_NAMES,
        JOINT_DELTA: JOINT_DELTA_NAMES,
        EE_DELTA: EE_DELTA_NAMES,
        EE_POSE: EE_POSE_NAMES,
    }[mode]


class ServoChain:
    """From an action to the servo targets a step sends, for one environment.

    The control mode converts the action into targets (rad) from the targets it
    commanded last (:attr:`commanded`); a control delay holds them back
    :attr:`delay_steps` steps (the servos meanwhile keep receiving the earlier ones); the
    STS3215 servo model, when there is one, limits their speed and quantises them.

    Args:
        control: the control mode.
        servo: the servo model (None: ideal servos).
        delay_steps: the control delay, in steps (a reset with physics randomisation
            may draw another).
    """

    def __init__(self, control: ControlMode, servo: Any = None, delay_steps: int = 0) -> None:
        self.control = control
        self.servo = servo
        self.delay_steps = int(delay_steps)
        self.commanded = np.zeros(len(constants.JOINT_NAMES))
        """The targets (rad) the last action commanded, or the reset's."""
        self.pending: list[np.ndarray] = []
        """The delayed targets, oldest first (``delay_steps`` of them)."""

    @property
    def passes_through(self) -> bool:
        """No delay and ideal servos: the targets are the control mode's own, so a batch
        of environments can convert its actions at once."""
        return not self.delay_steps and self.servo is None

    def reset(self, targets: np.ndarray) -> None:
        """The servos hold ``targets`` (rad) until the first actions reach them."""
        self.pending = [targets.copy() for _ in range(self.delay_steps)]
        if self.servo is not None:
            self.servo.reset(targets)
        self.control.reset()
        self.commanded = targets.copy()

    def hold(self, targets: np.ndarray) -> None:
        """Hold ``targets`` (rad) from now, as after a reset, keeping the control mode's state."""
        self.pending = [targets.copy() for _ in self.pending]
        self.commanded = targets.copy()
        if self.servo is not None:
            self.servo.reset(targets)

    def targets(self, action: np.ndarray) -> np.ndarray:
        """The servo targets (rad) of a validated ``action`` this step; updates
        :attr:`commanded`."""
        target = self.control.targets(action, self.commanded)
        self.commanded = target.copy()
        if self.delay_steps:
            # The servos receive the action of ``delay_steps`` steps before.
            self.pending.append(target)
            target = self.pending.pop(0)
        if self.servo is not None:
            target = self.servo(target)
        return target
