"""Episode logic: where the cube starts, what earns reward, what counts as success.

One :class:`dm_control.suite.base.Task` subclass per task. Tasks never draw random
numbers of their own: the environment hands them its ``np_random`` generator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from dm_control.suite import base

from gym_soarm import constants
from gym_soarm.physics import SoArmPhysics


def _norm(vector: np.ndarray) -> float:
    """Euclidean norm of a 1-D float array: what np.linalg.norm computes, with less overhead."""
    return math.sqrt(vector.dot(vector))


def tolerance(distance: float, bound: float, margin: float) -> float:
    """1 inside ``bound``, falling smoothly to 0.1 at ``bound + margin``, in [0, 1]."""
    if distance <= bound:
        return 1.0
    x = (distance - bound) / margin
    return float(math.exp(-math.log(10.0) * x * x))


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """Weights of the dense reward terms; they sum to 1 so the total is in [0, 1]."""

    terms: Mapping[str, float]

    def __post_init__(self) -> None:
        if not math.isclose(sum(self.terms.values()), 1.0):
            raise ValueError(f"reward weights must sum to 1, got {dict(self.terms)!r}")
        object.__setattr__(self, "terms", MappingProxyType(dict(self.terms)))

    def total(self, values: Mapping[str, float]) -> float:
        return float(sum(w * values[name] for name, w in self.terms.items()))


PICK_AND_PLACE_WEIGHTS = RewardWeights({"reach": 0.1, "grasp": 0.2, "lift": 0.3, "place": 0.4})
LIFT_WEIGHTS = RewardWeights({"reach": 0.2, "grasp": 0.3, "lift": 0.5})

REACH_MARGIN_M = 0.10
CARRY_HEIGHT_M = 0.05
PLACE_MARGIN_M = 0.20
RESTING_SPEED_M_S = 0.05
# Share of the place term earned by carrying the held cube over the pad, and by a cube
# that sits on the pad but is still held or moving; the release earns the rest.
PLACE_CARRY_CREDIT = 0.8
PLACE_ON_PAD_CREDIT = 0.9


@dataclasses.dataclass(frozen=True)
class EpisodeStart:
    """Where the cube starts: its grid cell and its yaw in degrees."""

    grid_cell: int
    yaw_deg: float


class SoArmTask(base.Task):
    """Shared episode logic of the SO-101 cube tasks."""

    name: str = ""
    description: str = ""
    weights: RewardWeights

    def __init__(self) -> None:
        super().__init__(random=None)
        self.rng: np.random.Generator | None = None
        self._requested_cell: int | None = None
        self._requested_yaw: float | None = None
        self.start: EpisodeStart | None = None

    def configure_episode(
        self, rng: np.random.Generator, grid_cell: int | None, yaw_deg: float | None
    ) -> None:
        """Set the generator and the (already validated) options of the next episode."""
        self.rng = rng
        self._requested_cell = grid_cell
        self._requested_yaw = yaw_deg

    def initialize_episode(self, physics: SoArmPhysics) -> None:
        """Home pose for the arm and the cube on its grid cell; called in a reset context."""
        if self.rng is None:
            raise RuntimeError("configure_episode() must be called before initialize_episode()")
        cell = self._requested_cell
        if cell is None:
            cell = int(self.rng.integers(constants.NUM_GRID_CELLS))
        yaw = self._requested_yaw
        if yaw is None:
            yaw = float(
                constants.CUBE_YAWS_DEG[int(self.rng.integers(len(constants.CUBE_YAWS_DEG)))]
            )
        self._requested_cell = self._requested_yaw = None  # options apply to one reset only
        physics.reset_to_home()
        x, y = constants.grid_cell_position(cell)
        half = math.radians(yaw) / 2
        physics.set_cube_pose(
            np.array([x, y, constants.TABLE_TOP_Z_M + constants.CUBE_HALF_M]),
            np.array([math.cos(half), 0.0, 0.0, math.sin(half)]),
        )
        self.start = EpisodeStart(cell, float(yaw))
        super().initialize_episode(physics)

    def before_step(self, action: np.ndarray, physics: SoArmPhysics) -> None:
        physics.set_joint_targets(action)

    def get_observation(self, physics: SoArmPhysics) -> dict[str, np.ndarray]:
        return {"agent_pos": physics.joint_angles()}

    # --- reward ------------------------------------------------------------------------
    def reward_terms(self, physics: SoArmPhysics, success: bool | None = None) -> dict[str, float]:
        """The named reward terms, each in [0, 1].

        Args:
            physics: the simulation to score.
            success: ``is_success(physics)`` when the caller already has it (it is not
                computed twice per step then).
        """
        raise NotImplementedError

    def get_reward(self, physics: SoArmPhysics) -> float:
        return self.weights.total(self.reward_terms(physics))

    def is_success(self, physics: SoArmPhysics) -> bool:
        raise NotImplementedError

    def get_termination(self, physics: SoArmPhysics) -> float | None:
        return 0.0 if self.is_success(physics) else None

    def _reach(self, physics: SoArmPhysics) -> float:
        distance = _norm(physics.grasp_center() - physics.cube_position())
        return tolerance(distance, 0.01, REACH_MARGIN_M)

    @staticmethod
    def _lift_progress(physics: SoArmPhysics) -> float:
        """How far a held cube is raised towards the carry height, in [0, 1]."""
        return min(max(physics.cube_bottom_height() / CARRY_HEIGHT_M, 0.0), 1.0)


class PickAndPlaceTask(SoArmTask):
    """Pick the cube up and put it down on the green pad.

    Success: the cube's centre is within the pad's radius, its bottom within 5 mm of
    the pad's top, it is at rest and neither jaw touches it.
    """

    name = "PickAndPlaceCube-v0"
    description = "Pick up the blue cube and place it on the green pad."
    weights = PICK_AND_PLACE_WEIGHTS

    @staticmethod
    def _goal_distance(physics: SoArmPhysics) -> float:
        """Horizontal distance (m) from the cube's centre to the pad's centre."""
        offset = physics.cube_position()[:2] - physics.goal_position()[:2]
        return math.hypot(offset[0], offset[1])

    @staticmethod
    def _on_goal(physics: SoArmPhysics, goal_distance: float) -> bool:
        if goal_distance > constants.GOAL_RADIUS_M:
            return False
        height = physics.cube_bottom_height() - constants.GOAL_TOP_Z_M
        return abs(height) <= constants.PLACE_HEIGHT_TOL_M

    def is_success(self, physics: SoArmPhysics) -> bool:
        return (
            self._on_goal(physics, self._goal_distance(physics))
            and not physics.cube_touched_by_jaws()
            and _norm(physics.cube_velocity()) < RESTING_SPEED_M_S
        )

    def reward_terms(self, physics: SoArmPhysics, success: bool | None = None) -> dict[str, float]:
        if self.is_success(physics) if success is None else success:
            return dict.fromkeys(self.weights.terms, 1.0)
        # Stages in order: reach, grasp, lift, place. A later stage counts every earlier
        # one as complete, so the reward never falls as the task progresses.
        goal_distance = self._goal_distance(physics)
        if self._on_goal(physics, goal_distance):
            # On the pad but still held or moving: only the release is missing.
            return {"reach": 1.0, "grasp": 1.0, "lift": 1.0, "place": PLACE_ON_PAD_CREDIT}
        if not physics.cube_grasped():
            return {"reach": self._reach(physics), "grasp": 0.0, "lift": 0.0, "place": 0.0}
        # A held cube above the pad counts as lifted, so lowering it onto the pad loses nothing.
        lift = 1.0 if goal_distance <= constants.GOAL_RADIUS_M else self._lift_progress(physics)
        near_goal = tolerance(goal_distance, constants.GOAL_RADIUS_M / 2, PLACE_MARGIN_M)
        return {
            "reach": 1.0,
            "grasp": 1.0,
            "lift": lift,
            "place": PLACE_CARRY_CREDIT * near_goal * lift,
        }


class LiftTask(SoArmTask):
    """Lift the cube 5 cm off the table.

    Success: the cube's bottom is at least 5 cm above the table while both jaws hold it.
    """

    name = "LiftCube-v0"
    description = "Pick up the blue cube and lift it 5 cm above the table."
    weights = LIFT_WEIGHTS

    def is_success(self, physics: SoArmPhysics) -> bool:
        return physics.cube_grasped() and physics.cube_bottom_height() >= constants.LIFT_HEIGHT_M

    def reward_terms(self, physics: SoArmPhysics, success: bool | None = None) -> dict[str, float]:
        if not physics.cube_grasped():
            return {"reach": self._reach(physics), "grasp": 0.0, "lift": 0.0}
        height = physics.cube_bottom_height() / constants.LIFT_HEIGHT_M
        return {"reach": 1.0, "grasp": 1.0, "lift": min(max(height, 0.0), 1.0)}


TASKS: dict[str, type[SoArmTask]] = {
    "pick_and_place": PickAndPlaceTask,
    "lift": LiftTask,
}
