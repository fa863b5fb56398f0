"""The pieces every task's reward is built from: bounded terms and the staged pick-and-place.

Each term lies in [0, 1] (dm_control's ``rewards.tolerance`` in spirit). The staged
reward of the pick-and-place tasks (``reach``, ``grasp``, ``lift``, ``place``) lives
here once: :func:`pick_terms` for the tasks that stop at the lift, and
:func:`pick_and_place_terms` for those that put the object somewhere. A later stage
counts every earlier one as complete, so the reward never falls as the task progresses.
Tasks compute the distances and flags once a step (:meth:`Task.evaluate
<gym_soarm.tasks.base.Task.evaluate>`) and hand them to these helpers.
"""

from __future__ import annotations

import math

import numpy as np

from gym_soarm.sim.physics import SoArmPhysics

REACH_BOUND_M = 0.01
"""The reach term is 1 with the jaws' centre this close to the object."""
REACH_MARGIN_M = 0.10
"""The reach term falls to 0.1 this far beyond :data:`REACH_BOUND_M` from the object."""
LIFT_HEIGHT_M = 0.05
"""A held object whose bottom is this high counts as lifted."""
PLACE_MARGIN_M = 0.20
"""The place term's carry share falls to 0.1 this far beyond the target."""
RESTING_SPEED_M_S = 0.05
"""An object slower than this is at rest."""
PLACE_CARRY_CREDIT = 0.8
"""Share of a place term earned by carrying the held object over its target."""
PLACED_CREDIT = 0.9
"""Share of a place term earned by an object on its target that is still held or
moving: letting go, at rest, earns the rest (the success)."""


def norm(vector: np.ndarray) -> float:
    """Euclidean norm of a 1-D float array: what np.linalg.norm computes, with less overhead."""
    return math.sqrt(vector.dot(vector))


def tolerance(distance: float, bound: float, margin: float) -> float:
    """1 inside ``bound``, falling smoothly to 0.1 at ``bound + margin``, in [0, 1]."""
    if distance <= bound:
        return 1.0
    x = (distance - bound) / margin
    return float(math.exp(-math.log(10.0) * x * x))


def reach_distance(physics: SoArmPhysics, name: str) -> float:
    """Distance (m) from the jaws' centre (``grasp_center``) to object ``name``'s centre."""
    return norm(physics.grasp_center() - physics.object_position(name))


def pick_progress(physics: SoArmPhysics, name: str) -> dict[str, float | bool]:
    """What the staged reward reads of object ``name``, for a task's evaluation:
    ``grasped``, ``height_m`` (its bottom above the table) and ``reach_distance_m``."""
    return {
        "grasped": physics.grasped(name),
        "height_m": physics.object_height(name),
        "reach_distance_m": reach_distance(physics, name),
    }


def reach_closeness(distance_m: float) -> float:
    """The reach term of a jaws-to-object distance: 1 within 1 cm, falling smoothly beyond."""
    return tolerance(distance_m, REACH_BOUND_M, REACH_MARGIN_M)


def reach_term(physics: SoArmPhysics, name: str) -> float:
    """1 with the jaws' centre within 1 cm of object ``name``, falling smoothly beyond."""
    return reach_closeness(reach_distance(physics, name))


def lift_progress(height_m: float, top_m: float = LIFT_HEIGHT_M, dead_band_m: float = 0.0) -> float:
    """How far an object's bottom at ``height_m`` is raised from ``dead_band_m`` towards
    ``top_m``, in [0, 1]."""
    return min(max((height_m - dead_band_m) / (top_m - dead_band_m), 0.0), 1.0)


def lift_term(physics: SoArmPhysics, name: str, height_m: float = LIFT_HEIGHT_M) -> float:
    """How far object ``name``'s bottom is raised towards ``height_m``, in [0, 1]."""
    return lift_progress(physics.object_height(name), height_m)


def pick_terms(*, grasped: bool, reach_distance_m: float, lift: float) -> dict[str, float]:
    """The ``reach``, ``grasp`` and ``lift`` stages of picking an object up.

    Args:
        grasped: both jaw pads hold the object.
        reach_distance_m: from the jaws' centre to the object (scored while not held).
        lift: the lift progress of the held object, in [0, 1].
    """
    if not grasped:
        return {"reach": reach_closeness(reach_distance_m), "grasp": 0.0, "lift": 0.0}
    return {"reach": 1.0, "grasp": 1.0, "lift": lift}


def pick_and_place_terms(
    *,
    on_target: bool,
    grasped: bool,
    reach_distance_m: float,
    lift: float,
    over_target: bool,
    near_target: float,
) -> dict[str, float]:
    """The ``reach``, ``grasp``, ``lift`` and ``place`` stages of an unfinished placement.

    An object on its target (held or moving) lacks only the release: every stage is
    complete but ``place``, at :data:`PLACED_CREDIT`. A held object over its target counts
    as lifted, so lowering it onto the target loses nothing; carrying it there earns up to
    :data:`PLACE_CARRY_CREDIT` of ``place``.

    Args:
        on_target: the object lies on its target (whether held or not).
        grasped: both jaw pads hold the object.
        reach_distance_m: from the jaws' centre to the object (scored while not held).
        lift: the lift progress of the held object, in [0, 1].
        over_target: the held object is (horizontally) over its target.
        near_target: closeness of the object to its target, in [0, 1].
    """
    if on_target:
        return {"reach": 1.0, "grasp": 1.0, "lift": 1.0, "place": PLACED_CREDIT}
    if not grasped:
        reach = reach_closeness(reach_distance_m)
        return {"reach": reach, "grasp": 0.0, "lift": 0.0, "place": 0.0}
    if over_target:
        lift = 1.0
    return {
        "reach": 1.0,
        "grasp": 1.0,
        "lift": lift,
        "place": PLACE_CARRY_CREDIT * near_target * lift,
    }
