"""gym_soarm: the SO-ARM101 arm as a Gymnasium environment on dm_control and MuJoCo.

Importing the package registers an environment id per task of the registry
(:mod:`gym_soarm.tasks`), ``gym_soarm/<Task>-v0``, plus the original ``SoArm-v0``
(pick and place; also ``gym_soarm/SoArm-v0``), and the preset
``gym_soarm/SO101Tabletop-v0``. :data:`ENV_IDS` lists them all, :data:`TASK_ENV_IDS` the
tasks' own (every ``gym.make`` keyword works with those).

Layout (``docs/architecture.md``): ``sim/`` (scene, physics, arrays, backends),
``tasks/`` and ``expert/`` (tasks with their experts), ``envs/`` (the step core and the
environment), ``vector/`` (vector envs), ``real/`` (the real arm), ``record/`` and
``data/`` (recording, the dataset format), ``rl/`` (learning), ``render/``, ``teleop/``,
``lerobot/``, ``bench/``, ``cli/`` (the programs, the generated docs and the episode
hashes).
"""

from __future__ import annotations

import contextlib
import os
from typing import Any


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

from gym_soarm import compat  # noqa: E402

compat.install()  # the programs' python -m names and the modules' earlier names

from gym_soarm.envs.env import SoArmEnv  # noqa: E402
from gym_soarm.envs.presets import TABLETOP_ID, register_presets  # noqa: E402
from gym_soarm.envs.snapshot import Snapshot  # noqa: E402
from gym_soarm.render.backend import GLBackendError  # noqa: E402
from gym_soarm.render.display import DisplayUnavailableError  # noqa: E402
from gym_soarm.render.video import save_frames_to_mp4  # noqa: E402
from gym_soarm.sim.meshes import MeshError  # noqa: E402
from gym_soarm.tasks import (  # noqa: E402
    ENV_IDS,
    TASK_ENV_IDS,
    TaskSpec,
    get_task,
    register_task,
    task_names,
)

__version__ = "0.7.0"

register_presets()  # gym_soarm/SO101Tabletop-v0: LeRobot's tabletop contract


def make_expert(env: Any, config: Any = None, kind: str = "state") -> Any:
    """The expert of ``env``'s task: the one that acts from the state unless
    ``kind="scripted"`` asks for the timed script; see :func:`gym_soarm.expert.make_expert`."""
    from gym_soarm.expert import make_expert as _make_expert

    return _make_expert(env, config, kind)


__all__ = [
    "ENV_IDS",
    "TABLETOP_ID",
    "TASK_ENV_IDS",
    "DisplayUnavailableError",
    "GLBackendError",
    "MeshError",
    "Snapshot",
    "SoArmEnv",
    "TaskSpec",
    "__version__",
    "get_task",
    "make_expert",
    "register_task",
    "save_frames_to_mp4",
    "task_names",
]
