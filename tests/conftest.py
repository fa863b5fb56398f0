"""Shared fixtures: small images keep the suite fast on a 2-core CPU."""

from __future__ import annotations

import signal

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm

SMALL = {"observation_height": 48, "observation_width": 64}
# Keys every task's reset and step info holds; each task adds its own.
COMMON_INFO_KEYS = {"is_success", "gripper_pos", "reward_terms", "task", "physics_unstable"}
# The keys of the grid tasks (SoArm-v0, pick-and-place and lift).
INFO_KEYS = COMMON_INFO_KEYS | {"cube_grid_position", "cube_rotation_deg", "cube_pos"}


def colour_counts(image: np.ndarray) -> dict[str, int]:
    """Pixels of the scene's telltale colours in an RGB image."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return {
        "blue cube": int(((b > 120) & (b > r + 60) & (b > g + 40)).sum()),
        "green pad": int(((g > 120) & (g > r + 50) & (g > b + 50)).sum()),
        "white arm": int(((r > 150) & (abs(r - g) < 20) & (abs(g - b) < 20)).sum()),
    }


@pytest.fixture
def make_env():
    """Build environments with gym.make and close them after the test."""
    envs: list[gym.Env] = []

    def _make(env_id: str = "SoArm-v0", **kwargs) -> gym.Env:
        env = gym.make(env_id, **kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()


@pytest.fixture
def state_env(make_env):
    return make_env("SoArm-v0", obs_type="environment_state_agent_pos")


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0):
    """Reset with ``seed`` and step with reproducible random actions."""
    rng = np.random.default_rng(action_seed)
    low, high = env.action_space.low, env.action_space.high
    obs, info = env.reset(seed=seed)
    trace = [(obs, 0.0, info)]
    for _ in range(steps):
        action = rng.uniform(low, high).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append((obs, reward, info))
        if terminated or truncated:
            break
    return trace


assert gym_soarm.ENV_IDS  # the import registers the ids used by every test


@pytest.fixture(autouse=True)
def _ctrl_c_as_a_terminal_gives_it():
    """Every test starts and ends with Python's own Ctrl-C handler in this process.

    Programs that the tests start (the recorder, the vector env's scripts) inherit this
    process's disposition of SIGINT, and a Python started with SIGINT ignored never
    raises KeyboardInterrupt: one test that left it ignored would make the Ctrl-C tests
    of later programs wait forever. A terminal never starts a program that way.
    """
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, signal.default_int_handler)
