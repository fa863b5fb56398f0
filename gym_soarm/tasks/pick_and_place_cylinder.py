"""``PickAndPlaceCylinder-v0``: stand the orange cylinder upright on the purple pad.

The scene: an upright orange cylinder (1.45 cm radius, 5.5 cm tall, 20 g) and a purple
pad of 4 cm radius painted on the table at (-0.18, 0.28) m (visual only: the cylinder
stands on the table beneath it). At every reset the cylinder's centre is drawn uniformly
in the reachable region x in [-0.12, 0.12] m, y in [0.275, 0.425] m, clear of the pad,
of the strip |x| < 0.05 m beneath the arm's resting pose (where the overview camera could
not see it) and at least 16 cm from the robot base's centre (nearer, the wrist cannot
hold the jaws vertical above the tall cylinder's top); its yaw is irrelevant.

Success: the cylinder stands upright (its axis within 10 degrees of vertical, on either
end) on the pad (its centre within the pad's radius, its bottom within 5 mm of the
table), neither jaw touches it and it is at rest.

Reward terms are stages — ``reach`` (jaws near the cylinder), ``grasp`` (both pads on
it), ``lift`` (its bottom raised towards 5 cm while held), ``place`` (carried over the
pad, then standing on it, then released) — and a later stage counts every earlier one
as complete, so the reward never falls as the task progresses.

The expert grasps the cylinder around its middle, from whichever side the wrist
reaches with least roll, carries it round the shoulder pan axis, lowers it onto the
pad, lets go and rises.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays, namespace, xy_distance
from gym_soarm.sim.kinematics import JawPose
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, Task, TaskSpec
from gym_soarm.tasks.placing import PlacementScoring
from gym_soarm.tasks.scripted import DEFAULT_CONFIG, ExpertConfig, PlaceExpert
from gym_soarm.tasks.state_expert import (
    DEFAULT_STATE_CONFIG,
    Move,
    PlaceStateExpert,
    StateExpertConfig,
)
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    fixture_position_field,
    object_pose_fields,
)

CYLINDER_RADIUS_M = 0.0145
CYLINDER_HALF_HEIGHT_M = 0.0275
CYLINDER = SceneObject(
    name="cylinder",
    shape="cylinder",
    size_m=(CYLINDER_RADIUS_M, CYLINDER_HALF_HEIGHT_M),
    colour="orange",
    mass_kg=0.02,
    position_m=placement.GRID_CENTER_M,
)
"""The 2.9 cm wide, 5.5 cm tall, 20 g orange cylinder, standing on its base."""

START_REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.12, 0.12), (0.275, 0.425))
"""Where the cylinder's centre (x, y) is drawn: where the arm reaches with its jaws down."""
ARM_SHADOW_HALF_WIDTH_M = 0.035
"""Half width of the strip of table (about x = 0) that the resting arm hides from the
overview camera: the cylinder's footprint starts clear of it."""
MIN_BASE_DISTANCE_M = 0.16
"""The cylinder starts at least this far from the robot base's centre: nearer, the wrist
cannot point the jaws straight down at the height that clears the cylinder's top."""
MAX_START_DRAWS = 1000

PAD_RADIUS_M = 0.04
PAD_POSITION_M = (-0.18, 0.28, 0.0)
PAD = Fixture(
    name="pad",
    position_m=PAD_POSITION_M,
    geoms=(
        FixtureGeom(
            "cylinder",
            (PAD_RADIUS_M, 0.0005),
            "purple",
            (0.0, 0.0, 0.0005),
            collides=False,
            emission=0.2,
        ),
    ),
    site_m=(0.0, 0.0, 0.001),
)
"""A thin purple disc on the table (visual only: the cylinder stands on the table beneath it)."""

MAX_TILT_DEG = 10.0
"""The cylinder counts as upright while its axis is within this angle of vertical."""
PLACE_HEIGHT_TOL_M = 0.005
LIFT_DEAD_BAND_M = 0.002
"""Lift counts from this height: closing jaws rock a standing cylinder by a fraction of it."""

_COS_MAX_TILT = math.cos(math.radians(MAX_TILT_DEG))


def tilt_cosine(quaternion: Array) -> Array:
    """Cosine of the angle between a body's z axis and the vertical, either way up (the
    cylinder is the same on either end), from its (w, x, y, z) quaternion (the last
    axis: ``(4,)`` or ``(n, 4)``)."""
    x, y = quaternion[..., 1], quaternion[..., 2]
    return abs(1.0 - 2.0 * (x * x + y * y))


