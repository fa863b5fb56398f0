"""``ReachTarget-v0``: bring the jaws to a red ball floating above the table.

The scene holds no free object, only the target: a red ball 3 cm across (the cube's
size, so that the 320 x 240 cameras see it) that is a visual marker: it never
collides, the jaws pass through it. At every reset it moves to a new spot drawn
uniformly in the box x in [-0.10, 0.10] m, y in [0.31, 0.43] m and centre height
z in [0.025, 0.12] m, which the jaws reach pointing down (nearer the shoulder, within
12 cm of its pan axis, they cannot reach high targets). The target is a fixture, a
static body of the compiled model: the reset writes its body position into this
environment's own copy of the model (``physics.model.body_pos``), so nothing is
recompiled, and every reset sets it, so a seed always gives the same episode.

Success: the ``grasp_center`` site (where a held object's centre sits, between the
jaws) is within 1 cm of the ball's centre; the episode ends there.
Reward term: ``reach``, 1 within that centimetre, falling smoothly with the distance
beyond it (to 0.1 at 11 cm).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.arrays import norm as batch_norm
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.rewards import REACH_MARGIN_M, tolerance
from gym_soarm.tasks.scripted import NoGraspExpert, Phase
from gym_soarm.tasks.state_expert import Move, StateExpert
from gym_soarm.tasks.state_fields import GRIPPER_POSITION_FIELD, fixture_position_field

TARGET_RADIUS_M = 0.015
"""The ball is as wide as the cube: smaller, it is a few pixels of a 320 x 240 camera."""
SUCCESS_DISTANCE_M = 0.01
"""The jaws' centre must come this close to the target's centre."""
TARGET_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.10, 0.10), (0.31, 0.43))
"""Where the target's (x, y) is drawn: 12 to 26 cm from the shoulder pan axis (at
y = 0.189 m), where the jaws reach every height of :data:`TARGET_HEIGHT_M` pointing down."""
TARGET_HEIGHT_M: tuple[float, float] = (0.025, 0.12)
"""The range the target's centre height (above the table top) is drawn from."""
TARGET_DEFAULT_M = (0.0, 0.35, 0.07)
"""Where the target sits in the compiled model, before the first reset moves it."""

TARGET = Fixture(
    name="target",
    position_m=TARGET_DEFAULT_M,
    geoms=(FixtureGeom("sphere", (TARGET_RADIUS_M,), "red", collides=False, emission=0.3),),
)
"""A red ball, visual only; its site (the point reached for) is its centre."""


class ReachTask(Task):
    """Touch the floating red target with the centre of the jaws."""

    weights = RewardWeights({"reach": 1.0})
    state_fields: ClassVar = (fixture_position_field("target", TARGET.name), GRIPPER_POSITION_FIELD)

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()
        (x0, x1), (y0, y1) = TARGET_REGION_M
        z0, z1 = TARGET_HEIGHT_M
        physics.set_fixture_position(TARGET.name, rng.uniform((x0, y0, z0), (x1, y1, z1)))

    def evaluate(self, sim: SimArrays) -> Evaluation:
        distance = batch_norm(sim.grasp_center() - sim.fixture_position(TARGET.name))
        return {"success": distance <= SUCCESS_DISTANCE_M, "target_distance_m": distance}

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        # 1 exactly when successful: the tolerance is 1 within the success distance.
        distance = evaluation["target_distance_m"]
        return {"reach": tolerance(distance, SUCCESS_DISTANCE_M, REACH_MARGIN_M)}

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "target_pos": sim.fixture_position(TARGET.name),
            "target_distance": evaluation["target_distance_m"],
        }


NEAR_M = 0.04
"""Within this distance of the target the state expert moves the jaws in a straight line."""

HOVER_ABOVE_M = 0.04
"""The expert first comes to rest this far straight above the target."""


class ReachExpert(NoGraspExpert):
    """Swing the closed jaws (pointing down) over the target, lower them onto it, and hold.

    The approach is a joint move to a hover above the target and the reach a straight
    line of ``grasp_center`` down to the target's centre.
    """

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("approach", c.approach_steps, self._begin_hover),
            Phase("reach", c.descend_steps, self._begin_reach),
            Phase("hold", c.hold_steps, self._hold_arm),
        ]

    def _target(self) -> np.ndarray:
        return self.env.physics.fixture_position(TARGET.name)

    def _natural_yaw(self, position: np.ndarray) -> float:
        """The jaws' yaw with the wrist unrolled, the arm turned towards ``position``."""
        _, rotation = self._kinematics.site_pose(self._seed_towards(position))
        return math.atan2(rotation[1, 0], rotation[0, 0])

    def _begin_hover(self) -> None:
        hover = self._target()
        hover[2] += HOVER_ABOVE_M
        self._swing_to(hover, self._natural_yaw(hover))

    def _begin_reach(self) -> None:
        self._line_move(self._target(), self._yaw)


class ReachStateExpert(StateExpert):
    """From the state: swing the closed jaws towards the target, then a straight line onto
    it. One attractor, no gate to hit: within a few centimetres every state is told to
    go straight at the target, which a learner imitates easily."""

    def decide(self, commanded: np.ndarray) -> Move:
        target = self.physics.fixture_position(TARGET.name)
        site, yaw = self.commanded_site(commanded)
        closed = self.config.gripper_closed_rad
        if float(np.linalg.norm(site - target)) <= NEAR_M:
            return Move("line", target, yaw, closed, speed_m=0.005, stage="reach")
        _, rotation = self._kinematics.site_pose(self.seed_towards(target))
        natural = math.atan2(rotation[1, 0], rotation[0, 0])
        return Move("joint", target, natural, closed, stage="approach")


SPEC = TaskSpec(
    name="ReachTarget-v0",
    task=ReachTask,
    expert=ReachExpert,
    max_episode_steps=120,
    scene=Scene(fixtures=(TARGET,)),
    instructions=("Move the gripper to the red ball.",),
    summary="move the jaws' centre to a red ball above the table",
    default_placement="uniform",
    aliases=("reach",),
    state_expert=ReachStateExpert,
)
