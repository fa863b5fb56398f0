"""``PickColoredCube-v0``: three cubes, red, green and blue; pick up the one the instruction names.

Each episode draws the target colour from the episode's generator and says it:
"Pick up the green cube." (``info["task"]``, the environment's ``task_description``).
The three 3 cm cubes start anywhere in the reachable region beside the arm's home pose
(not under it, where the overview camera cannot see them), at least 2 cm apart (so the
open jaws fit between them), with yaws in [0°, 90°).

Success: the named cube's bottom is at least 5 cm above the table while both jaws hold
it, and the other two still rest on the table (their bottoms below 5 mm).

Reward terms (on the named cube only; a held wrong cube earns nothing): ``reach`` (jaws
near it), ``grasp`` (both pads on it), ``lift`` (its height towards 5 cm while held, and
only while the other two stay on the table).

``environment_state``: each cube's position and quaternion (red, green, blue), the named
cube's position again (``target_pos``) and the gripper's position. ``info`` adds
``target_colour`` and ``target_pos``. The expert is the lift expert aimed at the named cube.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.objects import Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import (
    LIFT_HEIGHT_M,
    REACH_MARGIN_M,
    RewardWeights,
    Task,
    TaskSpec,
    lift_term,
    norm,
    position_field,
    quaternion_field,
    tolerance,
)
from gym_soarm.tasks.cube import CUBE_HALF_M
from gym_soarm.tasks.lift_cube import LiftExpert

COLOURS: tuple[str, ...] = ("red", "green", "blue")
"""The cubes' colours, in declaration order; each cube is called ``<colour>_cube``."""
CUBES: tuple[SceneObject, ...] = tuple(
    SceneObject(
        name=f"{colour}_cube",
        shape="box",
        size_m=(CUBE_HALF_M, CUBE_HALF_M, CUBE_HALF_M),
        colour=colour,
        mass_kg=0.02,
        position_m=(-0.06 + 0.06 * i, 0.35),
    )
    for i, colour in enumerate(COLOURS)
)
CUBE_NAMES: tuple[str, ...] = tuple(cube.name for cube in CUBES)

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.13, 0.13), (0.26, 0.40))
"""Where the cubes' centres start: ((x_min, x_max), (y_min, y_max)), within easy reach."""
ARM_LANE_HALF_WIDTH_M = 0.045
"""Centres keep this far from x = 0, out of the lane under the arm's home pose, so that the
overview camera, looking down past the arm, sees every cube at reset."""
CUBE_GAP_M = 0.02
"""Free space left between the footprints of any two cubes, so the open jaws fit."""
YAW_RANGE_DEG: tuple[float, float] = (0.0, 90.0)

ON_TABLE_HEIGHT_M = 0.005
"""A cube whose bottom is lower than this still rests on the table."""


def draw_beside_arm(
    rng: np.random.Generator,
    radii_m: Sequence[float],
    region_m: tuple[tuple[float, float], tuple[float, float]] = START_REGION_M,
    lane_half_width_m: float = ARM_LANE_HALF_WIDTH_M,
    keep_clear: Sequence[tuple[float, float, float]] = (),
    gap_m: float = CUBE_GAP_M,
    max_tries: int = 1000,
) -> list[tuple[float, float]]:
    """(x, y) for objects of footprint ``radii_m``, uniform in ``region_m`` outside the lane
    under the arm (``|x| < lane_half_width_m``), never overlapping.

    Args:
        rng: the episode's generator.
        radii_m: each object's footprint radius, in placing order.
        region_m: ((x_min, x_max), (y_min, y_max)) the centres lie in, symmetric about x = 0.
        lane_half_width_m: centres keep at least this far from x = 0.
        keep_clear: (x, y, radius) discs no object may overlap (pads).
        gap_m: free space left between any two footprints.
        max_tries: draws per object before giving up.

    Raises:
        ValueError: the region is not symmetric about x = 0 or leaves no room beside the lane.
        RuntimeError: an object found no free spot (the region is too crowded).
    """
    (x0, x1), (y0, y1) = region_m
    if not math.isclose(x0, -x1) or not 0.0 <= lane_half_width_m < x1:
        raise ValueError(
            f"region_m's x range must be symmetric about 0 and wider than the lane "
            f"(±{lane_half_width_m} m); got {region_m!r}."
        )
    placed: list[tuple[float, float, float]] = list(keep_clear)
    positions: list[tuple[float, float]] = []
    for radius in radii_m:
        for _ in range(max_tries):
            side = 1.0 if rng.integers(2) else -1.0
            x = side * float(rng.uniform(lane_half_width_m, x1))
            y = float(rng.uniform(y0, y1))
            if all(math.hypot(x - px, y - py) >= radius + pr + gap_m for px, py, pr in placed):
                break
        else:
            raise RuntimeError(
                f"no free spot for an object of radius {radius} m in {region_m} beside the "
                f"arm's lane after {max_tries} draws; the region is too crowded."
            )
        placed.append((x, y, radius))
        positions.append((x, y))
    return positions


