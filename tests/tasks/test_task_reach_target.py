"""ReachTarget-v0: the target moves at every reset, success is 1 cm, the front camera sees it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.tasks import reach_target
from gym_soarm.tasks.reach_target import (
    SUCCESS_DISTANCE_M,
    TARGET_HEIGHT_M,
    TARGET_REGION_M,
)

ENV_ID = gym_soarm.get_task("ReachTarget-v0").env_id


@pytest.fixture
def env():
    env = gym.make(ENV_ID, obs_type="environment_state_agent_pos")
    yield env
    env.close()


def test_every_reset_moves_the_target_inside_its_box(env):
    (x0, x1), (y0, y1) = TARGET_REGION_M
    z0, z1 = TARGET_HEIGHT_M
    positions = []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        target = np.array(info["target_pos"])
        assert x0 <= target[0] <= x1 and y0 <= target[1] <= y1 and z0 <= target[2] <= z1
        np.testing.assert_array_equal(obs["environment_state"][:3], target)
        positions.append(target)
    assert len({tuple(p) for p in positions}) == len(positions)
    # A seed gives its target back whatever came before.
    _, info = env.reset(seed=3)
    np.testing.assert_array_equal(info["target_pos"], positions[3])


def test_the_target_is_a_visual_marker(env):
    env.reset(seed=0)
    model = env.unwrapped.physics.model.ptr
    geoms = np.flatnonzero(model.geom_bodyid == model.body("target").id)
    assert geoms.size and not model.geom_contype[geoms].any()
    assert not model.geom_conaffinity[geoms].any()


def test_success_is_the_jaws_within_a_centimetre_and_ends_the_episode(env):
    expert = make_expert(env)
    obs, info = env.reset(seed=5)
    expert.reset()
    distances = []
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        distances.append(info["target_distance"])
        if terminated or truncated:
            break
    # The success step pays 1 and the most the steps left could have paid.
    left = env.spec.max_episode_steps - len(distances)
    assert terminated and info["is_success"] and reward == 1.0 + left
    assert distances[-1] <= SUCCESS_DISTANCE_M < min(distances[:-1])


def test_moving_an_unknown_fixture_names_what_it_expects(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no fixture 'bin'"):
        env.unwrapped.physics.set_fixture_position("bin", np.zeros(3))


def test_the_front_camera_sees_the_target_at_every_reset():
    """The overview camera looks down past the parked arm, which hides targets near x = 0."""
    env = gym.make(
        ENV_ID,
        obs_type="pixels",
        camera_config=["front_camera"],
        observation_height=240,
        observation_width=320,
    )
    try:
        model = env.unwrapped.physics.model.ptr
        geoms = np.flatnonzero(model.geom_bodyid == model.body(reach_target.TARGET.name).id)
        for seed in range(5):
            obs, _ = env.reset(seed=seed)
            saved = model.geom_rgba[geoms].copy(), model.geom_matid[geoms].copy()
            model.geom_rgba[geoms], model.geom_matid[geoms] = 0.0, -1
            try:
                hidden = env.unwrapped.observation()
            finally:
                model.geom_rgba[geoms], model.geom_matid[geoms] = saved
            changed = np.abs(obs["front_camera"].astype(int) - hidden["front_camera"]).max(-1)
            assert (changed > 30).sum() >= 12, f"seed {seed}: the front camera misses the target"
    finally:
        env.close()
