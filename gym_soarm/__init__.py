"""gym_soarm: the SO-ARM101 arm as a Gymnasium environment on dm_control and MuJoCo.

Importing the package registers three environment ids::

    SoArm-v0                         pick and place (the original id), 400 steps
    gym_soarm/PickAndPlaceCube-v0    pick and place, 400 steps
    gym_soarm/LiftCube-v0            lift the cube 5 cm, 250 steps
"""

from __future__ import annotations

import contextlib
import os


def _import_dm_control_without_gl() -> None:
    # dm_control picks (and for EGL, initialises) an OpenGL backend when it is first
    # imported. gym_soarm renders through MuJoCo itself, lazily, so keep dm_control
    # away from GL: an EGL display opened at import time would be inherited by
    # forked vector-env workers. MuJoCo is imported first, under the user's own
    # MUJOCO_GL, so that its mujoco.Renderer works in this process as it would
    # without gym_soarm (it reads the variable once, at import).
    # An invalid MUJOCO_GL makes MuJoCo raise; gym_soarm names it, with the fix, when
    # it first renders.
    with contextlib.suppress(RuntimeError):
        import mujoco  # noqa: F401
    saved = os.environ.get("MUJOCO_GL")
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import dm_control.mujoco  # noqa: F401
    finally:
        if saved is None:
            del os.environ["MUJOCO_GL"]
        else:
            os.environ["MUJOCO_GL"] = saved


_import_dm_control_without_gl()

from gymnasium.envs.registration import register, registry  # noqa: E402

from gym_soarm.display import DisplayUnavailableError  # noqa: E402
from gym_soarm.env import SoArmEnv  # noqa: E402
from gym_soarm.meshes import MeshError  # noqa: E402
from gym_soarm.rendering import GLBackendError  # noqa: E402
from gym_soarm.video import save_frames_to_mp4  # noqa: E402

__version__ = "0.5.0"

ENV_IDS: dict[str, tuple[str, int]] = {
    "SoArm-v0": ("pick_and_place", 400),
    "gym_soarm/PickAndPlaceCube-v0": ("pick_and_place", 400),
    "gym_soarm/LiftCube-v0": ("lift", 250),
}

for _env_id, (_task, _steps) in ENV_IDS.items():
    if _env_id not in registry:
        register(
            id=_env_id,
            entry_point="gym_soarm.env:SoArmEnv",
            max_episode_steps=_steps,
            kwargs={"task": _task},
        )


def __getattr__(name: str) -> object:
    # make_expert is imported on first use, so that `python -m gym_soarm.expert` runs
    # the module once, as __main__.
    if name == "make_expert":
        from gym_soarm.expert import make_expert

        return make_expert
    raise AttributeError(f"module 'gym_soarm' has no attribute {name!r}")


__all__ = [
    "ENV_IDS",
    "DisplayUnavailableError",
    "GLBackendError",
    "MeshError",
    "SoArmEnv",
    "__version__",
    "make_expert",
    "save_frames_to_mp4",
]
