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

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from gym_soarm.sim.arrays import Array, SimArrays, per_env
from gym_soarm.sim.arrays import namespace as sim_namespace
from gym_soarm.sim.objects import Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.cube import coloured_cubes
from gym_soarm.tasks.rewards import LIFT_HEIGHT_M, lift_progress, pick_terms, reach_distance
from gym_soarm.tasks.scripted import LiftExpert
from gym_soarm.tasks.state_expert import LiftStateExpert
from gym_soarm.tasks.state_fields import GRIPPER_POSITION_FIELD, object_pose_fields, position_field

COLOURS: tuple[str, ...] = ("red", "green", "blue")
"""The cubes' colours, in declaration order; each cube is called ``<colour>_cube``."""
CUBES: tuple[SceneObject, ...] = coloured_cubes(COLOURS, -0.06, 0.06, 0.35)
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


def instruction_for(colour: str) -> str:
    """The instruction sentence naming the cube of ``colour``."""
    return f"Pick up the {colour} cube."


def _of_target(sim: SimArrays, values: list[Array]) -> Array:
    """Each environment's value of its target cube, out of one value per cube (in
    :data:`CUBE_NAMES` order), ``(n,)`` or ``(n, k)`` each."""
    choice = sim.episode["target"]
    picked = values[-1]
    for k in range(len(values) - 2, -1, -1):
        chosen = choice == k
        picked = sim.xp.where(
            chosen[..., None] if picked.ndim > chosen.ndim else chosen, values[k], picked
        )
    return picked


class PickColoredCubeTask(Task):
    """Pick up the cube of the episode's colour, leaving the other two on the table."""

    weights = RewardWeights({"reach": 0.2, "grasp": 0.3, "lift": 0.5})
    state_fields: ClassVar = (
        *(field for name in CUBE_NAMES for field in object_pose_fields(name)),
        position_field(
            "target_pos",
            "target",
            lambda sim, task: _of_target(sim, [sim.object_position(n) for n in CUBE_NAMES]),
        ),
        GRIPPER_POSITION_FIELD,
    )

    episode_shapes: ClassVar = MappingProxyType({"target": ()})
    """The index of the episode's colour in :data:`COLOURS`."""

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
        self.episode["target"][0] = choice
        self.instruction = self.spec.instructions[choice]
        physics.reset_to_home()
        radii = [cube.footprint_radius_m for cube in CUBES]
        positions = placement.draw_beside_arm(
            rng, radii, START_REGION_M, ARM_LANE_HALF_WIDTH_M, gap_m=CUBE_GAP_M, by_side=True
        )
        placement.set_down(physics, rng, CUBES, positions, YAW_RANGE_DEG)

    def evaluate(self, sim: SimArrays) -> Evaluation:
        xp = sim.xp
        choice = sim.episode["target"]
        grasped = [sim.grasped(name) for name in CUBE_NAMES]
        heights = [sim.object_height(name) for name in CUBE_NAMES]
        reach = [reach_distance(sim, name) for name in CUBE_NAMES]
        others_on_table = xp.ones_like(grasped[0])
        other_grasped = xp.zeros_like(grasped[0])
        for k in range(len(CUBE_NAMES)):
            other = choice != k
            others_on_table = others_on_table & (~other | (heights[k] < ON_TABLE_HEIGHT_M))
            other_grasped = other_grasped | (other & grasped[k])
        target_grasped = _of_target(sim, grasped)
        height = _of_target(sim, heights)
        return {
            "success": target_grasped & (height >= LIFT_HEIGHT_M) & others_on_table,
            "grasped": target_grasped,
            "other_grasped": other_grasped,
            "others_on_table": others_on_table,
            "height_m": height,
            "reach_distance_m": _of_target(sim, reach),
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        xp = sim_namespace(evaluation["height_m"])
        # Another cube coming up with the target: lifting it earns nothing.
        lift = xp.where(evaluation["others_on_table"], lift_progress(evaluation["height_m"]), 0.0)
        terms = pick_terms(
            grasped=evaluation["grasped"],
            reach_distance_m=evaluation["reach_distance_m"],
            lift=lift,
        )
        # A held wrong cube earns nothing.
        wrong = ~evaluation["grasped"] & evaluation["other_grasped"]
        return {name: xp.where(wrong, 0.0, value) for name, value in terms.items()}

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "target_colour": per_env(sim.episode["target"], lambda c: COLOURS[int(c)]),
            "target_pos": _of_target(sim, [sim.object_position(n) for n in CUBE_NAMES]),
        }


class PickColoredCubeExpert(LiftExpert):
    """The lift expert on the cube the instruction names."""

    def grasp_object(self) -> str:
        return self.env.task_logic.target


class PickColoredCubeStateExpert(LiftStateExpert):
    """From the state: the lift on the cube the instruction names."""

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
    state_expert=PickColoredCubeStateExpert,
)
