"""Inverse kinematics of the SO-101's arm on the MJCF model itself.

Damped least squares on MuJoCo's Jacobian of the ``grasp_center`` site, on a private
``mujoco.MjData`` so the environment's state is never touched. The scripted experts
and the end-effector control modes (:mod:`gym_soarm.envs.control`) use it.

**The jaws' pose.** The shoulder lift, elbow and wrist flex axes are parallel and
horizontal, so those joints move the wrist in one vertical plane, the *arm's plane*,
which the shoulder pan turns about the vertical (it passes 0.18 mm beside the pan axis);
the wrist roll axis lies in that plane and is the jaws' own axis. The five arm joints
therefore leave the jaws five degrees of freedom, written :class:`JawPose`: the
``grasp_center`` position (3), ``pitch`` and ``roll``:

* ``pitch`` (rad): the tilt of the jaws' axis from straight down, within the arm's
  plane; positive swings the jaw tips away from the shoulder (pi/2: the jaws point
  horizontally outward), negative towards it. It is ``pi/2`` minus the sum of the
  shoulder lift, elbow and wrist flex angles, wrapped to a turn.
* ``roll`` (rad): the turn of the jaws about their own axis, 0 when the closing axis is
  horizontal and in the arm's plane (along its bearing); positive turns it counter-clockwise seen from
  above when the jaws point down. It is the wrist roll joint's angle minus 0.0487 rad
  (the gripper is mounted 2.8 degrees round), so its range is +-2.7925 rad (+-160 deg).

With the jaws pointing down (pitch 0), the site's rotation is
``downward_rotation(bearing + roll)``, the expert's orientation: the closing axis lies
horizontal at yaw ``bearing + roll``, where ``bearing`` is the direction the arm's plane
faces. Nothing else sets the jaws' yaw: the arm's plane must pass (to within the jaw
centre's 7 mm offset from the roll axis) through the jaw centre, so the bearing follows
from the position, and the yaw is not a free coordinate. (A position can be reached with
the arm facing it, as everything on the table is, or reaching backwards over its base;
:meth:`ArmKinematics.solve_pose` stays on the side it starts from.)
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numpy as np

from gym_soarm import constants

# Keeps the null-space projector of the position Jacobian finite at a singular pose
# while leaving it exact (to ~1e-8) everywhere else.
_NULLSPACE_REGULARISATION = 1e-10 * np.eye(3)
# Inverse kinematics stops within these of the target: a tenth of a millimetre, and an
# angle that moves the jaw tips (10 cm from the wrist) by a third of a millimetre.
POSITION_TOLERANCE_M = 1e-4
ROTATION_TOLERANCE_RAD = 3e-3
# solve_pose takes no step when the target is already this close (m and rad): the pose
# of the start itself, up to rounding.
_REACHED = 1e-9
# solve_pose moves no joint further than this per iteration (rad).
_MAX_POSE_STEP_RAD = 0.2
# solve_pose keeps the best joints it met, scored by the position error plus this much
# per radian of pitch error (m/rad), so that the position counts first.
_PITCH_WEIGHT_M_PER_RAD = 0.01


def downward_rotation(yaw_rad: float) -> np.ndarray:
    """World rotation of the ``grasp_center`` site with the jaws pointing straight down.

    The gripper frame's jaws extend along its -z axis and close along its x axis, so z
    points up and x lies horizontal at ``yaw_rad``.
    """
    cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
    # Columns: x = (cos, sin, 0), y = z cross x = (-sin, cos, 0), z = (0, 0, 1).
    return np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])


class JawPose(NamedTuple):
    """The jaws' five degrees of freedom (see the module docstring).

    Attributes:
        position: ``grasp_center`` site position (m, world frame), shape (3,).
        pitch: tilt of the jaws' axis from straight down within the arm's plane (rad);
            positive swings the tips away from the shoulder.
        roll: turn of the jaws about their own axis (rad), 0 with the closing axis
            horizontal in the arm's plane (along its bearing).
    """

    position: np.ndarray
    pitch: float
    roll: float


def orientation_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Small-angle rotation vector (rad, world frame) turning ``current`` to ``target``.

    Half the sum of the cross products of matching axes, computed as the axial vector
    of ``target @ current.T`` (the cross products themselves are slow in numpy).
    """
    turn = target @ current.T
    return 0.5 * np.array(
        [turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]]
    )


