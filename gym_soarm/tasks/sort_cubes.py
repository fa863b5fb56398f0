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
gripper's position. ``obs_type="state"`` adds the task's progress last: which cubes are
sorted, the cube worked on now (one-hot), and the vectors from the jaws to it and from it
to its pad. ``info`` adds ``cubes_sorted`` and each ``<colour>_cube_pos``.

The expert sorts the cubes in that order: one pick-and-place cycle each, with the jaws
rising straight up, open, after each release.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays, xy_distance
from gym_soarm.sim.arrays import namespace as sim_namespace
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.cube import CUBE_HALF_M, coloured_cubes
from gym_soarm.tasks.rewards import (
    PLACE_MARGIN_M,
    RESTING_SPEED_M_S,
    lift_progress,
    pick_and_place_terms,
    tolerance,
)
from gym_soarm.tasks.scripted import OneAfterAnother
from gym_soarm.tasks.state_expert import PlaceStateExpert
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    StateField,
    fixture_position_field,
    object_pose_fields,
)

COLOURS: tuple[str, ...] = ("red", "green", "blue")
"""The cubes' and pads' colours, in sorting order: ``<colour>_cube`` goes on ``<colour>_pad``."""
PAD_POSITIONS_M: dict[str, tuple[float, float, float]] = {
    "red": (-0.20, 0.27, 0.0),
    "green": (-0.10, 0.44, 0.0),
    "blue": (0.20, 0.27, 0.0),
}
PAD_RADIUS_M = 0.04
PAD_TOP_Z_M = 0.001

CUBES: tuple[SceneObject, ...] = coloured_cubes(COLOURS, -0.08, 0.08, 0.30)
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


PROGRESS_NAMES: tuple[str, ...] = (
    *(f"{c}_sorted" for c in COLOURS),
    *(f"current_is_{c}" for c in COLOURS),
    *(f"jaw_to_current_cube_{a}" for a in "xyz"),
    *(f"current_cube_to_pad_{a}" for a in "xyz"),
)
"""The names of sort's progress in ``obs_type="state"`` (``SortCubesTask.progress_fields``)."""


def _progress(sim: SimArrays, task: Any) -> Array:
    """``(n, 12)``: 1 where each cube lies on its own pad out of the jaws; the cube worked
    on now, one-hot (the first unsorted one, the last once all are); the vectors from the
    jaws to it and from it to its pad (m)."""
    xp, dtype = sim.xp, sim.qpos.dtype
    flags = [
        xp.astype(on_own_pad(sim, c)[0] & ~sim.touched_by_jaws(cube_name(c)), dtype)
        for c in COLOURS
    ]
    red = 1.0 - flags[0]
    green = flags[0] * (1.0 - flags[1])
    current = (red, green, 1.0 - red - green)
    cube = sum(
        w[..., None] * sim.object_position(cube_name(c))
        for w, c in zip(current, COLOURS, strict=True)
    )
    pad = sum(
        w[..., None] * sim.fixture_position(pad_name(c))
        for w, c in zip(current, COLOURS, strict=True)
    )
    values = [xp.stack([*flags, *current], axis=-1), cube - sim.grasp_center(), pad - cube]
    return xp.concat(values, axis=-1)


