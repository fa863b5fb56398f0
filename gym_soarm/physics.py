"""The SO-101 scene's physics, answering questions in the robot's own words.

Only this module turns names into indices: ids are looked up once, at construction,
and every accessor returns a fresh array (never a view the next step overwrites).
"""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco.wrapper import core as dm_core

from gym_soarm import constants, model


def _quat_to_zaxis_abs_sum(quat: np.ndarray) -> float:
    """Sum of |R[2, :]| for the rotation of a (w, x, y, z) quaternion.

    For a cube of half-size h, ``h`` times this sum is the height of its centre above
    its lowest corner, whatever its orientation.
    """
    w, x, y, z = quat
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    return abs(r20) + abs(r21) + abs(r22)


class SoArmPhysics(dm_mujoco.Physics):
    """Physics of the SO-101 on its table, with the cube and the goal pad."""

    @classmethod
    def from_scene(cls) -> SoArmPhysics:
        """A new physics instance of the packaged scene (the model is compiled once)."""
        return cls.from_model(dm_core.MjModel(model.load_scene_model()))

    def _reload_from_data(self, data):
        super()._reload_from_data(data)
        self._cache_ids()

    def _cache_ids(self) -> None:
        m = self.model.ptr

        def jid(name: str) -> int:
            return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)

        self._arm_qpos_adr = np.array(
            [m.jnt_qposadr[jid(n)] for n in constants.JOINT_NAMES], dtype=np.intp
        )
        self._arm_dof_adr = np.array(
            [m.jnt_dofadr[jid(n)] for n in constants.JOINT_NAMES], dtype=np.intp
        )
        self._cube_qpos_adr = int(m.jnt_qposadr[jid(constants.CUBE_JOINT)])
        self._cube_dof_adr = int(m.jnt_dofadr[jid(constants.CUBE_JOINT)])
        self._actuator_ids = np.array(
            [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in constants.JOINT_NAMES],
            dtype=np.intp,
        )
        site = mujoco.mjtObj.mjOBJ_SITE
        self._gripper_site = mujoco.mj_name2id(m, site, constants.GRIPPER_SITE)
        self._grasp_site = mujoco.mj_name2id(m, site, constants.GRASP_SITE)
        self._goal_site = mujoco.mj_name2id(m, site, constants.GOAL_SITE)
        self._cube_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, constants.CUBE_GEOM)
        self._pad_geoms = tuple(
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in constants.JAW_PAD_GEOMS
        )
        self._touch_adr = np.array(
            [
                m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, n)]
                for n in constants.JAW_TOUCH_SENSORS
            ],
            dtype=np.intp,
        )
        self._home_key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, constants.HOME_KEYFRAME)

    # --- robot -------------------------------------------------------------------
    def joint_angles(self) -> np.ndarray:
        """The six joint positions in radians, in ``constants.JOINT_NAMES`` order."""
        return self.data.qpos[self._arm_qpos_adr]

    def joint_velocities(self) -> np.ndarray:
        """The six joint velocities in rad/s."""
        return self.data.qvel[self._arm_dof_adr]

    def joint_targets(self) -> np.ndarray:
        """The six servo targets (the last action) in radians."""
        return self.data.ctrl[self._actuator_ids].copy()

    def set_joint_targets(self, targets: np.ndarray) -> None:
        """Set the six servo targets in radians (no clipping here)."""
        self.data.ctrl[self._actuator_ids] = targets

    def set_joint_angles(self, angles: np.ndarray) -> None:
        """Teleport the joints (used only inside a reset context)."""
        self.data.qpos[self._arm_qpos_adr] = angles
        self.data.qvel[self._arm_dof_adr] = 0.0

    def control_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper servo target bounds in radians."""
        rng = self.model.ptr.actuator_ctrlrange[self._actuator_ids]
        return rng[:, 0].copy(), rng[:, 1].copy()

    def joint_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper joint limits in radians."""
        m = self.model.ptr
        ids = [m.joint(n).id for n in constants.JOINT_NAMES]
        rng = m.jnt_range[ids]
        return rng[:, 0].copy(), rng[:, 1].copy()

    def gripper_position(self) -> np.ndarray:
        """World position (m) of the ``gripperframe`` site, the tool centre point."""
        return self.data.site_xpos[self._gripper_site].copy()

    def gripper_orientation(self) -> np.ndarray:
        """World rotation matrix (3, 3) of the ``gripperframe`` site."""
        return self.data.site_xmat[self._gripper_site].reshape(3, 3).copy()

    def grasp_center(self) -> np.ndarray:
        """World position (m) where a held cube's centre sits, between the jaws."""
        return self.data.site_xpos[self._grasp_site].copy()

    def jaw_touch(self) -> np.ndarray:
        """Normal force (N) sensed by the fixed and the moving jaw pad."""
        return self.data.sensordata[self._touch_adr].copy()

    def jaw_contacts(self) -> tuple[bool, bool]:
        """Whether the fixed and the moving jaw pad each touch the cube."""
        d = self.data.ptr
        n = d.ncon
        if n == 0:
            return False, False
        pairs = d.contact.geom[:n]
        cube = self._cube_geom
        touching = []
        for pad in self._pad_geoms:
            hit = ((pairs[:, 0] == pad) & (pairs[:, 1] == cube)) | (
                (pairs[:, 0] == cube) & (pairs[:, 1] == pad)
            )
            touching.append(bool(hit.any()))
        return touching[0], touching[1]

    def cube_grasped(self) -> bool:
        """True when both jaw pads touch the cube."""
        fixed, moving = self.jaw_contacts()
        return fixed and moving

    def cube_touched_by_jaws(self) -> bool:
        """True when either jaw pad touches the cube."""
        fixed, moving = self.jaw_contacts()
        return fixed or moving

    # --- cube and goal ------------------------------------------------------------
    def cube_position(self) -> np.ndarray:
        """World position (m) of the cube's centre."""
        a = self._cube_qpos_adr
        return self.data.qpos[a : a + 3].copy()

    def cube_quaternion(self) -> np.ndarray:
        """Cube orientation as a (w, x, y, z) quaternion."""
        a = self._cube_qpos_adr + 3
        return self.data.qpos[a : a + 4].copy()

    def cube_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Cube position (m) and (w, x, y, z) quaternion."""
        return self.cube_position(), self.cube_quaternion()

    def cube_velocity(self) -> np.ndarray:
        """Cube linear velocity (m/s) in the world frame."""
        a = self._cube_dof_adr
        return self.data.qvel[a : a + 3].copy()

    def cube_bottom_height(self) -> float:
        """Height (m) of the cube's lowest corner above the table top."""
        centre_z = self.data.qpos[self._cube_qpos_adr + 2]
        reach = constants.CUBE_HALF_M * _quat_to_zaxis_abs_sum(self.cube_quaternion())
        return float(centre_z - reach - constants.TABLE_TOP_Z_M)

    def set_cube_pose(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Teleport the cube (used only inside a reset context)."""
        a = self._cube_qpos_adr
        self.data.qpos[a : a + 3] = position
        self.data.qpos[a + 3 : a + 7] = quaternion
        d = self._cube_dof_adr
        self.data.qvel[d : d + 6] = 0.0

    def goal_position(self) -> np.ndarray:
        """World position (m) of the goal pad's top centre."""
        return self.data.site_xpos[self._goal_site].copy()

    # --- whole state -----------------------------------------------------------------
    def reset_to_home(self) -> None:
        """Load the ``home`` keyframe (all joints at 0 rad) into qpos, qvel and ctrl."""
        mujoco.mj_resetDataKeyframe(self.model.ptr, self.data.ptr, self._home_key)

    def state_is_finite(self) -> bool:
        """False when positions, velocities or accelerations hold NaN or inf."""
        d = self.data.ptr
        return bool(
            np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all() and np.isfinite(d.qacc).all()
        )
