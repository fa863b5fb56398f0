"""``PushCube-v0``: push the blue cube along the table onto the green square.

The scene: the 3 cm blue cube and a green square 7 cm across painted on the table (a
visual fixture, it never collides). The cube starts anywhere in x in [-0.09, 0.09] m,
y in [0.27, 0.39] m with a yaw in [0, 90) degrees; the square's centre lies 6 to 12 cm
from it in a direction drawn uniformly, kept where the arm can push: the square inside
x in [-0.12, 0.12] m, y in [0.25, 0.42] m, and the spot 5 cm behind the cube (on the
side away from the square) where the push starts 12 to 27 cm from the shoulder pan
axis. The square is a fixture, a
static body of the compiled model: the reset writes its body position into this
environment's own copy of the model (``physics.model.body_pos``), so nothing is
recompiled, and every reset sets it, so a seed always gives the same episode.

Success: the cube's centre is over the square, the cube is at rest, neither jaw
touches it, and it was never lifted: a cube whose bottom rose more than 1 cm above the
table (checked every control step) makes success impossible for the rest of the
episode.
Reward terms are stages: ``reach`` (the closed jaws just behind the cube, on the side
away from the square) and ``push`` (the cube's progress from where it started towards
the square; 0.9 once its centre is over the square, 1 at rest there and let go). A lifted cube
earns no ``push``; success gives every term 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.arrays import namespace as sim_namespace
from gym_soarm.sim.arrays import norm as batch_norm
from gym_soarm.sim.kinematics import downward_rotation
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.cube import CUBE, CUBE_HALF_M, CUBE_STATE_FIELDS
from gym_soarm.tasks.rewards import (
    PLACED_CREDIT,
    REACH_MARGIN_M,
    RESTING_SPEED_M_S,
    norm,
    tolerance,
)
from gym_soarm.tasks.scripted import DEFAULT_CONFIG, ExpertConfig, NoGraspExpert, Phase
from gym_soarm.tasks.state_expert import Move, StateExpert
from gym_soarm.tasks.state_fields import fixture_position_field

TARGET_HALF_M = 0.035
"""Half the side of the green square."""
TARGET_THICKNESS_M = 0.001
TARGET = Fixture(
    name="target",
    position_m=(0.0, 0.35, 0.0),
    geoms=(
        FixtureGeom(
            "box",
            (TARGET_HALF_M, TARGET_HALF_M, TARGET_THICKNESS_M / 2),
            "green",
            (0.0, 0.0, TARGET_THICKNESS_M / 2),
            collides=False,
            emission=0.2,
        ),
    ),
)
"""A thin green square on the table (visual only: the cube slides on the table beneath)."""

CUBE_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.09, 0.09), (0.27, 0.39))
TARGET_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.12, 0.12), (0.25, 0.42))
PUSH_DISTANCE_M: tuple[float, float] = (0.06, 0.12)
"""How far the square's centre lies from the cube's at reset."""
PUSH_START_BEHIND_M = 0.05
"""A push starts this far behind the cube's centre (the jaws and some clearance)."""
PUSH_START_RADIUS_M: tuple[float, float] = (0.12, 0.27)
"""Where a push may start: its distance from the shoulder pan axis."""
MAX_DRAWS = 1000

LIFT_LIMIT_M = 0.01
"""A cube whose bottom rises above this (m above the table) was lifted, not pushed."""
PUSHER_BEHIND_M: tuple[float, float] = (0.02, 0.05)
"""Where the reach term wants the centre of the jaws: on the push line, this far (m)
behind the cube's centre, at the height of the cube's centre."""
REACH_BOUND_M = 0.015


def draw_push(rng: np.random.Generator) -> tuple[tuple[float, float], tuple[float, float]]:
    """The cube's (x, y) and the square's (x, y), a pushable 6-12 cm apart.

    Draws the cube's position, a direction and a distance until the square lies in
    :data:`TARGET_REGION_M` and the push starts within :data:`PUSH_START_RADIUS_M`.

    Raises:
        RuntimeError: no pushable layout after :data:`MAX_DRAWS` draws.
    """
    (tx0, tx1), (ty0, ty1) = TARGET_REGION_M
    r0, r1 = PUSH_START_RADIUS_M
    pan_x, pan_y = constants.PAN_AXIS_XY_M
    for _ in range(MAX_DRAWS):
        ((cx, cy),) = placement.draw_uniform_positions(
            rng, (CUBE.footprint_radius_m,), CUBE_REGION_M
        )
        heading = float(rng.uniform(0.0, math.tau))
        distance = float(rng.uniform(*PUSH_DISTANCE_M))
        ux, uy = math.cos(heading), math.sin(heading)
        tx, ty = cx + distance * ux, cy + distance * uy
        sx, sy = cx - PUSH_START_BEHIND_M * ux, cy - PUSH_START_BEHIND_M * uy
        radius = math.hypot(sx - pan_x, sy - pan_y)
        if tx0 <= tx <= tx1 and ty0 <= ty <= ty1 and r0 <= radius <= r1:
            return (cx, cy), (tx, ty)
    raise RuntimeError(f"no pushable cube and square layout after {MAX_DRAWS} draws.")


