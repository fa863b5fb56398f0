"""Argument checks shared by the environment, the recorder, the tools and ``gym_soarm.lerobot``.

One rule for every error raised here: a value of the right type that is not one of the
valid values raises ``ValueError``; a value of the wrong type raises
:class:`ArgumentTypeError`, which is both a ``TypeError`` (as Python itself would say)
and a ``ValueError`` (so ``except ValueError`` catches every bad argument, as the
environment documents). Every message names the argument, what was expected, what came,
and how to fix it. Nothing is built or changed before the checks pass.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm import constants

MIN_IMAGE_SIZE = 16
MAX_IMAGE_SIZE = 2048


class ArgumentTypeError(TypeError, ValueError):
    """An argument of the wrong type (a ``TypeError`` and a ``ValueError``)."""


def choices(values: Sequence[Any]) -> str:
    """``'a', 'b', 'c'``: valid values as a message lists them."""
    return ", ".join(repr(v) for v in values)


def check_choice(name: str, value: Any, valid: Sequence[Any], none_ok: bool = False) -> Any:
    """``value`` if it is one of ``valid`` (or None with ``none_ok``), else ``ValueError``."""
    if none_ok and value is None:
        return value
    options = choices(valid) + (" or None" if none_ok else "")
    if not isinstance(value, str):
        raise ArgumentTypeError(
            f"{name} must be one of {options}; got {value!r} ({type(value).__name__}). "
            f"Pass e.g. {name}={valid[0]!r}."
        )
    if value not in valid:
        raise ValueError(
            f"{name} must be one of {options}; got {value!r}. Pass e.g. {name}={valid[0]!r}."
        )
    return value


def check_bool(name: str, value: Any) -> bool:
    """``value`` as a bool: True, False or a numpy bool (no ints, no strings)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(
            f"{name} must be True or False; got {value!r} ({type(value).__name__}). "
            f"Pass e.g. {name}=True."
        )
    return bool(value)


def check_int(
    name: str, value: Any, minimum: int, maximum: int | None = None, *, fix: str = ""
) -> int:
    """``value`` as an int within [minimum, maximum] (bools are not ints here); ``fix``
    ends the message ("Pass None for a random cell.")."""
    span = f"from {minimum} to {maximum}" if maximum is not None else f">= {minimum}"
    fix = f" {fix}" if fix else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentTypeError(
            f"{name} must be an int {span}; got {value!r} ({type(value).__name__}).{fix}"
        )
    if int(value) < minimum or (maximum is not None and int(value) > maximum):
        raise ValueError(f"{name} must be an int {span}; got {value!r}.{fix}")
    return int(value)


def check_number(
    name: str, value: Any, minimum: float | None = None, unit: str = "", *, fix: str = ""
) -> float:
    """``value`` as a finite float (>= minimum when given); ``fix`` ends the message."""
    what = f"a finite number{' of ' + unit if unit else ''}"
    if minimum is not None:
        what += f" >= {minimum:g}"
    fix = f" {fix}" if fix else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ArgumentTypeError(
            f"{name} must be {what}; got {value!r} ({type(value).__name__}).{fix}"
        )
    if not math.isfinite(float(value)) or (minimum is not None and float(value) < minimum):
        raise ValueError(f"{name} must be {what}; got {value!r}.{fix}")
    return float(value)


def check_positive(name: str, value: Any, *, fix: str = "") -> float:
    """``value`` as a float > 0 (bools are not numbers here; inf is allowed); ``fix``
    ends the message (default: a positive example of ``name``)."""
    fix = f" {fix or f'Pass a number > 0, e.g. {name}=1.0.'}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ArgumentTypeError(
            f"{name} must be a number > 0; got {value!r} ({type(value).__name__}).{fix}"
        )
    if not value > 0:
        raise ValueError(f"{name} must be a number > 0; got {value!r}.{fix}")
    return float(value)


def check_dataclass_fields(
    config: Any, picks: Callable[[str], bool], check: Callable[..., Any]
) -> None:
    """Run ``check(name, value, fix=...)`` on each field of the dataclass ``config`` whose
    name ``picks`` chooses (``lambda name: name.endswith("_steps")``), in declaration
    order; ``fix`` names the field's default ("Pass e.g. rise_steps=20 (the default).")."""
    for field in dataclasses.fields(config):
        if picks(field.name):
            default = field.default
            fix = (
                ""
                if default is dataclasses.MISSING
                else f"Pass e.g. {field.name}={default!r} (the default)."
            )
            check(field.name, getattr(config, field.name), fix=fix)


def check_subset(name: str, value: Any, valid: Sequence[str]) -> tuple[str, ...]:
    """A non-empty sequence of distinct values from ``valid``, returned in ``valid``'s order."""
    example = f"{name}={tuple(valid[:2])!r}"
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise ArgumentTypeError(
            f"{name} must be a tuple of values from {choices(valid)}; got {value!r} "
            f"({type(value).__name__}). Pass e.g. {example}."
        )
    for item in value:
        if not isinstance(item, str):
            raise ArgumentTypeError(
                f"{name} must hold strings from {choices(valid)}; got {item!r} "
                f"({type(item).__name__}) in {value!r}. Pass e.g. {example}."
            )
    unknown = [item for item in value if item not in valid]
    if unknown or not value or len(set(value)) != len(value):
        problem = (
            f"unknown {unknown!r}"
            if unknown
            else "nothing"
            if not value
            else f"repeated values in {list(value)!r}"
        )
        raise ValueError(
            f"{name} must be a non-empty tuple of distinct values from {choices(valid)}; got "
            f"{problem}. Pass e.g. {example}."
        )
    return tuple(v for v in valid if v in value)