def tilt_deg(quaternion: Array) -> Array:
    """The angle (degrees, 0 to 90) between a body's z axis and the vertical, either way
    up, from its (w, x, y, z) quaternion."""
    xp = namespace(quaternion)
    cosine = tilt_cosine(quaternion)
    return xp.acos(xp.minimum(xp.maximum(cosine, -1.0), 1.0)) * (180.0 / math.pi)


def draw_start(rng: np.random.Generator) -> tuple[float, float]:
    """The cylinder's start (x, y): uniform in :data:`START_REGION_M`, clear of the pad, of
    the strip the resting arm hides from the overview camera and of the base's surroundings.

    Raises:
        RuntimeError: no draw of :data:`MAX_START_DRAWS` was clear (a broken region).
    """
    px, py, _ = PAD_POSITION_M
    bx, by, _ = constants.ROBOT_BASE_POS_M
    radius = CYLINDER.footprint_radius_m
    for _ in range(MAX_START_DRAWS):
        ((x, y),) = placement.draw_uniform_positions(
            rng, [radius], START_REGION_M, keep_clear=[(px, py, PAD_RADIUS_M)]
        )
        clear_of_arm = abs(x) >= ARM_SHADOW_HALF_WIDTH_M + radius
        if clear_of_arm and math.hypot(x - bx, y - by) >= MIN_BASE_DISTANCE_M:
            return x, y
    raise RuntimeError(
        f"no start for the cylinder in {START_REGION_M} clear of |x| < "
        f"{ARM_SHADOW_HALF_WIDTH_M + radius} m and {MIN_BASE_DISTANCE_M} m from the base "
        f"after {MAX_START_DRAWS} draws."
    )


class PickAndPlaceCylinderTask(PlacementScoring, Task):
    """Pick the cylinder up and stand it, released and at rest, upright on the purple pad."""

    state_fields: ClassVar = (
        *object_pose_fields(CYLINDER.name),
        GRIPPER_POSITION_FIELD,
        fixture_position_field("pad", PAD.name),
    )
    goal_pairs: ClassVar = (("cylinder_pos", "pad_pos"),)
    episode_shapes: ClassVar = MappingProxyType({"start_xy": (2,)})
    """Where the cylinder started (x, y; m), for the info."""
    cylinder = carried = CYLINDER.name
    placed_key = "standing_on_pad"
    distance_key = "pad_distance_m"
    over_radius_m = PAD_RADIUS_M
    near_bound_m = PAD_RADIUS_M / 2
    lift_dead_band_m = LIFT_DEAD_BAND_M

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()
        x, y = draw_start(rng)
        physics.set_object_pose(
            self.cylinder,
            np.array([x, y, constants.TABLE_TOP_Z_M + CYLINDER_HALF_HEIGHT_M]),
            placement.yaw_quaternion(0.0),
        )
        self.episode["start_xy"][0] = (x, y)

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        tilt = tilt_deg(sim.object_quaternion(self.cylinder))
        return {
            "cylinder_start_xy": sim.episode["start_xy"],
            "cylinder_pos": sim.object_position(self.cylinder),
            "cylinder_tilt_deg": tilt,  # from vertical, either end up: 0 to 90
            "target_pos": sim.fixture_position(PAD.name),
        }

    def placed(self, sim: SimArrays) -> tuple[Array, Array]:
        """Standing on the pad: upright, centred within the pad's radius and with its
        bottom on the table."""
        position = sim.object_position(self.cylinder)
        distance = xy_distance(position, sim.fixture_position(PAD.name))
        upright = tilt_cosine(sim.object_quaternion(self.cylinder)) >= _COS_MAX_TILT
        bottom = position[..., 2] - CYLINDER_HALF_HEIGHT_M - constants.TABLE_TOP_Z_M
        on_table = sim.xp.abs(bottom) <= PLACE_HEIGHT_TOL_M
        return (distance <= PAD_RADIUS_M) & upright & on_table, distance


CYLINDER_EXPERT_CONFIG = dataclasses.replace(
    DEFAULT_CONFIG,
    hover_height_m=0.09,
    grasp_height_m=0.03,
    carry_height_m=0.09,
    retreat_height_m=0.11,
)
"""The expert's figures for the 5.5 cm tall cylinder: it hovers with the jaw tips above
its top, closes around its middle and carries it with its bottom 6 cm above the table."""

_GRASP_YAW_CANDIDATES = 16
"""Jaw directions tried (evenly round a full turn) when choosing how to grasp the cylinder."""


