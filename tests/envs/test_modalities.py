"""Depth and segmentation images (``image_modalities``)."""

from __future__ import annotations

import numpy as np
import pytest

from gym_soarm.validation import ArgumentTypeError

pytestmark = pytest.mark.gl

OVERVIEW = {
    "camera_config": ["overview_camera"],
    "observation_height": 96,
    "observation_width": 128,
}
ALL = ("rgb", "depth", "segmentation")


def _renderer(env):
    (renderer,) = env.unwrapped._observer.renderers.values()
    return renderer


def test_default_layout_is_unchanged(make_env):
    env = make_env(obs_type="pixels", **OVERVIEW)
    obs, _ = env.reset(seed=0)
    assert list(obs) == ["overview_camera"]
    assert obs["overview_camera"].dtype == np.uint8
    assert env.unwrapped.image_modalities == ("rgb",)


def test_depth_and_segmentation_of_the_overview_camera(make_env):
    env = make_env(obs_type="pixels", image_modalities=ALL, **OVERVIEW)
    obs, _ = env.reset(seed=0)
    assert list(obs) == ["pixels", "depth", "segmentation"]
    depth = obs["depth"]["overview_camera"]
    segments = obs["segmentation"]["overview_camera"]
    assert depth.dtype == np.float32 and depth.shape == (96, 128)
    assert segments.dtype == np.int32 and segments.shape == (96, 128)
    ids = env.unwrapped.segmentation_ids
    assert ids == {"background": 0, "table": 1, "robot": 2, "cube": 3, "goal": 4}
    # The camera looks straight down from 0.8 m above the table top.
    assert segments[48, 64] == ids["table"]
    assert depth[48, 64] == pytest.approx(0.8, abs=0.003)
    # The cube (3 cm tall) is where the segmentation says, its top 0.77 m away.
    cube = segments == ids["cube"]
    assert cube.sum() >= 4
    assert np.median(depth[cube]) == pytest.approx(0.77, abs=0.01)
    rgb = obs["pixels"]["overview_camera"][cube].astype(int)
    assert (rgb[:, 2] > rgb[:, 0] + 40).mean() > 0.8  # the blue cube
    # The floor (0.75 m below the table) and the robot are seen too.
    assert (segments == ids["robot"]).any() and (segments == ids["background"]).any()
    assert depth[segments == 0].max() == pytest.approx(1.55, abs=0.01)
    assert env.observation_space.contains(obs)


def test_pixels_agent_pos_spaces_contain_observations(make_env):
    env = make_env(
        "gym_soarm/StackCube-v0",
        image_modalities=("depth", "segmentation"),
        camera_config="front_wrist",
        observation_height=48,
        observation_width=64,
    )
    obs, _ = env.reset(seed=1)
    assert list(obs) == ["depth", "segmentation", "agent_pos"]
    assert list(obs["depth"]) == ["front_camera", "wrist_camera"]
    assert env.observation_space.contains(obs)
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    ids = env.unwrapped.segmentation_ids
    assert set(np.unique(obs["segmentation"]["front_camera"])) <= set(ids.values())


@pytest.mark.parametrize(
    ("modalities", "renders"),
    [(("rgb",), 1), (("depth",), 1), (("rgb", "depth"), 1), (ALL, 2), (("segmentation",), 1)],
)
def test_only_the_asked_images_are_rendered(make_env, modalities, renders):
    env = make_env(obs_type="pixels", image_modalities=modalities, **OVERVIEW)
    env.reset(seed=0)
    renderer = _renderer(env)
    before = renderer.render_count
    env.step(env.action_space.sample())
    assert renderer.render_count - before == renders
    assert renderer._segment_buffer is None or "segmentation" in modalities
    assert renderer._depth_buffer is None or "depth" in modalities


def test_images_are_deterministic(make_env):
    first, second = (make_env(obs_type="pixels", image_modalities=ALL, **OVERVIEW) for _ in "ab")
    a, _ = first.reset(seed=3)
    b, _ = second.reset(seed=3)
    for key in ("pixels", "depth", "segmentation"):
        np.testing.assert_array_equal(a[key]["overview_camera"], b[key]["overview_camera"])


@pytest.mark.parametrize(
    ("value", "error"),
    [
        (("rgb", "normals"), ValueError),
        ((), ValueError),
        (("rgb", "rgb"), ValueError),
        ("depth", ArgumentTypeError),
        ((1,), ArgumentTypeError),
    ],
)
def test_bad_modalities_raise(make_env, value, error):
    with pytest.raises(error, match=r"image_modalities must .*'rgb', 'depth', 'segmentation'"):
        make_env(image_modalities=value)
