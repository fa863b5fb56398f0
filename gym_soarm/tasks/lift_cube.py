"""``LiftCube-v0``: lift the blue cube 5 cm off the table.

Success: the cube's bottom is at least 5 cm above the table while both jaws hold it.
Reward terms: ``reach`` (jaws near the cube), ``grasp`` (both pads on it), ``lift``
(its height towards 5 cm while held).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gym_soarm.sim.objects import Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.base import LIFT_HEIGHT_M, RewardWeights, TaskSpec
from gym_soarm.tasks.cube import CUBE, CUBE_STATE_FIELDS, CubeGridTask
from gym_soarm.tasks.scripted import Phase, ScriptedExpert


class LiftTask(CubeGridTask):
    """Lift the cube 5 cm off the table, held by both jaws."""

    weights = RewardWeights({"reach": 0.2, "grasp": 0.3, "lift": 0.5})
    state_fields: ClassVar = CUBE_STATE_FIELDS

    def environment_state(self, physics: SoArmPhysics) -> np.ndarray:
        position, quaternion = physics.object_pose(self.cube)
        return np.concatenate([position, quaternion, physics.gripper_position()])

    def is_success(self, physics: SoArmPhysics) -> bool:
        return physics.grasped(self.cube) and physics.object_height(self.cube) >= LIFT_HEIGHT_M

    def reward_terms(self, physics: SoArmPhysics, success: bool | None = None) -> dict[str, float]:
        if not physics.grasped(self.cube):
            return {"reach": self._reach(physics), "grasp": 0.0, "lift": 0.0}
        height = physics.object_height(self.cube) / LIFT_HEIGHT_M
        return {"reach": 1.0, "grasp": 1.0, "lift": min(max(height, 0.0), 1.0)}


class LiftExpert(ScriptedExpert):
    """Approach, descend, close and lift the cube 2.5 cm above the 5 cm line, then hold."""

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("lift", c.lift_steps, self._begin_lift),
            Phase("hold", c.hold_steps, self._begin_hold),
        ]

    def _begin_hold(self) -> None:
        if self._holding():
            self._hold_arm()


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
)
