"""Experts: ``make_expert(env)`` for any registered task (acting from the state, or the timed script), and their success rate.

Each task's expert lives beside the task, in its module under :mod:`gym_soarm.tasks`
(the machinery is :mod:`gym_soarm.tasks.scripted`). It reads the simulation state
(never pixels), so it works with every ``obs_type``::

    env = gym.make("SoArm-v0")
    expert = gym_soarm.make_expert(env)
    obs, info = env.reset(seed=0)
    expert.reset()
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        if terminated or truncated:
            break

Run ``python -m gym_soarm.expert`` (or ``gym-soarm-expert``) to measure every task's
expert over its evaluation resets (the table in docs/tasks.md).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.tasks import get_task
from gym_soarm.tasks.scripted import DEFAULT_CONFIG, ExpertConfig, ScriptedExpert
from gym_soarm.tasks.state_expert import DEFAULT_STATE_CONFIG, StateExpert, StateExpertConfig
from gym_soarm.tasks.suites import EVAL_SEED
from gym_soarm.validation import ArgumentTypeError, check_choice

EVALUATION_SEEDS = 3
"""Seeds per grid cell and yaw for grid tasks (9 x 4 x 3 = 108 episodes)."""
EVALUATION_EPISODES = 100
"""Seeded resets (seeds 0 .. 99) for tasks that place objects anywhere."""


EXPERT_KINDS = ("state", "scripted")
"""``make_expert``'s kinds: ``"state"`` acts from the state alone (the default where the
task has one), ``"scripted"`` follows its timed script."""


def make_expert(
    env: gym.Env | gym.vector.VectorEnv,
    config: ExpertConfig | StateExpertConfig | None = None,
    kind: str = "state",
) -> ScriptedExpert | StateExpert | VectorExpert:
    """An expert for the task of ``env`` (what ``gym.make`` returns, or its env).

    The default, ``kind="state"``, is an expert that acts from the state: each call
    re-derives where the task stands from the simulation and the env's commanded servo
    targets, so two environments in the same state get the same action whatever their
    histories, it finishes from perturbed states, and it can label any state a learner
    visits. ``kind="scripted"`` is the timed script (minimum-jerk phases), which
    follows its plan from the reset on. A task without a state expert gets its script.

    A vector env (``gym.make_vec``'s batched or Warp env, or a ``SyncVectorEnv`` of
    gym_soarm environments) gets a :class:`VectorExpert`: the state expert of every
    environment, one batch of actions a call.

    Args:
        env: a gym_soarm environment, wrapped or not, or a vector env of them.
        config: the expert's figures: a :class:`StateExpertConfig` for ``"state"``, an
            :class:`ExpertConfig` for ``"scripted"`` (default: the expert's own).
        kind: ``"state"`` or ``"scripted"``.

    Returns:
        A policy: ``expert(obs, info)`` gives each action. Call ``expert.reset()`` after
        each ``env.reset(...)`` (a state expert needs none, but accepts it).

    Raises:
        TypeError: ``env`` is not a gym_soarm environment, or ``config`` is not the
            kind's config class.
        ValueError: ``kind`` is not one of :data:`EXPERT_KINDS`, or a vector env's
            ``kind`` is not ``"state"`` (a script follows one episode from its reset,
            while a vector env resets its environments as they end).
    """
    if isinstance(env, gym.vector.VectorEnv):
        return VectorExpert(env, config, kind)
    base = getattr(env, "unwrapped", None)
    if not isinstance(base, SoArmEnv):
        raise ArgumentTypeError(
            "make_expert expects an environment made by gym.make('SoArm-v0') or another "
            f"gym_soarm id; got {type(env).__name__}."
        )
    check_choice("kind", kind, EXPERT_KINDS)
    spec = base.task_spec
    if kind == "state" and spec.state_expert is not None and not isinstance(config, ExpertConfig):
        if config is None:
            return spec.state_expert(env)
        if not isinstance(config, StateExpertConfig):
            raise ArgumentTypeError(
                "config of a state expert must be a gym_soarm.expert.StateExpertConfig (e.g. "
                f"StateExpertConfig(line_speed_m=0.002)); got {type(config).__name__}."
            )
        return spec.state_expert(env, config)
    if config is None:
        config = DEFAULT_CONFIG
    if not isinstance(config, ExpertConfig):
        raise ArgumentTypeError(
            "config must be a gym_soarm.expert.ExpertConfig (e.g. "
            f"ExpertConfig(carry_steps=80)); got {type(config).__name__}."
        )
    if spec.expert is None:
        raise ValueError(f"task {spec.name!r} has no scripted expert.")
    return spec.expert(env, config)


class VectorExpert:
    """The state expert of each environment of a vector env: ``expert(obs, info)`` is the
    ``(num_envs, action_dim)`` batch of actions (float32) for the environments' states now.

    The batched vector env (``vector_env="batched"`` or ``"warp"``) copies each world's
    state into its environment first (:meth:`BatchedVectorEnv.synced_envs
    <gym_soarm.vector.batched.BatchedVectorEnv.synced_envs>`); a ``SyncVectorEnv`` of
    gym_soarm environments needs nothing. A state expert keeps nothing from one step to
    the next, so the vector env's automatic resets need no call to :meth:`reset`.

    Raises:
        TypeError: a vector env whose environments live in other processes (the native
            process env, ``AsyncVectorEnv``): their states are not here to read.
        ValueError: ``kind`` is not ``"state"``, or a task has no state expert.
    """

    def __init__(
        self,
        vector_env: gym.vector.VectorEnv,
        config: StateExpertConfig | None = None,
        kind: str = "state",
    ) -> None:
        check_choice("kind", kind, EXPERT_KINDS)
        if kind != "state":
            raise ValueError(
                f"a vector env's expert acts from the state; got kind={kind!r}. The timed "
                "script follows one episode from its reset: use it with a single env."
            )
        envs = getattr(vector_env.unwrapped, "envs", None)
        if envs is None:
            raise ArgumentTypeError(
                "make_expert needs the environments of a vector env in this process: "
                "gym.make_vec(..., vectorization_mode='vector_entry_point', "
                "vector_env='batched' or 'warp'), or a SyncVectorEnv; got "
                f"{type(vector_env.unwrapped).__name__}."
            )
        self.vector_env = vector_env.unwrapped
        self._sync = getattr(self.vector_env, "synced_envs", None)
        self.experts = []
        for env in envs:
            spec = env.unwrapped.task_spec
            if spec.state_expert is None:
                raise ValueError(f"task {spec.name!r} has no state expert.")
            self.experts.append(make_expert(env, config, "state"))

    def reset(self) -> None:
        """Nothing to reset (each environment's expert acts from its state)."""

    def __call__(self, obs: Any = None, info: dict[str, Any] | None = None) -> np.ndarray:
        if self._sync is not None:
            self._sync()
        return np.stack([expert(None, None) for expert in self.experts]).astype(np.float32)


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """Outcome of one evaluated episode."""

    seed: int
    options: dict[str, Any] | None
    success: bool
    steps: int
    episode_return: float = 0.0
    """The sum of the episode's rewards (undiscounted)."""


def evaluation_resets(
    task: str, seeds: int | None = None, object_placement: str | None = None
) -> list[tuple[int, dict | None]]:
    """The (seed, options) of the episodes ``task``'s expert is measured on.

    Grid tasks sweep every cell and seed yaw for ``seeds`` seeds (default 3); the others
    reset with seeds 0 .. ``seeds``-1 (default 100).
    """
    spec = get_task(task)
    logic = spec.make_task(object_placement)
    if seeds is None:
        seeds = EVALUATION_SEEDS if logic.placement == "grid" else EVALUATION_EPISODES
    return logic.evaluation_resets(seeds)


def run_episode(
    env: gym.Env, policy: Callable[[Any, dict], np.ndarray], seed: int, options: dict | None
) -> EpisodeResult:
    """Run one episode of ``policy`` (an expert or any callable) until it ends."""
    obs, info = env.reset(seed=seed, options=options)
    reset = getattr(policy, "reset", None)
    if reset is not None:
        reset()
    steps, total = 0, 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs, info))
        steps += 1
        total += float(reward)
        if terminated or truncated:
            break
    return EpisodeResult(seed, options, bool(info["is_success"]), steps, total)


