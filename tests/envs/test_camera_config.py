"""Camera configurations: which images come back, in which order, at which size."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SMALL, colour_counts

pytestmark = pytest.mark.gl

CONFIGS = {
    "front_only": ["front_camera"],
    "front_wrist": ["front_camera", "wrist_camera"],
    "all": ["overview_camera", "front_camera", "wrist_camera"],
}


def _assert_images(images: dict, names: list[str], shape=(48, 64, 3)):
    assert list(images) == names
    for name, image in images.items():
        assert image.shape == shape, name
        assert image.dtype == np.uint8
        assert image.flags["C_CONTIGUOUS"]
        assert image.std() > 5, f"{name} is flat"
    for a in names:
        for b in names:
            if a < b:
                assert not np.array_equal(images[a], images[b]), f"{a} and {b} are identical"


@pytest.mark.parametrize("config", list(CONFIGS))
def test_pixels_obs_has_the_configured_cameras_in_order(make_env, config):
    env = make_env("SoArm-v0", obs_type="pixels", camera_config=config, **SMALL)
    obs, _ = env.reset(seed=0)
    _assert_images(obs, CONFIGS[config])
    assert list(env.observation_space.spaces) == CONFIGS[config]
    obs, *_ = env.step(env.action_space.sample())
    _assert_images(obs, CONFIGS[config])
    assert obs in env.observation_space


@pytest.mark.parametrize("config", list(CONFIGS))
def test_pixels_agent_pos_obs_nests_the_cameras(make_env, config):
    env = make_env("SoArm-v0", obs_type="pixels_agent_pos", camera_config=config, **SMALL)
    obs, _ = env.reset(seed=0)
    assert list(obs) == ["pixels", "agent_pos"]
    _assert_images(obs["pixels"], CONFIGS[config])
    assert obs["agent_pos"].shape == (6,)


def test_camera_name_sequence_is_sorted_into_the_fixed_order(make_env):
    env = make_env(
        "SoArm-v0", obs_type="pixels", camera_config=["wrist_camera", "overview_camera"], **SMALL
    )
    obs, _ = env.reset(seed=0)
    _assert_images(obs, ["overview_camera", "wrist_camera"])


@pytest.mark.parametrize("height, width", [(16, 16), (33, 75), (480, 640), (720, 1280)])
def test_any_image_size_renders(make_env, height, width):
    env = make_env(
        "SoArm-v0",
        obs_type="pixels",
        camera_config="front_only",
        observation_height=height,
        observation_width=width,
    )
    obs, _ = env.reset(seed=0)
    image = obs["front_camera"]
    assert image.shape == (height, width, 3)
    assert image.std() > 5


def test_front_camera_sees_the_blue_cube_and_green_pad(make_env):
    env = make_env(
        "SoArm-v0",
        obs_type="pixels",
        camera_config="front_only",
        observation_height=240,
        observation_width=320,
    )
    obs, _ = env.reset(seed=0, options={"cube_grid_position": 4})
    counts = colour_counts(obs["front_camera"])
    assert counts["blue cube"] > 10, "no blue cube in view"
    assert counts["green pad"] > 10, "no green pad in view"