class PushTask(Task):
    """Push the cube over the green square without lifting it."""

    weights = RewardWeights({"reach": 0.3, "push": 0.7})
    state_fields: ClassVar = (*CUBE_STATE_FIELDS, fixture_position_field("target", TARGET.name))
    goal_pairs: ClassVar = (("cube_pos", "target_pos"),)
    episode_shapes: ClassVar = MappingProxyType(
        {"start_distance": (), "direction": (2,), "max_height": ()}
    )
    """The cube's start distance to the square's centre (m), the push's unit direction,
    and the highest the cube has been this episode (m)."""
    cube = CUBE.name

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()
        (cx, cy), (tx, ty) = draw_push(rng)
        yaw = float(rng.uniform(0.0, 90.0))
        physics.set_object_pose(
            self.cube,
            np.array([cx, cy, constants.TABLE_TOP_Z_M + CUBE_HALF_M]),
            placement.yaw_quaternion(yaw),
        )
        physics.set_fixture_position(TARGET.name, np.array([tx, ty, constants.TABLE_TOP_Z_M]))
        offset = np.array([tx - cx, ty - cy])
        distance = norm(offset)
        self.episode["start_distance"][0] = distance
        self.episode["direction"][0] = offset / distance
        self.episode["max_height"][0] = 0.0

    # --- episode bookkeeping --------------------------------------------------------
    def _lifted(self, sim: SimArrays) -> Array:
        """Whether the cube has been lifted above the limit this episode (updates the record)."""
        highest = sim.episode["max_height"]
        highest[...] = sim.xp.maximum(highest, sim.object_height(self.cube))
        return highest > LIFT_LIMIT_M

    def _pusher_distance(self, sim: SimArrays) -> Array:
        """Distance (m) from the jaws to the stretch of the push line just behind the cube."""
        xp = sim.xp
        cube = sim.object_position(self.cube)
        jaws = sim.jaw_pads_center()
        direction = sim.episode["direction"]
        # How far behind the cube's centre the jaws are, along the push, kept to the stretch.
        behind = xp.sum((cube[..., :2] - jaws[..., :2]) * direction, axis=-1)
        behind = xp.minimum(xp.maximum(behind, PUSHER_BEHIND_M[0]), PUSHER_BEHIND_M[1])
        spot_xy = cube[..., :2] - behind[..., None] * direction
        gap = jaws - xp.concat([spot_xy, cube[..., 2:]], axis=-1)
        return batch_norm(gap)

    def evaluate(self, sim: SimArrays) -> Evaluation:
        xp = sim.xp
        lifted = self._lifted(sim)
        # Horizontal offset (m) from the cube's centre to the square's centre.
        offset = (
            sim.fixture_position(TARGET.name)[..., :2] - sim.object_position(self.cube)[..., :2]
        )
        over_target = xp.all(xp.abs(offset) <= TARGET_HALF_M, axis=-1)
        return {
            "success": (
                ~lifted
                & over_target
                & (sim.object_speed(self.cube) < RESTING_SPEED_M_S)
                & ~sim.touched_by_jaws(self.cube)
            ),
            "lifted": lifted,
            "over_target": over_target,
            "target_distance_m": batch_norm(offset),
            "pusher_distance_m": self._pusher_distance(sim),
            "start_distance_m": sim.episode["start_distance"],
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        reach = tolerance(evaluation["pusher_distance_m"], REACH_BOUND_M, REACH_MARGIN_M)
        xp = sim_namespace(reach)
        # Progress from the start towards the square's edge (reached when over it).
        to_go = xp.maximum(evaluation["target_distance_m"] - TARGET_HALF_M, 0.0)
        progress = 1.0 - to_go / (evaluation["start_distance_m"] - TARGET_HALF_M)
        push = PLACED_CREDIT * xp.minimum(xp.maximum(progress, 0.0), 1.0)
        over, lifted = evaluation["over_target"], evaluation["lifted"]
        return {
            "reach": xp.where(~lifted & over, 1.0, reach),
            "push": xp.where(lifted, 0.0, xp.where(over, PLACED_CREDIT, push)),
        }

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "target_pos": sim.fixture_position(TARGET.name),
            "cube_pos": sim.object_position(self.cube),
            "cube_lifted": evaluation["lifted"],
        }


