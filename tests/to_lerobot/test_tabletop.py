"""LeRobot's tabletop task (PutCubesInBox-v0), its preset id and the EnvHub entry point."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import numpy as np
import pytest
from paths import ROOT

import gym_soarm
from gym_soarm.envs.presets import TABLETOP_ID
from gym_soarm.tasks.put_cubes_in_box import BOX, COLOURS, INSTRUCTION, cube_name, slot_of

TASK = "gym_soarm/PutCubesInBox-v0"


def _layout(env):
    physics = env.unwrapped.physics
    camera = physics.model.name2id("front_camera", "camera")
    return (
        np.stack([physics.object_position(cube_name(c)) for c in COLOURS]),
        physics.fixture_position(BOX.name),
        physics.model.ptr.cam_pos[camera].copy(),
    )


def test_seeds_offset_the_cubes_the_box_and_the_front_camera():
    env = gym.make(TASK, obs_type="state")
    _, info = env.reset(seed=1)
    assert env.unwrapped.task_description == INSTRUCTION
    assert info["cubes_in_box"] == 0 and not info["is_success"]
    first = _layout(env)
    env.reset(seed=2)
    second = _layout(env)
    env.reset(seed=1)
    again = _layout(env)
    for a, b, c in zip(first, second, again, strict=True):
        np.testing.assert_array_equal(a, c)  # the same seed, the same offsets
        assert not np.allclose(a, b)  # another seed moves each of them
    cubes = first[0]
    gaps = [np.linalg.norm(cubes[i, :2] - cubes[j, :2]) for i in range(4) for j in range(i)]
    assert min(gaps) > 0.04  # apart
    env.close()


def test_the_reward_is_the_fraction_of_cubes_in_the_box():
    env = gym.make(TASK, obs_type="state")
    env.reset(seed=0)
    rewards, steps = _fill_the_box(env)
    # 0.95 x the fraction, then the success bonus of every task: 1 and 1 for each step left.
    assert rewards[:3] == pytest.approx([0.2375, 0.475, 0.7125])
    assert rewards[3] == 1.0 + env.spec.max_episode_steps - steps
    env.close()


def _fill_the_box(env):
    """Put the cubes into the box one by one; the reward after each, and the steps."""
    base = env.unwrapped
    physics = base.physics
    box = physics.fixture_position(BOX.name)
    hold = base.commanded_targets.astype(np.float32)
    if base.units == "lerobot":
        hold = base.joint_units.from_radians(base.commanded_targets).astype(np.float32)
    rewards, steps = [], 0
    for count in range(1, 5):
        name = cube_name(COLOURS[count - 1])
        dx, dy = slot_of(name)
        physics.set_object_pose(name, box + np.array([dx, dy, 0.02]), np.array([1.0, 0, 0, 0]))
        physics.forward()
        for _ in range(15):  # it settles on the floor
            _, reward, terminated, _, info = env.step(hold)
            steps += 1
        assert info["cubes_in_box"] == count
        rewards.append(reward)
        assert terminated == info["is_success"] == (count == 4)
    return rewards, steps


def test_the_state_expert_puts_all_four_cubes_in():
    env = gym.make(TASK, obs_type="state")
    expert = gym_soarm.make_expert(env)
    obs, info = env.reset(seed=0)
    counts = []
    for _ in range(env.spec.max_episode_steps):
        obs, _, terminated, truncated, info = env.step(expert(obs, info))
        counts.append(int(info["cubes_in_box"]))
        if terminated or truncated:
            break
    assert info["is_success"] and counts[-1] == 4
    assert sorted(set(counts)) == [0, 1, 2, 3, 4]  # one cube at a time
    env.close()


def test_the_preset_applies_the_lerobot_contract():
    env = gym.make(TABLETOP_ID)
    obs, info = env.reset(seed=0)
    assert set(obs["pixels"]) == {"front", "wrist"}
    assert obs["pixels"]["front"].shape == obs["pixels"]["wrist"].shape == (480, 640, 3)
    assert obs["agent_pos"].shape == (6,)
    base = env.unwrapped
    assert env.metadata["render_fps"] == 30 and base.dt == pytest.approx(1 / 30)
    assert base.units == "lerobot" and base.control_mode == "joint_pos"
    # Actions: absolute targets in the follower's units (degrees, gripper 0-100).
    assert env.action_space.high[5] == pytest.approx(100.0)
    assert env.action_space.high[0] > 90
    assert env.observation_space["pixels"]["front"].shape == (480, 640, 3)
    assert env.observation_space.contains(obs)
    action = obs["agent_pos"].astype(np.float32)  # hold still: the agent_pos as targets
    obs, reward, *_ = env.step(action)
    assert reward == 0.0 and info["cubes_in_box"] == 0
    env.close()


def test_the_preset_pays_the_plain_fraction_of_cubes_in_the_box():
    env = gym.make(TABLETOP_ID, observation_height=48, observation_width=64)
    env.reset(seed=0)
    rewards, _ = _fill_the_box(env)
    assert rewards == [0.25, 0.5, 0.75, 1.0]  # LeRobot's reward: no success bonus
    env.close()


def test_the_preset_takes_settings_but_keeps_its_observation_layout():
    env = gym.make(TABLETOP_ID, observation_height=48, observation_width=64)
    obs, _ = env.reset(seed=0)
    assert obs["pixels"]["wrist"].shape == (48, 64, 3)
    env.close()
    with pytest.raises(ValueError, match="PutCubesInBox-v0 for other observations"):
        gym.make(TABLETOP_ID, obs_type="state")
    with pytest.raises(ValueError, match="camera_config"):
        gym.make(TABLETOP_ID, camera_config="front_only")


def _envhub():
    spec = importlib.util.spec_from_file_location("gym_soarm_envhub", ROOT / "envhub" / "env.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_envhub_entry_point_returns_a_suite_of_vector_envs():
    hub = _envhub()
    envs = hub.make_env(n_envs=2, use_async_envs=False, observation_height=48, observation_width=64)
    assert list(envs) == ["so101_tabletop"] and list(envs["so101_tabletop"]) == [0]
    vector = envs["so101_tabletop"][0]
    assert isinstance(vector, gym.vector.SyncVectorEnv) and vector.num_envs == 2
    obs, _ = vector.reset(seed=0)
    assert obs["pixels"]["front"].shape == (2, 48, 64, 3)
    _, reward, _, _, info = vector.step(obs["agent_pos"].astype(np.float32))
    np.testing.assert_array_equal(reward, [0.0, 0.0])
    np.testing.assert_array_equal(info["cubes_in_box"], [0, 0])
    vector.close()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_the_envhub_entry_point_refuses_bad_counts(bad):
    with pytest.raises(ValueError, match="n_envs must be a whole number >= 1"):
        _envhub().make_env(n_envs=bad)
