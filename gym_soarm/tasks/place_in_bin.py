"""``PlaceInBin-v0``: put the blue cube into the open box (the bin) on the table.

Scene: the bin, fixed to the table to the arm's right (centred at x = 0.15 m,
y = 0.30 m): a 3 mm floor plate and four 4 mm walls around an 8 x 8 cm inside, its rim
4 cm above the table; every part of it collides. And the 3 cm, 20 g blue cube, placed
uniformly at random with a random yaw in [0°, 90°) in the region the arm reaches well
(x in [-0.12, 0.12] m, y in [0.25, 0.40] m), 3 cm clear of the bin and 5 cm to either
side of x = 0, where the arm's home pose hides it from the overview camera.

Success: the whole cube lies inside the bin's inner footprint with its top below the
rim, resting on the bin (touching it), neither jaw touches it and it is at rest (speed
below 0.05 m/s).

Reward terms are stages — ``reach`` (jaws near the cube), ``grasp`` (both pads on it),
``lift`` (its height towards 5 cm while held), ``place`` (carried over the bin, then
lowered into it, then released) — and a later stage counts every earlier one as
complete, so the reward never falls as the task progresses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.arrays import norm as batch_norm
from gym_soarm.sim.kinematics import downward_rotation
from gym_soarm.sim.objects import Fixture, Scene, open_box_geoms
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, Task, TaskSpec
from gym_soarm.tasks.cube import CUBE, CUBE_HALF_M, cube_reach
from gym_soarm.tasks.open_box import OverRimExpert, OverRimStateExpert
from gym_soarm.tasks.placing import PlacementScoring
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    fixture_position_field,
    object_pose_fields,
)

BIN_POSITION_M: tuple[float, float, float] = (0.15, 0.30, 0.0)
"""Where the bin stands: the centre of its floor plate's underside, on the table."""
BIN_INNER_HALF_M = 0.04
"""Half the inside width of the bin (the inside is 8 x 8 cm)."""
BIN_WALL_M = 0.004
"""Thickness of the walls."""
BIN_FLOOR_M = 0.003
"""Thickness of the floor plate (the cube rests on it)."""
BIN_RIM_Z_M = 0.04
"""Height of the walls' top above the table."""
BIN_COLOUR = "white"
_OUTER_HALF_M = BIN_INNER_HALF_M + BIN_WALL_M


BIN = Fixture(
    name="bin",
    position_m=BIN_POSITION_M,
    geoms=open_box_geoms(BIN_INNER_HALF_M, BIN_WALL_M, BIN_FLOOR_M, BIN_RIM_Z_M, BIN_COLOUR),
    site_m=(0.0, 0.0, BIN_FLOOR_M),
)
"""The open box, fixed to the table; its site is the centre of the floor's top."""

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.12, 0.12), (0.25, 0.40))
"""Where the cube's centre starts: ((x_min, x_max), (y_min, y_max)), clear of the bin."""
BIN_CLEARANCE_M = 0.03
"""Free space kept between the cube's footprint and the bin's at the start (the jaws')."""
START_YAW_DEG: tuple[float, float] = (0.0, 90.0)
OVER_BIN_RADIUS_M = 0.02
"""A cube centre this close (horizontally) to the bin's centre counts as over the bin."""


class PlaceInBinTask(PlacementScoring, Task):
    """Put the cube into the bin, released and at rest."""

    state_fields: ClassVar = (
        *object_pose_fields(CUBE.name),
        GRIPPER_POSITION_FIELD,
        fixture_position_field("bin", BIN.name),
    )
    goal_pairs: ClassVar = (("cube_pos", "bin_pos"),)
    cube = carried = CUBE.name
    placed_key = "in_bin"
    distance_key = "bin_distance_m"
    over_radius_m = near_bound_m = OVER_BIN_RADIUS_M

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        """Home the arm and put the cube at a free spot clear of the bin, at a random yaw."""
        physics.reset_to_home()
        bin_x, bin_y, _ = BIN_POSITION_M
        keep_clear = ((bin_x, bin_y, math.hypot(_OUTER_HALF_M, _OUTER_HALF_M)),)
        ((x, y),) = placement.draw_beside_arm(
            rng,
            [CUBE.footprint_radius_m],
            START_REGION_M,
            keep_clear=keep_clear,
            gap_m=BIN_CLEARANCE_M,
        )
        yaw = float(rng.uniform(*START_YAW_DEG))
        physics.set_object_pose(
            self.cube,
            np.array([x, y, constants.TABLE_TOP_Z_M + CUBE.rest_height_m]),
            placement.yaw_quaternion(yaw),
        )

    # --- geometry of the bin -----------------------------------------------------------
    def placed(self, sim: SimArrays) -> tuple[Array, Array]:
        """In the bin: the whole cube inside the bin's inner footprint, its top below the rim."""
        xp = sim.xp
        position = sim.object_position(self.cube)
        offset = position[..., :2] - sim.fixture_position(BIN.name)[..., :2]
        reach_x, reach_y, reach_z = cube_reach(sim, self.cube)
        inside = (xp.abs(offset[..., 0]) + reach_x <= BIN_INNER_HALF_M) & (
            xp.abs(offset[..., 1]) + reach_y <= BIN_INNER_HALF_M
        )
        top = position[..., 2] + reach_z - constants.TABLE_TOP_Z_M
        return inside & (top < BIN_RIM_Z_M), batch_norm(offset)

    def settled(self, sim: SimArrays) -> Array:
        """Out of the jaws, at rest and resting on the bin."""
        return super().settled(sim) & sim.touching(self.cube, BIN.name)

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "cube_pos": sim.object_position(self.cube),
            "target_pos": sim.fixture_position(BIN.name),
        }


class PlaceInBinExpert(OverRimExpert):
    """Lift the cube, carry it over the bin above the rim, lower it in, release and rise."""

    rim_z_m = BIN_RIM_Z_M

    def place_target(self) -> np.ndarray:
        target = self.env.physics.fixture_position(BIN.name)
        target[2] += CUBE_HALF_M
        return target

    def _begin_retreat(self) -> None:
        # Slide the fixed jaw just off the cube's face (the half-open moving jaw stays clear
        # of the cube's other face), then rise out of the bin with the jaws as released.
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        closing_axis = downward_rotation(self._yaw)[:, 0]
        target = site - self.config.fixed_jaw_clearance_m * closing_axis
        target[2] = max(self.config.retreat_height_m, site[2])
        self._line_move(target, self._yaw)
        self._gripper(self._release_opening())


class PlaceInBinStateExpert(OverRimStateExpert):
    """From the state: grasp the cube, carry it over the bin above the rim, lower it in,
    let go with the jaws half open and rise."""

    rim_z_m = BIN_RIM_Z_M

    def place_target(self, name: str) -> np.ndarray:
        target = self.physics.fixture_position(BIN.name)
        target[2] += CUBE_HALF_M
        return target


SPEC = TaskSpec(
    name="PlaceInBin-v0",
    task=PlaceInBinTask,
    expert=PlaceInBinExpert,
    max_episode_steps=400,
    scene=Scene(objects=(CUBE,), fixtures=(BIN,)),
    instructions=("Pick up the blue cube and put it in the bin.",),
    summary="put the cube into the open box",
    aliases=("bin", "place_in_bin"),
    state_expert=PlaceInBinStateExpert,
)
