"""``PutCubesInBox-v0``: put all four cubes in the green box (LeRobot's tabletop task).

The task of Hugging Face's SO-101 tabletop simulation, with its instruction "Put all the
cubes in the green box.": four 3 cm, 20 g cubes (red, blue, yellow and purple) start
anywhere in the reachable region on the table, at least 2.5 cm apart and 2 cm clear of the box,
out of the lane under the arm's home pose, with yaws in [0°, 90°). The green box is open
(a 3 mm floor and four 4 mm walls round a 13 x 13 cm inside, its rim 2.5 cm above the
table) and stands to the arm's right; each reset moves it by up to 1.5 cm across and
2 cm along the table, and moves the front camera by up to 1 cm along each axis (the
seeded offsets of the cubes, the box and the front camera).

A cube is *in the box* when its whole footprint lies inside the box's inner walls and its
centre is below the rim. Success: all four in the box, released (neither jaw touches
any of them).

Reward terms: ``in_box``, the fraction of the cubes in the box (0, 0.25, ... 1; weight
0.95), and ``released``, 1 once all four are in and out of the jaws (weight 0.05), so
the reward stays under 1 until success, whose step pays 1 plus 1 for every step left as
every task's does. The preset ``gym_soarm/SO101Tabletop-v0`` pays the plain fraction, as
LeRobot's simulation does. ``info["cubes_in_box"]`` counts them.

``environment_state``: each cube's position and quaternion, the box's position and the
gripper's position.

The state expert puts the cubes in, one at a time in the order above, each on its own
quarter of the box floor.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.arrays import namespace as sim_namespace
from gym_soarm.sim.objects import Fixture, Scene, SceneObject, open_box_geoms
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.cube import CUBE_HALF_M, coloured_cubes, cube_reach
from gym_soarm.tasks.open_box import OverRimExpert, OverRimStateExpert
from gym_soarm.tasks.scripted import OneAfterAnother
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    fixture_position_field,
    object_pose_fields,
)

INSTRUCTION = "Put all the cubes in the green box."
COLOURS: tuple[str, ...] = ("red", "blue", "yellow", "purple")
"""The cubes' colours, in the expert's order: cube ``<colour>_cube``."""
BOX_POSITION_M: tuple[float, float, float] = (0.15, 0.30, 0.0)
"""Where the box stands before its offset: the centre of its floor plate's underside."""
BOX_OFFSET_M: tuple[float, float] = (0.015, 0.02)
"""The largest offset of the box drawn at a reset, across (x) and along (y) the table."""
CAMERA_OFFSET_M = 0.01
"""The largest offset of the front camera drawn at a reset, along each axis."""
BOX_INNER_HALF_M = 0.065
BOX_WALL_M = 0.004
BOX_FLOOR_M = 0.003
BOX_RIM_Z_M = 0.025
BOX_COLOUR = "green"
_OUTER_HALF_M = BOX_INNER_HALF_M + BOX_WALL_M
SLOT_OFFSET_M = 0.03
"""The expert's drop points: the box centre +- this along x and y (one quarter a cube)."""

CUBES: tuple[SceneObject, ...] = coloured_cubes(COLOURS, -0.12, 0.06, 0.30)


BOX = Fixture(
    name="box",
    position_m=BOX_POSITION_M,
    geoms=open_box_geoms(BOX_INNER_HALF_M, BOX_WALL_M, BOX_FLOOR_M, BOX_RIM_Z_M, BOX_COLOUR),
    site_m=(0.0, 0.0, BOX_FLOOR_M),
)
"""The open green box; its site is the centre of the floor's top."""

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.17, 0.17), (0.25, 0.40))
"""Where the cubes' centres start: ((x_min, x_max), (y_min, y_max)), clear of the box."""
ARM_LANE_HALF_WIDTH_M = 0.045
CUBE_GAP_M = 0.025
BOX_CLEARANCE_M = 0.02
YAW_RANGE_DEG: tuple[float, float] = (0.0, 90.0)


def cube_name(colour: str) -> str:
    """``"red"`` -> ``"red_cube"``."""
    return f"{colour}_cube"


SLOTS: tuple[tuple[float, float], ...] = ((1, -1), (1, 1), (-1, -1), (-1, 1))
"""The quarter of the box floor of each cube, in :data:`COLOURS` order: the far (+x) half
first, so that the jaws, leaving the box towards the cubes still outside (on its -x
side), never sweep over a cube already in."""


def slot_of(name: str) -> tuple[float, float]:
    """The (x, y) offset from the box's centre where the expert drops cube ``name``."""
    sx, sy = SLOTS[[cube_name(c) for c in COLOURS].index(name)]
    return (SLOT_OFFSET_M * sx, SLOT_OFFSET_M * sy)