def check_image_size(name: str, value: Any) -> int:
    """An image height or width in pixels, from 16 to 2048."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentTypeError(
            f"{name} must be an int from {MIN_IMAGE_SIZE} to {MAX_IMAGE_SIZE} pixels; got {value!r}."
        )
    if not MIN_IMAGE_SIZE <= int(value) <= MAX_IMAGE_SIZE:
        raise ValueError(
            f"{name} must be from {MIN_IMAGE_SIZE} to {MAX_IMAGE_SIZE} pixels; got {value!r}."
        )
    return int(value)


def resolve_camera_config(camera_config: str | Sequence[str]) -> tuple[str, ...]:
    """Cameras named by a camera config, in the fixed order overview, front, wrist."""
    if isinstance(camera_config, str):
        if camera_config not in constants.CAMERA_CONFIGS:
            raise ValueError(
                f"camera_config must be one of {choices(constants.CAMERA_CONFIGS)} or a sequence "
                f"of camera names from {choices(constants.CAMERA_NAMES)}; got {camera_config!r}."
            )
        return constants.CAMERA_CONFIGS[camera_config]
    if not isinstance(camera_config, Sequence):
        raise ArgumentTypeError(
            f"camera_config must be one of {choices(constants.CAMERA_CONFIGS)} or a sequence of "
            f"camera names; got {camera_config!r} ({type(camera_config).__name__})."
        )
    if not camera_config:
        raise ValueError(
            f"camera_config must be one of {choices(constants.CAMERA_CONFIGS)} or a non-empty "
            f"sequence of camera names from {choices(constants.CAMERA_NAMES)}; got {camera_config!r}."
        )
    unknown = [c for c in camera_config if c not in constants.CAMERA_NAMES]
    if unknown:
        raise ValueError(
            f"camera_config must name cameras from {choices(constants.CAMERA_NAMES)}; got "
            f"unknown cameras {unknown!r}. Pass e.g. camera_config=['front_camera']."
        )
    return tuple(c for c in constants.CAMERA_NAMES if c in camera_config)


def parse_cameras(text: str) -> tuple[str, ...]:
    """Cameras of a camera config name or of comma-separated camera names (command lines)."""
    if text in constants.CAMERA_CONFIGS:
        return resolve_camera_config(text)
    names = [name.strip() for name in str(text).split(",") if name.strip()]
    return resolve_camera_config(names)


def parse_size(text: str) -> tuple[int, int]:
    """Parse ``"HxW"`` (e.g. ``"480x640"``) into even (height, width) within the env's limits.

    Raises:
        ValueError: not two integers joined by ``x``, odd, or out of range.
    """
    parts = str(text).lower().split("x")
    try:
        height, width = (int(p) for p in parts)
    except ValueError:
        raise ValueError(f"size must be HEIGHTxWIDTH, e.g. 480x640; got {text!r}.") from None
    for name, value in (("height", height), ("width", width)):
        if not MIN_IMAGE_SIZE <= value <= MAX_IMAGE_SIZE or value % 2:
            raise ValueError(
                f"size {name} must be even and from {MIN_IMAGE_SIZE} to {MAX_IMAGE_SIZE} "
                f"(H.264 needs even sizes); got {value} in {text!r}."
            )
    return height, width


def check_fields(
    entry: Any, fields: Sequence[str], what: str, refuse: Callable[[str], ValueError]
) -> Mapping[str, Any]:
    """``entry`` of a file: a mapping whose keys are all in ``fields`` (some may be
    missing), else ``refuse(problem)`` is raised, the problem naming ``what``.

    Args:
        entry: the value read from the file.
        fields: the keys it may have.
        what: how the problem names it ("motor 'gripper'", "joints.gripper").
        refuse: makes the error from the problem (the file's name and the fix).
    """
    if not isinstance(entry, Mapping):
        raise refuse(f"{what} is a {type(entry).__name__}, not an object")
    extra = sorted(set(entry) - set(fields))
    if extra:
        raise refuse(f"{what} has an unknown field {extra[0]!r}; expected {', '.join(fields)}")
    return entry


def read_json_file(path: Any, expected: str, refuse: Callable[[str], ValueError]) -> Any:
    """The content of the JSON file at ``path``.

    Args:
        path: a ``str`` or ``os.PathLike``.
        expected: what the argument should be, the start of the type error's message
            ("calibration must be the path of ...").
        refuse: makes the error from a problem with the file (missing, unreadable, not
            JSON), naming the file and the fix.

    Raises:
        ArgumentTypeError: ``path`` is not a str or path.
        ValueError: ``refuse``'s, for a missing, unreadable or non-JSON file.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ArgumentTypeError(f"{expected}; got {path!r} ({type(path).__name__}).")
    file = Path(path)
    if not file.is_file():
        raise refuse("no such file")
    try:
        return json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise refuse(f"cannot be read ({exc})") from exc
    except json.JSONDecodeError as exc:
        raise refuse(f"is not JSON ({exc})") from exc
