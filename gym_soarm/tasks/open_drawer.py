"""``OpenDrawer-v0``: pull the drawer of the small cabinet open by at least 6 cm.

The scene: a small open-topped white cabinet (15 cm wide, 9 cm deep, 7 cm tall, made of
box walls) stands on the table with its front towards the robot. Its drawer (blue, a
tray with a front panel) slides on one joint straight out of the cabinet, towards the
robot, by up to 9 cm; a black bar handle, 1.2 cm thick, stands 4.5 cm proud of the
drawer's front at 4 cm above the table. The drawer's joint has damping and dry friction,
so it stays wherever it is left.

Reset: the drawer is closed (its joint at 0) and the cabinet stands somewhere on an arc
round the robot, facing the arm's shoulder pan axis: the handle's bearing is drawn
uniformly within 15 degrees either side of straight ahead and its distance from the pan
axis within [0.17, 0.185] m. Facing the arm keeps the pull straight along a radius of
the arm's reach, and the table's far edge bounds how far the cabinet can stand. The
cabinet is a fixed fixture, a static body of the compiled model: the reset writes its
body position and yaw into this environment's own copy of the model
(``physics.model.body_pos`` and ``body_quat``), so nothing is recompiled, and every
reset writes them, so a seed always gives the same episode. The drawer is the cabinet's
child body, so it moves with it.

Success: the drawer is open by at least 6 cm (``physics.fixture_joint_position``).

Reward terms are stages — ``reach`` (the jaws' centre near the handle), ``grasp`` (a jaw
pad on the handle, hooking or pinching it) and ``open`` (the drawer's opening as a
fraction of 6 cm) — and a later stage counts every earlier one as complete (a drawer
open by 5 mm or more counts as reached and grasped), so the reward never falls as the
task progresses.

The expert hovers over the handle with the jaws open and their closing axis along the
slide, lowers the moving jaw into the gap between the handle and the drawer's front,
closes the jaws on the bar, pulls 7.5 cm straight along the slide axis, lets go and rises
until the jaw tips clear the bar.
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
from gym_soarm.sim.objects import Fixture, FixtureGeom, FixtureJoint, Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.base import Evaluation, RewardWeights, Task, TaskSpec
from gym_soarm.tasks.rewards import reach_closeness
from gym_soarm.tasks.scripted import DEFAULT_CONFIG, ExpertConfig, Phase, ScriptedExpert
from gym_soarm.tasks.state_expert import Move, StateExpert
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    fixture_position_field,
    position_field,
    quaternion_field,
    scalar_field,
)

# --- the cabinet (its frame: origin on the table under its centre, -y out of its front) ---
CABINET_HALF_WIDTH_M = 0.075
CABINET_HALF_DEPTH_M = 0.045
CABINET_HEIGHT_M = 0.07
WALL_HALF_M = 0.003
CABINET = Fixture(
    name="cabinet",
    position_m=(0.0, 0.45, 0.0),
    geoms=(
        # floor
        FixtureGeom(
            "box",
            (CABINET_HALF_WIDTH_M, CABINET_HALF_DEPTH_M, WALL_HALF_M),
            "white",
            (0.0, 0.0, WALL_HALF_M),
        ),
        # left and right walls
        *(
            FixtureGeom(
                "box",
                (WALL_HALF_M, CABINET_HALF_DEPTH_M, CABINET_HEIGHT_M / 2),
                "white",
                (side * (CABINET_HALF_WIDTH_M - WALL_HALF_M), 0.0, CABINET_HEIGHT_M / 2),
            )
            for side in (-1.0, 1.0)
        ),
        # back wall
        FixtureGeom(
            "box",
            (CABINET_HALF_WIDTH_M, WALL_HALF_M, CABINET_HEIGHT_M / 2),
            "white",
            (0.0, CABINET_HALF_DEPTH_M - WALL_HALF_M, CABINET_HEIGHT_M / 2),
        ),
    ),
    site_m=(0.0, -CABINET_HALF_DEPTH_M, CABINET_HEIGHT_M / 2),
)
"""An open-topped white box (floor, sides, back) whose open front faces -y: the drawer's
housing. Its top is left open so that every camera sees the drawer inside."""

# --- the drawer (its frame is the cabinet's while closed; it slides along -y) --------------
DRAWER_TRAVEL_M = 0.09
FRONT_FACE_Y_M = -(CABINET_HALF_DEPTH_M + 0.002)
"""The drawer front's outer face, 2 mm proud of the cabinet's front edges."""
HANDLE_STANDOFF_M = 0.045
"""From the drawer front's outer face to the handle bar's centre."""
HANDLE_HALF_M = (0.04, 0.006, 0.005)
"""Half extents of the handle bar: 8 cm long, 1.2 cm thick (along the slide), 1 cm tall."""
HANDLE_HEIGHT_M = 0.04
HANDLE_Y_M = FRONT_FACE_Y_M - HANDLE_STANDOFF_M
POST_X_M = 0.034
CLEARANCE_M = 0.003
"""Free space between the drawer and the cabinet's walls (they never touch while it slides)."""
DRAWER_HALF_WIDTH_M = CABINET_HALF_WIDTH_M - 2 * WALL_HALF_M - CLEARANCE_M
FRONT_HALF_M = (DRAWER_HALF_WIDTH_M, 0.004, 0.028)
TRAY_FLOOR_Z_M = 0.012
TRAY_HALF_DEPTH_M = 0.036
TRAY_CENTRE_Y_M = FRONT_FACE_Y_M + 2 * FRONT_HALF_M[1] + TRAY_HALF_DEPTH_M
TRAY_WALL_HALF_HEIGHT_M = 0.018
POST_HALF_LENGTH_M = (HANDLE_STANDOFF_M - HANDLE_HALF_M[1]) / 2

