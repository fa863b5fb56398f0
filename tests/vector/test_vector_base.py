"""The vector envs' shell is written once (gym_soarm.vector.base.SoArmVectorBase); the
batched and process envs only move actions, observations and calls."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from gym_soarm.vector import BatchedVectorEnv, SoArmVectorEnv
from gym_soarm.vector.base import EpisodeClock, SoArmVectorBase

SHELL = (
    "reset",
    "step",
    "call",
    "call_some",
    "get_attr",
    "set_attr",
    "render",
    "close",
    "_check_open",
    "_note_ends",
    "_add_finals",
    "_batched_obs",
)
TRANSPORT = ("_reset", "_step", "_call", "_get_attr", "_set_attr", "close_extras")


@pytest.mark.parametrize("vector_env", [BatchedVectorEnv, SoArmVectorEnv], ids=lambda c: c.__name__)
def test_every_vector_env_is_transport_over_the_base(vector_env):
    assert issubclass(vector_env, SoArmVectorBase)
    for name in SHELL:
        assert name not in vars(vector_env), f"{vector_env.__name__} redefines {name}()"
    for name in TRANSPORT:
        assert name in vars(vector_env), f"{vector_env.__name__} lacks {name}()"


@pytest.mark.parametrize("vector_env", [BatchedVectorEnv, SoArmVectorEnv], ids=lambda c: c.__name__)
def test_the_time_limit_and_autoreset_have_one_owner(vector_env):
    # The clock of the base counts every episode's steps; no transport keeps its own.
    envs = vector_env(3, max_episode_steps=4, task="ReachTarget-v0", obs_type="state")
    try:
        envs.reset(seed=0)
        assert not any("elapsed" in name for name in vars(envs))
        for _ in range(3):
            _, _, _, truncated, _ = envs.step(np.zeros((3, 6), np.float32))
            assert not truncated.any()
        np.testing.assert_array_equal(envs._clock.elapsed, [3, 3, 3])
        envs.reset(options={"reset_mask": np.array([True, False, False])})
        np.testing.assert_array_equal(envs._clock.elapsed, [0, 3, 3])
        _, _, _, truncated, _ = envs.step(np.zeros((3, 6), np.float32))
        np.testing.assert_array_equal(truncated, [False, True, True])
        np.testing.assert_array_equal(envs._clock.ended, [False, True, True])
        _, rewards, _, truncated, _ = envs.step(np.zeros((3, 6), np.float32))  # NEXT_STEP
        np.testing.assert_array_equal(rewards[1:], [0.0, 0.0])
        np.testing.assert_array_equal(envs._clock.elapsed, [2, 0, 0])
    finally:
        envs.close()


@pytest.mark.parametrize(
    ("mode", "ended_after", "elapsed_after"),
    [
        (AutoresetMode.NEXT_STEP, [False, True, False], [3, 2, 0]),  # 2 restarted
        (AutoresetMode.SAME_STEP, [False, False, False], [3, 0, 0]),
        (AutoresetMode.DISABLED, [False, True, True], [3, 2, 2]),
    ],
)
def test_the_clock_plans_restarts_and_the_time_limit(mode, ended_after, elapsed_after):
    clock = EpisodeClock(3, mode=mode)
    clock.elapsed[:] = [2, 1, 1]  # env 0 past the limit (never truncated twice), 1 and 2 at it
    clock.ended[:] = [False, False, True] if mode is AutoresetMode.NEXT_STEP else False
    restart, time_up = clock.plan(2)
    if mode is AutoresetMode.NEXT_STEP:
        np.testing.assert_array_equal(restart, [False, False, True])
        np.testing.assert_array_equal(time_up, [True, True, False])  # a restart is not timed
    else:
        np.testing.assert_array_equal(restart, [False, False, False])
        np.testing.assert_array_equal(time_up, [True, True, True])
    clock.advance(restart, np.array([False, True, False]), time_up & [False, False, True])
    np.testing.assert_array_equal(clock.ended, ended_after)
    np.testing.assert_array_equal(clock.elapsed, elapsed_after)
