"""The scoring of the tasks that carry one object to a target and put it down there.

Pick-and-place, the cylinder, the bin and the stack score alike: success is the object
lying on its target, out of the jaws and at rest; the reward is the staged
:func:`~gym_soarm.tasks.rewards.pick_and_place_terms` of that object. Each task says only
where its object lies against its target (:meth:`PlacementScoring.placed`) and what
more must be let go or still (:meth:`PlacementScoring.settled`).
"""

from __future__ import annotations

from typing import ClassVar

from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.tasks.base import Evaluation, RewardWeights
from gym_soarm.tasks.rewards import (
    PLACE_MARGIN_M,
    RESTING_SPEED_M_S,
    lift_progress,
    pick_and_place_terms,
    pick_progress,
    tolerance,
)


class PlacementScoring:
    """Mixin of a :class:`~gym_soarm.tasks.base.Task` (listed before it) that puts
    :attr:`carried` down on a target.

    Its :meth:`evaluate` holds ``success``, the :attr:`placed_key` flag, the
    :attr:`distance_key` distance and :func:`~gym_soarm.tasks.rewards.pick_progress` of
    the carried object, in that order.
    """

    weights: ClassVar[RewardWeights] = RewardWeights(
        {"reach": 0.1, "grasp": 0.2, "lift": 0.3, "place": 0.4}
    )
    carried: ClassVar[str]
    """The object picked up and put down."""
    placed_key: ClassVar[str]
    """The evaluation's name for "the object lies on its target" (``"on_goal"``)."""
    distance_key: ClassVar[str]
    """The evaluation's name for the horizontal distance to the target (m)."""
    over_radius_m: ClassVar[float]
    """A held object within this distance is over its target (its lift counts as done)."""
    near_bound_m: ClassVar[float]
    """The distance within which the carry earns its full share of the place stage."""
    lift_dead_band_m: ClassVar[float] = 0.0
    """How high the object's bottom lies before any lift counts (a standing cylinder's)."""

    def placed(self, sim: SimArrays) -> tuple[Array, Array]:
        """``(on_target, distance_m)``, ``(n,)`` each: the object lies on its target (held or
        not), and its horizontal distance to it."""
        raise NotImplementedError(f"{type(self).__name__} must implement placed(sim).")

    def settled(self, sim: SimArrays) -> Array:
        """``(n,)``: the carried object is out of the jaws and at rest (a task may ask more)."""
        return ~sim.touched_by_jaws(self.carried) & (
            sim.object_speed(self.carried) < RESTING_SPEED_M_S
        )

    def evaluate(self, sim: SimArrays) -> Evaluation:
        on_target, distance = self.placed(sim)
        return {
            "success": on_target & self.settled(sim),
            self.placed_key: on_target,
            self.distance_key: distance,
            **pick_progress(sim, self.carried),
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        distance = evaluation[self.distance_key]
        return pick_and_place_terms(
            on_target=evaluation[self.placed_key],
            grasped=evaluation["grasped"],
            reach_distance_m=evaluation["reach_distance_m"],
            lift=lift_progress(evaluation["height_m"], dead_band_m=self.lift_dead_band_m),
            over_target=distance <= self.over_radius_m,
            near_target=tolerance(distance, self.near_bound_m, PLACE_MARGIN_M),
        )
