"""The state of a batch of simulations as arrays: what tasks read to score a step.

A task's evaluation, reward terms, success, info and ``state`` observation are functions
of a :class:`SimArrays` (:mod:`gym_soarm.tasks.base`): the positions, velocities, sites
and contact sensors of ``n`` simulations of one scene, every accessor answering with a
leading batch axis (``object_position("cube")`` is ``(n, 3)``, ``grasped("cube")`` is
``(n,)`` bool; indexing is always along the last axes, ``[..., k]``). One environment is
scored on its own ``MjData``'s arrays without the batch axis (:meth:`SimArrays.of_physics`):
the same code then answers NumPy scalars and small vectors, with :data:`SCALARS` as its
namespace, which spares it NumPy's per-call cost on arrays of one. The batched vector
env binds the same fields of all its simulations at once (``mujoco.batch``).

The arrays may be NumPy arrays or any array-API library's (torch tensors: the same task
code runs on them, :func:`namespace`), so a GPU physics backend only has to hand over
its arrays. Contacts come from the ``found`` contact sensors the scene adds
(:func:`gym_soarm.sim.scene.contact_sensor_name`), since a batch keeps no contact list.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from array_api_compat import array_namespace
from array_api_compat import device as array_device

from gym_soarm import constants
from gym_soarm.sim.objects import not_in_scene
from gym_soarm.sim.scene import contact_sensor_name

if TYPE_CHECKING:
    from gym_soarm.sim.physics import SoArmPhysics

Array = Any
"""An array of one array-API library (NumPy here; torch tensors work the same)."""

ARRAY_FIELDS: tuple[str, ...] = ("qpos", "qvel", "qacc", "site_xpos", "geom_xpos", "sensordata")
"""The ``MjData`` fields a :class:`SimArrays` reads (``mujoco.batch`` binds them)."""


_NUMPY_IS_STANDARD = hasattr(np, "concat") and hasattr(np, "atan2")


def _is_array(value: Any) -> bool:
    return isinstance(value, np.ndarray) and value.ndim > 0


class _Scalars:
    """The array-API functions the tasks use, for one environment's unbatched values.

    One environment is scored on its own simulation's arrays without a batch axis, so its
    flags and distances are NumPy scalars; these functions answer for them with Python's
    scalar operations, which cost a fraction of a NumPy call, and hand arrays (an
    object's position, ``(3,)``) to NumPy. For finite float64 values the results equal
    NumPy's bit for bit (the transcendental functions are NumPy's own); ``maximum`` and
    ``minimum`` do not propagate NaN as NumPy's do (a NaN state is a divergence, caught
    before any task is scored).
    """

    float32 = np.float32
    float64 = np.float64
    int64 = np.int64

    # The type checks are written out: these run a dozen times in one environment's step.
    @staticmethod
    def where(condition: Any, x1: Any, x2: Any) -> Any:
        if type(condition) is np.ndarray and condition.ndim:
            return np.where(condition, x1, x2)
        return x1 if condition else x2

    @staticmethod
    def maximum(x1: Any, x2: Any) -> Any:
        if (type(x1) is np.ndarray and x1.ndim) or (type(x2) is np.ndarray and x2.ndim):
            return np.maximum(x1, x2)
        return np.float64(x2) if x2 > x1 else np.float64(x1)

    @staticmethod
    def minimum(x1: Any, x2: Any) -> Any:
        if (type(x1) is np.ndarray and x1.ndim) or (type(x2) is np.ndarray and x2.ndim):
            return np.minimum(x1, x2)
        return np.float64(x2) if x2 < x1 else np.float64(x1)

    @staticmethod
    def abs(x: Any) -> Any:
        return abs(x)

    @staticmethod
    def sqrt(x: Any) -> Any:
        return np.sqrt(x) if _is_array(x) else np.float64(math.sqrt(x))

    exp = staticmethod(np.exp)
    acos = staticmethod(np.arccos)
    atan2 = staticmethod(np.arctan2)
    isfinite = staticmethod(np.isfinite)
    zeros_like = staticmethod(np.zeros_like)
    ones_like = staticmethod(np.ones_like)
    full_like = staticmethod(np.full_like)
    stack = staticmethod(np.stack)
    concat = staticmethod(np.concatenate)
    sum = staticmethod(np.sum)
    all = staticmethod(np.all)
    any = staticmethod(np.any)

    @staticmethod
    def astype(x: Any, dtype: Any) -> Any:
        if _is_array(x):
            return x.astype(dtype)
        scalar = _SCALAR_TYPES.get(dtype)  # a dtype or a scalar type: its scalar type
        return (np.dtype(dtype).type if scalar is None else scalar)(x)


_SCALAR_TYPES: dict[Any, Any] = {
    key: kind
    for kind in (np.float32, np.float64, np.int64, np.bool_)
    for key in (kind, np.dtype(kind))
}


SCALARS = _Scalars()
"""The namespace of one environment's unbatched values (:class:`_Scalars`)."""


