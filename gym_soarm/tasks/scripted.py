"""The scripted expert's machinery: phases, minimum-jerk motions and grasps.

A task's expert (beside its task, in the same module) subclasses
:class:`ScriptedExpert` and lists its phases. The expert moves through named phases —
typically approach above the object with the jaws open and aligned with its yaw,
descend, close, lift, then the task's own — with joint targets from inverse kinematics
on the MJCF model (:class:`~gym_soarm.sim.kinematics.ArmKinematics`) following a
minimum-jerk profile, so that the stiff 50 Hz position servos move smoothly. A grasp
that closes on nothing, or an object that falls out, is retried.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.envs.control import ControlMode
from gym_soarm.sim.kinematics import ArmKinematics, downward_rotation
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.grasp_figures import GraspFigures
from gym_soarm.validation import check_dataclass_fields, check_int

_QUARTER_TURN_RAD = math.pi / 2


@dataclasses.dataclass(frozen=True)
class ExpertConfig(GraspFigures):
    """Figures of the scripted motion: :class:`GraspFigures` and durations in control steps."""

    fixed_jaw_clearance_m: float = 0.004
    gripper_open_rad: float = 0.6
    """Gripper target while approaching: about 45 mm between the pads."""
    approach_steps: int = 55
    """Longest approach; a shorter joint move takes ``approach_speed_rad_per_step``."""
    approach_speed_rad_per_step: float = 0.03
    descend_steps: int = 35
    close_steps: int = 15
    lift_steps: int = 35
    carry_steps: int = 60
    lower_steps: int = 35
    release_steps: int = 12
    retreat_steps: int = 25
    hold_steps: int = 25
    """Lift task: how long to hold the object up after the lift."""
    rise_steps: int = 20
    """Before a new grasp: open the jaws and rise to the hover height."""
    max_regrasps: int = 2

    def __post_init__(self) -> None:
        super().__post_init__()
        check_dataclass_fields(
            self,
            lambda name: name.endswith("_steps"),
            lambda name, value, fix: check_int(name, value, 1, fix=fix),
        )
        check_int("max_regrasps", self.max_regrasps, 0)
        if not self.approach_speed_rad_per_step > 0.0:
            raise ValueError(
                "approach_speed_rad_per_step must be > 0; "
                f"got {self.approach_speed_rad_per_step!r}."
            )


DEFAULT_CONFIG = ExpertConfig()

# Elbow up, wrist bent down (arm joints, rad): where inverse kinematics starts from,
# turned towards the target by the shoulder pan.
READY_POSTURE_RAD = np.array([0.0, 0.0, 0.6, 1.1, 0.0])


def minimum_jerk(fraction: float) -> float:
    """Minimum-jerk progress (0 to 1, zero velocity and acceleration at both ends)."""
    s = min(max(fraction, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclasses.dataclass(frozen=True)
class Phase:
    """One segment of the script: its name, its length in steps and what starts it."""

    name: str
    steps: int
    begin: Callable[[], None]


class ScriptedExpert:
    """State-reading scripted policy for one SO-101 environment (base of every task's expert).

    Subclasses list their phases after the grasp in :meth:`_after_grasp_phases` and
    name the object to grasp in :meth:`grasp_object` (the scene's only object unless
    overridden).

    Call :meth:`reset` after every ``env.reset(...)`` (the expert also restarts by itself
    when it sees the simulation clock go back) and ``expert(obs, info)`` for each action.
    Observations are not used: the expert reads ``env.unwrapped.physics``.

    Each phase moves the servo targets from where the previous phase left them along a
    minimum-jerk profile: in joint space for the approach, round the shoulder pan axis
    for the carry, and in a straight line of the ``grasp_center`` site for every other
    arm motion. When a grasp fails (the jaws closed on nothing, or the object fell) the
    expert opens, rises and tries again, at most ``config.max_regrasps`` times.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        self.env = env.unwrapped
        self.config = config
        self._control: ControlMode = self.env.control
        physics: SoArmPhysics = self.env.physics
        self._kinematics = ArmKinematics(physics.model.ptr)
        self._n_arm = len(constants.ARM_JOINT_NAMES)
        self._roll = constants.ARM_JOINT_NAMES.index("wrist_roll")
        self._plan: list[Phase] = []
        self._phase_index = 0
        self._phase_step = 0
        self._phase_length = 1
        self._time = -math.inf
        self._regrasps = 0
        self._command = np.zeros(len(constants.JOINT_NAMES))
        self._segment: Callable[[float], np.ndarray] | None = None
        self._gripper_from = self._gripper_to = 0.0
        self._yaw = 0.0
        self._grasp_point = np.zeros(3)
        self._held_offset = np.zeros(3)

    def grasp_object(self) -> str:
        """Name of the object the next grasp is for: the scene's only object by default.

        Experts of scenes with several objects override this.
        """
        names = [item.name for item in self.env.task_spec.scene.objects]  # not distractors
        if len(names) != 1:
            raise NotImplementedError(
                f"{type(self).__name__} must name the object to grasp (override grasp_object); "
                f"this task has the objects {names}."
            )
        return names[0]

    # --- public API ------------------------------------------------------------------
    @property
    def phase(self) -> str:
        """Name of the phase the next action belongs to (``"done"`` after the script)."""
        if self._phase_index >= len(self._plan):
            return "done"
        return self._plan[self._phase_index].name

    @property
    def regrasps(self) -> int:
        """How many times this episode's grasp has been retried."""
        return self._regrasps

    def reset(self) -> None:
        """Start the script again from the environment's current (just reset) state."""
        physics = self.env.physics
        self._time = physics.data.time
        self._command = physics.joint_angles()
        self._regrasps = 0
        self._plan = self._grasp_phases() + self._after_grasp_phases()
        self._phase_index = 0
        self._begin_phase()

    def __call__(self, obs: Any = None, info: dict[str, Any] | None = None) -> np.ndarray:
        """The next action (float32) in the environment's ``control_mode`` and ``units``.

        The script's servo targets (:meth:`next_targets_radians`) become the mode's
        action through ``env.control.action_for_targets``: themselves for
        ``joint_pos``, their change from the env's current targets
        (``env.commanded_targets``) for ``joint_delta``, the jaws' pose (or its change)
        by forward kinematics for the ee modes.
        """
        targets = self.next_targets_radians()
        return self._control.action_for_targets(targets, self.env.commanded_targets)

    def next_targets_radians(self) -> np.ndarray:
        """The next six servo targets in radians (float64), gripper last.

        This advances the script like a call does; use one or the other per step.
        """
        now = self.env.physics.data.time
        if not self._plan or now < self._time:
            self.reset()
        self._time = now
        if self._phase_index < len(self._plan):
            self._phase_step += 1
            fraction = minimum_jerk(self._phase_step / self._phase_length)
            if self._segment is not None:
                self._command[: self._n_arm] = self._segment(fraction)
            gripper = self._gripper_from + fraction * (self._gripper_to - self._gripper_from)
            self._command[self._n_arm] = gripper
            if self._phase_step >= self._phase_length:
                self._phase_index += 1
                self._begin_phase()
        return self._command.copy()

    # --- the script ----------------------------------------------------------------------
    def _grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("approach", c.approach_steps, self._begin_approach),
            Phase("descend", c.descend_steps, self._begin_descend),
            Phase("close", c.close_steps, self._begin_close),
        ]

    def _after_grasp_phases(self) -> list[Phase]:
        raise NotImplementedError

    def _begin_phase(self) -> None:
        self._phase_step = 0
        if self._phase_index < len(self._plan):
            phase = self._plan[self._phase_index]
            self._phase_length = phase.steps
            # The gripper holds its last target unless the phase sets another.
            self._gripper(self._gripper_to)
            phase.begin()

    def _holding(self) -> bool:
        """False if the object is not in the jaws and a new grasp has been scheduled instead.

        Once ``config.max_regrasps`` retries are used up the script carries on regardless.
        """
        if (
            self.env.physics.grasped(self.grasp_object())
            or self._regrasps >= self.config.max_regrasps
        ):
            return True
        self._regrasps += 1
        # Start over from a grasp: rise, approach, descend, close, then lift and the rest.
        rise = Phase("rise", self.config.rise_steps, self._begin_rise)
        self._plan[self._phase_index :] = [
            rise,
            *self._grasp_phases(),
            *self._after_grasp_phases(),
        ]
        self._begin_phase()
        return False

    # --- motions --------------------------------------------------------------------------
    def _gripper(self, target: float) -> None:
        self._gripper_from = float(self._command[self._n_arm])
        self._gripper_to = target

    def _hold_arm(self) -> None:
        self._segment = None

    def _joint_move(self, target: np.ndarray) -> None:
        """Move the arm in joint space from the current targets to ``target``."""
        start = self._command[: self._n_arm].copy()
        self._segment = lambda s: start + s * (target - start)

    def _path_move(self, path: Callable[[float], tuple[np.ndarray, float]]) -> None:
        """Move ``grasp_center`` along ``path(s) -> (position, yaw)`` for s from 0 to 1.

        The jaws point down wherever the wrist allows it, turned to the path's yaw about
        the vertical. Each solve starts from the previous one, so the joints move smoothly.
        """
        guess = [self._command[: self._n_arm].copy()]

        def segment(s: float) -> np.ndarray:
            position, yaw = path(s)
            q, _, _ = self._kinematics.solve(guess[0], position, downward_rotation(yaw))
            guess[0] = q
            return q

        self._segment = segment

    def _line_move(self, position: np.ndarray, yaw: float) -> None:
        """Move ``grasp_center`` in a straight line to ``position``, turning to ``yaw``."""
        start, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        start_yaw, self._yaw = self._yaw, yaw
        self._path_move(
            lambda s: (start + s * (position - start), start_yaw + s * (yaw - start_yaw))
        )

    def _arc_move(self, position: np.ndarray) -> None:
        """Carry ``grasp_center`` to ``position`` round the shoulder pan axis.

        Distance from the axis, bearing and height change linearly, so the path keeps
        clear of the base, and the jaws turn with the bearing so that the wrist roll
        stays where it is.
        """
        kinematics = self._kinematics
        start, _ = kinematics.site_pose(self._command[: self._n_arm])
        r0, r1 = kinematics.radius(start), kinematics.radius(position)
        b0 = kinematics.bearing(start)
        turn = math.remainder(kinematics.bearing(position) - b0, math.tau)
        z0, z1 = start[2], position[2]
        start_yaw = self._yaw
        self._yaw = start_yaw + turn

        def path(s: float) -> tuple[np.ndarray, float]:
            return kinematics.cylindrical_point(
                r0 + s * (r1 - r0), b0 + s * turn, z0 + s * (z1 - z0)
            ), start_yaw + s * turn

        self._path_move(path)

    def _seed_towards(self, position: np.ndarray) -> np.ndarray:
        """An elbow-up, wrist-down posture turned towards ``position``: the IK start."""
        seed = READY_POSTURE_RAD.copy()
        seed[0] = self._kinematics.pan_towards(position)
        return seed

    def _grasp_yaws(self) -> list[float]:
        """The yaws the jaws may grasp the object at: its four face directions."""
        base = self.env.physics.object_yaw(self.grasp_object())
        return [base + quarter * _QUARTER_TURN_RAD for quarter in range(4)]

    def _choose_grasp_yaw(self, position: np.ndarray) -> float:
        """Of :meth:`_grasp_yaws`, the one the jaws reach with least wrist roll."""
        seed = self._seed_towards(position)
        yaws = self._grasp_yaws()
        best_yaw, best_cost = yaws[0], math.inf
        for yaw in yaws:
            q, position_error, rotation_error = self._kinematics.solve(
                seed, position, downward_rotation(yaw)
            )
            cost = abs(q[self._roll]) + 100.0 * (position_error + rotation_error)
            if cost < best_cost:
                best_yaw, best_cost = yaw, cost
        return best_yaw

    # --- phases ---------------------------------------------------------------------------
    def _begin_approach(self) -> None:
        config = self.config
        grasp = self.env.physics.object_position(self.grasp_object())
        grasp[2] = config.grasp_height_m
        self._yaw = self._choose_grasp_yaw(grasp)
        # The jaws descend with the fixed jaw clear of the object (shifted along the
        # gripper's -x axis, away from the moving jaw); closing pushes the object onto it.
        closing_axis = downward_rotation(self._yaw)[:, 0]
        self._grasp_point = grasp - config.fixed_jaw_clearance_m * closing_axis
        hover = self._grasp_point.copy()
        hover[2] = config.hover_height_m
        target, _, _ = self._kinematics.solve(
            self._seed_towards(hover), hover, downward_rotation(self._yaw)
        )
        # Short moves (a second attempt) take less time; the longest take approach_steps.
        distance = float(np.abs(target - self._command[: self._n_arm]).max())
        steps = math.ceil(distance / config.approach_speed_rad_per_step)
        self._phase_length = min(max(steps, config.rise_steps), config.approach_steps)
        self._joint_move(target)
        self._gripper(config.gripper_open_rad)

    def _begin_descend(self) -> None:
        self._line_move(self._grasp_point, self._yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_close(self) -> None:
        self._hold_arm()
        self._gripper(self.config.gripper_closed_rad)

    def _begin_rise(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[2] = max(site[2], self.config.hover_height_m)
        self._line_move(site, self._yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_lift(self) -> None:
        if not self._holding():
            return
        physics = self.env.physics
        # Where the held object sits relative to the site, to put it down precisely later.
        self._held_offset = physics.object_position(self.grasp_object()) - physics.grasp_center()
        target = self._kinematics.within_reach(physics.grasp_center(), self.config.lift_reach_m)
        target[2] = self.config.carry_height_m - self._held_offset[2]
        self._line_move(target, self._yaw)
        self._gripper(self.config.gripper_closed_rad)


class LiftExpert(ScriptedExpert):
    """Approach, descend, close and lift the object 2.5 cm above the 5 cm line, then hold.

    ``LiftCube-v0``'s expert; ``PickColoredCube-v0``'s aims it at the named cube.
    """

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("lift", c.lift_steps, self._begin_lift),
            Phase("hold", c.hold_steps, self._begin_hold),
        ]

    def _begin_hold(self) -> None:
        if self._holding():
            self._hold_arm()


class NoGraspExpert(ScriptedExpert):
    """Base of the experts that grasp nothing: their phases start with :meth:`_swing_to`.

    ``ReachTarget-v0``'s and ``PushCube-v0``'s experts build on it.
    """

    def _grasp_phases(self) -> list[Phase]:
        return []

    def _swing_to(self, position: np.ndarray, yaw: float) -> None:
        """Joint move of ``grasp_center`` to ``position``, jaws down at ``yaw`` and closed.

        The phase lasts as long as the largest joint turn needs at
        ``config.approach_speed_rad_per_step``, within ``config.rise_steps`` and
        ``config.approach_steps``.
        """
        config = self.config
        self._yaw = yaw
        goal, _, _ = self._kinematics.solve(
            self._seed_towards(position), position, downward_rotation(yaw)
        )
        distance = float(np.abs(goal - self._command[: self._n_arm]).max())
        steps = math.ceil(distance / config.approach_speed_rad_per_step)
        self._phase_length = min(max(steps, config.rise_steps), config.approach_steps)
        self._joint_move(goal)
        self._gripper(config.gripper_closed_rad)


class PlaceExpert(ScriptedExpert):
    """Grasp an object, lift it, carry it over a spot, lower it there, release and retreat.

    Subclasses give :meth:`place_target`: where the object's centre rests when placed.
    """

    def place_target(self) -> np.ndarray:
        """World position (m) of the placed object's centre, resting where it belongs."""
        raise NotImplementedError

    def _after_grasp_phases(self) -> list[Phase]:
        c = self.config
        return [
            Phase("lift", c.lift_steps, self._begin_lift),
            Phase("carry", c.carry_steps, self._begin_carry),
            Phase("lower", c.lower_steps, self._begin_lower),
            Phase("release", c.release_steps, self._begin_release),
            Phase("retreat", c.retreat_steps, self._begin_retreat),
        ]

    def _site_target(self, centre: np.ndarray) -> np.ndarray:
        """Where ``grasp_center`` goes to bring the held object's centre to ``centre``."""
        physics = self.env.physics
        self._held_offset = physics.object_position(self.grasp_object()) - physics.grasp_center()
        return centre - self._held_offset

    def _begin_carry(self) -> None:
        if not self._holding():
            return
        target = self.place_target()
        carry = max(self.config.carry_height_m, target[2] + self.config.carry_height_m / 2)
        self._arc_move(self._site_target(np.array([target[0], target[1], carry])))

    def _begin_lower(self) -> None:
        if not self._holding():
            return
        target = self.place_target()
        target[2] += self.config.place_clearance_m
        self._line_move(self._site_target(target), self._yaw)

    def _release_opening(self) -> float:
        """The gripper target that lets go."""
        return self.config.gripper_open_rad

    def _begin_release(self) -> None:
        self._hold_arm()
        self._gripper(self._release_opening())

    def _begin_retreat(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        # Slide the fixed jaw off the object's face, then rise.
        closing_axis = downward_rotation(self._yaw)[:, 0]
        target = site - self.config.fixed_jaw_clearance_m * 2.5 * closing_axis
        target[2] = max(self.config.retreat_height_m, site[2])
        self._line_move(target, self._yaw)


class OneAfterAnother(PlaceExpert):
    """A place expert's script for several objects, one after another (before another
    :class:`PlaceExpert` in the bases, it adds this to that one's placement).

    After each retreat a ``next`` phase looks at the table again: it plans a new grasp
    (approach, descend, close) and placement for the first object :meth:`remaining`
    names, the same one again if its placement missed, or ends the script when none is
    left. The retreat rises straight up with the jaws as released: the base retreat
    slides sideways first, towards the objects still to place, and sets no gripper
    motion of its own, so the release's would play again and pick the placed object
    back up.
    """

    objects: tuple[str, ...] = ()
    """Every object the script places (the first is worked on when none remains)."""

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        super().__init__(env, config)
        self._current = self.objects[0]

    def remaining(self) -> tuple[str, ...]:
        """The objects still to place, in order."""
        raise NotImplementedError

    def grasp_object(self) -> str:
        return self._current

    def reset(self) -> None:
        remaining = self.remaining()
        self._current = remaining[0] if remaining else self.objects[0]
        super().reset()

    def _after_grasp_phases(self) -> list[Phase]:
        return [*super()._after_grasp_phases(), Phase("next", 1, self._begin_next)]

    def _begin_retreat(self) -> None:
        site, _ = self._kinematics.site_pose(self._command[: self._n_arm])
        site[2] = max(self.config.retreat_height_m, site[2])
        self._line_move(site, self._yaw)
        self._gripper(self._release_opening())

    def _begin_next(self) -> None:
        self._hold_arm()
        remaining = self.remaining()
        if not remaining:
            return
        self._current = remaining[0]
        self._regrasps = 0
        self._plan[self._phase_index :] = [*self._grasp_phases(), *self._after_grasp_phases()]
        self._begin_phase()
