"""The pieces every task's reward is built from: bounded terms and the staged pick-and-place.

Each term lies in [0, 1] (dm_control's ``rewards.tolerance`` in spirit). The staged
reward of the pick-and-place tasks (``reach``, ``grasp``, ``lift``, ``place``) lives
here once: :func:`pick_terms` for the tasks that stop at the lift, and
:func:`pick_and_place_terms` for those that put the object somewhere. A later stage
counts every earlier one as complete, so the reward never falls as the task progresses.
Tasks compute the distances and flags once a step (:meth:`Task.evaluate
<gym_soarm.tasks.base.Task.evaluate>`) and hand them to these helpers. Everything here
but :func:`norm` works on arrays over a batch of environments (NumPy, or any array-API
library such as torch): one value per environment, ``(n,)``.
"""

from __future__ import annotations

import math

import numpy as np

from gym_soarm.sim.arrays import Array, SimArrays, namespace
from gym_soarm.sim.arrays import norm as batch_norm

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


LN10 = math.log(10.0)


def tolerance(distance: Array, bound: float, margin: float) -> Array:
    """1 inside ``bound``, falling smoothly to 0.1 at ``bound + margin``, in [0, 1]."""
    xp = namespace(distance)
    x = xp.maximum(distance - bound, 0.0) / margin
    return xp.exp(-LN10 * x * x)


def reach_distance(sim: SimArrays, name: str) -> Array:
    """``(n,)``: from the jaws' centre (``grasp_center``) to object ``name``'s centre (m)."""
    return batch_norm(sim.grasp_center() - sim.object_position(name))


def pick_progress(sim: SimArrays, name: str) -> dict[str, Array]:
    """What the staged reward reads of object ``name``, for a task's evaluation:
    ``grasped``, ``height_m`` (its bottom above the table) and ``reach_distance_m``."""
    return {
        "grasped": sim.grasped(name),
        "height_m": sim.object_height(name),
        "reach_distance_m": reach_distance(sim, name),
    }


def reach_closeness(distance_m: Array) -> Array:
    """The reach term of a jaws-to-object distance: 1 within 1 cm, falling smoothly beyond."""
    return tolerance(distance_m, REACH_BOUND_M, REACH_MARGIN_M)


def lift_progress(height_m: Array, top_m: float = LIFT_HEIGHT_M, dead_band_m: float = 0.0) -> Array:
    """How far an object's bottom at ``height_m`` is raised from ``dead_band_m`` towards
    ``top_m``, in [0, 1]."""
    xp = namespace(height_m)
    return xp.minimum(xp.maximum((height_m - dead_band_m) / (top_m - dead_band_m), 0.0), 1.0)


def pick_terms(*, grasped: Array, reach_distance_m: Array, lift: Array) -> dict[str, Array]:
    """The ``reach``, ``grasp`` and ``lift`` stages of picking an object up.

    Args:
        grasped: both jaw pads hold the object.
        reach_distance_m: from the jaws' centre to the object (scored while not held).
        lift: the lift progress of the held object, in [0, 1].
    """
    xp = namespace(reach_distance_m)
    held = xp.astype(grasped, reach_distance_m.dtype)
    return {
        "reach": xp.where(grasped, 1.0, reach_closeness(reach_distance_m)),
        "grasp": held,
        "lift": held * lift,
    }


def pick_and_place_terms(
    *,
    on_target: Array,
    grasped: Array,
    reach_distance_m: Array,
    lift: Array,
    over_target: Array,
    near_target: Array,
) -> dict[str, Array]:
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
    xp = namespace(reach_distance_m)
    dtype = reach_distance_m.dtype
    held = grasped | on_target
    held_lift = xp.where(over_target, 1.0, lift)
    carry = PLACE_CARRY_CREDIT * near_target * held_lift
    return {
        "reach": xp.where(held, 1.0, reach_closeness(reach_distance_m)),
        "grasp": xp.astype(held, dtype),
        "lift": xp.where(on_target, 1.0, xp.where(grasped, held_lift, 0.0)),
        "place": xp.where(on_target, PLACED_CREDIT, xp.where(grasped, carry, 0.0)),
    }


def norm(vector: np.ndarray) -> float:
    """Euclidean norm of one 1-D float array, as a float (for experts and placement)."""
    return math.sqrt(vector.dot(vector))