TRAY_GEOMS: tuple[FixtureGeom, ...] = (
    # front panel
    FixtureGeom(
        "box",
        FRONT_HALF_M,
        "blue",
        (0.0, FRONT_FACE_Y_M + FRONT_HALF_M[1], TRAY_FLOOR_Z_M + FRONT_HALF_M[2]),
        mass_kg=0.04,
    ),
    # tray floor
    FixtureGeom(
        "box",
        (DRAWER_HALF_WIDTH_M, TRAY_HALF_DEPTH_M, 0.002),
        "blue",
        (0.0, TRAY_CENTRE_Y_M, TRAY_FLOOR_Z_M + 0.002),
        mass_kg=0.03,
    ),
    # tray sides
    *(
        FixtureGeom(
            "box",
            (0.002, TRAY_HALF_DEPTH_M, TRAY_WALL_HALF_HEIGHT_M),
            "blue",
            (
                side * (DRAWER_HALF_WIDTH_M - 0.002),
                TRAY_CENTRE_Y_M,
                TRAY_FLOOR_Z_M + TRAY_WALL_HALF_HEIGHT_M,
            ),
            mass_kg=0.015,
        )
        for side in (-1.0, 1.0)
    ),
    # tray back
    FixtureGeom(
        "box",
        (DRAWER_HALF_WIDTH_M, 0.002, TRAY_WALL_HALF_HEIGHT_M),
        "blue",
        (
            0.0,
            TRAY_CENTRE_Y_M + TRAY_HALF_DEPTH_M - 0.002,
            TRAY_FLOOR_Z_M + TRAY_WALL_HALF_HEIGHT_M,
        ),
        mass_kg=0.015,
    ),
)
"""The drawer's box: front panel, floor, sides and back, all within the cabinet's walls."""

HANDLE_GEOMS: tuple[FixtureGeom, ...] = (
    FixtureGeom("box", HANDLE_HALF_M, "black", (0.0, HANDLE_Y_M, HANDLE_HEIGHT_M), mass_kg=0.01),
    *(
        FixtureGeom(
            "box",
            (0.004, POST_HALF_LENGTH_M, HANDLE_HALF_M[2]),
            "black",
            (side * POST_X_M, FRONT_FACE_Y_M - POST_HALF_LENGTH_M, HANDLE_HEIGHT_M),
            mass_kg=0.005,
        )
        for side in (-1.0, 1.0)
    ),
)
"""The handle: a bar across the front and the two posts that hold it."""

DRAWER_DAMPING_N_S_PER_M = 3.0
DRAWER_FRICTION_N = 0.3
"""The slide's damping and dry friction: a drawer of 0.14 kg that glides when pulled and
stops, and stays, where it is let go."""

