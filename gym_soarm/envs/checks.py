"""The checks of what a :class:`~gym_soarm.envs.env.SoArmEnv` is given at every step and reset.

:func:`check_action` takes an action to the float64 array the control mode converts, or
refuses it (shape, dtype, NaN/inf) before anything is stepped; :func:`check_reset_options`
takes ``reset``'s options to the task's checked options or to a snapshot to restore,
before anything changes. Each error says what was expected, what came and how to fix it.
"""

from __future__ import annotations

import math
import reprlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from gym_soarm.envs import snapshot as snapshots
from gym_soarm.envs.control import ControlMode
from gym_soarm.envs.world import World
from gym_soarm.validation import ArgumentTypeError, choices

# LeRobot's evaluation (lerobot >= 0.6) marks the start of every rollout with this reset
# option; it is accepted and has no effect.
LEROBOT_ROLLOUT_OPTION = "lerobot_new_rollout"
STATE_OPTION = "state"
"""The reset option that restores a :class:`~gym_soarm.envs.snapshot.Snapshot`."""


def check_action(
    action: Any, shape: tuple[int, ...], control_mode: str, control: ControlMode
) -> np.ndarray:
    """``action`` as a new float64 array (the control mode may modify it).

    Args:
        action: what the caller passed to ``step``.
        shape: the action space's shape.
        control_mode: the ``control_mode`` setting (for the messages).
        control: the control mode (its action names and description, for the messages).

    Raises:
        ValueError: not an array of real numbers of ``shape``, or NaN/inf in it.
    """
    if type(action) is np.ndarray and action.dtype.kind == "f" and action.shape == shape:
        array = action  # the common case, already known to be a real array of the right shape
    else:
        array = _action_array(action, shape, control_mode, control)
    array = array.astype(np.float64)  # our own copy, which the control mode may modify
    # A finite sum in plain floats proves every value finite (the common case, cheaply);
    # otherwise NumPy looks at each value (a sum of huge finite values may overflow).
    if not math.isfinite(sum(array.ravel().tolist())) and not np.isfinite(array).all():
        names = control.action_names
        bad = [names[i] for i in np.flatnonzero(~np.isfinite(array))]
        raise ValueError(
            f"action must be finite; got {array.tolist()!r} with NaN/inf for {bad}. "
            "The simulation was not stepped; check the policy's output (e.g. its "
            "normalisation statistics) before stepping."
        )
    return array


def _action_array(
    action: Any, shape: tuple[int, ...], control_mode: str, control: ControlMode
) -> np.ndarray:
    """``action`` as an array of real numbers of ``shape``, or a ``ValueError``."""
    try:
        array = np.asarray(action)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"action must be an array of shape {shape} in "
            f"control_mode={control_mode!r}: {control.description}; got "
            f"{action!r} ({exc}). Pass e.g. env.action_space.sample()."
        ) from None
    if array.dtype == np.bool_ or not np.issubdtype(array.dtype, np.number):
        raise ValueError(
            f"action must hold real numbers (float or int); got {reprlib.repr(action)} "
            f"with dtype {array.dtype}. Pass e.g. np.asarray(action, dtype=np.float32)."
        )
    if np.issubdtype(array.dtype, np.complexfloating):
        raise ValueError(
            f"action must be real-valued; got dtype {array.dtype}. "
            "Pass the real part, e.g. np.real(action).astype(np.float32)."
        )
    if array.shape != shape:
        raise ValueError(
            f"action must have shape {shape} in control_mode="
            f"{control_mode!r}: {control.description}; got shape "
            f"{array.shape}. Pass e.g. env.action_space.sample()."
        )
    return array


def check_reset_options(options: Mapping[str, Any] | None, world: World) -> dict[str, Any]:
    """The task's checked options, or ``{"state": snapshot}`` for a restore.

    Raises:
        TypeError: ``options`` is not a dict, or ``"state"`` holds no snapshot.
        ValueError: an unknown option, ``"state"`` beside the task's options, a bad
            value, or a snapshot that does not fit ``world``.
    """
    task, name = world.task, world.spec.name
    keys = task.option_keys
    example = f"options={{{keys[0]!r}: ...}}" if keys else "options=None"
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ArgumentTypeError(
            f"options must be a dict with keys from {choices(keys) or 'none'} (or "
            f'"state"); got {options!r}. Pass e.g. {example}.'
        )
    unknown = sorted(set(options) - {*keys, STATE_OPTION, LEROBOT_ROLLOUT_OPTION}, key=repr)
    if unknown:
        raise ValueError(
            f"unknown reset option(s) {unknown!r}: options must have keys from "
            f"{choices(keys) or 'none (this task takes no options)'} for {name}, or "
            f'"state" (a snapshot to restore); got {list(options)!r}. Remove the others.'
        )
    if STATE_OPTION in options:
        others = sorted(set(options) & set(keys), key=repr)
        if others:
            raise ValueError(
                f'reset option "state" restores a snapshot, which holds the whole '
                f"episode; it cannot be combined with the task's options {others!r}. "
                'Pass options={"state": snapshot} alone.'
            )
        return {STATE_OPTION: snapshots.check_restorable(options[STATE_OPTION], world)}
    return task.validate_options({k: v for k, v in options.items() if k in keys})