def namespace(*arrays: Array) -> Any:
    """The array-API namespace of ``arrays``: NumPy itself for NumPy arrays (2.x speaks
    the standard), :data:`SCALARS` for one environment's NumPy scalars, else
    ``array_api_compat``'s (torch ...)."""
    first = arrays[0]
    if isinstance(first, (np.generic, float, int)):
        return SCALARS
    numpy_only = len(arrays) == 1 or all(type(a) is np.ndarray for a in arrays)
    if _NUMPY_IS_STANDARD and type(first) is np.ndarray and numpy_only:
        return np
    return array_namespace(*arrays)


def to_numpy(values: Array) -> np.ndarray:
    """``values`` as a NumPy array on the host: NumPy arrays as they are, a torch tensor
    copied from its device (on a GPU this waits for it: a host synchronisation)."""
    if isinstance(values, np.ndarray):
        return values
    if hasattr(values, "detach"):  # torch
        return values.detach().cpu().numpy()
    return np.asarray(values)


def in_namespace(xp: Any, values: Any, like: Array) -> Array:
    """``values`` (host NumPy values) as an array of ``xp`` on the device of ``like``
    (NumPy's values as they are)."""
    if xp is np or xp is SCALARS:
        return values
    return xp.asarray(values, device=array_device(like))


def _cached(method: Any) -> Any:
    """Keep what ``method(self, *args)`` answered until :meth:`SimArrays.clear`."""
    key = method.__name__

    def read(self: SimArrays, *args: Any) -> Any:
        entry = (key, *args)
        value = self._cache.get(entry)
        if value is None:
            value = self._cache[entry] = method(self, *args)
        return value

    read.__name__ = key
    read.__doc__ = method.__doc__
    return read


@dataclasses.dataclass(frozen=True)
class _Object:
    shape: str
    size: tuple[float, ...]
    qpos: int
    dof: int