def _as_slice(indices: np.ndarray) -> slice | np.ndarray:
    """A slice for consecutive indices (numpy indexes a slice several times faster)."""
    first = int(indices[0])
    if np.array_equal(indices, np.arange(first, first + len(indices))):
        return slice(first, first + len(indices))
    return indices


def _dot(u: list[float], v: list[float]) -> float:
    """The dot product of two 4-vectors (written out: a generator costs several times more)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2] + u[3] * v[3]


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
        self._qpos_index = _as_slice(self._qpos_adr)
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
        base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, constants.ROBOT_BASE_BODY)
        self.base_position = self._data.xpos[base].copy()
        """The robot base's origin (m, world frame)."""
        self.base_rotation = self._data.xmat[base].reshape(3, 3).copy()
        """The robot base's rotation matrix (columns: its x, y, z axes in the world)."""
        self._init_jaw_geometry(joint_ids)

    def _init_jaw_geometry(self, joint_ids: list[int]) -> None:
        """Read the figures of :class:`JawPose` off the model at the zero posture."""
        names = constants.ARM_JOINT_NAMES
        self._lift_joint = joint_ids[names.index("shoulder_lift")]
        # Views into the private data, valid for its life.
        self._lift_axis = self._data.xaxis[self._lift_joint]
        self._site_rotation = self._data.site_xmat[self._site]
        self._site_position = self._data.site_xpos[self._site]
        self._roll_index = names.index("wrist_roll")
        self._pose_joints = np.array([j for j in range(len(names)) if j != self._roll_index])
        self._pose_dofs = _as_slice(self._dof_adr[self._pose_joints])
        self._pose_joints_list = self._pose_joints.tolist()
        self._free_lower = self.lower[self._pose_joints].tolist()
        self._free_upper = self.upper[self._pose_joints].tolist()
        self._position_damping = float(self._damping[0, 0])
        self._pitch_damping = float(self._rotation_damping[0, 0])
        self._lower_list, self._upper_list = self.lower.tolist(), self.upper.tolist()
        self._roll_middle = 0.5 * float(self.lower[self._roll_index] + self.upper[self._roll_index])
        # The arm's plane faces along (lift axis) x z or its opposite: where the jaws are.
        axis = self._lift_axis
        self._facing_sign = (
            1.0 if axis[1] * self._pan_zero[0] - axis[0] * self._pan_zero[1] > 0 else -1.0
        )
        self.roll_offset = self.jaw_pose(np.zeros(len(names))).roll
        """The jaws' roll (rad) with the wrist roll joint at 0: roll = wrist_roll + this."""

    def _position_and_pitch(self) -> tuple[list[float], float, float, float]:
        """Site position, pitch, and the cosine and sine of the arm's plane bearing, on
        the private data (several times per step: plain floats, cached views).

        The rotation as the arm's plane sees it is ``Rz(-bearing) @ R = Ry(-pitch) @
        Rz(roll)``; its third column gives the pitch.
        """
        ax, ay, _ = self._lift_axis.tolist()  # horizontal, across the arm's plane
        cos, sin = self._facing_sign * ay, -self._facing_sign * ax
        r = self._site_rotation.tolist()  # row-major 3 x 3
        pitch = math.atan2(-(cos * r[2] + sin * r[5]), r[8])
        return self._site_position.tolist(), pitch, cos, sin

    def _roll(self, cos: float, sin: float) -> float:
        """The jaws' roll on the private data, from the second row of the rotation as the
        arm's plane sees it (see :meth:`_position_and_pitch`)."""
        r = self._site_rotation.tolist()
        return math.atan2(cos * r[3] - sin * r[0], cos * r[4] - sin * r[1])

    def jaw_pose(self, arm_q: np.ndarray) -> JawPose:
        """The :class:`JawPose` that five arm joint angles (rad) put the jaws in."""
        self._set(arm_q)
        position, pitch, cos, sin = self._position_and_pitch()
        return JawPose(np.array(position), pitch, self._roll(cos, sin))

    def solve_pose(
        self,
        start: np.ndarray,
        pose: JawPose,
        position_tolerance: float = POSITION_TOLERANCE_M,
        pitch_tolerance: float = ROTATION_TOLERANCE_RAD,
        max_iterations: int | None = None,
        pitch_weight: float = _PITCH_WEIGHT_M_PER_RAD,
    ) -> tuple[np.ndarray, float, float]:
        """Joint angles putting the jaws in ``pose``, or as near as the joint limits allow.

        The wrist roll is the roll less :attr:`roll_offset` (of the angles a turn apart,
        the one nearest the middle of its range), set at once. The other four joints
        then follow damped least squares from ``start`` as in :meth:`solve`: the site's
        position first, the pitch within the freedom the position leaves, a joint at a
        limit held there, no joint moving more than 0.2 rad per iteration (the steps grow
        large near a stretched arm). Once position and pitch are reached, so is the
        jaws' yaw: the arm's plane has to pass the jaw centre at its fixed offset (the
        solution stays on the side of the shoulder that ``start`` is on).

        A target nearer than the tolerances still gets one step, so that small moves add
        up, unless it is the start's own pose; the iteration stops once within the
        tolerances, or when an iteration gains less than them (a target out of reach),
        and returns the best joints it met. Four joints and small matrices: the
        arithmetic is plain Python, several times faster than numpy here.

        Args:
            start: five arm joint angles (rad) to start the iteration from.
            pose: the target, its position in the world frame.
            position_tolerance: stop within this distance (m) of the position...
            pitch_tolerance: ... and this angle (rad) of the pitch.
            max_iterations: iteration limit (default: the one given at construction).
            pitch_weight: the joints kept are those of the least position error (m) plus
                this much per radian of pitch error (m/rad). The default, 0.01, gives up
                1 cm of position for 1 rad of pitch; a tiny weight puts the position
                first: the pitch yields wherever the commanded one and the position
                cannot both be reached (what ``ee_delta`` asks for).

        Returns:
            The five joint angles (within their limits), the remaining position error
            (m) and the remaining orientation error (rad: the pitch's and the roll's
            errors, root of the sum of squares) of those angles.
        """
        lower, upper = self._lower_list, self._upper_list
        q = [
            min(max(v, lo), hi)
            for v, lo, hi in zip(
                np.asarray(start, dtype=np.float64).tolist(), lower, upper, strict=True
            )
        ]
        i = self._roll_index
        roll = self._roll_middle + math.remainder(
            pose.roll - self.roll_offset - self._roll_middle, math.tau
        )
        q[i] = min(max(roll, lower[i]), upper[i])
        roll_error = abs(math.remainder(pose.roll - self.roll_offset - q[i], math.tau))
        tx, ty, tz = pose.position.tolist()
        iterations = self._max_iterations if max_iterations is None else max_iterations
        model, data, site = self._model, self._data, self._site
        free, free_lower, free_upper = self._pose_joints_list, self._free_lower, self._free_upper
        best_q, best_position, best_pitch, best_score = q, math.inf, math.inf, math.inf
        for iteration in range(iterations + 1):
            self._set(q)
            (px, py, pz), pitch, cos, sin = self._position_and_pitch()
            dx, dy, dz = tx - px, ty - py, tz - pz
            dpitch = math.remainder(pose.pitch - pitch, math.tau)
            position_error = math.sqrt(dx * dx + dy * dy + dz * dz)
            pitch_error = abs(dpitch)
            if iteration == 0:  # a move smaller than the tolerances still gets a step
                done = position_error < _REACHED and pitch_error < _REACHED
            else:
                # Reached, or no better than before (a target out of reach).
                done = (position_error < position_tolerance and pitch_error < pitch_tolerance) or (
                    best_position - position_error < position_tolerance
                    and best_pitch - pitch_error < pitch_tolerance
                )
            score = position_error + pitch_weight * pitch_error
            if score < best_score:
                best_q, best_position, best_pitch, best_score = q, position_error, dpitch, score
            if done or iteration == iterations:
                break
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, self._jacp, self._jacr, site)
            jac = self._jacp[:, self._pose_dofs].tolist()
            rx, ry, _ = self._jacr[:, self._pose_dofs].tolist()
            # The pitch turns about the horizontal axis across the arm's plane.
            pitch_row = [sin * rx[k] - cos * ry[k] for k in range(4)]
            dp = (dx, dy, dz)
            step = self._pose_step(jac, pitch_row, dp, dpitch)
            moved = [q[j] for j in free]
            # A joint that this step would push past its limit is held there, and the
            # others take over its share (the pitch yields before the position does).
            blocked = [
                (v + d <= lo and d < 0.0) or (v + d >= hi and d > 0.0)
                for v, d, lo, hi in zip(moved, step, free_lower, free_upper, strict=True)
            ]
            if True in blocked:
                keep = [0.0 if b else 1.0 for b in blocked]
                jac = [[v * k for v, k in zip(row, keep, strict=True)] for row in jac]
                pitch_row = [v * k for v, k in zip(pitch_row, keep, strict=True)]
                step = self._pose_step(jac, pitch_row, dp, dpitch)
                step = [d * k for d, k in zip(step, keep, strict=True)]
            # Near a stretched arm the step grows large: shorten it, keeping its direction.
            largest = max(abs(step[0]), abs(step[1]), abs(step[2]), abs(step[3]))
            shrink = _MAX_POSE_STEP_RAD / largest if largest > _MAX_POSE_STEP_RAD else 1.0
            q = q.copy()
            for j, v, d, lo, hi in zip(free, moved, step, free_lower, free_upper, strict=True):
                q[j] = min(max(v + shrink * d, lo), hi)
            if largest < 1e-9:
                break
        return np.array(best_q), best_position, math.hypot(best_pitch, roll_error)

    def _pose_step(
        self,
        jac: list[list[float]],
        pitch_row: list[float],
        dp: tuple[float, float, float],
        dpitch: float,
    ) -> list[float]:
        """One prioritised damped-least-squares step of four joints: position, then pitch.

        ``jac`` is the 3 x 4 position Jacobian (rows), ``pitch_row`` the pitch's 1 x 4.
        """
        # Written out on plain floats: a, b, c are the Jacobian's rows, index = joint.
        (a0, a1, a2, a3), (b0, b1, b2, b3), (c0, c1, c2, c3) = jac
        damping = self._position_damping
        aa = a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3 + damping
        bb = b0 * b0 + b1 * b1 + b2 * b2 + b3 * b3 + damping
        cc = c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3 + damping
        ab = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
        ac = a0 * c0 + a1 * c1 + a2 * c2 + a3 * c3
        bc = b0 * c0 + b1 * c1 + b2 * c2 + b3 * c3
        # (J J^T + damping) x = dp by cofactors (the matrix is symmetric positive definite).
        k_aa, k_ab, k_ac = bb * cc - bc * bc, ac * bc - ab * cc, ab * bc - ac * bb
        k_bb, k_bc, k_cc = aa * cc - ac * ac, ab * ac - aa * bc, aa * bb - ab * ab
        det = aa * k_aa + ab * k_ab + ac * k_ac
        dx, dy, dz = dp
        xa = (k_aa * dx + k_ab * dy + k_ac * dz) / det
        xb = (k_ab * dx + k_bb * dy + k_bc * dz) / det
        xc = (k_ac * dx + k_bc * dy + k_cc * dz) / det
        step = [
            xa * a0 + xb * b0 + xc * c0,
            xa * a1 + xb * b1 + xc * c1,
            xa * a2 + xb * b2 + xc * c2,
            xa * a3 + xb * b3 + xc * c3,
        ]
        # The direction the position leaves free: the signed 3 x 3 minors of the Jacobian
        # (all zero where the arm is stretched or a joint is held: the pitch waits), from
        # the 2 x 2 minors m_jk of rows b and c over joints j < k.
        m01, m02, m03 = b0 * c1 - b1 * c0, b0 * c2 - b2 * c0, b0 * c3 - b3 * c0
        m12, m13, m23 = b1 * c2 - b2 * c1, b1 * c3 - b3 * c1, b2 * c3 - b3 * c2
        null = [
            a1 * m23 - a2 * m13 + a3 * m12,
            -(a0 * m23 - a2 * m03 + a3 * m02),
            a0 * m13 - a1 * m03 + a3 * m01,
            -(a0 * m12 - a1 * m02 + a2 * m01),
        ]
        size = _dot(null, null)
        if size < 1e-24:
            return step
        gain = _dot(pitch_row, null) / math.sqrt(size)
        amount = gain * (dpitch - _dot(pitch_row, step)) / (gain * gain + self._pitch_damping)
        scale = amount / math.sqrt(size)
        return [step[j] + scale * null[j] for j in range(4)]

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

    def _set(self, arm_q: np.ndarray | list[float]) -> None:
        self._data.qpos[self._qpos_index] = arm_q
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
            dr = orientation_error(current, rotation)
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
