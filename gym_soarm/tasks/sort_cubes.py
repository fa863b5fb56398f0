"""``SortCubes-v0``: put the red, green and blue cubes on the pads of their colours.

Three 3 cm cubes, red, green and blue, start anywhere in the reachable region between
the pads, beside the arm's home pose (not under it, where the overview camera cannot see
them), at least 2 cm apart, with yaws in [0°, 90°). Three thin pads of the same colours
lie on the table, fixed: red on the left at (-0.20, 0.27), blue on the right at
(0.20, 0.27) and green at the back left at (-0.10, 0.44), each 4 cm in radius (visual
only: a cube rests on the table beneath its pad).

Success: every cube's centre is within its own pad's radius, its bottom within 5 mm of
the pad's top, neither jaw touches it and it is at rest.

Reward terms, each in [0, 1] and never falling as the task progresses:

* ``red_sorted``, ``green_sorted``, ``blue_sorted``: 1 while that cube lies on its pad,
  out of the jaws.
* ``reach``, ``grasp``, ``lift``, ``place``: the pick-and-place stages of the cube being
  worked on, shared with the cubes already sorted: each stage term is (sorted cubes +
  this cube's stage) / cubes, so a sorted cube counts every stage as complete and moving
  on to the next cube loses nothing. The cube worked on is the unsorted one furthest
  along (held, or on its pad), else the first unsorted one in the order red, green, blue;
  ``reach`` measures the jaws' horizontal distance to it, and their height only beyond
  10 cm above it.

``environment_state``: each cube's position and quaternion, each pad's position and the
gripper's position. ``info`` adds ``cubes_sorted`` and each ``<colour>_cube_pos``.

The expert sorts the cubes in that order: one pick-and-place cycle each, with the jaws
rising straight up, open, after each release.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import (
    GRIPPER_POSITION_FIELD,
    Evaluation,
    RewardWeights,
    Task,
    TaskSpec,
    fixture_position_field,
    object_pose_fields,
)
from gym_soarm.tasks.cube import CUBE_HALF_M
from gym_soarm.tasks.rewards import (
    PLACE_MARGIN_M,
    RESTING_SPEED_M_S,
    lift_progress,
    pick_and_place_terms,
    tolerance,
)
from gym_soarm.tasks.scripted import DEFAULT_CONFIG, ExpertConfig, Phase, PlaceExpert
from gym_soarm.tasks.state_expert import PlaceStateExpert

COLOURS: tuple[str, ...] = ("red", "green", "blue")
"""The cubes' and pads' colours, in sorting order: ``<colour>_cube`` goes on ``<colour>_pad``."""
PAD_POSITIONS_M: dict[str, tuple[float, float, float]] = {
    "red": (-0.20, 0.27, 0.0),
    "green": (-0.10, 0.44, 0.0),
    "blue": (0.20, 0.27, 0.0),
}
PAD_RADIUS_M = 0.04
PAD_TOP_Z_M = 0.001

CUBES: tuple[SceneObject, ...] = tuple(
    SceneObject(
        name=f"{colour}_cube",
        shape="box",
        size_m=(CUBE_HALF_M, CUBE_HALF_M, CUBE_HALF_M),
        colour=colour,
        mass_kg=0.02,
        position_m=(-0.08 + 0.08 * i, 0.30),
    )
    for i, colour in enumerate(COLOURS)
)
PADS: tuple[Fixture, ...] = tuple(
    Fixture(
        name=f"{colour}_pad",
        position_m=PAD_POSITIONS_M[colour],
        geoms=(
            FixtureGeom(
                "cylinder",
                (PAD_RADIUS_M, 0.0005),
                colour,
                (0.0, 0.0, 0.0005),
                collides=False,
                emission=0.2,
            ),
        ),
        site_m=(0.0, 0.0, PAD_TOP_Z_M),
    )
    for colour in COLOURS
)
"""Thin discs on the table, one per colour (visual only)."""

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.12, 0.12), (0.26, 0.36))
"""Where the cubes' centres start: ((x_min, x_max), (y_min, y_max)), between the pads and
beside the arm's home pose (:func:`~gym_soarm.tasks.placement.draw_beside_arm`)."""
ARM_LANE_HALF_WIDTH_M = 0.045
"""Centres keep this far from x = 0, out of the lane under the arm's home pose."""
CUBE_GAP_M = 0.02
YAW_RANGE_DEG: tuple[float, float] = (0.0, 90.0)

REACH_HEADROOM_M = 0.10
"""Height above a cube within which ``reach`` ignores the jaws' height."""
PLACE_HEIGHT_TOL_M = 0.005
STAGES: tuple[str, ...] = ("reach", "grasp", "lift", "place")
# How far along a cube is, to choose the one worked on (the stages' weights in a single
# pick-and-place).
_STAGE_WEIGHTS: dict[str, float] = {"reach": 0.1, "grasp": 0.2, "lift": 0.3, "place": 0.4}


