"""make_expert(vector_env): every environment's state expert, one batch of actions a call."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import VectorExpert

ENV_ID = "gym_soarm/LiftCube-v0"
SEEDS = [0, 5, 9]


def _batched(n=3, **kwargs):
    return gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", obs_type="state", **kwargs
    )


def test_the_batched_envs_expert_acts_as_each_envs_own():
    envs = _batched()
    singles = [gym.make(ENV_ID, obs_type="state") for _ in SEEDS]
    try:
        expert = gym_soarm.make_expert(envs)
        assert isinstance(expert, VectorExpert)
        own = [gym_soarm.make_expert(env) for env in singles]
        obs, info = envs.reset(seed=SEEDS)
        for env, seed in zip(singles, SEEDS, strict=True):
            env.reset(seed=seed)
        done = np.zeros(len(SEEDS), dtype=bool)
        for _ in range(120):
            actions = expert(obs, info)
            assert actions.shape == (len(SEEDS), 6) and actions.dtype == np.float32
            for i, (env, policy) in enumerate(zip(singles, own, strict=True)):
                if not done[i]:  # until its episode ends (the vector env then resets it)
                    np.testing.assert_array_equal(actions[i], policy(None, None))
                    env.step(actions[i])
            obs, _, terminated, truncated, info = envs.step(actions)
            assert not truncated.any()
            done |= terminated
            if done.all():
                break
        assert done.all()  # every cube lifted
    finally:
        envs.close()
        for env in singles:
            env.close()


def test_it_keeps_acting_across_automatic_resets():
    envs = _batched(2)
    try:
        expert = gym_soarm.make_expert(envs)
        obs, info = envs.reset(seed=[1, 2])
        successes = np.zeros(2, dtype=int)
        for _ in range(300):
            obs, _, terminated, _, info = envs.step(expert(obs, info))
            successes += terminated
        assert (successes >= 2).all()  # a second episode after the reset succeeds too
    finally:
        envs.close()


def test_a_sync_vector_env_of_gym_soarm_envs():
    envs = gym.vector.SyncVectorEnv([lambda: gym.make(ENV_ID, obs_type="state")] * 2)
    try:
        expert = gym_soarm.make_expert(envs)
        obs, info = envs.reset(seed=[3, 4])
        for _ in range(120):
            obs, _, terminated, _, info = envs.step(expert(obs, info))
            if terminated.any():
                break
        assert terminated.any()
    finally:
        envs.close()


def test_a_process_vector_env_and_a_script_are_refused():
    envs = gym.make_vec(
        ENV_ID,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        vector_env="processes",
        obs_type="state",
        num_processes=1,
    )
    try:
        with pytest.raises(TypeError, match="in this process"):
            gym_soarm.make_expert(envs)
    finally:
        envs.close()
    envs = _batched(2)
    try:
        with pytest.raises(ValueError, match="acts from the state"):
            gym_soarm.make_expert(envs, kind="scripted")
    finally:
        envs.close()
