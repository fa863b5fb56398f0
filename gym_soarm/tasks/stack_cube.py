"""``StackCube-v0``: put the red cube on top of the blue cube.

Scene: a red and a blue 3 cm, 20 g cube, placed uniformly at random (never overlapping,
with room for the jaws between them) in the region the arm reaches well — x in
[-0.11, 0.11] m, y in [0.27, 0.40] m, at least 11.5 cm from the shoulder pan axis and
5 cm to either side of x = 0, where the arm's home pose hides them from the overview
camera — each with a random yaw in [0°, 90°).

Success: the red cube rests on the blue one — its centre within 1.5 cm horizontally of
the blue cube's centre, its bottom within 5 mm of the blue cube's top and touching it —
neither jaw touches either cube, and both are at rest (speeds below 0.05 m/s).

Reward terms are stages — ``reach`` (jaws near the red cube), ``grasp`` (both pads on
it), ``lift`` (its height towards 5 cm while held), ``place`` (carried over the blue
cube, then set on it, then released) — and a later stage counts every earlier one as
complete, so the reward never falls as the task progresses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays, xy_distance
from gym_soarm.sim.objects import Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, Task, TaskSpec
from gym_soarm.tasks.cube import CUBE_HALF_M, CUBE_SIZE_M, coloured_cubes
from gym_soarm.tasks.placing import PlacementScoring
from gym_soarm.tasks.rewards import RESTING_SPEED_M_S
from gym_soarm.tasks.scripted import PlaceExpert
from gym_soarm.tasks.state_expert import PlaceStateExpert
from gym_soarm.tasks.state_fields import GRIPPER_POSITION_FIELD, object_pose_fields

RED_CUBE, BLUE_CUBE = coloured_cubes(("red", "blue"), -0.05, 0.10, 0.33)
"""The cube to stack (red) and the one to stack it on (blue): 3 cm, 20 g each."""

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.11, 0.11), (0.27, 0.40))
"""Where the cubes' centres start: ((x_min, x_max), (y_min, y_max)), well within reach."""
START_GAP_M = 0.035
"""Free space between the two cubes' footprints at the start: room for an open jaw."""
MIN_PAN_DISTANCE_M = 0.115
"""Closest a cube's centre starts to the pan axis: nearer, the arm cannot hold the jaws
vertical as high as a cube carried over the other one, and the stack would tilt."""
START_YAW_DEG: tuple[float, float] = (0.0, 90.0)
"""Range of the cubes' start yaws (a cube looks the same every quarter turn)."""

STACK_RADIUS_M = 0.015
"""How far (horizontally) the red centre may lie from the blue centre on a stack."""
STACK_HEIGHT_TOL_M = 0.005
"""How far the red cube's bottom may lie from the blue cube's top on a stack."""