def cube_name(colour: str) -> str:
    """``"red"`` -> ``"red_cube"``."""
    return f"{colour}_cube"


def pad_name(colour: str) -> str:
    """``"red"`` -> ``"red_pad"``."""
    return f"{colour}_pad"


class SortCubesTask(Task):
    """Put each cube on the pad of its colour, released and at rest."""

    weights = RewardWeights(
        {
            "reach": 0.1,
            "grasp": 0.15,
            "lift": 0.2,
            "place": 0.25,
            **{f"{colour}_sorted": 0.3 / len(COLOURS) for colour in COLOURS},
        }
    )
    state_fields: ClassVar = (
        *(field for colour in COLOURS for field in object_pose_fields(cube_name(colour))),
        *(fixture_position_field(pad_name(colour), pad_name(colour)) for colour in COLOURS),
        GRIPPER_POSITION_FIELD,
    )
    goal_pairs: ClassVar = tuple((f"{c}_cube_pos", f"{c}_pad_pos") for c in COLOURS)

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()
        radii = [cube.footprint_radius_m for cube in CUBES]
        keep_clear = [(x, y, PAD_RADIUS_M) for x, y, _ in PAD_POSITIONS_M.values()]
        positions = placement.draw_beside_arm(
            rng,
            radii,
            START_REGION_M,
            ARM_LANE_HALF_WIDTH_M,
            keep_clear=keep_clear,
            gap_m=CUBE_GAP_M,
            by_side=True,
        )
        placement.set_down(physics, rng, CUBES, positions, YAW_RANGE_DEG)

    # --- per cube ----------------------------------------------------------------------
    def pad_distance(self, physics: SoArmPhysics, colour: str) -> float:
        """Horizontal distance (m) from the cube's centre to its own pad's centre."""
        cx, cy, _ = physics.object_position(cube_name(colour)).tolist()
        px, py, _ = physics.fixture_position(pad_name(colour)).tolist()
        return math.hypot(cx - px, cy - py)

    def on_pad(self, physics: SoArmPhysics, colour: str, distance: float | None = None) -> bool:
        """Whether the cube of ``colour`` lies on its own pad (held or not)."""
        if distance is None:
            distance = self.pad_distance(physics, colour)
        if distance > PAD_RADIUS_M:
            return False
        return abs(physics.object_height(cube_name(colour)) - PAD_TOP_Z_M) <= PLACE_HEIGHT_TOL_M

    def is_sorted(self, physics: SoArmPhysics, colour: str) -> bool:
        """Whether the cube of ``colour`` lies on its own pad, out of the jaws."""
        return self.on_pad(physics, colour) and not physics.touched_by_jaws(cube_name(colour))

    def unsorted(self, physics: SoArmPhysics) -> tuple[str, ...]:
        """The colours whose cube is not yet sorted, in sorting order."""
        return tuple(colour for colour in COLOURS if not self.is_sorted(physics, colour))

    def _reach_distance(self, physics: SoArmPhysics, cube: str) -> float:
        """How far the jaws are from ``cube``: horizontally, and in height once more than
        :data:`REACH_HEADROOM_M` above it (so rising off a placed cube loses nothing)."""
        dx, dy, dz = (physics.grasp_center() - physics.object_position(cube)).tolist()
        return math.hypot(dx, dy, max(abs(dz) - REACH_HEADROOM_M, 0.0))

    def _evaluate_cube(self, physics: SoArmPhysics, colour: str) -> dict[str, Any]:
        """One cube's flags and distances (see :meth:`evaluate`)."""
        cube = cube_name(colour)
        distance = self.pad_distance(physics, colour)
        on_pad = self.on_pad(physics, colour, distance)
        is_sorted = on_pad and not physics.touched_by_jaws(cube)
        return {
            "sorted": is_sorted,
            "at_rest": physics.object_speed(cube) < RESTING_SPEED_M_S,
            "on_pad": on_pad,
            "pad_distance_m": distance,
            "grasped": physics.grasped(cube),
            "height_m": physics.object_height(cube),
            "reach_distance_m": self._reach_distance(physics, cube),
        }

    @staticmethod
    def _stages(cube: dict[str, Any]) -> dict[str, float]:
        """The pick-and-place stages of one unsorted cube (its :meth:`_evaluate_cube`)."""
        distance = cube["pad_distance_m"]
        return pick_and_place_terms(
            on_target=cube["on_pad"],
            grasped=cube["grasped"],
            reach_distance_m=cube["reach_distance_m"],
            lift=lift_progress(cube["height_m"]),
            over_target=distance <= PAD_RADIUS_M,
            near_target=tolerance(distance, PAD_RADIUS_M / 2, PLACE_MARGIN_M),
        )

    # --- success and reward ----------------------------------------------------------------
    def evaluate(self, physics: SoArmPhysics) -> Evaluation:
        cubes = {colour: self._evaluate_cube(physics, colour) for colour in COLOURS}
        return {
            "success": all(cube["sorted"] and cube["at_rest"] for cube in cubes.values()),
            "unsorted": tuple(colour for colour in COLOURS if not cubes[colour]["sorted"]),
            "cubes": cubes,
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, float]:
        unsorted = evaluation["unsorted"]
        terms = {f"{colour}_sorted": float(colour not in unsorted) for colour in COLOURS}
        done = len(COLOURS) - len(unsorted)
        if unsorted:
            # The cube furthest along is the one being worked on (the first on a tie).
            progress = [self._stages(evaluation["cubes"][colour]) for colour in unsorted]
            # Reaching alone does not count here, so the cube reached for is the first
            # unsorted one until another is held or on its pad.
            current = max(
                progress,
                key=lambda s: sum(_STAGE_WEIGHTS[k] * s[k] for k in ("grasp", "lift", "place")),
            )
        else:
            current = dict.fromkeys(STAGES, 0.0)
        for stage in STAGES:
            terms[stage] = (done + current[stage]) / len(COLOURS)
        return terms

    def compute_info(self, physics: SoArmPhysics, evaluation: Evaluation) -> dict[str, Any]:
        unsorted = evaluation["unsorted"]
        return {
            "cubes_sorted": len(COLOURS) - len(unsorted),
            **{
                f"{colour}_cube_pos": physics.object_position(cube_name(colour))
                for colour in COLOURS
            },
        }


