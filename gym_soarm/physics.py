"""The SO-101 scene's physics, answering questions in the robot's own words.

Only this module turns names into indices: ids are looked up once, at construction,
and every accessor returns a fresh array (never a view the next step overwrites).

The accessors run several times per environment step, so they read MuJoCo's arrays
directly (views cached at construction) rather than through dm_control's wrappers.
"""

from __future__ import annotations

import logging
import math

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco.wrapper import core as dm_core
from dm_control.rl import control

from gym_soarm import constants, model

logger = logging.getLogger(__name__)
_WARNING_NAMES: tuple[str, ...] = tuple(mujoco.mjtWarning.__members__)
_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)


def _quat_to_zaxis_abs_sum(quat: np.ndarray | list[float]) -> float:
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
    def from_scene(cls, visual: str = "fast") -> SoArmPhysics:
        """A new physics instance of the packaged scene (the model is compiled once).

        Args:
            visual: ``"fast"`` (simplified visual meshes) or ``"high"`` (full-detail
                meshes). Both have the same physics; only rendering differs.
        """
        return cls.from_model(dm_core.MjModel(model.load_scene_model(visual)))

    def _reload_from_data(self, data):
        super()._reload_from_data(data)
        self._cache_ids()

    def _cache_ids(self) -> None:
        m = self.model.ptr
        d = self.data.ptr
        # MuJoCo's own structs and array views, valid for the life of this data.
        self._mj_model = m
        self._mj_data = d
        self._mj_option = m.opt
        self._qpos = d.qpos
        self._qvel = d.qvel
        self._qacc = d.qacc
        self._ctrl = d.ctrl
        self._site_xpos = d.site_xpos
        self._site_xmat = d.site_xmat
        self._sensordata = d.sensordata

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
        # Views of the named quantities; the accessors hand out copies of them.
        q, v = self._cube_qpos_adr, self._cube_dof_adr
        self._cube_pos = self._qpos[q : q + 3]
        self._cube_quat = self._qpos[q + 3 : q + 7]
        self._cube_z_and_quat = self._qpos[q + 2 : q + 7]
        self._cube_linvel = self._qvel[v : v + 3]
        self._gripper_xpos = self._site_xpos[self._gripper_site]
        self._grasp_xpos = self._site_xpos[self._grasp_site]
        self._goal_xpos = self._site_xpos[self._goal_site]

    # --- stepping --------------------------------------------------------------------
    def step(self, nstep: int = 1) -> None:
        """Advance the simulation by ``nstep`` physics steps.

        Does what :meth:`dm_control.mujoco.Physics.step` does (with ``legacy_step``,
        mj_step1 runs last so positions, sites and contacts match the new state; a new
        MuJoCo warning raises :class:`dm_control.rl.control.PhysicsError`, or is logged
        inside ``suppress_physics_errors()``), with less Python around the MuJoCo calls.
        """
        m, d = self._mj_model, self._mj_data
        before = self._warnings.tolist()  # a list compares faster than the strided view
        if not self.legacy_step:
            mujoco.mj_step(m, d, nstep)
        elif self._mj_option.integrator != _RK4:
            mujoco.mj_step2(m, d)
            if nstep > 1:
                mujoco.mj_step(m, d, nstep - 1)
            mujoco.mj_step1(m, d)
        else:
            mujoco.mj_step(m, d, nstep)
            mujoco.mj_step1(m, d)
        after = self._warnings.tolist()
        if after != before:
            self._report_new_warnings(before, after)

    def _report_new_warnings(self, before: list[int], after: list[int]) -> None:
        # mjtWarning also lists mjNWARNING, the count, which has no counter of its own.
        names = [
            name for name, old, new in zip(_WARNING_NAMES, before, after, strict=False) if new > old
        ]
        if not names:  # counters were cleared by a reset and none went up
            return
        message = f"Physics state is invalid. Warning(s) raised: {', '.join(names)}"
        if self._warnings_cause_exception:
            raise control.PhysicsError(message)
        logger.warning(message)

    # --- robot -------------------------------------------------------------------
    def joint_angles(self) -> np.ndarray:
        """The six joint positions in radians, in ``constants.JOINT_NAMES`` order."""
        return self._qpos[self._arm_qpos_adr]

    def joint_velocities(self) -> np.ndarray:
        """The six joint velocities in rad/s."""
        return self._qvel[self._arm_dof_adr]

    def joint_targets(self) -> np.ndarray:
        """The six servo targets (the last action) in radians."""
        return self._ctrl[self._actuator_ids]

    def set_joint_targets(self, targets: np.ndarray) -> None:
        """Set the six servo targets in radians (no clipping here)."""
        self._ctrl[self._actuator_ids] = targets

    def set_joint_angles(self, angles: np.ndarray) -> None:
        """Teleport the joints (used only inside a reset context)."""
        self._qpos[self._arm_qpos_adr] = angles
        self._qvel[self._arm_dof_adr] = 0.0

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
        return self._gripper_xpos.copy()

    def gripper_orientation(self) -> np.ndarray:
        """World rotation matrix (3, 3) of the ``gripperframe`` site."""
        return self._site_xmat[self._gripper_site].reshape(3, 3).copy()

    def grasp_center(self) -> np.ndarray:
        """World position (m) where a held cube's centre sits, between the jaws."""
        return self._grasp_xpos.copy()

    def jaw_touch(self) -> np.ndarray:
        """Normal force (N) sensed by the fixed and the moving jaw pad."""
        return self._sensordata[self._touch_adr]

    def jaw_contacts(self) -> tuple[bool, bool]:
        """Whether the fixed and the moving jaw pad each touch the cube."""
        d = self._mj_data
        n = d.ncon
        if n == 0:
            return False, False
        cube = self._cube_geom
        fixed_pad, moving_pad = self._pad_geoms
        fixed = moving = False
        # A plain loop: there are only a handful of contacts, and numpy costs more.
        for geom1, geom2 in d.contact.geom[:n].tolist():
            other = geom2 if geom1 == cube else geom1 if geom2 == cube else -1
            if other == fixed_pad:
                fixed = True
            elif other == moving_pad:
                moving = True
        return fixed, moving

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
        return self._cube_pos.copy()

    def cube_quaternion(self) -> np.ndarray:
        """Cube orientation as a (w, x, y, z) quaternion."""
        return self._cube_quat.copy()

    def cube_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Cube position (m) and (w, x, y, z) quaternion."""
        return self.cube_position(), self.cube_quaternion()

    def cube_velocity(self) -> np.ndarray:
        """Cube linear velocity (m/s) in the world frame."""
        return self._cube_linvel.copy()

    def cube_bottom_height(self) -> float:
        """Height (m) of the cube's lowest corner above the table top."""
        centre_z, *quat = self._cube_z_and_quat.tolist()
        reach = constants.CUBE_HALF_M * _quat_to_zaxis_abs_sum(quat)
        return float(centre_z - reach - constants.TABLE_TOP_Z_M)

    def set_cube_pose(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Teleport the cube (used only inside a reset context)."""
        a = self._cube_qpos_adr
        self._qpos[a : a + 3] = position
        self._qpos[a + 3 : a + 7] = quaternion
        d = self._cube_dof_adr
        self._qvel[d : d + 6] = 0.0

    def goal_position(self) -> np.ndarray:
        """World position (m) of the goal pad's top centre."""
        return self._goal_xpos.copy()

    # --- whole state -----------------------------------------------------------------
    def reset_to_home(self) -> None:
        """Load the ``home`` keyframe (all joints at 0 rad) into qpos, qvel and ctrl."""
        mujoco.mj_resetDataKeyframe(self._mj_model, self._mj_data, self._home_key)

    def state_is_finite(self) -> bool:
        """False when positions, velocities or accelerations hold NaN or inf."""
        # A float sum is NaN or inf as soon as one term is (without numpy's warnings), and
        # cheaper than np.isfinite(...).all() three times. Finite terms could only
        # overflow it beyond 1e307; MuJoCo resets a state long before (beyond 1e10).
        total = sum(self._qpos.tolist()) + sum(self._qvel.tolist()) + sum(self._qacc.tolist())
        return math.isfinite(total)
