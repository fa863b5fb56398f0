"""``PickAndPlaceCube-v0`` (also ``SoArm-v0``): put the blue cube on the green pad.

Success: the cube's centre is within the pad's 4 cm radius, its bottom within 5 mm of
the pad's top, it is at rest and neither jaw touches it. Reward terms are stages —
``reach``, ``grasp``, ``lift``, ``place`` — and a later stage counts every earlier one
as complete, so the reward never falls as the task progresses.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays, xy_distance
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene
from gym_soarm.tasks.base import TaskSpec
from gym_soarm.tasks.cube import CUBE, CUBE_HALF_M, CUBE_STATE_FIELDS, CubeGridTask
from gym_soarm.tasks.placing import PlacementScoring
from gym_soarm.tasks.scripted import PlaceExpert
from gym_soarm.tasks.state_expert import PlaceStateExpert
from gym_soarm.tasks.state_fields import fixture_position_field

GOAL_RADIUS_M = 0.04
GOAL_TOP_Z_M = 0.001
GOAL_POSITION_M = (0.2, 0.27, 0.0)
GOAL = Fixture(
    name="goal",
    position_m=GOAL_POSITION_M,
    geoms=(
        FixtureGeom(
            "cylinder",
            (GOAL_RADIUS_M, 0.0005),
            "green",
            (0.0, 0.0, 0.0005),
            collides=False,
            emission=0.2,
        ),
    ),
    site_m=(0.0, 0.0, GOAL_TOP_Z_M),
)
"""A thin green disc on the table (visual only: the cube rests on the table beneath it)."""

PLACE_HEIGHT_TOL_M = 0.005


class PickAndPlaceTask(PlacementScoring, CubeGridTask):
    """Pick the cube up and put it down, released and at rest, on the green pad."""

    state_fields: ClassVar = (*CUBE_STATE_FIELDS, fixture_position_field("goal", GOAL.name))
    goal_pairs: ClassVar = (("cube_pos", "goal_pos"),)
    carried = CUBE.name
    placed_key = "on_goal"
    distance_key = "goal_distance_m"
    over_radius_m = GOAL_RADIUS_M
    near_bound_m = GOAL_RADIUS_M / 2

    def placed(self, sim: SimArrays) -> tuple[Array, Array]:
        """On the pad: the cube's centre within its radius and its bottom on the pad's top."""
        distance = xy_distance(sim.object_position(self.cube), sim.fixture_position(GOAL.name))
        on_goal = (distance <= GOAL_RADIUS_M) & (
            sim.xp.abs(sim.object_height(self.cube) - GOAL_TOP_Z_M) <= PLACE_HEIGHT_TOL_M
        )
        return on_goal, distance


class PickAndPlaceExpert(PlaceExpert):
    """Lift the cube, carry it over the pad, lower it, release it and move away."""

    def place_target(self) -> np.ndarray:
        goal = self.env.physics.fixture_position(GOAL.name)
        return np.array([goal[0], goal[1], constants.TABLE_TOP_Z_M + CUBE_HALF_M])


class PickAndPlaceStateExpert(PlaceStateExpert):
    """From the state: grasp the cube, carry it over the pad, lower it, let go, rise."""

    def place_target(self, name: str) -> np.ndarray:
        goal = self.physics.fixture_position(GOAL.name)
        return np.array([goal[0], goal[1], constants.TABLE_TOP_Z_M + CUBE_HALF_M])


SPEC = TaskSpec(
    name="PickAndPlaceCube-v0",
    task=PickAndPlaceTask,
    expert=PickAndPlaceExpert,
    max_episode_steps=400,
    scene=Scene(objects=(CUBE,), fixtures=(GOAL,)),
    instructions=("Pick up the blue cube and place it on the green pad.",),
    summary="pick the cube up and place it on the green pad",
    default_placement="grid",
    aliases=("pick_and_place",),
    extra_env_ids=("SoArm-v0", "gym_soarm/SoArm-v0"),
    state_expert=PickAndPlaceStateExpert,
)
