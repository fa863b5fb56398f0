"""The SO-101 scene's physics, answering questions in the robot's own words.

Only this module turns names into indices: ids are looked up once, at construction,
and every accessor returns a fresh array (never a view the next step overwrites).

The accessors run several times per environment step, so they read MuJoCo's arrays
directly (views cached at construction) rather than through dm_control's wrappers.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco.wrapper import core as dm_core
from dm_control.rl import control

from gym_soarm import constants
from gym_soarm.sim import objects, scene
from gym_soarm.sim.arrays import ARRAY_FIELDS, SimIndex

logger = logging.getLogger(__name__)
_WARNING_NAMES: tuple[str, ...] = tuple(mujoco.mjtWarning.__members__)
_NO_SENSORS = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)


@dataclasses.dataclass(frozen=True)
class _ObjectIndex:
    """Ids and array views of one free object, looked up once."""

    shape: str
    size: tuple[float, ...]
    geom: int
    geoms: frozenset[int]
    pos: np.ndarray
    quat: np.ndarray
    z_and_quat: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    linvel: np.ndarray


@dataclasses.dataclass(frozen=True)
class _FixtureIndex:
    """Ids and array views of one fixture, looked up once."""

    body: int
    xpos: np.ndarray
    geoms: frozenset[int]
    joint: int
    qpos_adr: int


class SoArmPhysics(dm_mujoco.Physics):
    """Physics of the SO-101 on its table with one task's objects and fixtures.

    The robot's accessors speak of joints, servos and the jaws; everything else is
    asked for by the name it was declared with (``object_position("cube")``,
    ``fixture_position("goal")``, ``touching("red_cube", "blue_cube")``).
    """

    layout: objects.Scene = objects.EMPTY_SCENE

    @classmethod
    def from_scene(
        cls, layout: objects.Scene = objects.EMPTY_SCENE, visual: str = "fast", label: str = "scene"
    ) -> SoArmPhysics:
        """A new physics instance of the arena with ``layout``'s objects and fixtures.

        The model is compiled once per process, scene and visual variant.

        Args:
            layout: the task's objects and fixtures.
            visual: ``"fast"`` (simplified visual meshes) or ``"high"`` (full-detail
                meshes). Both have the same physics; only rendering differs.
            label: names the cached compiled model (the task's name).
        """
        physics = cls.from_model(dm_core.MjModel(scene.load_scene_model(layout, visual, label)))
        physics.layout = layout
        physics._index_layout()
        return physics

    def copy(self, share_model: bool = False) -> SoArmPhysics:
        """A copy of this physics (see dm_control), with the same objects and fixtures."""
        new = super().copy(share_model)
        new.layout = self.layout
        new._index_layout()
        return new

    def __getstate__(self):
        return self.data, self.layout

    def __setstate__(self, state) -> None:
        data, self.layout = state
        super().__setstate__(data)

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
        self.array_views = {name: getattr(d, name) for name in ARRAY_FIELDS}
        """Live views of the fields a :class:`~gym_soarm.sim.arrays.SimArrays` reads."""

        def jid(name: str) -> int:
            return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)

        self._arm_qpos_adr = np.array(
            [m.jnt_qposadr[jid(n)] for n in constants.JOINT_NAMES], dtype=np.intp
        )
        self._arm_dof_adr = np.array(
            [m.jnt_dofadr[jid(n)] for n in constants.JOINT_NAMES], dtype=np.intp
        )
        site = mujoco.mjtObj.mjOBJ_SITE
        self._gripper_site = mujoco.mj_name2id(m, site, constants.GRIPPER_SITE)
        self._grasp_site = mujoco.mj_name2id(m, site, constants.GRASP_SITE)
        self._pad_geoms = tuple(
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in constants.JAW_PAD_GEOMS
        )
        self._table_geoms = frozenset(
            {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, constants.TABLE_GEOM)}
        )
        self._actuator_ids = np.array(
            [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in constants.JOINT_NAMES],
            dtype=np.intp,
        )
        self._touch_adr = np.array(
            [
                m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, n)]
                for n in constants.JAW_TOUCH_SENSORS
            ],
            dtype=np.intp,
        )
        self._home_key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, constants.HOME_KEYFRAME)
        self._gripper_xpos = self._site_xpos[self._gripper_site]
        self._grasp_xpos = self._site_xpos[self._grasp_site]
        self._index_layout()

    def _index_layout(self) -> None:
        """Look every declared object and fixture up by name, once."""
        m = self._mj_model
        self._objects: dict[str, _ObjectIndex] = {}
        for item in self.layout.objects:
            joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, item.name)
            q, v = int(m.jnt_qposadr[joint]), int(m.jnt_dofadr[joint])
            geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, item.name)
            self._objects[item.name] = _ObjectIndex(
                shape=item.shape,
                size=tuple(item.size_m),
                geom=geom,
                geoms=frozenset({geom}),
                pos=self._qpos[q : q + 3],
                quat=self._qpos[q + 3 : q + 7],
                z_and_quat=self._qpos[q + 2 : q + 7],
                qpos=self._qpos[q : q + 7],
                qvel=self._qvel[v : v + 6],
                linvel=self._qvel[v : v + 3],
            )
        self._fixtures: dict[str, _FixtureIndex] = {}
        for fixture in self.layout.fixtures:
            body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, fixture.name)
            site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, fixture.name)
            joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, fixture.name)
            geoms = frozenset(int(g) for g in np.flatnonzero(m.geom_bodyid == body))
            self._fixtures[fixture.name] = _FixtureIndex(
                body=body,
                xpos=self._site_xpos[site],
                geoms=geoms,
                joint=joint,
                qpos_adr=int(m.jnt_qposadr[joint]) if joint >= 0 else -1,
            )
        self.sim_index = SimIndex.of_model(m, self.layout)
        """Where this scene's parts lie in its arrays (:class:`~gym_soarm.sim.arrays.SimIndex`)."""
        self._geom_groups: dict[str, frozenset[int]] = {
            "table": self._table_geoms,
            **{name: index.geoms for name, index in self._objects.items()},
            **{name: index.geoms for name, index in self._fixtures.items()},
        }

    # --- segmentation ----------------------------------------------------------------
    def segmentation_ids(self) -> dict[str, int]:
        """Segment ids of segmentation images: ``"background"`` 0 (the floor and the sky),
        ``"table"`` 1, ``"robot"`` 2, then each object and each fixture in declaration
        order (objects first).
        """
        names = ("background", "table", "robot", *self._objects, *self._fixtures)
        return {name: index for index, name in enumerate(names)}

    def geom_segments(self) -> np.ndarray:
        """int32 array: the segment id (:meth:`segmentation_ids`) of every geom of the model.

        A fixture's parts are its own (a fixture attached to another keeps its own id).
        """
        m = self._mj_model
        ids = self.segmentation_ids()
        body_of_geom = np.asarray(m.geom_bodyid)
        root_of_body = np.asarray(m.body_rootid)
        segments = np.zeros(m.ngeom, dtype=np.int32)
        body = mujoco.mjtObj.mjOBJ_BODY
        table = mujoco.mj_name2id(m, body, constants.TABLE_BODY)
        robot = mujoco.mj_name2id(m, body, constants.ROBOT_BASE_BODY)
        segments[root_of_body[body_of_geom] == table] = ids["table"]
        segments[root_of_body[body_of_geom] == robot] = ids["robot"]
        for name in (*self._objects, *self._fixtures):
            segments[body_of_geom == mujoco.mj_name2id(m, body, name)] = ids[name]
        return segments

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
            if nstep > 1:
                # The sensors (the scene's contact sensors) are read once a control
                # step: computed on its last substep only. They never act on the
                # dynamics, so the state is the same bit for bit.
                option = self._mj_option
                flags = option.disableflags
                option.disableflags = flags | _NO_SENSORS
                try:
                    mujoco.mj_step2(m, d)
                    if nstep > 2:
                        mujoco.mj_step(m, d, nstep - 2)
                finally:
                    option.disableflags = flags
                mujoco.mj_step(m, d, 1)
            else:
                mujoco.mj_step2(m, d)
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

    def set_servo_force_limit(self, torque_nm: float) -> None:
        """Limit every servo's force to +-``torque_nm`` (N·m) on this model copy."""
        m = self._mj_model
        m.actuator_forcerange[self._actuator_ids] = (-torque_nm, torque_nm)
        m.actuator_forcelimited[self._actuator_ids] = 1

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
        """World position (m) where a held object's centre sits, between the jaws."""
        return self._grasp_xpos.copy()

    def jaw_touch(self) -> np.ndarray:
        """Normal force (N) sensed by the fixed and the moving jaw pad."""
        return self._sensordata[self._touch_adr]

    def _object(self, name: str) -> _ObjectIndex:
        index = self._objects.get(name)
        if index is None:
            raise objects.not_in_scene("object", name, self._objects)
        return index

    def _fixture(self, name: str) -> _FixtureIndex:
        index = self._fixtures.get(name)
        if index is None:
            raise objects.not_in_scene("fixture", name, self._fixtures)
        return index

    def jaw_contacts(self, name: str) -> tuple[bool, bool]:
        """Whether the fixed and the moving jaw pad each touch object ``name``."""
        d = self._mj_data
        n = d.ncon
        if n == 0:
            return False, False
        geom = self._object(name).geom
        fixed_pad, moving_pad = self._pad_geoms
        fixed = moving = False
        # A plain loop: there are only a handful of contacts, and numpy costs more.
        for geom1, geom2 in d.contact.geom[:n].tolist():
            other = geom2 if geom1 == geom else geom1 if geom2 == geom else -1
            if other == fixed_pad:
                fixed = True
            elif other == moving_pad:
                moving = True
        return fixed, moving

    def grasped(self, name: str) -> bool:
        """True when both jaw pads touch object ``name``."""
        fixed, moving = self.jaw_contacts(name)
        return fixed and moving

    def touched_by_jaws(self, name: str) -> bool:
        """True when either jaw pad touches object ``name``."""
        fixed, moving = self.jaw_contacts(name)
        return fixed or moving

    def touching(self, first: str, second: str) -> bool:
        """True when objects/fixtures ``first`` and ``second`` touch (``"table"`` too)."""
        groups = self._geom_groups
        for name in (first, second):
            if name not in groups:
                raise ValueError(
                    f"unknown object or fixture {name!r}; this scene has {sorted(groups)}."
                )
        a, b = groups[first], groups[second]
        d = self._mj_data
        for geom1, geom2 in d.contact.geom[: d.ncon].tolist():
            if (geom1 in a and geom2 in b) or (geom1 in b and geom2 in a):
                return True
        return False

    def jaw_pads_center(self) -> np.ndarray:
        """World position (m) midway between the two jaw pads: the centre of closed jaws."""
        xpos = self._mj_data.geom_xpos
        fixed, moving = self._pad_geoms
        return (xpos[fixed] + xpos[moving]) / 2

    def fixture_part_geoms(self, name: str, parts: Sequence[int]) -> frozenset[int]:
        """The geom ids of fixture ``name``'s parts: indices into its declared geoms.

        Raises:
            ValueError: no fixture ``name``, or it has no part of one of those indices.
        """
        m = self._mj_model
        self._fixture(name)
        ids = {
            index: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{name}_{index}")
            for index in parts
        }
        missing = [index for index, geom in ids.items() if geom < 0]
        if missing:
            raise ValueError(
                f"fixture {name!r} has no geoms {missing}; pass indices into its declared geoms."
            )
        return frozenset(ids.values())

    def jaw_contacts_with(self, geoms: frozenset[int]) -> tuple[bool, bool]:
        """Whether the fixed and the moving jaw pad each touch one of ``geoms`` (geom ids,
        e.g. :meth:`fixture_part_geoms`)."""
        d = self._mj_data
        fixed_pad, moving_pad = self._pad_geoms
        fixed = moving = False
        for geom1, geom2 in d.contact.geom[: d.ncon].tolist():
            if geom1 in geoms:
                other = geom2
            elif geom2 in geoms:
                other = geom1
            else:
                continue
            fixed = fixed or other == fixed_pad
            moving = moving or other == moving_pad
        return fixed, moving

    # --- objects and fixtures, by name ---------------------------------------------------
    @property
    def object_names(self) -> tuple[str, ...]:
        """The free objects of this scene, in declaration order."""
        return tuple(self._objects)

    @property
    def fixture_names(self) -> tuple[str, ...]:
        """The fixtures of this scene, in declaration order."""
        return tuple(self._fixtures)

    def object_position(self, name: str) -> np.ndarray:
        """World position (m) of object ``name``'s centre."""
        return self._object(name).pos.copy()

    def object_quaternion(self, name: str) -> np.ndarray:
        """Orientation of object ``name`` as a (w, x, y, z) quaternion."""
        return self._object(name).quat.copy()

    def object_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and (w, x, y, z) quaternion of object ``name``."""
        index = self._object(name)
        return index.pos.copy(), index.quat.copy()

    def object_velocity(self, name: str) -> np.ndarray:
        """Linear velocity (m/s, world frame) of object ``name``."""
        return self._object(name).linvel.copy()

    def object_speed(self, name: str) -> float:
        """Linear speed (m/s) of object ``name``."""
        vx, vy, vz = self._object(name).linvel.tolist()
        return math.sqrt(vx * vx + vy * vy + vz * vz)

    def object_yaw(self, name: str) -> float:
        """Yaw (rad) of object ``name``'s x axis about the world z axis."""
        w, x, y, z = self._object(name).quat.tolist()
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    def object_height(self, name: str) -> float:
        """Height (m) of object ``name``'s lowest point above the table top."""
        index = self._object(name)
        centre_z, w, x, y, z = index.z_and_quat.tolist()
        r20 = 2.0 * (x * z - w * y)
        r21 = 2.0 * (y * z + w * x)
        r22 = 1.0 - 2.0 * (x * x + y * y)
        size = index.size
        if index.shape == "box":
            reach = size[0] * abs(r20) + size[1] * abs(r21) + size[2] * abs(r22)
        elif index.shape == "cylinder":
            reach = size[1] * abs(r22) + size[0] * math.sqrt(max(0.0, 1.0 - r22 * r22))
        else:
            reach = size[0]
        return float(centre_z - reach - constants.TABLE_TOP_Z_M)

    def set_object_pose(self, name: str, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Teleport object ``name`` at rest (used only inside a reset context)."""
        index = self._object(name)
        index.pos[:] = position
        index.quat[:] = quaternion
        index.qvel[:] = 0.0

    def push_object(self, name: str, velocity_m_s: np.ndarray) -> None:
        """Give object ``name`` the linear velocity ``velocity_m_s`` (a push; its pose and
        spin stay), as a perturbation between two steps."""
        self._object(name).qvel[:3] = velocity_m_s

    def fixture_position(self, name: str) -> np.ndarray:
        """World position (m) of fixture ``name``'s site (the point a task aims at)."""
        return self._fixture(name).xpos.copy()

    def set_fixture_position(self, name: str, position: np.ndarray) -> None:
        """Put fixed fixture ``name``'s body at world ``position`` (m), in a reset context.

        The body position is a parameter of this environment's own copy of the model, so
        nothing is recompiled; the forward kinematics at the end of the reset place it.

        Raises:
            ValueError: no fixture ``name``, or it moves on a joint or hangs from another
                fixture (its body position is then not a world position).
        """
        index = self._fixture(name)
        fixture = next(f for f in self.layout.fixtures if f.name == name)
        if fixture.joint is not None or fixture.parent is not None:
            raise ValueError(
                f"fixture {name!r} moves on a joint or hangs from another fixture; only a "
                "fixture fixed to the world can be moved to a world position."
            )
        self._mj_model.body_pos[index.body] = position

    def fixture_body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and (w, x, y, z) quaternion of fixture ``name``'s body, as the model
        holds them (relative to its parent: the world, for a fixture fixed to it)."""
        body = self._fixture(name).body
        m = self._mj_model
        return m.body_pos[body].copy(), m.body_quat[body].copy()

    def set_fixture_pose(self, name: str, position: np.ndarray, quaternion: np.ndarray) -> None:
        """Put fixed fixture ``name``'s body at world ``position`` (m) turned by ``quaternion``
        (w, x, y, z), in a reset context; fixtures hanging from it move with it.

        Raises:
            ValueError: as :meth:`set_fixture_position`.
        """
        self.set_fixture_position(name, position)
        self._mj_model.body_quat[self._fixture(name).body] = quaternion

    def fixture_joint_axis(self, name: str) -> np.ndarray:
        """World direction (unit) of fixture ``name``'s joint axis (a slide's opening direction).

        Raises:
            ValueError: no fixture ``name``, or it has no joint.
        """
        index = self._fixture(name)
        if index.joint < 0:
            raise ValueError(f"fixture {name!r} has no joint; it does not move.")
        return self._mj_data.xaxis[index.joint].copy()

    def geom_discs(self, name: str) -> list[tuple[float, float, float]]:
        """(x, y, bounding radius) in m of every geom of object or fixture ``name``'s body,
        where the latest kinematics (:meth:`forward_kinematics`) put them."""
        if name in self._objects:
            body = int(self._mj_model.geom_bodyid[self._objects[name].geom])
        else:
            body = self._fixture(name).body
        m, d = self._mj_model, self._mj_data
        discs = []
        for geom in np.flatnonzero(m.geom_bodyid == body):
            x, y, _ = d.geom_xpos[geom]
            discs.append((float(x), float(y), float(m.geom_rbound[geom])))
        return discs

    def forward_kinematics(self) -> None:
        """Place every body and geom from qpos now (inside a reset context, before it ends)."""
        mujoco.mj_kinematics(self._mj_model, self._mj_data)

    def fixture_joint_position(self, name: str) -> float:
        """Position of fixture ``name``'s joint (m for a slide, rad for a hinge)."""
        index = self._fixture(name)
        if index.qpos_adr < 0:
            raise ValueError(f"fixture {name!r} has no joint; it does not move.")
        return float(self._qpos[index.qpos_adr])

    def max_object_distance(self) -> tuple[str, float] | None:
        """The object farthest from the world origin and that distance (m), or None."""
        best: tuple[str, float] | None = None
        for name, index in self._objects.items():
            distance = max(map(abs, index.pos.tolist()))
            if best is None or distance > best[1]:
                best = (name, distance)
        return best

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