@dataclasses.dataclass(frozen=True)
class SimIndex:
    """Where every named part of one scene's model lies in the arrays: found once.

    Built from a model by :meth:`of_model`; every simulation of a batch shares it.
    """

    arm_qpos: tuple[int, ...]
    arm_dof: tuple[int, ...]
    grasp_site: int
    gripper_site: int
    objects: Mapping[str, _Object]
    fixture_sites: Mapping[str, int]
    fixture_joints: Mapping[str, int]
    contacts: Mapping[tuple[str, str], int]
    """Sensor address of each contact sensor, keyed by both orders of its pair."""
    touch: tuple[int, int]
    pads: tuple[int, int]
    """Geom ids of the fixed and the moving jaw pad."""

    @functools.cached_property
    def arm_qpos_index(self) -> np.ndarray:
        """:attr:`arm_qpos` as an index array."""
        return np.array(self.arm_qpos, dtype=np.intp)

    @functools.cached_property
    def arm_dof_index(self) -> np.ndarray:
        """:attr:`arm_dof` as an index array."""
        return np.array(self.arm_dof, dtype=np.intp)

    @classmethod
    def of_model(cls, model: mujoco.MjModel, layout: Any) -> SimIndex:
        """The index of ``model``, a scene compiled with ``layout``'s objects and fixtures."""

        def oid(kind: mujoco.mjtObj, name: str) -> int:
            return mujoco.mj_name2id(model, kind, name)

        joint, site = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_SITE
        arm = [oid(joint, name) for name in constants.JOINT_NAMES]
        objects = {}
        for item in layout.objects:
            j = oid(joint, item.name)
            objects[item.name] = _Object(
                item.shape,
                tuple(item.size_m),
                int(model.jnt_qposadr[j]),
                int(model.jnt_dofadr[j]),
            )
        fixture_joints = {}
        for fixture in layout.fixtures:
            j = oid(joint, fixture.name)
            if j >= 0:
                fixture_joints[fixture.name] = int(model.jnt_qposadr[j])
        contacts: dict[tuple[str, str], int] = {}
        prefix = contact_sensor_name("", "")[: -len(":")]
        for sensor in range(model.nsensor):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, sensor) or ""
            if name.startswith(prefix):
                first, second = name[len(prefix) :].split(":")
                contacts[first, second] = contacts[second, first] = int(model.sensor_adr[sensor])
        touch = tuple(
            int(model.sensor_adr[oid(mujoco.mjtObj.mjOBJ_SENSOR, name)])
            for name in constants.JAW_TOUCH_SENSORS
        )
        return cls(
            arm_qpos=tuple(int(model.jnt_qposadr[j]) for j in arm),
            arm_dof=tuple(int(model.jnt_dofadr[j]) for j in arm),
            grasp_site=oid(site, constants.GRASP_SITE),
            gripper_site=oid(site, constants.GRIPPER_SITE),
            objects=objects,
            fixture_sites={f.name: oid(site, f.name) for f in layout.fixtures},
            fixture_joints=fixture_joints,
            contacts=contacts,
            touch=(touch[0], touch[1]),
            pads=tuple(oid(mujoco.mjtObj.mjOBJ_GEOM, name) for name in constants.JAW_PAD_GEOMS),
        )


