"""Inverse kinematics of the SO-101's arm on the MJCF model itself.

Damped least squares on MuJoCo's Jacobian of the ``grasp_center`` site, on a private
``mujoco.MjData`` so the environment's state is never touched. The scripted experts
use it.
"""

from __future__ import annotations

import math

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


def downward_rotation(yaw_rad: float) -> np.ndarray:
    """World rotation of the ``grasp_center`` site with the jaws pointing straight down.

    The gripper frame's jaws extend along its -z axis and close along its x axis, so z
    points up and x lies horizontal at ``yaw_rad``.
    """
    cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
    # Columns: x = (cos, sin, 0), y = z cross x = (-sin, cos, 0), z = (0, 0, 1).
    return np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])


def orientation_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Small-angle rotation vector (rad, world frame) turning ``current`` to ``target``.

    Half the sum of the cross products of matching axes, computed as the axial vector
    of ``target @ current.T`` (the cross products themselves are slow in numpy).
    """
    turn = target @ current.T
    return 0.5 * np.array(
        [turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]]
    )


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
