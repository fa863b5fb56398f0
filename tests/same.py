"""Comparing what environments return, exactly: the package's vector envs against
Gymnasium's ``SyncVectorEnv`` of single ``gym.make`` environments."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from gym_soarm.vector.batched import BatchedVectorEnv
from gym_soarm.vector.processes import SoArmVectorEnv


def assert_same(a: Any, b: Any, where: str = "", atol: float = 0.0) -> None:
    """Equal structure, types, dtypes, shapes and bits; with ``atol``, floating-point
    values only within ``atol`` of each other."""
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]", atol)
        return
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, set(a) ^ set(b))
        for key in a:
            assert_same(a[key], b[key], f"{where}/{key}", atol)
        return
    if isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            if isinstance(x, (dict, np.ndarray)):
                assert_same(x, y, f"{where}[{i}]", atol)
            else:
                assert x == y, (where, i, x, y)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (where, a.dtype, b.dtype, a.shape, b.shape)
    if atol and a.dtype.kind == "f":
        np.testing.assert_allclose(a, b, atol=atol, err_msg=where)
    else:
        assert np.array_equal(a, b), (where, a, b)


def compare_with_sync(
    env_id: str,
    num_envs: int,
    steps: int,
    seed: int,
    mode: AutoresetMode,
    num_processes: int | None = None,
    vector_env: str = "processes",
    **kwargs: Any,
) -> list[np.ndarray]:
    """Step the native (``vector_env``) and the synchronous vector envs with the same
    actions; return the done flags of each step."""
    native = gym.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=mode,
        num_processes=num_processes,
        vector_env=vector_env,
        **kwargs,
    )
    sync = gym.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        **kwargs,
    )
    dones = []
    try:
        expected = SoArmVectorEnv if vector_env == "processes" else BatchedVectorEnv
        assert isinstance(native.unwrapped, expected)
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
