"""Builds each task's MuJoCo model from parts: arena, robot, the task's objects and fixtures.

The robot (``so101.xml``) and the arena (``scene.xml``: table, lights, cameras) are MJCF
files; this module places the robot's base, supplies the verified meshes and adds a
task's declared :class:`~gym_soarm.sim.objects.Scene` (objects and fixtures) with
``mujoco.MjSpec`` before compiling.
There are two visual variants of the same model, ``"fast"`` and ``"high"``, whose
meshes are rebuilt from the provider's by :mod:`gym_soarm.sim.visual_meshes` with the
settings of each render quality. The visual meshes carry no mass and never collide, so
both variants have the same physics, bit for bit.

Compiling takes most of a second (mostly mesh processing), so it happens once per
process and variant, and the compiled model is also kept in the user cache directory
(:mod:`gym_soarm.sim.cache`) as a MuJoCo binary file, named after a digest of every
source, the mesh settings and the MuJoCo version. Every environment gets its own copy
of the compiled model, so that per-environment visual settings never leak between
environments.
"""

from __future__ import annotations

import copy
import functools
import logging
import math
import xml.etree.ElementTree as ET
from importlib import resources

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.sim import cache, meshes, objects, visual_meshes

logger = logging.getLogger(__name__)

ROBOT_FILE = "so101.xml"
SCENE_FILE = "scene.xml"
VISUAL_VARIANTS: tuple[str, ...] = tuple(visual_meshes.MESH_SETTINGS)  # ("fast", "high")
# Bump when the way models are built changes, so old cached binaries are not reused.
MODEL_CACHE_VERSION = 3


def _asset_text(name: str) -> str:
    return (
        resources.files("gym_soarm.sim")
        .joinpath("assets")
        .joinpath(name)
        .read_text(encoding="utf-8")
    )


def _check_variant(visual: str) -> None:
    if visual not in VISUAL_VARIANTS:
        raise ValueError(f"visual must be one of {VISUAL_VARIANTS}; got {visual!r}.")


def robot_xml() -> str:
    """The robot MJCF with its base placed and yawed as the scene requires."""
    root = ET.fromstring(_asset_text(ROBOT_FILE))
    base = root.find("./worldbody/body[@name='base']")
    if base is None:  # pragma: no cover - guards an edit of the packaged file
        raise RuntimeError(f"{ROBOT_FILE} has no body named 'base'")
    half_yaw = math.radians(constants.ROBOT_BASE_YAW_DEG) / 2
    base.set("pos", " ".join(repr(v) for v in constants.ROBOT_BASE_POS_M))
    base.set("quat", f"{math.cos(half_yaw)!r} 0 0 {math.sin(half_yaw)!r}")
    return ET.tostring(root, encoding="unicode")


def _add_material(spec: mujoco.MjSpec, colour: str, emission: float, cache: dict) -> str:
    name = f"{colour}_glow{emission:g}" if emission else colour
    if name not in cache:
        spec.add_material(
            name=name, rgba=list(objects.COLOURS[colour]), specular=0.3, emission=emission
        )
        cache[name] = name
    return name