def evaluate(
    task: str, seeds: int | None = None, kind: str = "state", **env_kwargs: Any
) -> list[EpisodeResult]:
    """Run ``task``'s expert (of ``kind``, see :func:`make_expert`) over its evaluation
    resets (state observations)."""
    check_choice("kind", kind, EXPERT_KINDS)
    spec = get_task(task)
    env = gym.make(spec.env_id, obs_type="environment_state_agent_pos", **env_kwargs)
    try:
        expert = make_expert(env, kind=kind)
        return [
            run_episode(env, expert, seed, options)
            for seed, options in evaluation_resets(
                spec.name, seeds, env_kwargs.get("object_placement")
            )
        ]
    finally:
        env.close()


def evaluate_protocol(
    task: str, episodes: int, kind: str = "state", **env_kwargs: Any
) -> list[EpisodeResult]:
    """Run ``task``'s expert (of ``kind``) on the benchmark's protocol: episode ``k``
    resets with seed ``EVAL_SEED + k`` and no options, as ``lerobot-eval`` resets it
    (state observations)."""
    check_choice("kind", kind, EXPERT_KINDS)
    spec = get_task(task)
    env = gym.make(spec.env_id, obs_type="environment_state_agent_pos", **env_kwargs)
    try:
        expert = make_expert(env, kind=kind)
        return [run_episode(env, expert, EVAL_SEED + k, None) for k in range(episodes)]
    finally:
        env.close()


__all__ = [
    "DEFAULT_CONFIG",
    "DEFAULT_STATE_CONFIG",
    "EXPERT_KINDS",
    "EpisodeResult",
    "ExpertConfig",
    "ScriptedExpert",
    "StateExpert",
    "StateExpertConfig",
    "VectorExpert",
    "evaluate",
    "evaluate_protocol",
    "evaluation_resets",
    "make_expert",
    "run_episode",
]
