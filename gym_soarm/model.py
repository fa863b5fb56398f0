"""Builds the MuJoCo model of the scene from the MJCF pieces in ``assets/``.

The robot (``so101.xml``) and the workspace (``scene.xml``) are separate files; this
module places the robot's base, supplies the verified meshes and compiles the result
once per process. Every environment gets its own copy of the compiled model, so that
per-environment visual settings never leak between environments.
"""

from __future__ import annotations

import copy
import functools
import math
import xml.etree.ElementTree as ET
from importlib import resources

import mujoco

from gym_soarm import constants, meshes

ROBOT_FILE = "so101.xml"
SCENE_FILE = "scene.xml"


def _asset_text(name: str) -> str:
    return (
        resources.files("gym_soarm").joinpath("assets").joinpath(name).read_text(encoding="utf-8")
    )


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


def scene_assets() -> dict[str, bytes]:
    """Files the scene MJCF refers to: the placed robot and the verified meshes."""
    assets = dict(meshes.load_meshes())
    assets[ROBOT_FILE] = robot_xml().encode()
    return assets


@functools.lru_cache(maxsize=1)
def _compiled_scene() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(_asset_text(SCENE_FILE), scene_assets())


def load_scene_model() -> mujoco.MjModel:
    """A fresh copy of the compiled scene model (compiled once per process)."""
    return copy.copy(_compiled_scene())