class SimArrays:
    """``n`` simulations of one scene, read as arrays with a leading batch axis.

    Args:
        index: where the scene's parts lie (:class:`SimIndex`).
        arrays: the ``MjData`` fields of :data:`ARRAY_FIELDS`, each ``(n, ...)``, as
            they are after a step (positions-stage values current).
        episode: each environment's per-episode values, ``(n, ...)`` arrays by name (what
            a task keeps between steps: a start distance, the most an object rose ...).
            Tasks may update them in place.
    """

    def __init__(
        self, index: SimIndex, arrays: Mapping[str, Array], episode: dict[str, Array] | None = None
    ) -> None:
        self.index = index
        self.qpos = arrays["qpos"]
        self.qvel = arrays["qvel"]
        self.qacc = arrays["qacc"]
        self.site_xpos = arrays["site_xpos"]
        self.geom_xpos = arrays["geom_xpos"]
        self.sensordata = arrays["sensordata"]
        self.episode: dict[str, Array] = {} if episode is None else episode
        self.xp = SCALARS if self.qpos.ndim == 1 else namespace(self.qpos)
        self._cache: dict[tuple[Any, ...], Any] = {}

    def clear(self) -> None:
        """Forget what was read: call after the arrays changed (a step, a reset)."""
        self._cache.clear()

    @classmethod
    def of_physics(
        cls, physics: SoArmPhysics, episode: dict[str, Array] | None = None
    ) -> SimArrays:
        """One environment's simulation, unbatched: live views of its ``MjData``.

        Every accessor answers without the batch axis (``object_position`` is ``(3,)``,
        ``grasped`` a NumPy bool), and :attr:`xp` is :data:`SCALARS`. ``episode``: the
        task's values, each ``(1, ...)`` as the task keeps them (viewed without the axis).
        """
        values = {} if episode is None else {k: v.reshape(v.shape[1:]) for k, v in episode.items()}
        return cls(physics.sim_index, physics.array_views, values)

    @property
    def n(self) -> int:
        """How many simulations (1 for one environment's unbatched arrays)."""
        return 1 if self.qpos.ndim == 1 else int(self.qpos.shape[0])

    # --- the robot ---------------------------------------------------------------------
    @_cached
    def joint_angles(self) -> Array:
        """``(n, 6)``: the joint positions (rad), gripper last."""
        return self.qpos[..., self.index.arm_qpos_index]

    @_cached
    def joint_velocities(self) -> Array:
        """``(n, 6)``: the joint velocities (rad/s)."""
        return self.qvel[..., self.index.arm_dof_index]

    def grasp_center(self) -> Array:
        """``(n, 3)``: where a held object's centre sits, between the jaws (m)."""
        return self.site_xpos[..., self.index.grasp_site, :]

    def gripper_position(self) -> Array:
        """``(n, 3)``: the ``gripperframe`` site (m)."""
        return self.site_xpos[..., self.index.gripper_site, :]

    @_cached
    def jaw_pads_center(self) -> Array:
        """``(n, 3)``: midway between the two jaw pads (the centre of closed jaws, m)."""
        fixed, moving = self.index.pads
        return (self.geom_xpos[..., fixed, :] + self.geom_xpos[..., moving, :]) / 2

    # --- objects -----------------------------------------------------------------------
    def _object(self, name: str) -> _Object:
        item = self.index.objects.get(name)
        if item is None:
            raise not_in_scene("object", name, self.index.objects)
        return item

    def object_position(self, name: str) -> Array:
        """``(n, 3)``: the centre of object ``name`` (m)."""
        q = self._object(name).qpos
        return self.qpos[..., q : q + 3]

    def object_quaternion(self, name: str) -> Array:
        """``(n, 4)``: the orientation of object ``name`` (w, x, y, z)."""
        q = self._object(name).qpos
        return self.qpos[..., q + 3 : q + 7]

    def object_velocity(self, name: str) -> Array:
        """``(n, 3)``: the linear velocity of object ``name`` (m/s)."""
        v = self._object(name).dof
        return self.qvel[..., v : v + 3]

    @_cached
    def object_speed(self, name: str) -> Array:
        """``(n,)``: the linear speed of object ``name`` (m/s)."""
        return norm(self.object_velocity(name))

    def object_yaw(self, name: str) -> Array:
        """``(n,)``: the yaw (rad) of object ``name``'s x axis about the world z axis."""
        q = self.object_quaternion(name)
        w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
        return self.xp.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    @_cached
    def object_height(self, name: str) -> Array:
        """``(n,)``: the height of object ``name``'s lowest point above the table top (m)."""
        item = self._object(name)
        q = item.qpos
        xp = self.xp
        if xp is SCALARS:  # one environment: Python floats, the same arithmetic
            z, w, x, y, k = self.qpos[q + 2 : q + 7].tolist()
        else:
            z, w, x, y, k = (self.qpos[..., q + i] for i in range(2, 7))
        r20 = 2.0 * (x * k - w * y)
        r21 = 2.0 * (y * k + w * x)
        r22 = 1.0 - 2.0 * (x * x + y * y)
        size = item.size
        if item.shape == "box":
            reach = size[0] * xp.abs(r20) + size[1] * xp.abs(r21) + size[2] * xp.abs(r22)
        elif item.shape == "cylinder":
            reach = size[1] * xp.abs(r22) + size[0] * xp.sqrt(xp.maximum(1.0 - r22 * r22, 0.0))
        else:
            reach = size[0] + 0.0 * z
        height = z - reach - constants.TABLE_TOP_Z_M
        return np.float64(height) if xp is SCALARS else height

    # --- fixtures ----------------------------------------------------------------------
    def fixture_position(self, name: str) -> Array:
        """``(n, 3)``: fixture ``name``'s site (the point a task aims at, m)."""
        site = self.index.fixture_sites.get(name)
        if site is None:
            raise not_in_scene("fixture", name, self.index.fixture_sites)
        return self.site_xpos[..., site, :]

    def fixture_joint_position(self, name: str) -> Array:
        """``(n,)``: the position of fixture ``name``'s joint (m for a slide)."""
        adr = self.index.fixture_joints.get(name)
        if adr is None:
            raise ValueError(f"fixture {name!r} has no joint; it does not move.")
        return self.qpos[..., adr]

    # --- contacts ----------------------------------------------------------------------
    @_cached
    def _contact(self, first: str, second: str) -> Array:
        adr = self.index.contacts.get((first, second))
        if adr is None:
            raise ValueError(
                f"no contact sensor between {first!r} and {second!r}: this scene has the "
                "jaw pads against objects and fixture parts, and objects against the table, "
                "each other and fixtures."
            )
        if self.xp is SCALARS:  # one environment: a plain index, the same NumPy bool
            return self.sensordata[adr] > 0
        return self.sensordata[..., adr] > 0

    def jaw_contacts(self, name: str) -> tuple[Array, Array]:
        """``(n,)`` each: whether the fixed and the moving jaw pad touch object or fixture
        part ``name`` (a fixture part is ``"<fixture>_<index>"``)."""
        fixed, moving = constants.JAW_PAD_GEOMS
        return self._contact(fixed, name), self._contact(moving, name)

    def grasped(self, name: str) -> Array:
        """``(n,)``: both jaw pads touch object ``name``."""
        fixed, moving = self.jaw_contacts(name)
        return fixed & moving

    def touched_by_jaws(self, name: str) -> Array:
        """``(n,)``: either jaw pad touches object ``name``."""
        fixed, moving = self.jaw_contacts(name)
        return fixed | moving

    def touching(self, first: str, second: str) -> Array:
        """``(n,)``: object ``first`` touches ``second`` (an object, a fixture or ``"table"``)."""
        second = constants.TABLE_GEOM if second == "table" else second
        first = constants.TABLE_GEOM if first == "table" else first
        return self._contact(first, second)

    def jaw_touch(self) -> Array:
        """``(n, 2)``: the normal force (N) on the fixed and the moving jaw pad."""
        return self.xp.stack([self.sensordata[..., a] for a in self.index.touch], axis=-1)

    # --- soundness -----------------------------------------------------------------------
    def state_is_finite(self) -> Array:
        """``(n,)``: positions, velocities and accelerations are all finite."""
        xp = self.xp
        total = xp.sum(self.qpos, axis=-1) + xp.sum(self.qvel, axis=-1) + xp.sum(self.qacc, axis=-1)
        return xp.isfinite(total)


