"""The task registry: the one list of tasks that everything else reads.

Gym ids, :data:`gym_soarm.ENV_IDS`, the expert, the recorder's ``--task``, the LeRobot
config, the benchmark and the README's table of environments all come from here.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import gymnasium as gym
from gymnasium.envs.registration import parse_env_id, register, registry

from gym_soarm.tasks.base import TaskSpec
from gym_soarm.validation import ArgumentTypeError

ENTRY_POINT = "gym_soarm.envs.env:SoArmEnv"
VECTOR_ENTRY_POINT = "gym_soarm.vector.batched:make_vector_env"

_TASKS: dict[str, TaskSpec] = {}
_SPELLINGS: dict[str, str] = {}  # name, alias or env id -> name
_ENV_IDS: dict[str, tuple[str, int]] = {}
_TASK_ENV_IDS: dict[str, tuple[str, int]] = {}

ENV_IDS: Mapping[str, tuple[str, int]] = MappingProxyType(_ENV_IDS)
"""Every registered gym id -> (task name, max_episode_steps), kept up to date: the tasks'
ids and the presets' (``gym_soarm/SO101Tabletop-v0``)."""
TASK_ENV_IDS: Mapping[str, tuple[str, int]] = MappingProxyType(_TASK_ENV_IDS)
"""The tasks' own gym ids (every ``gym.make`` keyword works with them), without the
presets, whose observations are fixed."""


def register_preset_id(env_id: str, task: str, max_episode_steps: int) -> None:
    """Record a preset's gym id (registered by the caller) in :data:`ENV_IDS`."""
    _ENV_IDS[env_id] = (get_task(task).name, int(max_episode_steps))


def register_task(spec: TaskSpec) -> TaskSpec:
    """Add a task to the registry and register its gym ids.

    Args:
        spec: the task's declaration.

    Returns:
        ``spec``, so a module can write ``SPEC = register_task(TaskSpec(...))``.

    Raises:
        TypeError: ``spec`` is not a :class:`TaskSpec`.
        ValueError: its name, an alias or an id is already taken by another task.
    """
    if not isinstance(spec, TaskSpec):
        raise ArgumentTypeError(f"register_task expects a TaskSpec; got {type(spec).__name__}.")
    if _TASKS.get(spec.name) == spec:
        return spec  # the same module imported twice
    for env_id in spec.env_ids:
        try:
            parse_env_id(env_id)
        except gym.error.Error as exc:
            raise ValueError(f"cannot register {spec.name!r}: {exc}") from None
        existing = registry.get(env_id)
        if existing is not None and (
            existing.entry_point != ENTRY_POINT or existing.kwargs.get("task") != spec.name
        ):
            raise ValueError(
                f"cannot register {spec.name!r}: gym id {env_id!r} already belongs to "
                f"{existing.entry_point} ({existing.kwargs}). Choose another id."
            )
    spellings = (spec.name, *spec.aliases, *spec.env_ids)
    taken = [s for s in spellings if s in _SPELLINGS]
    if taken:
        raise ValueError(
            f"cannot register {spec.name!r}: {taken} already name "
            f"{sorted({_SPELLINGS[s] for s in taken})}. Choose another name or alias."
        )
    for env_id in spec.env_ids:
        if env_id not in registry:
            register(
                id=env_id,
                entry_point=ENTRY_POINT,
                vector_entry_point=VECTOR_ENTRY_POINT,
                max_episode_steps=spec.max_episode_steps,
                kwargs={"task": spec.name},
            )
    _TASKS[spec.name] = spec
    for spelling in spellings:
        _SPELLINGS[spelling] = spec.name
    for env_id in spec.env_ids:
        _ENV_IDS[env_id] = _TASK_ENV_IDS[env_id] = (spec.name, spec.max_episode_steps)
    return spec


def unregister_task(name: str) -> TaskSpec:
    """Remove a task (by name, alias or id) and its gym ids; returns its spec.

    Raises:
        ValueError: no such task.
    """
    spec = get_task(name)
    del _TASKS[spec.name]
    for spelling in [s for s, n in _SPELLINGS.items() if n == spec.name]:
        del _SPELLINGS[spelling]
    for env_id in spec.env_ids:
        _ENV_IDS.pop(env_id, None)
        _TASK_ENV_IDS.pop(env_id, None)
        registry.pop(env_id, None)
    return spec


def task_names() -> tuple[str, ...]:
    """Every registered task's name, in registration order."""
    return tuple(_TASKS)


def task_aliases() -> tuple[str, ...]:
    """Every task's short aliases (``lift``, ``reach`` ...), in registration order."""
    return tuple(s for s, n in _SPELLINGS.items() if s != n and "/" not in s and "-v" not in s)


def task_spellings() -> tuple[str, ...]:
    """Every accepted spelling: names, aliases and gym ids."""
    return tuple(_SPELLINGS)


def get_task(name: str) -> TaskSpec:
    """The spec of a task by its name, an alias or one of its gym ids.

    Raises:
        ValueError: unknown name; the message lists the registered ones.
    """
    if not isinstance(name, str):
        raise ArgumentTypeError(
            f"task must be a task name such as 'LiftCube-v0'; got {name!r} ({type(name).__name__})."
        )
    resolved = _SPELLINGS.get(name)
    if resolved is None:
        aliases = task_aliases()
        raise ValueError(
            f"task must be one of {', '.join(_TASKS)} (or an alias: {', '.join(aliases)}, or a "
            f"gym id); got {name!r}. Register a new task with gym_soarm.register_task(spec)."
        )
    return _TASKS[resolved]
