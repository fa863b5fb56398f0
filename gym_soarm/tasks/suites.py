"""Task suites: named groups of tasks that are evaluated, and recorded, together.

A suite is what ``lerobot-eval --env.type=soarm --env.task=soarm_core`` evaluates and
what ``python -m gym_soarm.record --task soarm_core`` records. Every program that takes a
task also takes a *selection*: a task (``"LiftCube-v0"``, an alias or a gym id), a suite
name, or a comma list of both (``"soarm_core,StackCube-v0"``).

==================  ======================================================================
suite               tasks
==================  ======================================================================
``soarm_core``      ReachTarget, LiftCube, PickAndPlaceCube, PushCube: one object each
``soarm_multi``     StackCube, PlaceInBin, SortCubes, PickAndPlaceCylinder, OpenDrawer,
                    PutCubesInBox (LeRobot's tabletop task): two or more objects, or an
                    object and a fixture
``soarm_language``  PickColoredCube: the instruction names the object to pick
``soarm_robust``    the core tasks under ``visual_randomization="heavy"`` and
                    ``physics_randomization="light"``
``soarm_all``       the four suites above, each reported on its own
==================  ======================================================================

The evaluation protocol is fixed: episode ``k`` of a task resets with seed
``EVAL_SEED + k``. :data:`EVAL_SEED` is 1000, ``lerobot-eval``'s default ``--seed``, so
``lerobot-eval`` follows the protocol unless told otherwise, and the same policy gets
the same numbers on every run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from gym_soarm.tasks.registry import get_task, task_aliases, task_names
from gym_soarm.validation import ArgumentTypeError

EVAL_SEED = 1000
"""Episode ``k`` of an evaluation resets with seed ``EVAL_SEED + k`` (``lerobot-eval``'s default)."""

TASK_GROUP = "soarm"
"""The group of tasks named one by one in a selection (the LeRobot env type)."""


@dataclass(frozen=True)
class Suite:
    """A named list of tasks, with the variation keywords that the suite fixes.

    Attributes:
        name: the suite's name, e.g. ``"soarm_core"``.
        tasks: registered task names, in evaluation order (LeRobot's task index).
        variation: ``gym.make`` keywords every task of the suite runs with, e.g.
            ``{"visual_randomization": "heavy"}``; they are part of the suite's
            definition and override the same settings given for plain tasks.
        summary: one line for tables and ``--help``.
    """

    name: str
    tasks: tuple[str, ...]
    variation: Mapping[str, Any] = field(default_factory=dict)
    summary: str = ""


@dataclass(frozen=True)
class SelectedTask:
    """One task of a selection: its group (a suite, or :data:`TASK_GROUP`) and index there."""

    group: str
    index: int
    task: str
    variation: Mapping[str, Any]


_CORE = ("ReachTarget-v0", "LiftCube-v0", "PickAndPlaceCube-v0", "PushCube-v0")
_SUITES: dict[str, Suite] = {
    suite.name: suite
    for suite in (
        Suite("soarm_core", _CORE, summary="reach, lift, pick-and-place, push: one object each"),
        Suite(
            "soarm_multi",
            (
                "StackCube-v0",
                "PlaceInBin-v0",
                "SortCubes-v0",
                "PickAndPlaceCylinder-v0",
                "OpenDrawer-v0",
                "PutCubesInBox-v0",
            ),
            summary="stack, bin, sort, cylinder, drawer, four cubes in a box: several objects, "
            "or an object and a fixture",
        ),
        Suite(
            "soarm_language",
            ("PickColoredCube-v0",),
            summary="the instruction chooses the object",
        ),
        Suite(
            "soarm_robust",
            _CORE,
            variation=MappingProxyType(
                {"visual_randomization": "heavy", "physics_randomization": "light"}
            ),
            summary="the core tasks with heavy visual and light physics randomisation",
        ),
    )
}
ALL_SUITE = "soarm_all"
SUITE_NAMES: tuple[str, ...] = (*_SUITES, ALL_SUITE)
"""Every suite name, ``soarm_all`` last."""


def get_suite(name: str) -> Suite:
    """The suite called ``name`` (not ``soarm_all``, which stands for the other four)."""
    if name not in _SUITES:
        raise ValueError(f"suite must be one of {', '.join(_SUITES)}; got {name!r}.")
    return _SUITES[name]


def suite_summary() -> list[tuple[str, str, tuple[str, ...]]]:
    """``(name, summary, tasks)`` of every suite, for tables and ``--help``."""
    return [(s.name, s.summary, s.tasks) for s in _SUITES.values()]


def resolve_selection(selection: str) -> tuple[SelectedTask, ...]:
    """The tasks of a selection, grouped as ``lerobot-eval`` reports them.

    Args:
        selection: a task's name, alias or gym id, a suite name (``soarm_core``,
            ``soarm_multi``, ``soarm_language``, ``soarm_robust``, ``soarm_all``), or a
            comma list of them.

    Returns:
        One :class:`SelectedTask` per (group, task): a suite's tasks form the group
        named after the suite, indexed in the suite's order; tasks named one by one
        form the group ``"soarm"``, indexed in the order given. ``soarm_all`` stands for
        its four suites. A task listed twice in one group counts once.

    Raises:
        TypeError: ``selection`` is not a string.
        ValueError: an empty selection or an unknown name; the message lists the
            suites and tasks.
    """
    if not isinstance(selection, str):
        raise ArgumentTypeError(
            "task must be a task name, a suite name or a comma list of them, e.g. "
            f"'soarm_core' or 'LiftCube-v0,PushCube-v0'; got {selection!r} "
            f"({type(selection).__name__})."
        )
    names = [part.strip() for part in selection.split(",") if part.strip()]
    if not names:
        raise ValueError(
            "task must name at least one task or suite, e.g. 'LiftCube-v0' or 'soarm_core'; "
            f"got {selection!r}."
        )
    groups: dict[str, list[tuple[str, Mapping[str, Any]]]] = {}
    for name in names:
        suites = list(_SUITES) if name == ALL_SUITE else [name] if name in _SUITES else []
        if suites:
            for suite_name in suites:
                suite = _SUITES[suite_name]
                for task in suite.tasks:
                    _add(groups, suite.name, get_task(task).name, suite.variation)
            continue
        try:
            task = get_task(name).name
        except ValueError:
            raise ValueError(
                f"task must be a task name ({', '.join(task_names())}), one of their aliases "
                f"({', '.join(task_aliases())}), a gym id, a suite "
                f"({', '.join(SUITE_NAMES)}) or a comma list of them; got {name!r}."
            ) from None
        _add(groups, TASK_GROUP, task, {})
    return tuple(
        SelectedTask(group, index, task, MappingProxyType(dict(variation)))
        for group, members in groups.items()
        for index, (task, variation) in enumerate(members)
    )


def distinct_tasks(selected: tuple[SelectedTask, ...]) -> list[SelectedTask]:
    """The selection without repeats of one task with the same settings, in order."""
    kept: list[SelectedTask] = []
    for item in selected:
        if all((item.task, item.variation) != (seen.task, seen.variation) for seen in kept):
            kept.append(item)
    return kept


def shared_state_names(
    selected: tuple[SelectedTask, ...], object_placement: str | None = None
) -> tuple[str, ...]:
    """The ``environment_state`` names that every selected task shares.

    One policy (or one dataset) reads ``observation.environment_state`` from all of
    them, so the layouts must be the same value for value, not only in size.

    Raises:
        ValueError: the layouts differ; the message lists each task's and the fixes.
    """
    names: dict[str, tuple[str, ...]] = {}
    for item in selected:
        placement = item.variation.get("object_placement", object_placement)
        names[item.task] = get_task(item.task).make_task(placement).state_names
    if len(set(names.values())) > 1:
        listed = ", ".join(f"{task} ({', '.join(n)})" for task, n in names.items())
        raise ValueError(
            "observation.environment_state must have one layout for every selected task; "
            f"they differ: {listed}. Use cameras (camera_config/obs_type with pixels) for "
            "several tasks, or one task at a time."
        )
    return next(iter(names.values()))


def selection_tasks(selection: str) -> tuple[str, ...]:
    """The distinct task names of a selection, in order of first appearance."""
    return tuple(dict.fromkeys(item.task for item in resolve_selection(selection)))


def _add(
    groups: dict[str, list[tuple[str, Mapping[str, Any]]]],
    group: str,
    task: str,
    variation: Mapping[str, Any],
) -> None:
    members = groups.setdefault(group, [])
    if all(existing != task for existing, _ in members):
        members.append((task, variation))