def norm(vectors: Array) -> Array:
    """The Euclidean norm over the last axis."""
    if type(vectors) is np.ndarray and vectors.ndim == 1:
        # One vector: Python floats, summed in NumPy's order, the same result.
        total = 0.0
        for value in vectors.tolist():
            total += value * value
        return np.float64(math.sqrt(total))
    return namespace(vectors).sqrt((vectors * vectors).sum(-1))


def xy_distance(points: Array, others: Array) -> Array:
    """The horizontal distance (x and y) of ``points`` from ``others``, ``(..., 3)`` each."""
    return norm(points[..., :2] - others[..., :2])


_PLAIN: dict[type, Any] = {np.float64: float, np.bool_: bool, float: float, bool: bool, int: int}


def item(value: Any) -> Any:
    """One environment's unbatched value as its info gives it: a Python bool, int or
    float, a fresh array, or the value itself (a colour, a cell or None)."""
    convert = _PLAIN.get(type(value))  # the common scalar types, looked up at once
    if convert is not None:
        return convert(value)
    if isinstance(value, np.ndarray):
        return value.copy() if value.ndim else item(value[()])
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    return value


def per_env(values: Array, convert: Any) -> Any:
    """``convert`` applied to each environment's value of ``values`` (``(n,)``: a list)
    or to one environment's (unbatched: the value itself), for info values that are not
    numbers."""
    if getattr(values, "ndim", 0) == 0:
        return convert(values.item() if hasattr(values, "item") else values)
    return [convert(v) for v in values.tolist()]  # NumPy arrays and torch tensors alike


__all__ = [
    "ARRAY_FIELDS",
    "SCALARS",
    "SimArrays",
    "SimIndex",
    "in_namespace",
    "item",
    "namespace",
    "norm",
    "per_env",
    "to_numpy",
    "xy_distance",
]
