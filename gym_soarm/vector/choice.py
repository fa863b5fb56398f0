"""Which vector env a ``gym.make_vec`` call gets, and the checks of its keywords.

:func:`~gym_soarm.vector.batched.make_vector_env` (the ids' vector entry point) reads
``vector_env`` (:data:`VECTOR_ENVS`); the batched env its ``physics``
(:data:`PHYSICS_BACKENDS`) and ``array_api``. The checks here refuse, before anything is
built, what a vector env cannot do: a task hook that acts on one environment's physics
(batched), settings that change a world's model at every reset (Warp), torch tensors
from the process-based env.
"""

from __future__ import annotations

from typing import Any

from gym_soarm.envs.settings import STATE_OBS_TYPES
from gym_soarm.sim.warp_backend import check_device
from gym_soarm.validation import check_choice
from gym_soarm.vector.views import ARRAY_APIS


def check_batchable(spec: Any) -> None:
    """Refuse a task whose ``before_step`` hook acts on one environment's physics."""
    from gym_soarm.tasks.base import Task

    if spec.task.before_step is not Task.before_step:
        raise ValueError(
            f"{spec.name}'s task overrides before_step(action, physics), which acts on one "
            "environment's physics between its own steps; the batched vector env steps every "
            "simulation at once and cannot call it. Use vector_env='processes'."
        )


def wants_batched(env_kwargs: dict[str, Any]) -> bool:
    """Whether ``vector_env="auto"`` batches these environments: state observations, and
    a task that leaves ``before_step`` to the environment."""
    from gym_soarm.tasks import DEFAULT_TASK, get_task

    settings = env_kwargs.get("settings")
    obs_type = env_kwargs.get("obs_type", getattr(settings, "obs_type", None))
    task = env_kwargs.get("task", getattr(settings, "task", None)) or DEFAULT_TASK
    try:
        spec = get_task(task)
    except (ValueError, TypeError):  # an unknown task: the environment names the error
        return obs_type in STATE_OBS_TYPES
    try:
        check_batchable(spec)
    except ValueError:
        return False
    return obs_type in STATE_OBS_TYPES


def check_warp_settings(env_kwargs: dict[str, Any]) -> None:
    """Refuse the settings whose resets change a world's physics model beyond what the
    Warp backend batches per world (fixture poses)."""
    settings = env_kwargs.get("settings")
    level = env_kwargs.get(
        "physics_randomization", getattr(settings, "physics_randomization", "none")
    )
    if level != "none":
        raise ValueError(
            f"physics_randomization={level!r} draws masses, friction, gains and damping into "
            "each environment's model at every reset; the Warp backend shares one model "
            "across its worlds and batches only the fixtures' poses. Use "
            "physics_randomization='none' with vector_env='warp', or vector_env='batched'."
        )


PHYSICS_BACKENDS: tuple[str, ...] = ("mujoco", "warp")
"""The physics of the batched vector env: C MuJoCo's ``mujoco.batch`` or MuJoCo Warp."""

VECTOR_ENVS: tuple[str, ...] = ("auto", "batched", "processes", "warp")
"""Values of ``vector_env``: how ``gym.make_vec(..., vectorization_mode="vector_entry_point")``
steps the environments."""


def check_physics(
    physics: str, device: str | None, array_api: str, env_kwargs: dict[str, Any]
) -> str:
    """Check the batched env's ``physics``, ``device`` and ``array_api`` (and, for
    MuJoCo Warp, the settings); the device of its arrays: ``"cpu"`` for ``mujoco.batch``,
    the Warp device (torch names it alike) for ``"warp"``.

    Raises:
        ValueError: an unknown value, a ``device`` without MuJoCo Warp, or a setting that
            Warp cannot batch.
    """
    check_choice("physics", physics, PHYSICS_BACKENDS)
    check_choice("array_api", array_api, ARRAY_APIS)
    if physics == "mujoco":
        if device is not None:
            raise ValueError(
                f"device applies to physics='warp' (MuJoCo Warp); got device={device!r} with "
                "physics='mujoco'. Remove device or pass vector_env='warp'."
            )
        return "cpu"
    device = check_device("cuda" if device is None else device)
    check_warp_settings(env_kwargs)
    return device


def check_numpy_only(array_api: str) -> None:
    """Refuse ``array_api`` other than ``"numpy"`` for the process-based env."""
    if array_api != "numpy":
        raise ValueError(
            f"array_api={array_api!r} applies to vector_env='batched' and 'warp'; the "
            "process-based env (vector_env='processes', or 'auto' for pixels or with "
            "num_processes or start_method) returns NumPy arrays. Pass "
            "vector_env='batched' or 'warp', or wrap the env in "
            "gymnasium.wrappers.vector.NumpyToTorch."
        )


__all__ = [
    "PHYSICS_BACKENDS",
    "VECTOR_ENVS",
    "check_batchable",
    "check_numpy_only",
    "check_physics",
    "check_warp_settings",
    "wants_batched",
]