class PickAndPlaceCylinderExpert(PlaceExpert):
    """Grasp the cylinder around its middle, carry it over the pad, stand it there, let go.

    With the default :class:`ExpertConfig` it uses :data:`CYLINDER_EXPERT_CONFIG`
    (higher hover, grasp and carry heights); any other config is used as given.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        super().__init__(env, CYLINDER_EXPERT_CONFIG if config is DEFAULT_CONFIG else config)

    def grasp_object(self) -> str:
        return CYLINDER.name

    def place_target(self) -> np.ndarray:
        pad = self.env.physics.fixture_position(PAD.name)
        return np.array([pad[0], pad[1], constants.TABLE_TOP_Z_M + CYLINDER_HALF_HEIGHT_M])

    def _begin_retreat(self) -> None:
        super()._begin_retreat()
        # Keep the jaws open while rising (the release phase opened them).
        self._gripper(self.config.gripper_open_rad)

    def _grasp_yaws(self) -> list[float]:
        """A round object can be grasped from any side."""
        return [math.tau * index / _GRASP_YAW_CANDIDATES for index in range(_GRASP_YAW_CANDIDATES)]


CYLINDER_STATE_CONFIG = dataclasses.replace(
    DEFAULT_STATE_CONFIG,
    hover_height_m=CYLINDER_EXPERT_CONFIG.hover_height_m,
    grasp_height_m=CYLINDER_EXPERT_CONFIG.grasp_height_m,
    carry_height_m=CYLINDER_EXPERT_CONFIG.carry_height_m,
    retreat_height_m=CYLINDER_EXPERT_CONFIG.retreat_height_m,
)
"""The state expert's heights for the tall cylinder (as the scripted one's)."""


LYING_DEG = 45.0
"""A cylinder tilted further than this lies on its side: the expert stands it up first."""
STAND_RADIUS_M = 0.26
"""Distance from the shoulder pan axis where a lying cylinder is stood up, on the pad's
bearing: the jaws can point horizontally there (nearer the base, as at the pad itself,
the wrist flex runs out of range)."""
STAND_HEIGHT_M = 0.065
"""Height of the jaws' centre while a held lying cylinder turns upright."""
STANDING_PITCH_RAD = math.pi / 2
"""The jaws' pitch (horizontal, tips outward) that holds the turned cylinder upright."""
PITCHED_RAD = 0.3
"""Jaws pitched further than this, by the cylinder: the stand-up is under way."""
UPRIGHT_DEG = 8.0
"""A held cylinder within this tilt of vertical is set down on the table."""
LYING_CARRY_SPEEDUP = 2.0
"""A held lying cylinder goes out to the stand point at this many times ``carry_speed_m``:
the stand-up (about 150 steps, 60-70 of them this carry) and the second grasp after it
take about 200 of the task's 400 steps."""
_N_ARM_JOINTS = len(constants.ARM_JOINT_NAMES)