class PutCubesInBoxTask(Task):
    """Put all four cubes in the box; reward the fraction in it."""

    weights = RewardWeights({"in_box": 0.95, "released": 0.05})
    state_fields: ClassVar = (
        *(field for colour in COLOURS for field in object_pose_fields(cube_name(colour))),
        fixture_position_field("box", BOX.name),
        GRIPPER_POSITION_FIELD,
    )
    goal_pairs: ClassVar = tuple((f"{c}_cube_pos", "box_pos") for c in COLOURS)

    def __init__(self, spec: TaskSpec) -> None:
        super().__init__(spec)
        self._nominal_camera: np.ndarray | None = None

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        """Home the arm, move the box and the front camera, then set the cubes down."""
        physics.reset_to_home()
        x, y, z = BOX_POSITION_M
        box = np.array(
            [
                x + rng.uniform(-BOX_OFFSET_M[0], BOX_OFFSET_M[0]),
                y + rng.uniform(-BOX_OFFSET_M[1], BOX_OFFSET_M[1]),
                z,
            ]
        )
        physics.set_fixture_position(BOX.name, box)
        model = physics.model.ptr
        camera = physics.model.name2id("front_camera", "camera")
        if self._nominal_camera is None:  # the scene's own pose, before any offset
            self._nominal_camera = model.cam_pos[camera].copy()
        offset = rng.uniform(-CAMERA_OFFSET_M, CAMERA_OFFSET_M, 3)
        model.cam_pos[camera] = self._nominal_camera + offset
        keep_clear = ((box[0], box[1], math.hypot(_OUTER_HALF_M, _OUTER_HALF_M) + BOX_CLEARANCE_M),)
        positions = placement.draw_beside_arm(
            rng,
            [cube.footprint_radius_m for cube in CUBES],
            START_REGION_M,
            ARM_LANE_HALF_WIDTH_M,
            keep_clear=keep_clear,
            gap_m=CUBE_GAP_M,
        )
        placement.set_down(physics, rng, CUBES, positions, YAW_RANGE_DEG)

    def _in_box(self, sim: SimArrays, name: str) -> Array:
        """Cube ``name`` lies inside the inner walls, its centre below the rim."""
        xp = sim.xp
        offset = sim.object_position(name)[..., :2] - sim.fixture_position(BOX.name)[..., :2]
        reach_x, reach_y, _ = cube_reach(sim, name)
        inside = (xp.abs(offset[..., 0]) + reach_x <= BOX_INNER_HALF_M) & (
            xp.abs(offset[..., 1]) + reach_y <= BOX_INNER_HALF_M
        )
        height = sim.object_position(name)[..., 2] - constants.TABLE_TOP_Z_M
        return inside & (height < BOX_RIM_Z_M)

    def evaluate(self, sim: SimArrays) -> Evaluation:
        """``<colour>_in_box`` per cube and ``cubes_in_box``; success when all four are,
        out of the jaws."""
        xp = sim.xp
        flags = {colour: self._in_box(sim, cube_name(colour)) for colour in COLOURS}
        count = sum(xp.astype(flag, xp.int64) for flag in flags.values())
        success = flags[COLOURS[0]]
        for colour in COLOURS[1:]:
            success = success & flags[colour]
        for colour in COLOURS:
            success = success & ~sim.touched_by_jaws(cube_name(colour))
        return {
            "success": success,
            "cubes_in_box": count,
            **{f"{colour}_in_box": flag for colour, flag in flags.items()},
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        xp = sim_namespace(evaluation["success"])
        fraction = evaluation["cubes_in_box"] / len(COLOURS)
        return {"in_box": fraction, "released": xp.astype(evaluation["success"], fraction.dtype)}

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "cubes_in_box": evaluation["cubes_in_box"],
            **{f"{colour}_cube_pos": sim.object_position(cube_name(colour)) for colour in COLOURS},
            "box_pos": sim.fixture_position(BOX.name),
        }

    def outside(self, physics: SoArmPhysics) -> tuple[str, ...]:
        """The cubes not yet put in the box (outside it, or in it but still in the jaws),
        in the expert's order."""
        sim = self.arrays(physics)
        evaluation = self.evaluate(sim)
        return tuple(
            cube_name(c)
            for c in COLOURS
            if not bool(evaluation[f"{c}_in_box"]) or bool(sim.touched_by_jaws(cube_name(c)))
        )


def _drop_point(physics: SoArmPhysics, name: str) -> np.ndarray:
    """Where cube ``name``'s centre rests on its quarter of the box floor."""
    box = physics.fixture_position(BOX.name)
    dx, dy = slot_of(name)
    return np.array([box[0] + dx, box[1] + dy, box[2] + CUBE_HALF_M])


class PutCubesInBoxExpert(OneAfterAnother, OverRimExpert):
    """The timed script: each cube outside the box in turn, picked and dropped on its
    quarter of the box floor; a ``next`` phase looks at the table after each retreat."""

    rim_z_m = BOX_RIM_Z_M
    objects = tuple(cube_name(colour) for colour in COLOURS)

    def remaining(self) -> tuple[str, ...]:
        return self.env.task_logic.outside(self.env.physics)

    def place_target(self) -> np.ndarray:
        return _drop_point(self.env.physics, self._current)


class PutCubesInBoxStateExpert(OverRimStateExpert):
    """From the state: the first cube outside the box is picked, carried over the rim
    and let go on its own quarter of the floor."""

    rim_z_m = BOX_RIM_Z_M

    def grasp_object(self) -> str:
        outside = self.env.task_logic.outside(self.physics)
        return outside[0] if outside else cube_name(COLOURS[-1])

    def place_target(self, name: str) -> np.ndarray:
        return _drop_point(self.physics, name)


SPEC = TaskSpec(
    name="PutCubesInBox-v0",
    task=PutCubesInBoxTask,
    expert=PutCubesInBoxExpert,
    max_episode_steps=1500,
    scene=Scene(objects=CUBES, fixtures=(BOX,)),
    instructions=(INSTRUCTION,),
    summary="put all four cubes in the green box (LeRobot's tabletop task)",
    default_placement="uniform",
    aliases=("cubes_in_box", "tabletop"),
    state_expert=PutCubesInBoxStateExpert,
)