DRAWER = Fixture(
    name="drawer",
    parent="cabinet",
    position_m=(0.0, 0.0, 0.0),
    joint=FixtureJoint(
        kind="slide",
        axis=(0.0, -1.0, 0.0),
        range=(0.0, DRAWER_TRAVEL_M),
        damping=DRAWER_DAMPING_N_S_PER_M,
        frictionloss=DRAWER_FRICTION_N,
    ),
    geoms=TRAY_GEOMS + HANDLE_GEOMS,
    site_m=(0.0, HANDLE_Y_M, HANDLE_HEIGHT_M),
)
"""The blue drawer: a front panel, an open tray and a black bar handle. Its site (the
point ``fixture_position("drawer")`` reports) is the handle bar's centre."""

HANDLE_GEOM_INDICES = tuple(range(len(TRAY_GEOMS), len(TRAY_GEOMS) + len(HANDLE_GEOMS)))
"""The handle's places among the drawer's geoms (MuJoCo names them ``drawer_<index>``)."""

# --- reset, success and reward figures ------------------------------------------------------
HANDLE_BEARING_DEG = (75.0, 105.0)
"""The handle's bearing from the shoulder pan axis (degrees about world z; 90 is straight
ahead, +y): the cabinet stands anywhere in this arc, facing the axis."""
HANDLE_RADIUS_M = (0.17, 0.185)
"""The handle's distance from the shoulder pan axis (m) while the drawer is closed."""

OPEN_SUCCESS_M = 0.06
"""The drawer counts as open from this far out."""
STAGE_CREDIT_OPEN_M = 0.005
"""A drawer open this far counts as reached and grasped."""


def drawer_placement(rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """Draw the cabinet's world position (m) and yaw (rad) for one reset.

    The handle's bearing and distance from the shoulder pan axis are drawn uniformly
    within :data:`HANDLE_BEARING_DEG` and :data:`HANDLE_RADIUS_M`; the cabinet's front
    faces the axis, so the drawer slides straight towards it.
    """
    bearing = math.radians(float(rng.uniform(*HANDLE_BEARING_DEG)))
    radius = float(rng.uniform(*HANDLE_RADIUS_M))
    # The handle sits -HANDLE_Y_M in front of the cabinet's origin, along the radius.
    origin_radius = radius - HANDLE_Y_M
    pan_x, pan_y = constants.PAN_AXIS_XY_M
    x = pan_x + origin_radius * math.cos(bearing)
    y = pan_y + origin_radius * math.sin(bearing)
    # The cabinet's -y (its front) points back along the radius, at the pan axis.
    return np.array([x, y, constants.TABLE_TOP_Z_M]), bearing - math.pi / 2


def place_fixture(physics: SoArmPhysics, name: str, position: np.ndarray, yaw: float) -> None:
    """Put static fixture ``name``'s body at ``position`` (world, m) turned ``yaw`` (rad).

    Only inside a reset context: the body's pose is a model parameter (this environment's
    own copy of the model) that the forward kinematics ending the reset reads. Fixtures
    attached to it (``parent=name``) move with it.

    Raises:
        ValueError: the scene has no fixture ``name`` (or it cannot be moved).
    """
    quaternion = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    physics.set_fixture_pose(name, position, quaternion)


def handle_geoms(physics: SoArmPhysics) -> frozenset[int]:
    """The geom ids of the drawer's handle (bar and posts)."""
    return physics.fixture_part_geoms(DRAWER.name, HANDLE_GEOM_INDICES)


def slide_direction(physics: SoArmPhysics) -> np.ndarray:
    """World direction (unit, horizontal) in which the drawer opens."""
    return physics.fixture_joint_axis(DRAWER.name)


HANDLE_PARTS: tuple[str, ...] = tuple(f"{DRAWER.name}_{i}" for i in HANDLE_GEOM_INDICES)
"""The names of the handle's parts (bar and posts), as contacts name them."""


class OpenDrawerTask(Task):
    """Pull the cabinet's drawer open by at least 6 cm."""

    weights = RewardWeights({"reach": 0.2, "grasp": 0.3, "open": 0.5})
    state_fields: ClassVar = (
        fixture_position_field("handle", DRAWER.name),
        scalar_field(
            "drawer_opening",
            1.0,
            lambda sim, task: sim.fixture_joint_position(DRAWER.name),
        ),
        position_field("cabinet_pos", "cabinet", lambda sim, task: sim.episode["cabinet_pos"]),
        quaternion_field(
            "cabinet_quat_wxyz", "cabinet", lambda sim, task: sim.episode["cabinet_quat"]
        ),
        GRIPPER_POSITION_FIELD,
    )

    episode_shapes: ClassVar = MappingProxyType(
        {"cabinet_pos": (3,), "cabinet_quat": (4,), "cabinet_yaw": ()}
    )
    """Where this episode placed the cabinet: its position (m), quaternion and yaw (rad)."""

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()  # also closes the drawer: its joint's home is 0
        position, yaw = drawer_placement(rng)
        place_fixture(physics, CABINET.name, position, yaw)
        body_position, body_quaternion = physics.fixture_body_pose(CABINET.name)
        self.episode["cabinet_pos"][0] = body_position
        self.episode["cabinet_quat"][0] = body_quaternion
        self.episode["cabinet_yaw"][0] = yaw

    def evaluate(self, sim: SimArrays) -> Evaluation:
        opening = sim.fixture_joint_position(DRAWER.name)
        touched = sim.xp.zeros_like(opening > 0)
        for part in HANDLE_PARTS:
            fixed, moving = sim.jaw_contacts(part)
            touched = touched | fixed | moving
        return {
            "success": opening >= OPEN_SUCCESS_M,
            "opening_m": opening,
            "handle_touched": touched,
            "handle_distance_m": batch_norm(sim.grasp_center() - sim.fixture_position(DRAWER.name)),
        }

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        xp = sim_namespace(evaluation["opening_m"])
        opening = evaluation["opening_m"]
        opened = xp.minimum(xp.maximum(opening / OPEN_SUCCESS_M, 0.0), 1.0)
        staged = (opening >= STAGE_CREDIT_OPEN_M) | evaluation["handle_touched"]
        reach = reach_closeness(evaluation["handle_distance_m"])
        return {
            "reach": xp.where(staged, 1.0, reach),
            "grasp": xp.astype(staged, opening.dtype),
            "open": opened,
        }

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "drawer_opening_m": evaluation["opening_m"],
            "handle_pos": sim.fixture_position(DRAWER.name),
            "cabinet_pos": sim.episode["cabinet_pos"],
            "cabinet_yaw_deg": sim.episode["cabinet_yaw"] * (180.0 / math.pi),
        }