class PickAndPlaceCylinderStateExpert(PlaceStateExpert):
    """From the state: grasp the cylinder round its middle from the side needing least
    wrist roll, carry it over the pad, stand it there, let go and rise.

    A cylinder lying on its side (after a push, a shove or a slip) is stood up first,
    where the arm can: grasped from above across its middle, carried out to
    :data:`STAND_RADIUS_M` on the pad's bearing with its axis turned into the arm's
    plane (the jaws' closing line at right angles to it), turned upright by pitching
    the jaws up to horizontal about that line, set down on the table and let go; the
    jaws back away and turn down again, and the standing cylinder is picked and placed
    as usual. Every stage is read off the state: the cylinder's tilt, whether it is
    held, and the commanded jaws' pitch.
    """

    def __init__(self, env: gym.Env, config: StateExpertConfig = CYLINDER_STATE_CONFIG) -> None:
        super().__init__(env, config)

    def grasp_object(self) -> str:
        return CYLINDER.name

    def tilt_deg(self) -> float:
        """The cylinder's tilt from vertical (degrees)."""
        return float(tilt_deg(self.physics.object_quaternion(CYLINDER.name)))

    def _axis_yaw(self) -> float:
        """The direction of the cylinder's axis on the table (rad)."""
        w, x, y, z = (float(v) for v in self.physics.object_quaternion(CYLINDER.name))
        # The body's z axis (the cylinder's) in the world: its horizontal part.
        return math.atan2(2.0 * (y * z - w * x), 2.0 * (x * z + w * y))

    def grasp_yaws(self, name: str) -> list[float]:
        if self.tilt_deg() > LYING_DEG:  # closing across the lying body
            across = self._axis_yaw() + math.pi / 2
            return [across, across + math.pi]
        return [math.tau * k / _GRASP_YAW_CANDIDATES for k in range(_GRASP_YAW_CANDIDATES)]

    def grasp_height(self, name: str) -> float:
        if self.tilt_deg() > LYING_DEG:  # level with the lying body's axis
            return constants.TABLE_TOP_Z_M + CYLINDER_RADIUS_M + 0.002
        return self.config.grasp_height_m

    def place_target(self, name: str) -> np.ndarray:
        pad = self.physics.fixture_position(PAD.name)
        return np.array([pad[0], pad[1], constants.TABLE_TOP_Z_M + CYLINDER_HALF_HEIGHT_M])

    def decide(self, commanded: np.ndarray) -> Move:
        pose = self._kinematics.jaw_pose(commanded[:_N_ARM_JOINTS])
        # Pitched jaws at the cylinder: the stand-up (the arm's rest pose has the jaws
        # horizontal too, far from anything).
        near = np.linalg.norm(self.physics.object_position(CYLINDER.name) - pose.position)
        if pose.pitch > PITCHED_RAD and near < 0.06:
            return self._stand_up(commanded, pose)
        return super().decide(commanded)

    def transport(self, name: str, commanded: np.ndarray, site: np.ndarray, yaw: float) -> Move:
        if self.tilt_deg() > LYING_DEG:
            return self._carry_to_stand(site, yaw)
        return super().transport(name, commanded, site, yaw)

    def _carry_to_stand(self, site: np.ndarray, yaw: float) -> Move:
        """Held lying: out to the stand point with the cylinder's axis along the arm's
        plane, then start pitching the jaws up."""
        c = self.config
        kinematics = self._kinematics
        # Out on the pad's bearing: the cylinder is stood a short carry from the pad.
        pad = self.physics.fixture_position(PAD.name)
        stand = kinematics.cylindrical_point(
            STAND_RADIUS_M, kinematics.bearing(pad), STAND_HEIGHT_M
        )
        # The closing line at right angles to the arm's plane (a roll of a quarter turn,
        # the nearer one): the pitch then turns about it, the cylinder's axis with it.
        across = kinematics.bearing(stand) + math.pi / 2
        if abs(math.remainder(yaw - across, math.tau)) > math.pi / 2:
            across += math.pi
        turned = abs(math.remainder(yaw - across, math.tau)) < 0.05
        if float(np.linalg.norm(site - stand)) < 0.01 and turned:
            return Move(
                "pose", stand, yaw, c.gripper_closed_rad, pitch=STANDING_PITCH_RAD, stage="stand"
            )
        return Move(
            "line",
            stand,
            across,
            c.gripper_closed_rad,
            speed_m=LYING_CARRY_SPEEDUP * c.carry_speed_m,
            stage="carry",
        )

    def _stand_up(self, commanded: np.ndarray, pose: JawPose) -> Move:
        """The jaws pitched at the cylinder: turn it upright, set it down and let go; or,
        with nothing held, back away and turn the jaws down again."""
        c = self.config
        physics = self.physics
        gripper_command = float(commanded[_N_ARM_JOINTS])
        held = physics.grasped(CYLINDER.name) and gripper_command <= c.gripper_closed_rad + 0.05
        if held and self.tilt_deg() > UPRIGHT_DEG:
            return Move(
                "pose", pose.position, 0.0, c.gripper_closed_rad,
                pitch=STANDING_PITCH_RAD, stage="stand",
            )  # fmt: skip
        if held:
            bottom = physics.object_position(CYLINDER.name)[2] - CYLINDER_HALF_HEIGHT_M
            clearance = bottom - constants.TABLE_TOP_Z_M
            if clearance > 0.006:
                down = pose.position - np.array([0.0, 0.0, clearance - 0.003])
                return Move(
                    "pose", down, 0.0, c.gripper_closed_rad, speed_m=0.006,
                    pitch=STANDING_PITCH_RAD, stage="set down",
                )  # fmt: skip
            return Move("hold", None, 0.0, c.gripper_open_rad, stage="let go")
        if gripper_command < c.gripper_open_rad - 0.05:
            return Move("hold", None, 0.0, c.gripper_open_rad, stage="let go")
        kinematics = self._kinematics
        back = kinematics.cylindrical_point(
            kinematics.radius(pose.position) - 0.04,
            kinematics.bearing(pose.position),
            c.hover_height_m,
        )
        return Move(
            "pose", back, 0.0, c.gripper_open_rad, speed_m=0.006, pitch=0.0, stage="back away"
        )


SPEC = TaskSpec(
    name="PickAndPlaceCylinder-v0",
    task=PickAndPlaceCylinderTask,
    expert=PickAndPlaceCylinderExpert,
    max_episode_steps=400,
    scene=Scene(objects=(CYLINDER,), fixtures=(PAD,)),
    instructions=("Pick up the orange cylinder and stand it upright on the purple pad.",),
    summary="pick the cylinder up and stand it upright on the purple pad",
    default_placement="uniform",
    aliases=("pick_and_place_cylinder",),
    state_expert=PickAndPlaceCylinderStateExpert,
)