# --- the expert -------------------------------------------------------------------------
# How far the leading face of the closed jaws is ahead of the grasp_center site along
# the push: the fixed jaw's outer face lies 18 mm along the gripper's -x axis; the
# moving jaw's pad lies 1 mm behind the site on its +x axis, and tilted, so that it
# meets the cube about 4 mm ahead of the site (measured: pushes end centred).
FIXED_FACE_AHEAD_M = 0.018
MOVING_FACE_AHEAD_M = 0.004
PUSH_HEIGHT_M = 0.019
"""Height of grasp_center while pushing: the pads meet the cube round its middle."""
PUSH_CLEARANCE_M = 0.015
"""Gap between the leading jaw and the cube as the jaws come down behind it."""
TOUCH_GAP_M = 0.003
"""The jaws slow to a stop this short of the cube, so the push starts gently."""
HOVER_ABOVE_M = 0.04
BACK_OFF_M = 0.02
"""After the push the jaws draw back this far from the cube as they rise."""


class PushExpert(NoGraspExpert):
    """Close the jaws, come down behind the cube, push it in a line onto the square, back off.

    No grasp: the approach is a joint move to a hover behind the cube, then a straight
    descent, a straight push that brings the cube's centre to the square's centre, a
    short hold and a retreat up and back.
    """

    touch_steps = 12
    push_steps = 75
    settle_steps = 5

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        super().__init__(env, config)
        self._push_start = np.zeros(3)
        self._push_touch = np.zeros(3)
        self._push_end = np.zeros(3)
        self._push_direction = np.array([0.0, 1.0])

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("approach", c.approach_steps, self._begin_approach_push),
            Phase("descend", c.descend_steps, self._begin_descend_push),
            Phase("touch", self.touch_steps, self._begin_touch),
            Phase("push", self.push_steps, self._begin_push),
            Phase("settle", self.settle_steps, self._hold_arm),
            Phase("retreat", c.retreat_steps, self._begin_back_off),
        ]

    def _plan_push(self) -> None:
        """The push line and the jaws' yaw, from the cube and the square as they are now."""
        physics = self.env.physics
        cube = physics.object_position(self.grasp_object())
        target = physics.fixture_position(TARGET.name)
        offset = target[:2] - cube[:2]
        direction = offset / norm(offset)
        heading = math.atan2(direction[1], direction[0])
        # How far the cube reaches towards the jaws, along the push.
        turn = physics.object_yaw(self.grasp_object()) - heading
        extent = CUBE_HALF_M * (abs(math.cos(turn)) + abs(math.sin(turn)))
        # Lead with the fixed jaw (the gripper's -x axis along the push) or the moving jaw
        # (its +x axis), whichever the wrist reaches with less roll.
        best = None
        for yaw, ahead in ((heading + math.pi, FIXED_FACE_AHEAD_M), (heading, MOVING_FACE_AHEAD_M)):
            start = cube.copy()
            start[:2] -= (extent + ahead + PUSH_CLEARANCE_M) * direction
            start[2] = PUSH_HEIGHT_M
            q, position_error, rotation_error = self._kinematics.solve(
                self._seed_towards(start), start, downward_rotation(yaw)
            )
            cost = abs(q[self._roll]) + 100.0 * (position_error + rotation_error)
            if best is None or cost < best[0]:
                best = (cost, yaw, ahead, start)
        _, self._yaw, ahead, self._push_start = best
        self._push_touch = self._push_start.copy()
        self._push_touch[:2] += (PUSH_CLEARANCE_M - TOUCH_GAP_M) * direction
        # The push ends with the cube's centre on the square's, a face square to the jaws.
        end = target.copy()
        end[:2] -= (CUBE_HALF_M + ahead) * direction
        end[2] = PUSH_HEIGHT_M
        self._push_end = end
        self._push_direction = direction

    def _begin_approach_push(self) -> None:
        self._plan_push()
        hover = self._push_start.copy()
        hover[2] += HOVER_ABOVE_M
        self._swing_to(hover, self._yaw)

    def _begin_descend_push(self) -> None:
        self._line_move(self._push_start, self._yaw)

    def _begin_touch(self) -> None:
        self._line_move(self._push_touch, self._yaw)

    def _begin_push(self) -> None:
        self._line_move(self._push_end, self._yaw)

    def _begin_back_off(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[:2] -= BACK_OFF_M * self._push_direction
        site[2] = self.config.hover_height_m
        self._line_move(site, self._yaw)


_N_ARM = len(constants.ARM_JOINT_NAMES)
"""Where the gripper comes among the joints."""
PUSH_HOVER_M = PUSH_HEIGHT_M + HOVER_ABOVE_M
"""Height of grasp_center while coming over the push's start (the scripted hover)."""
PUSH_ALIGNED_M = (0.005, 0.012)
"""Sideways distance of the jaws from the push line within which they descend (high) and
within which they keep pushing (low)."""
PUSH_YAW_ALIGNED_RAD = (0.08, 0.25)
"""The same for the jaws' yaw against the push's yaw."""
PUSH_BEHIND_M = (-0.015, 0.06)
"""Gap between the leading jaw and the cube's near face within which low jaws push."""
PUSH_SPEED_M = 0.0025
"""Fastest straight move of the jaws while pushing (m per step)."""
TOUCH_SPEED_M = 0.0015
"""Speed of the jaws as they meet the cube."""
CENTRED_M = 0.005
"""The push stops once the cube's centre is this close to the square's centre ..."""
CENTRED_LOOSE_M = 0.02
"""... or this close while the jaws are not at the cube, pushing."""
ENGAGED_GAP_M = 0.01
"""Jaws low, aligned and within this gap of the cube are pushing it."""
CLEAR_RADIUS_M = 0.06
"""After the push the jaws back off to this horizontal distance from the cube's centre."""


class PushStateExpert(StateExpert):
    """From the state: come down behind the cube on the line to the square, push along it.

    Each step draws the push line from the cube's centre, as it is now, to the square's
    centre and the start of a push on it (the closed jaws behind the cube, leading with
    the jaw the wrist reaches with less roll, as :class:`PushExpert` does). Low jaws on
    that line behind the cube push it towards the point that brings its centre onto the
    square's; jaws anywhere else rise, swing over the start and come down. Once the cube
    is centred the jaws back off and rise; they never close on it.
    """

    def _leading(self, cube: np.ndarray, direction: np.ndarray) -> list[tuple[float, float]]:
        """The two ways of pushing along ``direction``: (yaw, how far the leading face
        lies ahead of grasp_center)."""
        heading = math.atan2(direction[1], direction[0])
        return [(heading + math.pi, FIXED_FACE_AHEAD_M), (heading, MOVING_FACE_AHEAD_M)]

    def _extent(self, direction: np.ndarray) -> float:
        """How far the cube reaches from its centre towards the jaws, along ``direction``."""
        heading = math.atan2(direction[1], direction[0])
        turn = self.physics.object_yaw(CUBE.name) - heading
        return CUBE_HALF_M * (abs(math.cos(turn)) + abs(math.sin(turn)))

    def _start(self, cube: np.ndarray, direction: np.ndarray, ahead: float) -> np.ndarray:
        start = cube.copy()
        start[:2] -= (self._extent(direction) + ahead + PUSH_CLEARANCE_M) * direction
        start[2] = PUSH_HEIGHT_M
        return start

    def decide(self, commanded: np.ndarray) -> Move:
        c = self.config
        physics = self.physics
        closed = c.gripper_closed_rad
        cube = physics.object_position(CUBE.name)
        target = physics.fixture_position(TARGET.name)
        site, yaw = self.commanded_site(commanded)
        measured = physics.grasp_center()
        offset = target[:2] - cube[:2]
        to_go = float(np.hypot(*offset))
        low = site[2] < PUSH_HOVER_M - 0.01
        # The push line: from the cube's centre to the square's (any line once there).
        direction = offset / to_go if to_go > 1e-6 else np.array([0.0, 1.0])
        # Which jaw leads: the one the jaws already turn to when close, else least roll.
        options = self._leading(cube, direction)
        near = low or float(np.hypot(*(site[:2] - cube[:2]))) < 0.06
        if near:
            push_yaw, ahead = min(
                options, key=lambda option: abs(math.remainder(option[0] - yaw, math.tau))
            )
        else:
            push_yaw, ahead = min(
                options,
                key=lambda option: self.solve(self._start(cube, direction, option[1]), option[0])[
                    1
                ],
            )
        extent = self._extent(direction)
        # Where the jaws stand against the line: sideways, and the gap ahead to the cube.
        relative = site[:2] - cube[:2]
        sideways = abs(float(relative[0] * direction[1] - relative[1] * direction[0]))
        gap = -float(relative @ direction) - extent - ahead
        yaw_error = abs(math.remainder(yaw - push_yaw, math.tau))
        engaged = (
            low
            and sideways < PUSH_ALIGNED_M[1]
            and yaw_error < PUSH_YAW_ALIGNED_RAD[1]
            and PUSH_BEHIND_M[0] < gap < ENGAGED_GAP_M
        )
        if self.held_back(commanded):  # targets far off (pressed on something): relax first
            return Move("relax", None, yaw, closed, stage="relax")
        if to_go < CENTRED_M or (to_go < CENTRED_LOOSE_M and not engaged):
            return self._back_off(cube, site, yaw)
        start = self._start(cube, direction, ahead)
        hover = start.copy()
        hover[2] = PUSH_HOVER_M
        shut = float(physics.joint_angles()[_N_ARM]) < closed + 0.15
        if low:
            aligned = (
                sideways < PUSH_ALIGNED_M[1]
                and yaw_error < PUSH_YAW_ALIGNED_RAD[1]
                and PUSH_BEHIND_M[0] < gap < PUSH_BEHIND_M[1]
                and measured[2] - site[2] < 0.012  # not held up by the cube's top
            )
            if not aligned:
                return self.rise(commanded, PUSH_HOVER_M, closed, push_yaw)
            if site[2] > PUSH_HEIGHT_M + 0.003:
                down = site.copy()
                down[2] = PUSH_HEIGHT_M
                return Move("line", down, push_yaw, closed, stage="descend")
            # Push: the jaws' leading face to where the cube's near face is once its
            # centre is on the square's (at least as far as the cube has still to go).
            along = float(site[:2] @ direction)
            goal_along = max(
                float(target[:2] @ direction) - extent - ahead, along + to_go - CENTRED_M / 2
            )
            goal = site.copy()
            goal[:2] += (goal_along - along) * direction
            goal[2] = PUSH_HEIGHT_M
            # Back onto the line, sideways, as the jaws go.
            goal[:2] += self._line_point(cube, direction, goal[:2]) - goal[:2]
            speed = TOUCH_SPEED_M if gap > 0.0 and gap < 0.006 else PUSH_SPEED_M
            speed = min(speed, max(0.0005, 0.25 * (goal_along - along)))
            return Move("line", goal, push_yaw, closed, speed_m=speed, stage="push")
        # High: over the start, then straight down once the jaws are there (measured too).
        horizontal = max(
            float(np.hypot(*(site[:2] - start[:2]))), float(np.hypot(*(measured[:2] - start[:2])))
        )
        if horizontal < PUSH_ALIGNED_M[0] and yaw_error < PUSH_YAW_ALIGNED_RAD[0] and shut:
            return Move("line", start, push_yaw, closed, stage="descend")
        if float(np.linalg.norm(site - hover)) > 0.02:
            return Move("joint", hover, push_yaw, closed, stage="approach")
        return Move("line", hover, push_yaw, closed, stage="align")

    @staticmethod
    def _line_point(cube: np.ndarray, direction: np.ndarray, point: np.ndarray) -> np.ndarray:
        """The point of the push line nearest ``point`` (horizontal)."""
        return cube[:2] + float((point - cube[:2]) @ direction) * direction

    def _back_off(self, cube: np.ndarray, site: np.ndarray, yaw: float) -> Move:
        """Draw the jaws back from the cube and up, then hold."""
        closed = self.config.gripper_closed_rad
        away = site[:2] - cube[:2]
        distance = float(np.hypot(*away))
        if distance >= CLEAR_RADIUS_M - 0.005 and site[2] >= PUSH_HOVER_M - 0.01:
            return Move("hold", None, yaw, closed, stage="done")
        clear = site.copy()
        if distance > 1e-6:
            clear[:2] = cube[:2] + away * (max(distance, CLEAR_RADIUS_M) / distance)
        clear[2] = max(site[2], PUSH_HOVER_M)
        return Move("line", clear, yaw, closed, speed_m=0.003, stage="back off")


SPEC = TaskSpec(
    name="PushCube-v0",
    task=PushTask,
    expert=PushExpert,
    max_episode_steps=250,
    scene=Scene(objects=(CUBE,), fixtures=(TARGET,)),
    instructions=("Push the blue cube onto the green square without lifting it.",),
    summary="push the cube along the table onto the green square",
    default_placement="uniform",
    aliases=("push",),
    state_expert=PushStateExpert,
)
