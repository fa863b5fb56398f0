"""The native thread-pool vector env against N single environments, bit for bit."""

from __future__ import annotations

import threading
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import SMALL
from gymnasium.vector import AutoresetMode

import gym_soarm
from gym_soarm.vector import SoArmVectorEnv

ENV_ID = "gym_soarm/LiftCube-v0"
STATE = {"obs_type": "environment_state_agent_pos"}


def assert_same(a: Any, b: Any, where: str = "") -> None:
    """Equal structure, types, dtypes, shapes and bits."""
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
        return
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, set(a) ^ set(b))
        for key in a:
            assert_same(a[key], b[key], f"{where}/{key}")
        return
    if isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            if isinstance(x, (dict, np.ndarray)):
                assert_same(x, y, f"{where}[{i}]")
            else:
                assert x == y, (where, i, x, y)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (where, a.dtype, b.dtype, a.shape, b.shape)
    assert np.array_equal(a, b), (where, a, b)


def compare_with_sync(
    num_envs: int, steps: int, seed: int, mode: AutoresetMode, **kwargs: Any
) -> list[np.ndarray]:
    """Step the native and the synchronous vector envs with the same actions; return
    the done flags of each step."""
    native = gym.make_vec(
        ENV_ID,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
        **kwargs,
    )
    sync = gym.make_vec(
        ENV_ID,
        num_envs=num_envs,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        **kwargs,
    )
    dones = []
    try:
        assert isinstance(native.unwrapped, SoArmVectorEnv)
        assert native.metadata["autoreset_mode"] == mode
        assert native.observation_space == sync.observation_space
        assert native.action_space == sync.action_space
        assert_same(native.reset(seed=seed), sync.reset(seed=seed), "reset")
        rng = np.random.default_rng(seed)
        space = native.single_action_space
        for t in range(steps):
            actions = rng.uniform(space.low, space.high, (num_envs, 6)).astype(np.float32)
            got, want = native.step(actions), sync.step(actions)
            for name, x, y in zip(("obs", "rew", "term", "trunc", "info"), got, want, strict=True):
                assert_same(x, y, f"step {t} {name}")
            dones.append(got[2] | got[3])
    finally:
        native.close()
        sync.close()
    return dones


def test_every_id_has_the_vector_entry_point():
    for env_id in gym_soarm.ENV_IDS:
        assert gym.spec(env_id).vector_entry_point == "gym_soarm.vector:SoArmVectorEnv"


def test_state_next_step_matches_single_envs_bit_for_bit():
    dones = compare_with_sync(3, 40, 7, AutoresetMode.NEXT_STEP, max_episode_steps=12, **STATE)
    assert sum(d.all() for d in dones) >= 3  # several episodes ended and were reset


def test_state_same_step_matches_single_envs_bit_for_bit():
    dones = compare_with_sync(2, 30, 3, AutoresetMode.SAME_STEP, max_episode_steps=10, **STATE)
    assert sum(d.all() for d in dones) == 3


def test_pixels_match_single_envs_bit_for_bit():
    dones = compare_with_sync(
        2, 9, 5, AutoresetMode.NEXT_STEP, max_episode_steps=4, camera_config="front_wrist", **SMALL
    )
    assert sum(d.all() for d in dones) == 2


def test_each_env_renders_on_one_thread():
    envs = gym.make_vec(
        ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", num_threads=2, **SMALL
    )
    inner = envs.unwrapped
    seen: list[set[str]] = [set() for _ in range(3)]

    def job(partition: list[int]) -> None:
        for i in partition:
            seen[i].add(threading.current_thread().name)

    try:
        envs.reset(seed=0)
        for _ in range(3):
            envs.step(np.zeros((3, 6), np.float32))
            inner._run(job)  # the same partitions as reset and step
        frames = envs.call("render_camera_image", "front_camera")
        assert all(frame.shape == (48, 64, 3) for frame in frames)
        assert seen == [{"gym_soarm-vector-0"}, {"gym_soarm-vector-1"}, {"gym_soarm-vector-0"}]
    finally:
        envs.close()


def test_disabled_mode_and_reset_mask():
    envs = gym.make_vec(
        ENV_ID,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        autoreset_mode="Disabled",
        max_episode_steps=3,
        **STATE,
    )
    try:
        envs.reset(seed=1)
        zeros = np.zeros((2, 6), np.float32)
        for _ in range(3):
            *_, truncated, _ = envs.step(zeros)
        assert truncated.all()
        with pytest.raises(RuntimeError, match="reset_mask"):
            envs.step(zeros)
        _, info = envs.reset(options={"reset_mask": np.array([True, False])})
        assert info["_is_success"].tolist() == [True, False]
        with pytest.raises(RuntimeError, match=r"\[1\]"):
            envs.step(zeros)
        envs.reset(options={"reset_mask": np.array([False, True])})
        envs.step(zeros)
    finally:
        envs.close()


def test_close_closes_every_env_and_thread():
    envs = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", **SMALL)
    envs.reset(seed=0)
    inner = envs.unwrapped
    threads = list(inner._threads)
    assert threads
    envs.close()
    assert envs.closed
    assert all(env._closed for env in inner.envs)
    assert not any(thread.is_alive() for thread in threads)
    envs.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((3, 6), np.float32))


def test_bad_arguments_name_what_was_expected():
    with pytest.raises(ValueError, match="num_envs"):
        SoArmVectorEnv(0, **STATE)
    with pytest.raises(ValueError, match="autoreset_mode"):
        SoArmVectorEnv(1, autoreset_mode="sometimes", **STATE)
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", **STATE)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            envs.step(np.zeros((2, 6), np.float32))
        envs.reset(seed=0)
        with pytest.raises(ValueError, match=r"shape \(2, 6\)"):
            envs.step(np.zeros(6, np.float32))
        with pytest.raises(ValueError, match="num_envs=2"):
            envs.reset(seed=[1, 2, 3])
    finally:
        envs.close()
