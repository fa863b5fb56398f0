"""``LiftCube-v0``: lift the blue cube 5 cm off the table.

Success: the cube's bottom is at least 5 cm above the table while both jaws hold it.
Reward terms: ``reach`` (jaws near the cube), ``grasp`` (both pads on it), ``lift``
(its height towards 5 cm while held).
"""

from __future__ import annotations

from typing import ClassVar

from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.objects import Scene
from gym_soarm.tasks.base import Evaluation, RewardWeights, TaskSpec
from gym_soarm.tasks.cube import CUBE, CUBE_STATE_FIELDS, CubeGridTask
from gym_soarm.tasks.rewards import LIFT_HEIGHT_M, lift_progress, pick_progress, pick_terms
from gym_soarm.tasks.scripted import LiftExpert
from gym_soarm.tasks.state_expert import LiftStateExpert


class LiftTask(CubeGridTask):
    """Lift the cube 5 cm off the table, held by both jaws."""

    weights = RewardWeights({"reach": 0.2, "grasp": 0.3, "lift": 0.5})
    state_fields: ClassVar = CUBE_STATE_FIELDS

    def evaluate(self, sim: SimArrays) -> Evaluation:
        progress = pick_progress(sim, self.cube)
        return {
            "success": progress["grasped"] & (progress["height_m"] >= LIFT_HEIGHT_M),
            **progress,
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        return pick_terms(
            grasped=evaluation["grasped"],
            reach_distance_m=evaluation["reach_distance_m"],
            lift=lift_progress(evaluation["height_m"]),
        )


SPEC = TaskSpec(
    name="LiftCube-v0",
    task=LiftTask,
    expert=LiftExpert,
    max_episode_steps=250,
    scene=Scene(objects=(CUBE,)),
    instructions=("Pick up the blue cube and lift it 5 cm above the table.",),
    summary="lift the cube 5 cm above the table",
    default_placement="grid",
    aliases=("lift",),
    state_expert=LiftStateExpert,
)
