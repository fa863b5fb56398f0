"""The figures of a grasp, carry and release that both kinds of expert share."""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class GraspFigures:
    """Heights in metres and gripper targets in radians of the experts' grasp and place.

    :class:`~gym_soarm.tasks.scripted.ExpertConfig` (the timed script) and
    :class:`~gym_soarm.tasks.state_expert.StateExpertConfig` add their timing to these.
    """

    hover_height_m: float = 0.05
    """Height of the ``grasp_center`` site above the table while coming over an object."""
    grasp_height_m: float = 0.018
    """Height of ``grasp_center`` when closing on an object on the table: the jaw tips
    just clear the table."""
    fixed_jaw_clearance_m: float = 0.012
    """Gap left between the fixed jaw and the object while descending; closing closes it.
    12 mm: a policy cloned from the state expert that descends up to a centimetre off
    still clears the object's top (with 7 mm a jaw landed on it in most of a cloned
    policy's failures; ``docs/learning.md``)."""
    carry_height_m: float = 0.075
    """Height of a held object's centre while carrying it (and of the lift target)."""
    lift_reach_m: tuple[float, float] = (0.13, 0.20)
    """While lifting, the object also moves to this range of horizontal distances from the
    shoulder pan axis, where the arm holds it high with the jaws still vertical."""
    place_clearance_m: float = 0.003
    """Height of the object's bottom above its resting place when the jaws let go."""
    retreat_height_m: float = 0.10
    """Height of ``grasp_center`` after a release."""
    gripper_open_rad: float = 0.8
    """Gripper target while approaching."""
    gripper_closed_rad: float = -0.17453
    """Gripper target while holding: the closed end of its range, the servo's torque limit
    sets the grip force."""

    def __post_init__(self) -> None:
        low, high = self.lift_reach_m
        if not 0.0 < low <= high:
            raise ValueError(
                "lift_reach_m must be (min, max) metres with 0 < min <= max; "
                f"got {self.lift_reach_m!r}."
            )