def on_own_pad(sim: SimArrays, colour: str) -> tuple[Array, Array, Array]:
    """``(on_pad, distance_m, height_m)``, ``(n,)`` each: the ``colour`` cube's centre is
    within its pad's radius and its bottom on the pad (held or not); its horizontal
    distance to the pad's centre; its bottom's height."""
    cube = cube_name(colour)
    distance = xy_distance(sim.object_position(cube), sim.fixture_position(pad_name(colour)))
    height = sim.object_height(cube)
    on_pad = (distance <= PAD_RADIUS_M) & (sim.xp.abs(height - PAD_TOP_Z_M) <= PLACE_HEIGHT_TOL_M)
    return on_pad, distance, height


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
    progress_fields: ClassVar = (
        StateField("progress", PROGRESS_NAMES, 2 * constants.POSITION_BOUND_M, _progress),
    )
    """Which cubes are sorted, the cube worked on now (the first unsorted one in
    :data:`COLOURS` order; the last once all are), the vector from the jaws to it and from
    it to its pad: a policy that reads the positions alone has to work out which cube
    comes next, and cloned from the expert it blends the cubes and stalls."""

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
    def _evaluate_cube(self, sim: SimArrays, colour: str) -> dict[str, Array]:
        """One cube's flags and distances, ``(n,)`` each (see :meth:`evaluate`)."""
        xp = sim.xp
        cube = cube_name(colour)
        on_pad, distance, height = on_own_pad(sim, colour)
        # How far the jaws are from the cube: horizontally, and in height once more than
        # REACH_HEADROOM_M above it (so rising off a placed cube loses nothing).
        gap = sim.grasp_center() - sim.object_position(cube)
        rise = xp.maximum(xp.abs(gap[..., 2]) - REACH_HEADROOM_M, 0.0)
        return {
            "sorted": on_pad & ~sim.touched_by_jaws(cube),
            "at_rest": sim.object_speed(cube) < RESTING_SPEED_M_S,
            "on_pad": on_pad,
            "pad_distance_m": distance,
            "grasped": sim.grasped(cube),
            "height_m": height,
            "reach_distance_m": xp.sqrt(gap[..., 0] ** 2 + gap[..., 1] ** 2 + rise * rise),
        }

    @staticmethod
    def _stages(evaluation: Evaluation, colour: str) -> dict[str, Array]:
        """The pick-and-place stages of one cube (its part of :meth:`evaluate`)."""
        distance = evaluation[f"{colour}_pad_distance_m"]
        return pick_and_place_terms(
            on_target=evaluation[f"{colour}_on_pad"],
            grasped=evaluation[f"{colour}_grasped"],
            reach_distance_m=evaluation[f"{colour}_reach_distance_m"],
            lift=lift_progress(evaluation[f"{colour}_height_m"]),
            over_target=distance <= PAD_RADIUS_M,
            near_target=tolerance(distance, PAD_RADIUS_M / 2, PLACE_MARGIN_M),
        )

    def unsorted(self, physics: SoArmPhysics) -> tuple[str, ...]:
        """The colours whose cube is not yet on its own pad out of the jaws, in sorting order."""
        evaluation = self.evaluate(self.arrays(physics))
        return tuple(c for c in COLOURS if not bool(evaluation[f"{c}_sorted"]))

    # --- success and reward ----------------------------------------------------------------
    def evaluate(self, sim: SimArrays) -> Evaluation:
        """Per cube ``<colour>_sorted``, ``_at_rest``, ``_on_pad``, ``_pad_distance_m``,
        ``_grasped``, ``_height_m`` and ``_reach_distance_m``; success when all are sorted
        and at rest."""
        evaluation: Evaluation = {}
        success = None
        for colour in COLOURS:
            cube = self._evaluate_cube(sim, colour)
            evaluation.update({f"{colour}_{key}": value for key, value in cube.items()})
            done = cube["sorted"] & cube["at_rest"]
            success = done if success is None else success & done
        return {"success": success, **evaluation}

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        xp = sim_namespace(evaluation["success"])
        sorted_flags = {c: evaluation[f"{c}_sorted"] for c in COLOURS}
        dtype = evaluation[f"{COLOURS[0]}_height_m"].dtype
        terms = {f"{c}_sorted": xp.astype(sorted_flags[c], dtype) for c in COLOURS}
        done = sum(terms.values())
        # The unsorted cube furthest along is the one being worked on (the first on a
        # tie); reaching alone does not count here, so the cube reached for is the first
        # unsorted one until another is held or on its pad. All sorted: no current cube.
        current = {stage: xp.zeros_like(done) for stage in STAGES}
        best = xp.full_like(done, -1.0)
        for colour in COLOURS:
            stages = self._stages(evaluation, colour)
            score = sum(_STAGE_WEIGHTS[k] * stages[k] for k in ("grasp", "lift", "place"))
            better = ~sorted_flags[colour] & (score > best)
            current = {k: xp.where(better, stages[k], current[k]) for k in STAGES}
            best = xp.where(better, score, best)
        for stage in STAGES:
            terms[stage] = (done + current[stage]) / len(COLOURS)
        return terms

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        xp = sim.xp
        count = sum(xp.astype(evaluation[f"{c}_sorted"], xp.int64) for c in COLOURS)
        return {
            "cubes_sorted": count,
            **{f"{colour}_cube_pos": sim.object_position(cube_name(colour)) for colour in COLOURS},
        }


class SortCubesExpert(OneAfterAnother):
    """Pick and place each unsorted cube onto its pad in turn, in :data:`COLOURS` order.

    After each retreat a ``next`` phase looks at the table again: it plans a new grasp
    (approach, descend, close) and placement for the first cube not yet on its pad, which
    is the same cube again if its placement missed, or ends the script when all are sorted.
    """

    objects = tuple(cube_name(colour) for colour in COLOURS)

    def remaining(self) -> tuple[str, ...]:
        return tuple(cube_name(c) for c in self.env.task_logic.unsorted(self.env.physics))

    def place_target(self) -> np.ndarray:
        colour = COLOURS[self.objects.index(self._current)]
        pad = self.env.physics.fixture_position(pad_name(colour))
        return np.array([pad[0], pad[1], constants.TABLE_TOP_Z_M + CUBE_HALF_M])


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

    def pad_yaw(self, name: str) -> float:
        """The jaws' yaw over ``name``'s pad with the wrist unrolled: along the pad's
        bearing from the pan axis (a pad is round: any yaw places the cube)."""
        return self._kinematics.bearing(self.place_target(name))

    def carry_turn(self, name: str, yaw: float, turn: float) -> float:
        # Every cube arrives with the wrist unrolled, so the arm leaves each pad in one
        # posture and the next approach starts as alike as the first does from home.
        return math.remainder(self.pad_yaw(name) - yaw, math.tau)

    def place_yaw(self, name: str, yaw: float) -> float:
        return self.pad_yaw(name)


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
