"""Control rates: how many physics steps make one control step.

An environment steps its servos' targets ``control_hz`` times a second (the
``control_hz`` setting; 50 by default, 30 for LeRobot's real SO-101 datasets) and
advances the physics by a whole number of physics steps between two of them. The physics
step is 2 ms (500 Hz) where that divides the control period, else 1/600 s: 50 Hz is 10
steps of 2 ms (the default, as it always was), 30 Hz is 20 steps of 1/600 s. A rate that
neither divides is refused, naming the rates that work (:func:`control_rates`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gym_soarm.validation import ArgumentTypeError

PHYSICS_RATES_HZ: tuple[int, ...] = (500, 600)
"""The physics rates, in order of preference (500 Hz: the 2 ms step of the default)."""
DEFAULT_CONTROL_HZ = 50
MAX_CONTROL_HZ = 100
"""The fastest control rate offered (one STS3215 position read takes ~1 ms on the bus;
a real follower is driven at 30-60 Hz)."""


@dataclass(frozen=True)
class ControlTiming:
    """One control rate and the physics that divides it.

    Attributes:
        control_hz: control steps (and frames of videos and datasets) a second.
        physics_hz: physics steps a second.
        substeps: physics steps a control step.
    """

    control_hz: int
    physics_hz: int
    substeps: int

    @property
    def timestep_s(self) -> float:
        """One physics step (s): ``MjModel.opt.timestep``."""
        return 1.0 / self.physics_hz

    @property
    def control_timestep_s(self) -> float:
        """One control step (s): ``env.unwrapped.dt``."""
        return self.substeps / self.physics_hz


def control_rates(max_hz: int = MAX_CONTROL_HZ) -> tuple[int, ...]:
    """Every whole control rate up to ``max_hz`` that a physics rate divides."""
    return tuple(
        hz for hz in range(1, max_hz + 1) if any(rate % hz == 0 for rate in PHYSICS_RATES_HZ)
    )


def check_control_hz(name: str, value: Any) -> int:
    """``value`` as a control rate (int Hz), or a ``ValueError``/``TypeError`` naming the
    rates that work."""
    rates = ", ".join(map(str, control_rates()))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ArgumentTypeError(
            f"{name} must be a whole number of control steps a second; got {value!r} "
            f"({type(value).__name__}). Rates that work: {rates}."
        )
    if not value > 0 or value != int(value) or int(value) not in control_rates():
        raise ValueError(
            f"{name} must be a control rate whose period is a whole number of physics steps "
            f"(of 2 ms or 1/600 s); got {value!r}. Rates that work: {rates} "
            "(30 for LeRobot's SO-101 datasets, 50 by default)."
        )
    return int(value)


def control_timing(control_hz: int = DEFAULT_CONTROL_HZ) -> ControlTiming:
    """The physics of ``control_hz`` (checked, see :func:`check_control_hz`)."""
    hz = check_control_hz("control_hz", control_hz)
    physics_hz = next(rate for rate in PHYSICS_RATES_HZ if rate % hz == 0)
    return ControlTiming(hz, physics_hz, physics_hz // hz)


__all__ = [
    "DEFAULT_CONTROL_HZ",
    "PHYSICS_RATES_HZ",
    "ControlTiming",
    "check_control_hz",
    "control_rates",
    "control_timing",
]