def _geom_type(shape: str) -> mujoco.mjtGeom:
    return {
        "box": mujoco.mjtGeom.mjGEOM_BOX,
        "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
        "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    }[shape]


def _add_fixture(
    spec: mujoco.MjSpec, fixture: objects.Fixture, parents: dict, materials: dict, moving: set
) -> None:
    parent = spec.worldbody if fixture.parent is None else parents[fixture.parent]
    # A fixture moves if it has a joint or hangs from one that moves: its parts need mass.
    if fixture.joint is not None or fixture.parent in moving:
        moving.add(fixture.name)
    body = parent.add_body(name=fixture.name, pos=list(fixture.position_m))
    parents[fixture.name] = body
    joint = fixture.joint
    if joint is not None:
        body.add_joint(
            name=fixture.name,
            type=mujoco.mjtJoint.mjJNT_SLIDE
            if joint.kind == "slide"
            else mujoco.mjtJoint.mjJNT_HINGE,
            axis=list(joint.axis),
            range=list(joint.range),
            limited=mujoco.mjtLimited.mjLIMITED_TRUE,
            damping=joint.damping,
            frictionloss=joint.frictionloss,
        )
    for index, part in enumerate(fixture.geoms):
        collides = int(part.collides)
        body.add_geom(
            name=f"{fixture.name}_{index}",
            type=_geom_type(part.shape),
            size=list(part.size_m) + [0.0] * (3 - len(part.size_m)),
            pos=list(part.position_m),
            material=_add_material(spec, part.colour, part.emission, materials),
            contype=collides,
            conaffinity=collides,
            condim=3,
            mass=part.mass_kg if fixture.name in moving else 0.0,
        )
    body.add_site(name=fixture.name, pos=list(fixture.site_m), size=[0.005, 0, 0], group=3)


def _add_object(spec: mujoco.MjSpec, item: objects.SceneObject, materials: dict) -> None:
    x, y = item.position_m
    body = spec.worldbody.add_body(
        name=item.name, pos=[x, y, constants.TABLE_TOP_Z_M + item.rest_height_m]
    )
    body.add_freejoint(name=item.name)
    body.add_geom(
        name=item.name,
        type=_geom_type(item.shape),
        size=list(item.size_m) + [0.0] * (3 - len(item.size_m)),
        mass=item.mass_kg,
        material=_add_material(spec, item.colour, 0.0, materials),
        contype=1,
        conaffinity=1,
        condim=4,
        friction=list(item.friction),
    )
    body.add_site(name=item.name, size=[0.004, 0, 0], group=3)


def build_spec(scene: objects.Scene, visual: str = "fast") -> mujoco.MjSpec:
    """The arena, the robot and ``scene``'s fixtures and objects as one ``mujoco.MjSpec``.

    Fixtures come first, then objects, each in declaration order; the ``home`` keyframe
    holds the arm at 0 rad and every object where it was declared.
    """
    _check_variant(visual)
    return _add_layout(_arena_spec(visual_meshes.quality_meshes(visual)), scene)


def _arena_spec(mesh_files: dict[str, bytes]) -> mujoco.MjSpec:
    """The arena MJCF with the placed robot included and ``mesh_files`` supplied."""
    return mujoco.MjSpec.from_string(
        _asset_text(SCENE_FILE),
        include={ROBOT_FILE: robot_xml().encode()},
        assets=dict(mesh_files),
    )


def _add_layout(spec: mujoco.MjSpec, scene: objects.Scene) -> mujoco.MjSpec:
    materials: dict[str, str] = {}
    parents: dict[str, mujoco.MjsBody] = {}
    moving: set[str] = set()
    for fixture in scene.fixtures:
        _add_fixture(spec, fixture, parents, materials, moving)
    for item in scene.objects:
        _add_object(spec, item, materials)
    _add_contact_sensors(spec, scene)
    spec.add_key(name=constants.HOME_KEYFRAME, ctrl=[0.0] * len(constants.JOINT_NAMES))
    return spec


def contact_sensor_name(first: str, second: str) -> str:
    """The name of the contact sensor between two scene parts (its order is the sensor's)."""
    return f"contact:{first}:{second}"


def _contact_sensor(
    spec: mujoco.MjSpec, first: tuple[mujoco.mjtObj, str], second: tuple[mujoco.mjtObj, str]
) -> None:
    spec.add_sensor(
        name=contact_sensor_name(first[1], second[1]),
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        objtype=first[0],
        objname=first[1],
        reftype=second[0],
        refname=second[1],
        intprm=[1, 0, 1],  # data="found": how many contacts match
    )


def _add_contact_sensors(spec: mujoco.MjSpec, scene: objects.Scene) -> None:
    """A ``found`` contact sensor for every contact a task asks about.

    Tasks read contacts from these sensors (positions stage, so current after every
    step), which is what lets them be evaluated over a batch of simulations whose
    contact lists are not kept: each jaw pad against each object and each collidable
    fixture part, and each object against the table, every other object and every
    fixture. Sensors never change the dynamics.
    """
    geom, body = mujoco.mjtObj.mjOBJ_GEOM, mujoco.mjtObj.mjOBJ_BODY
    names = [item.name for item in scene.objects]
    for k, name in enumerate(names):
        for pad in constants.JAW_PAD_GEOMS:
            _contact_sensor(spec, (geom, pad), (geom, name))
        _contact_sensor(spec, (geom, name), (geom, constants.TABLE_GEOM))
        for other in names[k + 1 :]:
            _contact_sensor(spec, (geom, name), (geom, other))
        for fixture in scene.fixtures:
            _contact_sensor(spec, (geom, name), (body, fixture.name))
    for fixture in scene.fixtures:
        for index, part in enumerate(fixture.geoms):
            if part.collides:
                for pad in constants.JAW_PAD_GEOMS:
                    _contact_sensor(spec, (geom, pad), (geom, f"{fixture.name}_{index}"))


def model_cache_name(scene: objects.Scene, visual: str, label: str = "scene") -> str:
    """File name of the cached compiled model of ``scene`` (a digest of every source)."""
    _check_variant(visual)
    key = cache.digest(
        f"model cache v{MODEL_CACHE_VERSION}",
        f"mujoco {mujoco.__version__}",
        visual,
        visual_meshes.settings_tag(visual),
        _asset_text(SCENE_FILE),
        robot_xml(),
        repr(scene),
        *(f"{name} {sha}" for name, sha in sorted(meshes.MESH_SHA256.items())),
    )
    return f"models/{_safe_label(label)}-{visual}-{key[:24]}.mjb"


def _safe_label(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label)


@functools.lru_cache(maxsize=64)
def _compiled_scene(scene: objects.Scene, visual: str, label: str) -> mujoco.MjModel:
    meshes.load_meshes()  # a missing or changed provider mesh fails even with a cached model
    name = model_cache_name(scene, visual, label)
    path = cache.cached_path(name)
    if path is not None and path.is_file():
        try:
            return mujoco.MjModel.from_binary_path(str(path))
        except (ValueError, OSError) as exc:
            logger.info("discarding the unreadable cached model %s (%s)", path, exc)
    model = build_spec(scene, visual).compile()
    if path is not None:
        buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, buffer)
        if cache.write(name, buffer.tobytes()) is not None:
            cache.prune(f"models/{_safe_label(label)}-{visual}-*.mjb", keep=name)
    return model


def provider_mesh_model(scene: objects.Scene = objects.EMPTY_SCENE) -> mujoco.MjModel:
    """``scene`` compiled with the provider's meshes as they are (never cached).

    Slow to compile and to render; for comparing the meshes of the render qualities
    with their source.

    Raises:
        gym_soarm.sim.meshes.MeshError: a provider mesh is missing or changed.
    """
    return _add_layout(_arena_spec(meshes.load_meshes()), scene).compile()


def load_scene_model(
    scene: objects.Scene = objects.EMPTY_SCENE, visual: str = "fast", label: str = "scene"
) -> mujoco.MjModel:
    """A fresh copy of the compiled model of ``scene`` with ``"fast"`` or ``"high"`` meshes.

    Compiled once per process and kept in the user cache directory; ``label`` (the
    task's name) names the cached file.

    Raises:
        ValueError: ``visual`` is not one of :data:`VISUAL_VARIANTS`.
        gym_soarm.sim.meshes.MeshError: a provider mesh is missing or changed.
    """
    _check_variant(visual)
    return copy.copy(_compiled_scene(scene, visual, label))
