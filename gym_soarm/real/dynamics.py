"""Dynamics files: the servo and joint figures of one real arm, fitted or written by hand.

``dynamics=PATH`` (a ``gym.make`` keyword, the recorder's and the teleop's
``--dynamics`` and the LeRobot config's ``dynamics`` field) reads a JSON file of the
format ``gym_soarm.dynamics/1`` and writes its figures into the environment's own copy
of the model (nothing is recompiled, other environments are untouched)::

    {
      "format": "gym_soarm.dynamics/1",
      "joints": {
        "shoulder_pan": {"kp": 720.5, "kv": 21.3, "damping": 0.55,
                         "armature": 0.031, "frictionloss": 0.07},
        "elbow_flex": {"kp": 690.0},
        ...
      },
      "control_delay_steps": 1,
      "fit": {...}
    }

=================  ============  =============================================  ==========
field              unit          what it sets                                   model's
=================  ============  =============================================  ==========
``kp``             N·m/rad       the position servo's gain (``kp`` of the MJCF   998
                                 ``<position>``)
``kv``             N·m·s/rad     the servo's velocity gain (``kv``)              15
``damping``        N·m·s/rad     the joint's own damping                         0.6
``armature``       kg·m²         the joint's armature (rotor inertia)            0.028
``frictionloss``   N·m           the joint's dry friction                        0.05
=================  ============  =============================================  ==========

The servo pushes with ``kp * (target - q) - kv * qdot``, bounded by its force range
(3.35 N·m). Values are absolute, in SI units. Joints are the six of
:data:`gym_soarm.constants.JOINT_NAMES` (``gripper`` included); an absent joint or
field keeps the model's value. ``control_delay_steps`` (an integer >= 0, at most
:data:`MAX_DELAY_STEPS`) makes the servos receive the action of that many 20 ms steps
before; absent, there is no delay. ``fit`` is the report that ``python -m
gym_soarm.sysid`` writes (how well the figures reproduce the dataset they were fitted
to); it is kept and not used.

Files are written as ``gym_soarm.dynamics/1``; files that name the format
``gym_soarm.real.dynamics/1`` (the same content, as one release wrote it) load as well.

With ``physics_randomization`` the randomiser draws its servo gains and damping around
the file's values and adds its own delay (0 or 1 steps with ``"heavy"``) to the file's.

Only numpy, MuJoCo and the standard library are used here.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.sim.randomization import arm_indices, set_servo_gains
from gym_soarm.validation import check_fields, read_json_file

FORMAT = "gym_soarm.dynamics/1"
"""The ``format`` string of a dynamics file, as :func:`write_dynamics` writes it."""
FORMATS: tuple[str, ...] = (FORMAT, "gym_soarm.real.dynamics/1")
"""The ``format`` strings a dynamics file may hold: :data:`FORMAT` and the name one
release wrote for the same content."""
JOINT_FIELDS: tuple[str, ...] = ("kp", "kv", "damping", "armature", "frictionloss")
"""The figures a joint's entry may hold, each an absolute SI value >= 0 (``kp`` > 0)."""
FIELD_UNITS: dict[str, str] = {
    "kp": "N*m/rad",
    "kv": "N*m*s/rad",
    "damping": "N*m*s/rad",
    "armature": "kg*m^2",
    "frictionloss": "N*m",
}
TOP_LEVEL: tuple[str, ...] = ("format", "joints", "control_delay_steps", "fit")
"""The keys a dynamics file may hold."""
MAX_DELAY_STEPS = 50
"""The longest control delay a file may give (50 steps of 20 ms: one second)."""


@dataclass(frozen=True)
class Dynamics:
    """A dynamics file's content, checked (see the module docstring).

    Attributes:
        joints: joint -> field -> value, only what the file gives, in JOINT_NAMES order.
        control_delay_steps: the control delay in steps; None when the file gives none.
        fit: the fit report (``python -m gym_soarm.sysid``), or None.
        path: the file it was read from, or None.
    """

    joints: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    control_delay_steps: int | None = None
    fit: Mapping[str, Any] | None = None
    path: str | None = None

    @property
    def delay_steps(self) -> int:
        """The control delay in steps (0 when the file gives none)."""
        return self.control_delay_steps or 0

    def to_json(self) -> dict[str, Any]:
        """The file's content (``format``, ``joints``, ``control_delay_steps``, ``fit``)."""
        content: dict[str, Any] = {
            "format": FORMAT,
            "joints": {name: dict(values) for name, values in self.joints.items()},
        }
        if self.control_delay_steps is not None:
            content["control_delay_steps"] = self.control_delay_steps
        if self.fit is not None:
            content["fit"] = self.fit
        return content


def _refuse(source: object, problem: str) -> ValueError:
    return ValueError(
        f"dynamics file {source}: {problem}. A dynamics file is a JSON object "
        f'{{"format": "{FORMAT}", "joints": {{joint: {{field: value}}}}, '
        '"control_delay_steps": k}, as python -m gym_soarm.sysid writes it (see '
        "gym_soarm.real.dynamics)."
    )


def _joint_values(source: object, name: str, entry: Any) -> dict[str, float]:
    """One joint's fields of a dynamics file (checked, as floats)."""
    entry = check_fields(
        entry, JOINT_FIELDS, f"joints.{name}", lambda problem: _refuse(source, problem)
    )
    values: dict[str, float] = {}
    for key in JOINT_FIELDS:
        if key not in entry:
            continue
        value = entry[key]
        where = f"joints.{name}.{key}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _refuse(source, f"{where} must be a number ({FIELD_UNITS[key]}); got {value!r}")
        if not math.isfinite(value):
            raise _refuse(source, f"{where} must be finite; got {value!r}")
        if key == "kp" and value <= 0:
            raise _refuse(
                source, f"{where} must be a positive gain ({FIELD_UNITS[key]}); got {value!r}"
            )
        if value < 0:
            raise _refuse(source, f"{where} must be >= 0 ({FIELD_UNITS[key]}); got {value!r}")
        values[key] = float(value)
    return values


