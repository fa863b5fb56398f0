"""Command-line options shared by gym_soarm's programs, and the flags generated from
:class:`gym_soarm.envs.settings.EnvSettings` (:func:`add_settings_arguments`)."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from gym_soarm import constants
from gym_soarm.envs.settings import EnvSettings, setting_fields
from gym_soarm.real.replay import REPLAY_TASK
from gym_soarm.real.units import UNITS
from gym_soarm.tasks import get_task, task_names
from gym_soarm.tasks.suites import resolve_selection


def task_name(text: str) -> str:
    """argparse type of a program's single ``--task``: a task's name (``LiftCube-v0``),
    alias (``lift``) or gym id (``gym_soarm/LiftCube-v0``), returned as the task's name;
    anything else is argparse's usage error (exit 2) that lists the names and aliases."""
    try:
        return get_task(text).name
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def task_selection(text: str) -> str:
    """argparse type of ``--task``: a task, a suite or a comma list of them, checked."""
    try:
        resolve_selection(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def int_at_least(minimum: int) -> Callable[[str], int]:
    """argparse type of an int option that must be ``minimum`` or more (``--steps``)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected an int >= {minimum}; got {text!r}"
            ) from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected an int >= {minimum}; got {value}")
        return value

    return parse


def add_dataset_scene_arguments(parser: argparse.ArgumentParser, overrides: Sequence[str]) -> None:
    """Which dataset and how its joints and scenes are read back (replay and sysid): ``--units``,
    ``--calibration``, ``--wrist-roll-offset-deg``, ``--task``, ``--seed`` and the flags
    of the gym.make keywords ``overrides`` that may change a recording's own; ``--root``
    first, the dataset's folder."""
    parser.add_argument("--root", required=True, help="the dataset folder (holds meta/info.json)")
    parser.add_argument(
        "--units",
        choices=UNITS,
        default=None,
        help="the dataset's joint units (default: a gym_soarm recording's own, else from robot_type: gym_soarm = radians, "
        "else lerobot; use lerobot_range for LeRobot's older -100..100 datasets)",
    )
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="PATH",
        help="the recording arm's LeRobot calibration JSON (LeRobot units)",
    )
    parser.add_argument(
        "--wrist-roll-offset-deg",
        type=float,
        default=None,
        metavar="DEG",
        help="the arm's wrist_roll reading when the model's is at 0 rad (default: the "
        "recording's own, else 0)",
    )
    parser.add_argument(
        "--task",
        type=task_name,
        default=None,
        metavar="TASK",
        help="the scene of every episode, by name, alias or gym id: "
        f"{', '.join(task_names())} (default: each episode's recorded task in gym_soarm "
        f"recordings, else {REPLAY_TASK}: no object in the way)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="episode K resets the scene with SEED + K, as the recorder did (default 0)",
    )
    add_override_arguments(parser, overrides, "a gym_soarm recording", "the recording")


def dataset_scene_keywords(args: argparse.Namespace) -> dict[str, Any]:
    """The keywords of :func:`~gym_soarm.real.replay.replay` and
    :func:`~gym_soarm.real.sysid.fit_dynamics` that :func:`add_dataset_scene_arguments`'
    flags and the settings flags give (all but the episodes)."""
    return {
        "units": args.units,
        "calibration": args.calibration,
        "wrist_roll_offset_deg": args.wrist_roll_offset_deg,
        "task": args.task,
        "seed": args.seed,
        "settings": settings_given(args),
    }


def camera_config_argument(text: str) -> str | list[str]:
    """``--camera-config`` as the recorder takes it: a config name (``front_wrist``,
    ``none`` ...) as is, camera names (``front_camera,wrist_camera``) as a list."""
    if "," in text or text in constants.CAMERA_NAMES:
        return [name.strip() for name in text.split(",") if name.strip()]
    return text


# --- flags generated from the environment settings --------------------------------------
IMAGE_SETTINGS: tuple[str, ...] = (
    "camera_config",
    "observation_height",
    "observation_width",
    "render_mode",
    "render_camera",
    "render_quality",
    "image_modalities",
)
"""The settings of images and windows: fixed by the programs that render nothing."""

SETTINGS_DEST = "_settings_fields"
"""The ``argparse.Namespace`` attribute listing the settings fields a parser has flags for."""


def settings_flag(name: str) -> str:
    """The command-line flag of a settings field: ``dynamics`` -> ``--dynamics``."""
    return "--" + name.replace("_", "-")


def _setting_type(item: dataclasses.Field) -> Callable[[str], Any]:
    """argparse ``type`` of a settings field: its text read and checked by its own check."""
    parse = item.metadata.get("parse")
    if parse is None and item.metadata.get("choices"):
        return str  # argparse's choices check it, and name the valid ones
    if parse is None:
        kind = type(item.default)
        parse = kind if kind in (int, float) else str

    def read(text: str) -> Any:
        try:
            value = parse(text)
            item.metadata["check"](item.name, value)
        except (TypeError, ValueError) as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return value

    read.__name__ = item.name  # argparse names the type in its messages
    return read


