"""Every registered id with every observation type and camera config: reset, step, close.

Small 32 x 24 images keep the whole matrix fast; each cell checks that the observation
spaces contain what the environment returns and that the pixels are really rendered.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import COMMON_INFO_KEYS, INFO_KEYS

import gym_soarm
from gym_soarm import constants
from gym_soarm.envs.env import OBS_TYPES
from gym_soarm.real.units import UNITS

pytestmark = pytest.mark.gl

HEIGHT, WIDTH = 24, 32
STEPS = 3


def _check_observation(env: gym.Env, obs, cameras: tuple[str, ...], obs_type: str) -> None:
    assert env.observation_space.contains(obs), obs_type
    if obs_type == "environment_state_agent_pos":
        assert list(obs) == ["agent_pos", "environment_state"]
        assert all(np.isfinite(v).all() for v in obs.values())
        return
    if obs_type == "state":
        assert obs.dtype == np.float32 and obs.shape == (len(env.unwrapped.observation_names),)
        assert np.isfinite(obs).all()
        return
    pixels = obs if obs_type == "pixels" else obs["pixels"]
    if obs_type == "pixels_agent_pos":
        assert list(obs) == ["pixels", "agent_pos"] and np.isfinite(obs["agent_pos"]).all()
    assert tuple(pixels) == cameras
    for frame in pixels.values():
        assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
        assert frame.flags["C_CONTIGUOUS"]
        assert frame.std() > 2.0, "a blank frame"


@pytest.mark.parametrize("camera_config", list(constants.CAMERA_CONFIGS))
@pytest.mark.parametrize("obs_type", OBS_TYPES)
@pytest.mark.parametrize("env_id", list(gym_soarm.TASK_ENV_IDS))
def test_every_id_obs_type_and_camera_config_resets_steps_and_closes(
    env_id, obs_type, camera_config
):
    env = gym.make(
        env_id,
        obs_type=obs_type,
        camera_config=camera_config,
        observation_height=HEIGHT,
        observation_width=WIDTH,
        render_mode="rgb_array",
    )
    try:
        cameras = (
            ()
            if obs_type == "environment_state_agent_pos"
            else (constants.CAMERA_CONFIGS[camera_config])
        )
        obs, info = env.reset(seed=1)
        _check_observation(env, obs, cameras, obs_type)
        keys = set(info)
        assert keys >= COMMON_INFO_KEYS
        if gym_soarm.get_task(env_id).default_placement == "grid":
            assert keys == INFO_KEYS
        for _ in range(STEPS):
            action = env.action_space.sample()
            assert env.action_space.contains(action)
            obs, reward, terminated, truncated, info = env.step(action)
            _check_observation(env, obs, cameras, obs_type)
            assert set(info) == keys and not info["physics_unstable"]
            assert isinstance(reward, float) and 0.0 <= reward <= 1.0
            assert terminated is False and truncated is False
        frame = env.render()
        assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
    finally:
        env.close()
        env.close()


@pytest.mark.parametrize("units", UNITS)
@pytest.mark.parametrize("env_id", list(gym_soarm.TASK_ENV_IDS))
def test_every_id_and_joint_unit_keeps_observations_in_their_spaces(env_id, units):
    env = gym.make(env_id, obs_type="environment_state_agent_pos", units=units)
    try:
        rng = np.random.default_rng(0)
        obs, _ = env.reset(seed=2)
        assert env.observation_space.contains(obs)
        low, high = env.action_space.low, env.action_space.high
        for target in (low, high, rng.uniform(low, high).astype(np.float32)):
            for _ in range(10):
                obs, *_ = env.step(target)
            assert env.observation_space.contains(obs), (units, obs["agent_pos"].tolist())
    finally:
        env.close()