class OpenDrawerExpert(ScriptedExpert):
    """Hover over the handle, lower the jaws round the bar, close, pull 7.5 cm, let go, rise.

    The jaws close along the slide axis with the moving jaw on the drawer's side of the
    bar, so the pull presses the moving jaw's pad against the bar: a hook as well as a
    pinch.
    """

    hover_height_m = 0.08
    """Height of ``grasp_center`` above the handle's approach, jaw tips clear of the bar."""
    pull_m = 0.075
    """How far the jaws pull the handle along the slide (the drawer opens ~4 mm more as
    they close on the bar)."""
    retreat_height_m = 0.07
    """Height of ``grasp_center`` after letting go: the jaw tips 1.5 cm above the bar."""
    pull_steps = 60
    open_rad = 0.3
    """Gripper target while approaching: the moving pad 4 cm from the fixed one, so that
    the moving jaw fits between the bar and the drawer's front."""
    fixed_jaw_gap_m = 0.004
    """Gap left between the fixed pad and the bar's near face while descending."""

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        super().__init__(env, config)
        self._slide = np.array([0.0, -1.0, 0.0])

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("pull", self.pull_steps, self._begin_pull),
            Phase("release", c.release_steps, self._begin_release),
            Phase("retreat", c.retreat_steps, self._begin_retreat),
        ]

    def _begin_approach(self) -> None:
        physics = self.env.physics
        self._slide = slide_direction(physics)
        handle = physics.fixture_position(DRAWER.name)
        # The jaws' x axis (fixed -> moving jaw) points into the cabinet, against the slide.
        outward = -self._slide
        self._yaw = math.atan2(outward[1], outward[0])
        # The fixed pad's inner face sits 15 mm behind grasp_center along -x.
        pad_offset = 0.015 - HANDLE_HALF_M[1] - self.fixed_jaw_gap_m
        self._grasp_point = handle + pad_offset * outward
        hover = self._grasp_point.copy()
        hover[2] = self.hover_height_m
        target, _, _ = self._kinematics.solve(
            self._seed_towards(hover), hover, downward_rotation(self._yaw)
        )
        distance = float(np.abs(target - self._command[: self._n_arm]).max())
        steps = math.ceil(distance / self.config.approach_speed_rad_per_step)
        self._phase_length = min(max(steps, self.config.rise_steps), self.config.approach_steps)
        self._joint_move(target)
        self._gripper(self.open_rad)

    def _begin_descend(self) -> None:
        self._line_move(self._grasp_point, self._yaw)
        self._gripper(self.open_rad)

    def _begin_pull(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        self._line_move(site + self.pull_m * self._slide, self._yaw)
        self._gripper(self.config.gripper_closed_rad)

    def _begin_release(self) -> None:
        self._hold_arm()
        self._gripper(self.open_rad)

    def _begin_retreat(self) -> None:
        # Straight up until the jaw tips clear the bar; the arm, folded near its base, holds
        # the jaws vertical no higher.
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[2] = max(self.retreat_height_m, site[2])
        self._line_move(site, self._yaw)
        self._gripper(self.open_rad)


_N_ARM = len(constants.ARM_JOINT_NAMES)
"""Where the gripper comes among the joints."""
PULL_TO_M = OpenDrawerExpert.pull_m
"""The opening the state expert's pull aims for (m)."""
LET_GO_M = OPEN_SUCCESS_M + 0.01
"""From this opening on (m) the state expert lets go of the handle."""
SAFE_HEIGHT_M = 0.11
"""Height of ``grasp_center`` for jaws over the cabinet: their tips clear its walls."""
PULL_SPEED_M = 0.002
"""Fastest straight move of the jaws while pulling (m per step)."""
HANDLE_MISSED_RAD = -0.12
"""A measured gripper angle under this, with the jaws commanded shut, closed on nothing
(on the bar the jaws stop at about -0.05 rad)."""


class OpenDrawerStateExpert(StateExpert):
    """From the state: come over the handle, lower the open jaws round the bar, close,
    pull along the slide until the drawer is open, let go and rise.

    The figures (yaw along the slide, grasp point, heights, opening) are
    :class:`OpenDrawerExpert`'s. Each step reads the drawer's opening, where its handle is
    and whether the jaws hold the bar (commanded shut, round the bar and touching it);
    holding it they pull it towards the opening :data:`PULL_TO_M`, otherwise they (re)grasp
    the handle wherever it is now.
    """

    hover_height_m = OpenDrawerExpert.hover_height_m
    retreat_height_m = OpenDrawerExpert.retreat_height_m
    open_rad = OpenDrawerExpert.open_rad
    fixed_jaw_gap_m = OpenDrawerExpert.fixed_jaw_gap_m

    def decide(self, commanded: np.ndarray) -> Move:
        c = self.config
        physics = self.physics
        slide = slide_direction(physics)
        outward = -slide
        grasp_yaw = math.atan2(outward[1], outward[0])
        handle = physics.fixture_position(DRAWER.name)
        opening = physics.fixture_joint_position(DRAWER.name)
        site, yaw = self.commanded_site(commanded)
        measured = physics.grasp_center()
        gripper_command = float(commanded[_N_ARM])
        gripper_measured = float(physics.joint_angles()[_N_ARM])
        if self.held_back(commanded):  # targets far off (pressed on something): relax first
            return Move("relax", None, yaw, float(commanded[_N_ARM]), stage="relax")
        if opening >= LET_GO_M:
            return self._let_go(site, yaw, gripper_measured)
        shut = gripper_command <= c.gripper_closed_rad + 0.05
        around = (
            float(np.hypot(*(measured[:2] - handle[:2]))) < 0.02
            and abs(float(measured[2] - handle[2])) < 0.012
        )
        if shut and around and any(physics.jaw_contacts_with(handle_geoms(physics))):
            pull = measured + (PULL_TO_M - opening) * slide
            pull[2] = handle[2]
            return Move(
                "line", pull, grasp_yaw, c.gripper_closed_rad, speed_m=PULL_SPEED_M, stage="pull"
            )
        return self._approach(handle, outward, grasp_yaw, site, measured, commanded)

    def _approach(
        self,
        handle: np.ndarray,
        outward: np.ndarray,
        grasp_yaw: float,
        site: np.ndarray,
        measured: np.ndarray,
        commanded: np.ndarray,
    ) -> Move:
        """Come over the handle with the jaws open, lower them round the bar and close."""
        c = self.config
        gripper_command = float(commanded[_N_ARM])
        gripper_measured = float(self.physics.joint_angles()[_N_ARM])
        # The fixed pad's inner face sits 15 mm behind grasp_center along -x.
        pad_offset = 0.015 - HANDLE_HALF_M[1] - self.fixed_jaw_gap_m
        grasp = handle + pad_offset * outward
        hover = grasp.copy()
        hover[2] = self.hover_height_m
        # Jaws over the cabinet rise higher, their tips clear of its walls, before they swing.
        over = self._over_cabinet(site, outward) or self._over_cabinet(measured, outward)
        top = SAFE_HEIGHT_M if over else self.hover_height_m
        low = site[2] < top - 0.01
        offset = float(np.hypot(*(site[:2] - grasp[:2])))
        if not low:  # start a descent only once the jaws are there, not just commanded there
            offset = max(offset, float(np.hypot(*(measured[:2] - grasp[:2]))))
        yaw_error = abs(math.remainder(self.commanded_site(commanded)[1] - grasp_yaw, math.tau))
        # Jaws held up by something (the bar's top): not aligned, rise again.
        blocked = measured[2] - site[2] > 0.012
        aligned = (
            offset < (c.aligned_low_m if low else c.aligned_m)
            and yaw_error < (0.2 if low else 0.08)
            and not blocked
        )
        is_open = gripper_command >= self.open_rad - 0.05
        opening = gripper_command > gripper_measured + 0.02
        closing = not is_open and not opening
        at_grasp = (
            float(np.linalg.norm(site - grasp)) < c.arrived_m
            and float(np.linalg.norm(measured - grasp)) < 2.5 * c.arrived_m
        )
        if closing and aligned and low:
            shut = gripper_command <= c.gripper_closed_rad + 0.01
            if shut and gripper_measured < HANDLE_MISSED_RAD:
                return Move("hold", None, grasp_yaw, self.open_rad, stage="missed")
            return Move("hold", None, grasp_yaw, c.gripper_closed_rad, stage="close")
        if aligned and is_open:
            if at_grasp:
                return Move("hold", None, grasp_yaw, c.gripper_closed_rad, stage="close")
            return Move("line", grasp, grasp_yaw, self.open_rad, stage="descend")
        if low and not aligned:
            return self.rise(commanded, top, self.open_rad, grasp_yaw)
        # A joint move all the way to the hover posture (the one the descent starts from:
        # straighter moves there tilt the wrist and can catch the drawer's front).
        if over:  # first out of the cabinet's way, above the hover point
            hover[2] = SAFE_HEIGHT_M
        hover_q, _ = self.solve(hover, grasp_yaw)
        if float(np.abs(hover_q - commanded[:_N_ARM]).max()) > 2e-3:
            return Move("joint", hover, grasp_yaw, self.open_rad, stage="approach")
        return Move("line", hover, grasp_yaw, self.open_rad, stage="align")

    def _over_cabinet(self, point: np.ndarray, inward: np.ndarray) -> bool:
        """Whether ``point`` lies over the cabinet or its drawer or near them (6 cm round
        the sides and back, 1.2 cm in front of the drawer's front as it is now)."""
        physics = self.physics
        cabinet = physics.fixture_body_pose(CABINET.name)[0]
        relative = point[:2] - cabinet[:2]
        depth = float(relative @ inward[:2])
        side = abs(float(relative[0] * inward[1] - relative[1] * inward[0]))
        front = -FRONT_FACE_Y_M + physics.fixture_joint_position(DRAWER.name) + 0.012
        margin = 0.06
        return (
            side < CABINET_HALF_WIDTH_M + margin and -front < depth < CABINET_HALF_DEPTH_M + margin
        )

    def _let_go(self, site: np.ndarray, yaw: float, gripper_measured: float) -> Move:
        """Open the jaws, then rise until their tips clear the bar, and stay."""
        if gripper_measured < self.open_rad - 0.1:
            return Move("hold", None, yaw, self.open_rad, stage="release")
        if site[2] >= self.retreat_height_m - 0.003:
            return Move("hold", None, yaw, self.open_rad, stage="done")
        up = site.copy()
        up[2] = self.retreat_height_m
        return Move("line", up, yaw, self.open_rad, stage="retreat")


SPEC = TaskSpec(
    name="OpenDrawer-v0",
    task=OpenDrawerTask,
    expert=OpenDrawerExpert,
    max_episode_steps=250,
    scene=Scene(fixtures=(CABINET, DRAWER)),
    instructions=("Pull the blue drawer open by its black handle.",),
    summary="pull the cabinet's drawer open by at least 6 cm",
    default_placement="uniform",
    aliases=("open_drawer",),
    state_expert=OpenDrawerStateExpert,
)