def instruction_for(colour: str) -> str:
    """The instruction sentence naming the cube of ``colour``."""
    return f"Pick up the {colour} cube."


def set_cubes_down(
    physics: SoArmPhysics,
    rng: np.random.Generator,
    cubes: Sequence[SceneObject],
    positions: Sequence[tuple[float, float]],
) -> None:
    """Rest each cube on the table at its (x, y), turned by a yaw drawn from
    :data:`YAW_RANGE_DEG` (one draw per cube, in order)."""
    for cube, (x, y) in zip(cubes, positions, strict=True):
        yaw = float(rng.uniform(*YAW_RANGE_DEG))
        physics.set_object_pose(
            cube.name,
            np.array([x, y, constants.TABLE_TOP_Z_M + CUBE_HALF_M]),
            placement.yaw_quaternion(yaw),
        )


class PickColoredCubeTask(Task):
    """Pick up the cube of the episode's colour, leaving the other two on the table."""

    weights = RewardWeights({"reach": 0.2, "grasp": 0.3, "lift": 0.5})
    state_fields: ClassVar = (
        *(
            field
            for colour in COLOURS
            for field in (
                position_field(f"{colour}_cube_pos", f"{colour}_cube"),
                quaternion_field(f"{colour}_cube_quat_wxyz", f"{colour}_cube"),
            )
        ),
        position_field("target_pos", "target"),
        position_field("gripper_pos", "gripper"),
    )

    def __init__(self, spec: TaskSpec) -> None:
        super().__init__(spec)
        self.colour = COLOURS[0]

    @property
    def target(self) -> str:
        """Name of the cube the episode's instruction names (``"green_cube"``)."""
        return f"{self.colour}_cube"

    @property
    def others(self) -> tuple[str, ...]:
        """The cubes that must stay on the table."""
        return tuple(name for name in CUBE_NAMES if name != self.target)

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        choice = int(rng.integers(len(COLOURS)))
        self.colour = COLOURS[choice]
        self.instruction = self.spec.instructions[choice]
        physics.reset_to_home()
        radii = [cube.footprint_radius_m for cube in CUBES]
        positions = draw_beside_arm(rng, radii)
        set_cubes_down(physics, rng, CUBES, positions)

    def environment_state(self, physics: SoArmPhysics) -> np.ndarray:
        parts: list[np.ndarray] = []
        for name in CUBE_NAMES:
            position, quaternion = physics.object_pose(name)
            parts += [position, quaternion]
        parts += [physics.object_position(self.target), physics.gripper_position()]
        return np.concatenate(parts)

    def _others_on_table(self, physics: SoArmPhysics) -> bool:
        return all(physics.object_height(name) < ON_TABLE_HEIGHT_M for name in self.others)

    def is_success(self, physics: SoArmPhysics) -> bool:
        return (
            physics.grasped(self.target)
            and physics.object_height(self.target) >= LIFT_HEIGHT_M
            and self._others_on_table(physics)
        )

    def reward_terms(self, physics: SoArmPhysics, success: bool | None = None) -> dict[str, float]:
        if self.is_success(physics) if success is None else success:
            return dict.fromkeys(self.weights.terms, 1.0)
        if not physics.grasped(self.target):
            if any(physics.grasped(name) for name in self.others):
                return dict.fromkeys(self.weights.terms, 0.0)
            distance = norm(physics.grasp_center() - physics.object_position(self.target))
            return {"reach": tolerance(distance, 0.01, REACH_MARGIN_M), "grasp": 0.0, "lift": 0.0}
        height = lift_term(physics, self.target)
        if not self._others_on_table(physics):
            # Another cube comes up with the target: lifting it earns nothing.
            height = 0.0
        return {"reach": 1.0, "grasp": 1.0, "lift": height}

    def episode_info(self, physics: SoArmPhysics) -> dict[str, Any]:
        return {
            "target_colour": self.colour,
            "target_pos": physics.object_position(self.target),
        }


class PickColoredCubeExpert(LiftExpert):
    """The lift expert on the cube the instruction names."""

    def grasp_object(self) -> str:
        return self.env.task_logic.target


SPEC = TaskSpec(
    name="PickColoredCube-v0",
    task=PickColoredCubeTask,
    expert=PickColoredCubeExpert,
    max_episode_steps=250,
    scene=Scene(objects=CUBES),
    instructions=tuple(instruction_for(colour) for colour in COLOURS),
    summary="pick up the cube of the named colour out of three",
    default_placement="uniform",
    aliases=("pick_colored_cube",),
)