class SortCubesExpert(PlaceExpert):
    """Pick and place each unsorted cube onto its pad in turn, in :data:`COLOURS` order.

    After each retreat a ``next`` phase looks at the table again: it plans a new grasp
    (approach, descend, close) and placement for the first cube not yet on its pad, which
    is the same cube again if its placement missed, or ends the script when all are sorted.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        super().__init__(env, config)
        self._colour = COLOURS[0]

    def grasp_object(self) -> str:
        return cube_name(self._colour)

    def place_target(self) -> np.ndarray:
        pad = self.env.physics.fixture_position(pad_name(self._colour))
        return np.array([pad[0], pad[1], constants.TABLE_TOP_Z_M + CUBE_HALF_M])

    def reset(self) -> None:
        unsorted = self.env.task_logic.unsorted(self.env.physics)
        self._colour = unsorted[0] if unsorted else COLOURS[0]
        super().reset()

    def _after_grasp_phases(self) -> list[Phase]:
        return [*super()._after_grasp_phases(), Phase("next", 1, self._begin_next)]

    def _begin_retreat(self) -> None:
        # Straight up with the jaws open. The base retreat slides sideways first, which
        # moves the jaws away from the next cube, and sets no gripper motion of its own, so
        # the release's (closed to open) would play again and pick the placed cube back up.
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[2] = max(self.config.retreat_height_m, site[2])
        self._line_move(site, self._yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_next(self) -> None:
        self._hold_arm()
        unsorted = self.env.task_logic.unsorted(self.env.physics)
        if not unsorted:
            return
        self._colour = unsorted[0]
        self._regrasps = 0
        self._plan[self._phase_index :] = [*self._grasp_phases(), *self._after_grasp_phases()]
        self._begin_phase()


class SortCubesStateExpert(PlaceStateExpert):
    """From the state: the first cube (in :data:`COLOURS` order) not yet on its pad is
    picked and placed on it; a cube just let go is cleared before the next one."""

    def _colour(self) -> str:
        unsorted = self.env.task_logic.unsorted(self.physics)
        return unsorted[0] if unsorted else COLOURS[-1]

    def grasp_object(self) -> str:
        return cube_name(self._colour())

    def place_target(self, name: str) -> np.ndarray:
        colour = next(c for c in COLOURS if cube_name(c) == name)
        pad = self.physics.fixture_position(pad_name(colour))
        return np.array([pad[0], pad[1], constants.TABLE_TOP_Z_M + CUBE_HALF_M])


SPEC = TaskSpec(
    name="SortCubes-v0",
    task=SortCubesTask,
    expert=SortCubesExpert,
    max_episode_steps=1000,
    scene=Scene(objects=CUBES, fixtures=PADS),
    instructions=("Put the red, green and blue cubes on the pads of their colours.",),
    summary="sort three cubes onto the pads of their colours",
    default_placement="uniform",
    aliases=("sort_cubes",),
    state_expert=SortCubesStateExpert,
)