def check_dynamics(content: Any, source: object = "<dict>") -> Dynamics:
    """Check a dynamics file's parsed content.

    Args:
        content: the JSON object (a dict).
        source: what to name in messages (the file's path).

    Raises:
        ValueError: the content is not a ``gym_soarm.dynamics/1`` object, names an
            unknown key, joint or field, or a value is not a finite number, is negative
            (``kp`` must be positive) or the delay is not an integer 0 to
            :data:`MAX_DELAY_STEPS`. The message names ``source`` and the field.
    """
    if not isinstance(content, Mapping):
        raise _refuse(source, f"holds a {type(content).__name__}, not an object")
    unknown = sorted(set(content) - set(TOP_LEVEL))
    if unknown:
        raise _refuse(
            source, f"unknown key {unknown[0]!r}; expected only {', '.join(map(repr, TOP_LEVEL))}"
        )
    if content.get("format") not in FORMATS:
        raise _refuse(
            source,
            f"field 'format' is {content.get('format')!r}; expected "
            f"{' or '.join(map(repr, FORMATS))}",
        )
    entries = content.get("joints", {})
    if not isinstance(entries, Mapping):
        raise _refuse(source, f"field 'joints' is a {type(entries).__name__}, not an object")
    names = constants.JOINT_NAMES
    for name in entries:
        if name not in names:
            raise _refuse(
                source, f"unknown joint {name!r} in 'joints'; the SO-101 has {', '.join(names)}"
            )
    joints = {name: _joint_values(source, name, entries[name]) for name in names if name in entries}
    delay = content.get("control_delay_steps")
    if delay is not None:
        if isinstance(delay, bool) or not isinstance(delay, int):
            raise _refuse(
                source, f"field 'control_delay_steps' must be an integer of steps; got {delay!r}"
            )
        if not 0 <= delay <= MAX_DELAY_STEPS:
            raise _refuse(
                source,
                f"field 'control_delay_steps' must be 0 to {MAX_DELAY_STEPS} steps; got {delay!r}",
            )
    fit = content.get("fit")
    if fit is not None and not isinstance(fit, Mapping):
        raise _refuse(source, f"field 'fit' is a {type(fit).__name__}, not an object")
    return Dynamics(joints, delay, fit, None if source == "<dict>" else str(source))


def load_dynamics(path: str | os.PathLike[str]) -> Dynamics:
    """Read and check a dynamics file.

    Raises:
        TypeError: ``path`` is not a str or path (also a ``ValueError``).
        ValueError: the file is missing, unreadable or not JSON, or its content is bad
            (see :func:`check_dynamics`); the message names the file and the field.
    """
    content = read_json_file(
        path,
        f"dynamics must be the path of a {FORMAT} JSON file (str or os.PathLike) or None "
        "(fit one with python -m gym_soarm.sysid)",
        lambda problem: _refuse(os.fspath(path), problem),
    )
    dynamics = check_dynamics(content, os.fspath(path))
    return Dynamics(dynamics.joints, dynamics.control_delay_steps, dynamics.fit, os.fspath(path))


def write_dynamics(dynamics: Dynamics, path: str | os.PathLike[str]) -> None:
    """Write ``dynamics`` as a JSON file (checked first: a bad one writes nothing).

    Raises:
        ValueError: the content is bad, or the file cannot be written.
    """
    content = dynamics.to_json()
    check_dynamics(content, os.fspath(path))
    try:
        Path(path).write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"dynamics file {os.fspath(path)}: cannot be written ({exc}).") from exc


def read_model_dynamics(model: mujoco.MjModel) -> dict[str, dict[str, float]]:
    """The model's figures of the six joints: joint -> field -> value (all five fields)."""
    actuators, dofs = arm_indices(model)
    return {
        name: {
            "kp": float(model.actuator_gainprm[actuators[i], 0]),
            "kv": float(-model.actuator_biasprm[actuators[i], 2]),
            "damping": float(model.dof_damping[dofs[i]]),
            "armature": float(model.dof_armature[dofs[i]]),
            "frictionloss": float(model.dof_frictionloss[dofs[i]]),
        }
        for i, name in enumerate(constants.JOINT_NAMES)
    }


def apply_dynamics(model: mujoco.MjModel, joints: Mapping[str, Mapping[str, float]]) -> None:
    """Write joint figures (joint -> field -> value, checked) into ``model`` in place.

    Fields that ``joints`` does not give keep the model's values. The control delay is
    not part of the model: the environment applies it.
    """
    actuators, dofs = arm_indices(model)
    current = read_model_dynamics(model)
    kp = np.array([joints.get(n, {}).get("kp", current[n]["kp"]) for n in constants.JOINT_NAMES])
    kv = np.array([joints.get(n, {}).get("kv", current[n]["kv"]) for n in constants.JOINT_NAMES])
    set_servo_gains(model, actuators, kp, kv)
    for key, array in (
        ("damping", model.dof_damping),
        ("armature", model.dof_armature),
        ("frictionloss", model.dof_frictionloss),
    ):
        for i, name in enumerate(constants.JOINT_NAMES):
            if key in joints.get(name, {}):
                array[dofs[i]] = joints[name][key]
