"""The experts from perturbed states: ``python -m gym_soarm.expert --perturbed``.

A state expert (:class:`~gym_soarm.tasks.state_expert.StateExpert`) must finish from any
reachable state, not only from a reset. Each perturbation brings an episode into a state
the expert's own episodes never visit, then the expert acts until the episode ends:

* ``random``: 10 to 40 random actions from the reset;
* ``push``: after 20 to 120 expert steps, an object of the task gets a horizontal kick of
  0.2 to 0.4 m/s (it slides, tips or falls out of the jaws);
* ``drop``: once the expert holds its object, the jaws are opened for 10 steps;
* ``jaws``: the episode starts with the jaws half closed and the arm elsewhere (15 steps
  of a random arm move with the gripper at 0.2 rad);
* ``shove``: after 15 to 60 expert steps, 12 steps of random absolute joint targets
  (anywhere in the joints' ranges, whatever the control mode), then the expert again.
  A shove that leaves an object off the table or out of the arm's reach
  (:data:`REACH_M` from the shoulder pan axis) once it has come to rest
  (:data:`SETTLE_STEPS` later, or when the episode ends if sooner), or an episode that
  ends before the shove is over, is not counted (``applied`` False).

Tasks without an object have no ``push``, those that grasp none no ``drop``. Every perturbation is drawn from the
episode's seed, so a run is reproducible.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.expert import EXPERT_KINDS, make_expert
from gym_soarm.tasks import get_task
from gym_soarm.validation import check_choice, check_int, check_subset

PERTURBATIONS: tuple[str, ...] = ("random", "push", "drop", "jaws", "shove")
"""The perturbations :func:`evaluate_perturbed` knows."""

PERTURBED_SEED = 5_000
"""Episode ``k`` of a perturbed run resets with seed ``PERTURBED_SEED + k`` (unseen seeds)."""

_N_ARM = len(constants.ARM_JOINT_NAMES)
SHOVE_STEPS = 12
"""Steps of random absolute joint targets in a ``shove``."""
SETTLE_STEPS = 50
"""Steps after a shove (1 s) at which the objects must lie on the table and in reach
for the episode to count: a rolling or falling object has come to rest by then."""
REACH_M: tuple[float, float] = (0.08, 0.28)
"""Horizontal distances from the shoulder pan axis where an object counts as in reach."""


def _in_reach(env: gym.Env, objects: Sequence[str]) -> bool:
    """Whether every object rests on the table within :data:`REACH_M` of the pan axis."""
    physics = env.unwrapped.physics
    for name in objects:
        position = physics.object_position(name)
        radius = float(np.hypot(*(position[:2] - np.asarray(constants.PAN_AXIS_XY_M))))
        if position[2] < constants.TABLE_TOP_Z_M - 0.005 or not REACH_M[0] <= radius <= REACH_M[1]:
            return False
    return True


def _random_targets_action(env: gym.Env, rng: np.random.Generator) -> np.ndarray:
    """An action that sends the servos to random absolute targets within their ranges."""
    base = env.unwrapped
    low, high = base.physics.control_range()
    targets = rng.uniform(low, high)
    return base.control.action_for_targets(targets, np.asarray(base.commanded_targets))


@dataclasses.dataclass(frozen=True)
class PerturbedResult:
    """One perturbed episode: which perturbation, its seed, whether it succeeded."""

    perturbation: str
    seed: int
    success: bool
    applied: bool
    """False when the perturbation never happened (the episode ended before it, or the
    expert never held its object before a ``drop``)."""


def _hold_action(env: gym.Env, gripper_rad: float, arm_change: np.ndarray | None = None):
    base = env.unwrapped
    commanded = np.asarray(base.commanded_targets, dtype=np.float64)
    targets = commanded.copy()
    if arm_change is not None:
        targets[:_N_ARM] += arm_change
    targets[_N_ARM] = gripper_rad
    return base.control.action_for_targets(targets, commanded)


def _run(env: gym.Env, perturbation: str, seed: int, kind: str) -> PerturbedResult:
    base = env.unwrapped
    rng = np.random.default_rng(seed)
    expert = make_expert(env, kind=kind)
    obs, info = env.reset(seed=seed)
    objects = [item.name for item in base.task_spec.scene.objects]
    applied = False
    step = 0
    kick_at = int(rng.integers(20, 121))
    shove_at = int(rng.integers(15, 61))
    checked = False
    random_steps = int(rng.integers(10, 41))
    drop_left = 10
    env.action_space.seed(seed)
    while True:
        action = None
        if perturbation == "random" and step < random_steps:
            action, applied = env.action_space.sample(), True
        elif perturbation == "jaws" and step < 15:
            action = _hold_action(env, 0.2, rng.uniform(-0.03, 0.03, _N_ARM))
            applied = True
        elif perturbation == "push" and step == kick_at and objects:
            name = objects[int(rng.integers(len(objects)))]
            angle = rng.uniform(0.0, 2.0 * np.pi)
            speed = rng.uniform(0.2, 0.4)
            base.physics.push_object(name, np.array([np.cos(angle), np.sin(angle), 0.0]) * speed)
            applied = True
        elif (
            perturbation == "drop"
            and drop_left
            and (applied or any(base.physics.grasped(name) for name in objects))
        ):
            action, applied = _hold_action(env, expert.config.gripper_open_rad), True
            drop_left -= 1
        elif perturbation == "shove" and shove_at <= step < shove_at + SHOVE_STEPS:
            action, applied = _random_targets_action(env, rng), True
        if action is None:
            action = expert(obs, info)
        obs, _, terminated, truncated, info = env.step(action)
        step += 1
        settled = step == shove_at + SHOVE_STEPS + SETTLE_STEPS
        ended = terminated or truncated
        if perturbation == "shove" and objects and applied and (settled or (ended and not checked)):
            applied, checked = step >= shove_at + SHOVE_STEPS and _in_reach(env, objects), True
        if terminated or truncated:
            if perturbation == "shove" and step < shove_at + SHOVE_STEPS:
                applied = False
            return PerturbedResult(perturbation, seed, bool(info["is_success"]), applied)


def evaluate_perturbed(
    task: str,
    episodes: int = 20,
    perturbations: Sequence[str] = PERTURBATIONS,
    kind: str = "state",
    **env_kwargs,
) -> list[PerturbedResult]:
    """Run ``task``'s expert (of ``kind``, see :func:`~gym_soarm.expert.make_expert`)
    after each perturbation on ``episodes`` unseen seeds.

    Raises:
        ValueError: an unknown perturbation or task, or ``episodes`` < 1.
    """
    spec = get_task(task)
    episodes = check_int("episodes", episodes, 1)
    perturbations = check_subset("perturbations", perturbations, PERTURBATIONS)
    check_choice("kind", kind, EXPERT_KINDS)
    env = gym.make(spec.env_id, obs_type="environment_state_agent_pos", **env_kwargs)
    try:
        objects = bool(spec.scene.objects)
        grasps = objects and hasattr(make_expert(env), "grasp_object")
        return [
            _run(env, perturbation, PERTURBED_SEED + k, kind)
            for perturbation in perturbations
            if perturbation in ("random", "jaws", "shove")
            or (perturbation == "push" and objects)
            or (perturbation == "drop" and grasps)
            for k in range(episodes)
        ]
    finally:
        env.close()
