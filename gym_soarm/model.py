"""Builds the MuJoCo model of the scene from the MJCF pieces in ``assets/``.

The robot (``so101.xml``) and the workspace (``scene.xml``) are separate files; this
module places the robot's base, supplies the verified meshes and compiles the result.
There are two visual variants of the same model, ``"fast"`` and ``"high"``, whose
meshes are rebuilt from the provider's by :mod:`gym_soarm.visual_meshes` with the
settings of each render quality. The visual meshes carry no mass and never collide, so
both variants have the same physics, bit for bit.

Compiling takes most of a second (mostly mesh processing), so it happens once per
process and variant, and the compiled model is also kept in the user cache directory
(:mod:`gym_soarm.cache`) as a MuJoCo binary file, named after a digest of every
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

from gym_soarm import cache, constants, meshes, visual_meshes

logger = logging.getLogger(__name__)

ROBOT_FILE = "so101.xml"
SCENE_FILE = "scene.xml"
VISUAL_VARIANTS: tuple[str, ...] = tuple(visual_meshes.MESH_SETTINGS)  # ("fast", "high")
# Bump when the way models are built changes, so old cached binaries are not reused.
MODEL_CACHE_VERSION = 1


def _asset_text(name: str) -> str:
    return (
        resources.files("gym_soarm").joinpath("assets").joinpath(name).read_text(encoding="utf-8")
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


def scene_assets(visual: str = "fast") -> dict[str, bytes]:
    """Files the scene MJCF refers to: the placed robot and the meshes of ``visual``."""
    _check_variant(visual)
    return _with_robot(visual_meshes.quality_meshes(visual))


def _with_robot(mesh_files: dict[str, bytes]) -> dict[str, bytes]:
    assets = dict(mesh_files)
    assets[ROBOT_FILE] = robot_xml().encode()
    return assets


def model_cache_name(visual: str) -> str:
    """File name of the cached compiled model of ``visual`` (a digest of its sources)."""
    _check_variant(visual)
    key = cache.digest(
        f"model cache v{MODEL_CACHE_VERSION}",
        f"mujoco {mujoco.__version__}",
        visual,
        visual_meshes.settings_tag(visual),
        _asset_text(SCENE_FILE),
        robot_xml(),
        *(f"{name} {sha}" for name, sha in sorted(meshes.MESH_SHA256.items())),
    )
    return f"models/scene-{visual}-{key[:24]}.mjb"


def _compile(visual: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(_asset_text(SCENE_FILE), scene_assets(visual))


@functools.lru_cache(maxsize=len(VISUAL_VARIANTS))
def _compiled_scene(visual: str) -> mujoco.MjModel:
    meshes.load_meshes()  # a missing or changed provider mesh fails even with a cached model
    name = model_cache_name(visual)
    path = cache.cached_path(name)
    if path is not None and path.is_file():
        try:
            return mujoco.MjModel.from_binary_path(str(path))
        except (ValueError, OSError) as exc:
            logger.info("discarding the unreadable cached model %s (%s)", path, exc)
    model = _compile(visual)
    if path is not None:
        buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, buffer)
        if cache.write(name, buffer.tobytes()) is not None:
            cache.prune(f"models/scene-{visual}-*.mjb", keep=name)
    return model


def provider_mesh_model() -> mujoco.MjModel:
    """The scene compiled with the provider's meshes as they are (never cached).

    Slow to compile and to render; for comparing the meshes of the render qualities
    with their source.

    Raises:
        gym_soarm.meshes.MeshError: a provider mesh is missing or changed.
    """
    return mujoco.MjModel.from_xml_string(
        _asset_text(SCENE_FILE), _with_robot(meshes.load_meshes())
    )


def load_scene_model(visual: str = "fast") -> mujoco.MjModel:
    """A fresh copy of the compiled scene model with ``"fast"`` or ``"high"`` visual meshes.

    Raises:
        ValueError: ``visual`` is not one of :data:`VISUAL_VARIANTS`.
        gym_soarm.meshes.MeshError: a provider mesh is missing or changed.
    """
    _check_variant(visual)
    return copy.copy(_compiled_scene(visual))