class StackCubeTask(PlacementScoring, Task):
    """Stack the red cube on the blue cube, released and at rest."""

    state_fields: ClassVar = (
        *object_pose_fields(RED_CUBE.name),
        *object_pose_fields(BLUE_CUBE.name),
        GRIPPER_POSITION_FIELD,
    )
    goal_pairs: ClassVar = (("red_cube_pos", "blue_cube_pos"),)
    top = carried = RED_CUBE.name
    bottom = BLUE_CUBE.name
    placed_key = "on_blue"
    distance_key = "offset_m"
    over_radius_m = near_bound_m = STACK_RADIUS_M

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        """Home the arm and drop both cubes at free spots with random yaws."""
        physics.reset_to_home()
        items = (RED_CUBE, BLUE_CUBE)
        # A disc round the pan axis that keeps every centre MIN_PAN_DISTANCE_M from it (the
        # draw keeps footprint + disc radius + gap between centre and axis).
        footprint = max(item.footprint_radius_m for item in items)
        near_arm = (*constants.PAN_AXIS_XY_M, MIN_PAN_DISTANCE_M - footprint - START_GAP_M)
        spots = placement.draw_beside_arm(
            rng,
            [item.footprint_radius_m for item in items],
            START_REGION_M,
            keep_clear=(near_arm,),
            gap_m=START_GAP_M,
        )
        for item, (x, y) in zip(items, spots, strict=True):
            yaw = float(rng.uniform(*START_YAW_DEG))
            physics.set_object_pose(
                item.name,
                np.array([x, y, constants.TABLE_TOP_Z_M + item.rest_height_m]),
                placement.yaw_quaternion(yaw),
            )

    # --- geometry of the stack ---------------------------------------------------------
    def placed(self, sim: SimArrays) -> tuple[Array, Array]:
        """On the blue cube: centred within :data:`STACK_RADIUS_M` of it, the red cube's
        bottom on its top (held or not)."""
        red, blue = sim.object_position(self.top), sim.object_position(self.bottom)
        offset = xy_distance(red, blue)
        blue_top = blue[..., 2] + CUBE_HALF_M
        red_bottom = sim.object_height(self.top) + constants.TABLE_TOP_Z_M
        on_blue = (offset <= STACK_RADIUS_M) & (
            sim.xp.abs(red_bottom - blue_top) <= STACK_HEIGHT_TOL_M
        )
        return on_blue, offset

    def settled(self, sim: SimArrays) -> Array:
        """Both cubes out of the jaws and at rest, the red one touching the blue one."""
        return (
            super().settled(sim)
            & sim.touching(self.top, self.bottom)
            & ~sim.touched_by_jaws(self.bottom)
            & (sim.object_speed(self.bottom) < RESTING_SPEED_M_S)
        )

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        blue = sim.object_position(self.bottom)
        return {
            "red_cube_pos": sim.object_position(self.top),
            "blue_cube_pos": blue,
            # Where the red cube's centre rests when stacked: on top of the blue cube.
            "target_pos": sim.xp.concat([blue[..., :2], blue[..., 2:] + CUBE_SIZE_M], axis=-1),
        }


class StackCubeExpert(PlaceExpert):
    """Grasp the red cube, carry it over the blue one, turn it square to it, set it down."""

    def grasp_object(self) -> str:
        return RED_CUBE.name

    def place_target(self) -> np.ndarray:
        target = self.env.physics.object_position(BLUE_CUBE.name)
        target[2] += CUBE_SIZE_M
        return target

    def _begin_lower(self) -> None:
        if not self._holding():
            return
        # Turn the held cube (by at most 45°) so its faces line up with the blue cube's:
        # the jaw tips, just above the red cube's bottom, then stay clear of blue corners.
        physics = self.env.physics
        turn = math.remainder(
            physics.object_yaw(BLUE_CUBE.name) - physics.object_yaw(RED_CUBE.name),
            math.pi / 2,
        )
        target = self.place_target()
        target[2] += self.config.place_clearance_m
        # The held cube's centre turns with the jaws about the site's vertical axis.
        self._held_offset = physics.object_position(RED_CUBE.name) - physics.grasp_center()
        cos, sin = math.cos(turn), math.sin(turn)
        dx, dy, dz = self._held_offset.tolist()
        offset = np.array([cos * dx - sin * dy, sin * dx + cos * dy, dz])
        self._line_move(target - offset, self._yaw + turn)

    def _begin_retreat(self) -> None:
        super()._begin_retreat()
        # Keep the jaws open while moving away (the base retreat leaves the gripper's
        # interpolation from the release's closed start, which would close them again).
        self._gripper(self.config.gripper_open_rad)


class StackCubeStateExpert(PlaceStateExpert):
    """From the state: grasp the red cube, carry it over the blue one, turn it square to
    it while lowering, let go and rise."""

    def grasp_object(self) -> str:
        return RED_CUBE.name

    def place_target(self, name: str) -> np.ndarray:
        target = self.physics.object_position(BLUE_CUBE.name)
        target[2] += CUBE_SIZE_M
        return target

    def place_yaw(self, name: str, yaw: float) -> float:
        physics = self.physics
        turn = math.remainder(
            physics.object_yaw(BLUE_CUBE.name) - physics.object_yaw(RED_CUBE.name), math.pi / 2
        )
        return yaw + turn


SPEC = TaskSpec(
    name="StackCube-v0",
    task=StackCubeTask,
    expert=StackCubeExpert,
    max_episode_steps=400,
    scene=Scene(objects=(RED_CUBE, BLUE_CUBE)),
    instructions=("Stack the red cube on top of the blue cube.",),
    summary="stack the red cube on the blue cube",
    aliases=("stack",),
    state_expert=StackCubeStateExpert,
)
