"""Every task of gym_soarm: one module each, registered here.

A task module declares a :class:`~gym_soarm.tasks.base.Task` subclass, its scripted
expert and a :class:`~gym_soarm.tasks.base.TaskSpec`; the list below registers the
built-in ones. Users register their own tasks with :func:`register_task` (see "Tasks are
modules" in docs/tasks.md).
"""

from __future__ import annotations

import importlib

from gym_soarm.tasks.base import Task, TaskSpec
from gym_soarm.tasks.registry import (
    ENV_IDS,
    TASK_ENV_IDS,
    get_task,
    register_task,
    task_names,
    task_spellings,
    unregister_task,
)
from gym_soarm.tasks.state_fields import StateField

BUILTIN_TASK_MODULES: tuple[str, ...] = (
    "pick_and_place_cube",
    "lift_cube",
    "reach_target",
    "push_cube",
    "stack_cube",
    "place_in_bin",
    "pick_and_place_cylinder",
    "open_drawer",
    "pick_colored_cube",
    "sort_cubes",
    "put_cubes_in_box",
)
"""The built-in task modules, in the order the registry (and the README) lists them."""

DEFAULT_TASK: str = "PickAndPlaceCube-v0"
"""The task of the original id ``SoArm-v0``: the default of every program that takes a task."""

BUILTIN_TASKS: tuple[str, ...] = tuple(
    register_task(importlib.import_module(f"gym_soarm.tasks.{module}").SPEC).name
    for module in BUILTIN_TASK_MODULES
)
"""The names of the built-in tasks, in registry order."""

__all__ = [
    "BUILTIN_TASKS",
    "BUILTIN_TASK_MODULES",
    "DEFAULT_TASK",
    "ENV_IDS",
    "TASK_ENV_IDS",
    "StateField",
    "Task",
    "TaskSpec",
    "get_task",
    "register_task",
    "task_names",
    "task_spellings",
    "unregister_task",
]