def settings_except(*names: str) -> tuple[str, ...]:
    """Every settings field but ``names``: what a program that takes only those excludes."""
    return tuple(name for name in EnvSettings.names() if name not in names)


def add_settings_arguments(
    parser: argparse.ArgumentParser,
    *,
    exclude: Sequence[str] = (),
    defaults: Mapping[str, Any] | None = None,
    helps: Mapping[str, str] | None = None,
    title: str = "environment",
    description: str | None = "gym.make keywords (see docs/keywords.md)",
    default_text: str | None = None,
) -> tuple[str, ...]:
    """Add a flag per :class:`~gym_soarm.envs.settings.EnvSettings` field, generated from it.

    Every field gets ``--field-name`` (its dest is the field's name), except those in
    ``exclude`` (the program sets them itself or has its own flag for them). The flag
    reads its text with the field's parser and checks it with the field's check, so a
    bad value is a usage error. Bool fields get ``--name``/``--no-name``.

    Args:
        parser: the parser (or argument group's parser) to add to.
        exclude: field names to leave out.
        defaults: per field, the flag's default when not the field's own (e.g. None for
            "the recording's own" in replay).
        helps: per field, a help text instead of the field's doc.
        title: the argument group's title.
        description: the argument group's description.
        default_text: what the help says of a flag's default (default: its value).

    Returns:
        The fields added (also recorded in the parsed namespace for
        :func:`settings_from_args`).

    Raises:
        ValueError: ``exclude``, ``defaults`` or ``helps`` name an unknown field.
    """
    defaults = dict(defaults or {})
    helps = dict(helps or {})
    names = EnvSettings.names()
    unknown = sorted((set(exclude) | set(defaults) | set(helps)) - set(names))
    if unknown:
        raise ValueError(f"unknown settings fields {unknown}; the fields are {', '.join(names)}.")
    group = parser.add_argument_group(title, description)
    added = []
    for item in setting_fields():
        if item.name in exclude:
            continue
        default = defaults.get(item.name, item.default)
        shown = ",".join(default) if isinstance(default, tuple) else default
        text = helps.get(item.name, item.metadata["doc"])
        if item.name not in helps:
            text += f" (default {shown})" if default_text is None else f" ({default_text})"
        text = text.replace("%", "%%")
        if isinstance(item.default, bool):
            group.add_argument(
                settings_flag(item.name),
                dest=item.name,
                action=argparse.BooleanOptionalAction,
                default=default,
                help=text,
            )
        else:
            group.add_argument(
                settings_flag(item.name),
                dest=item.name,
                type=_setting_type(item),
                choices=None if item.metadata.get("parse") else item.metadata.get("choices"),
                default=default,
                metavar=_metavar(item),
                help=text,
            )
        added.append(item.name)
    previous = parser.get_default(SETTINGS_DEST) or ()
    parser.set_defaults(**{SETTINGS_DEST: (*previous, *added)})
    return tuple(added)


def _metavar(item: dataclasses.Field) -> str | None:
    return item.metadata.get("metavar")  # None: argparse shows the choices


def add_override_arguments(
    parser: argparse.ArgumentParser, names: Sequence[str], source: str, short: str
) -> None:
    """The flags of the gym.make keywords ``names`` that change the settings ``source``
    carries (``"the policy"``); each defaults to None: ``source``'s own, else gym.make's.
    ``short`` names the source again in the defaults' text."""
    add_settings_arguments(
        parser,
        exclude=settings_except(*names),
        defaults=dict.fromkeys(names),
        description=f"gym.make keywords over {source}'s own (see docs/keywords.md)",
        default_text=f"default: {short}'s own, else gym.make's",
    )


def settings_given(args: argparse.Namespace) -> dict[str, Any]:
    """The generated settings flags' values in ``args`` (see
    :func:`add_settings_arguments`), as keywords; None values left out (not given)."""
    names = getattr(args, SETTINGS_DEST, ())
    return {name: getattr(args, name) for name in names if getattr(args, name) is not None}


def settings_from_args(
    args: argparse.Namespace,
    base: EnvSettings | Mapping[str, Any] | None = None,
    **fixed: Any,
) -> EnvSettings:
    """The :class:`~gym_soarm.envs.settings.EnvSettings` of parsed flags.

    ``base`` (settings or keywords; default: the defaults) is overlaid with the flags'
    values (None: not given, the base's stays), then with ``fixed`` (what the program
    sets itself, such as ``obs_type``).

    Raises:
        ValueError, TypeError: the combination is not valid (e.g. a wrist offset with
            radians); the message names the keyword.
    """
    if isinstance(base, EnvSettings):
        base = base.to_kwargs()
    values = {**dict(base or {}), **settings_given(args), **fixed}
    return EnvSettings.from_kwargs(**values)
