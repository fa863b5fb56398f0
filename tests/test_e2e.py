"""End-to-end behaviour of the registered environments with real MuJoCo and EGL."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from conftest import SMALL, rollout
from gymnasium.utils.env_checker import check_env

import gym_soarm
from gym_soarm import constants
from gym_soarm.sim import meshes
from gym_soarm.tasks import cube, placement

pytestmark = pytest.mark.gl

ALL_IDS = list(gym_soarm.TASK_ENV_IDS)
# Actions are absolute joint targets in radians bounded by the servo ranges (by design),
# so Gymnasium's advice to normalise the action Box to [-1, 1] does not apply.
ACTION_ADVICE = ".*For Box action spaces, we recommend using a symmetric and normalized space"


def _gui_available() -> bool:
    from gym_soarm.render import display

    return display.window_support_problem() is None


@pytest.mark.parametrize("env_id", ALL_IDS)
@pytest.mark.parametrize("obs_type", ["pixels_agent_pos", "environment_state_agent_pos"])
def test_check_env_passes_with_warnings_as_errors(env_id, obs_type):
    env = gym.make(env_id, obs_type=obs_type, **SMALL)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            warnings.filterwarnings("ignore", message=ACTION_ADVICE)
            check_env(env.unwrapped, skip_render_check=not _gui_available())
    finally:
        env.close()


def test_registered_ids_have_their_tasks_and_limits():
    expected = {
        "SoArm-v0": ("PickAndPlaceCube-v0", 400),
        "gym_soarm/PickAndPlaceCube-v0": ("PickAndPlaceCube-v0", 400),
        "gym_soarm/LiftCube-v0": ("LiftCube-v0", 250),
    }
    for env_id, (task, steps) in expected.items():
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == steps
        env = gym.make(env_id, obs_type="environment_state_agent_pos")
        assert env.unwrapped.task == task
        assert env.unwrapped.task_description.endswith(".")
        assert env.metadata["render_fps"] == 50
        env.close()


def test_spaces_match_the_specification(state_env):
    space = state_env.action_space
    assert space.shape == (6,) and space.dtype == np.float32
    np.testing.assert_allclose(
        space.low, [-1.91986, -1.74533, -1.69, -1.65806, -2.74385, -0.17453], atol=1e-6
    )
    np.testing.assert_allclose(
        space.high, [1.91986, 1.74533, 1.69, 1.65806, 2.84121, 1.74533], atol=1e-6
    )
    obs, _ = state_env.reset(seed=0)
    assert obs["agent_pos"].dtype == np.float64 and obs["agent_pos"].shape == (6,)
    assert obs["environment_state"].shape == (13,)
    np.testing.assert_array_equal(obs["agent_pos"], np.zeros(6))  # home keyframe


def test_info_keys_and_types_on_reset_and_step(state_env):
    _, info = state_env.reset(seed=3)
    _, reward, terminated, truncated, step_info = state_env.step(state_env.action_space.sample())
    for i in (info, step_info):
        assert type(i["is_success"]) is bool
        assert isinstance(i["cube_grid_position"], int) and 0 <= i["cube_grid_position"] <= 8
        assert i["cube_rotation_deg"] in placement.GRID_YAWS_DEG
        assert i["cube_pos"].shape == (3,) and i["gripper_pos"].shape == (3,)
        assert set(i["reward_terms"]) == {"reach", "grasp", "lift", "place"}
        assert i["task"] == "Pick up the blue cube and place it on the green pad."
        assert i["physics_unstable"] is False
    assert isinstance(reward, float) and terminated is False and truncated is False


def test_environment_state_layout(state_env):
    obs, info = state_env.reset(seed=1)
    state = obs["environment_state"]
    physics = state_env.unwrapped.physics
    np.testing.assert_array_equal(state[0:3], info["cube_pos"])
    np.testing.assert_array_equal(state[3:7], physics.object_quaternion("cube"))
    np.testing.assert_array_equal(state[7:10], info["gripper_pos"])
    np.testing.assert_array_equal(state[10:13], physics.fixture_position("goal"))


def test_grid_cells_place_the_cube_at_the_table_offsets(state_env):
    centre = None
    positions = {}
    for cell in range(9):
        _, info = state_env.reset(
            seed=0, options={"cube_grid_position": cell, "cube_rotation_deg": 0}
        )
        positions[cell] = info["cube_pos"]
        assert info["cube_grid_position"] == cell
    centre = positions[4]
    np.testing.assert_allclose(centre[:2], placement.GRID_CENTER_M, atol=1e-9)
    dxs, dys = (-0.10, 0.0, 0.10), (-0.075, 0.0, 0.075)
    for cell, pos in positions.items():
        np.testing.assert_allclose(pos[:2] - centre[:2], [dxs[cell // 3], dys[cell % 3]], atol=1e-9)
        assert pos[2] == pytest.approx(cube.CUBE_HALF_M)


def test_reset_options_apply_to_one_reset_only(state_env):
    cells, yaws = set(), set()
    _, info = state_env.reset(seed=0, options={"cube_grid_position": 2, "cube_rotation_deg": 17.5})
    assert info["cube_grid_position"] == 2 and info["cube_rotation_deg"] == 17.5
    quat = state_env.unwrapped.physics.object_quaternion("cube")
    assert 2 * math.degrees(math.atan2(quat[3], quat[0])) == pytest.approx(17.5)
    for seed in range(40):
        _, info = state_env.reset(seed=seed)
        cells.add(info["cube_grid_position"])
        yaws.add(info["cube_rotation_deg"])
    assert len(cells) > 3, "random cells should follow once the option is gone"
    assert yaws <= set(placement.GRID_YAWS_DEG) and len(yaws) > 1


def test_same_seed_gives_bit_identical_rollouts_pixels_included(make_env):
    first = rollout(make_env("SoArm-v0", **SMALL), seed=11, steps=15)
    second = rollout(make_env("SoArm-v0", **SMALL), seed=11, steps=15)
    assert len(first) == len(second)
    for (o1, r1, i1), (o2, r2, i2) in zip(first, second, strict=False):
        assert r1 == r2
        np.testing.assert_array_equal(o1["agent_pos"], o2["agent_pos"])
        for cam in o1["pixels"]:
            np.testing.assert_array_equal(o1["pixels"][cam], o2["pixels"][cam])
        np.testing.assert_array_equal(i1["cube_pos"], i2["cube_pos"])


def test_different_seeds_give_different_episodes(state_env):
    starts = set()
    for seed in range(6):
        _, info = state_env.reset(seed=seed)
        starts.add((info["cube_grid_position"], info["cube_rotation_deg"]))
    assert len(starts) > 1


def test_pixels_are_fresh_arrays_every_step(make_env):
    env = make_env("SoArm-v0", **SMALL)
    obs0, _ = env.reset(seed=0)
    frame0 = obs0["pixels"]["front_camera"]
    snapshot = frame0.copy()
    obs1, *_ = env.step(env.action_space.high)
    frame1 = obs1["pixels"]["front_camera"]
    assert (
        frame1.flags["C_CONTIGUOUS"] and frame1.flags["OWNDATA"]
    ) or frame1.base is not frame0.base
    assert not np.shares_memory(frame0, frame1)
    np.testing.assert_array_equal(frame0, snapshot)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"obs_type": "pixel"}, "obs_type must be one of"),
        ({"camera_config": "front"}, "camera_config must be one of"),
        ({"camera_config": ["front_camera", "top_camera"]}, "unknown cameras"),
        ({"camera_config": []}, "non-empty"),
        ({"observation_height": 8}, "observation_height"),
        ({"observation_width": 4096}, "observation_width"),
        ({"observation_width": 64.0}, "observation_width must be an int"),
        ({"render_mode": "video"}, "render_mode must be one of"),
        ({"render_camera": "side_camera"}, "render_camera must be one of"),
        ({"render_quality": "ultra"}, "render_quality must be one of"),
        ({"reward_type": "shaped"}, "reward_type must be one of"),
        ({"task": "juggle"}, "task must be one of"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes:UserWarning")
def test_bad_keyword_raises_value_error_listing_valid_values(kwargs, fragment):
    with pytest.raises(ValueError, match=fragment) as excinfo:
        gym.make("SoArm-v0", **kwargs)
    assert "got" in str(excinfo.value)


@pytest.mark.parametrize(
    "options, fragment",
    [
        ({"cube_grid_position": 9}, "from 0 to 8"),
        ({"cube_grid_position": -1}, "from 0 to 8"),
        ({"cube_grid_position": True}, "must be an int"),
        ({"cube_grid_position": 4.0}, "must be an int"),
        ({"cube_rotation_deg": float("nan")}, "finite"),
        ({"cube_rotation_deg": float("inf")}, "finite"),
        ({"cube_rotation_deg": "45"}, "finite number"),
        ({"cube_rotation_deg": False}, "finite number"),
        ({"grid": 3}, "unknown reset option"),
        (["cube_grid_position"], "options must be a dict"),
    ],
)
def test_bad_reset_option_raises_and_leaves_the_env_usable(state_env, options, fragment):
    state_env.reset(seed=5)
    _obs, *_ = state_env.step(state_env.action_space.high * 0.3)
    before = state_env.unwrapped.physics.data.qpos.copy()
    with pytest.raises(ValueError, match=fragment):
        state_env.reset(options=options)
    np.testing.assert_array_equal(state_env.unwrapped.physics.data.qpos, before)
    state_env.step(np.zeros(6))
    _, info = state_env.reset(seed=5, options={"cube_grid_position": 8})
    assert info["cube_grid_position"] == 8


@pytest.mark.parametrize(
    "action, fragment",
    [
        (np.array([0, 0, 0, 0, 0, np.nan]), "finite"),
        (np.array([np.inf, 0, 0, 0, 0, 0]), "finite"),
        (np.zeros(5), "shape"),
        (np.zeros((6, 1)), "shape"),
        (np.zeros(7), "shape"),
        (np.array(["a"] * 6), "real numbers"),
        (np.ones(6, dtype=bool), "real numbers"),
        ([0.0, 0.1], "shape"),
    ],
)
def test_bad_action_raises_before_touching_the_simulation(state_env, action, fragment):
    state_env.reset(seed=2)
    state_env.step(np.full(6, 0.2))
    physics = state_env.unwrapped.physics
    qpos, qvel, ctrl, time = (
        physics.data.qpos.copy(),
        physics.data.qvel.copy(),
        physics.data.ctrl.copy(),
        physics.data.time,
    )
    with pytest.raises(ValueError, match=fragment):
        state_env.step(action)
    np.testing.assert_array_equal(physics.data.qpos, qpos)
    np.testing.assert_array_equal(physics.data.qvel, qvel)
    np.testing.assert_array_equal(physics.data.ctrl, ctrl)
    assert physics.data.time == time
    obs, *_ = state_env.step(np.zeros(6))
    assert np.isfinite(obs["agent_pos"]).all()


def test_out_of_range_actions_are_clipped_to_the_servo_range(state_env):
    state_env.reset(seed=0)
    state_env.step(np.full(6, 10.0, dtype=np.float32))
    ctrl = state_env.unwrapped.physics.joint_targets()
    np.testing.assert_allclose(ctrl, state_env.action_space.high, atol=1e-6)
    state_env.step(np.full(6, -10.0))
    np.testing.assert_allclose(
        state_env.unwrapped.physics.joint_targets(), state_env.action_space.low, atol=1e-6
    )


def test_servos_reach_a_reachable_target_within_a_second(state_env):
    state_env.reset(seed=0)
    target = np.array([0.6, -0.6, 0.6, 0.6, 0.8, 0.8], dtype=np.float32)
    for _ in range(50):  # 1 s at 50 Hz
        obs, *_ = state_env.step(target)
    np.testing.assert_allclose(obs["agent_pos"], target, atol=0.05)


def test_servo_settles_without_large_overshoot(state_env):
    state_env.reset(seed=0)
    target = np.array([0.5, -0.5, 0.5, 0.5, 0.5, 0.5])
    history = []
    for _ in range(25):  # 0.5 s
        obs, *_ = state_env.step(target)
        history.append(obs["agent_pos"])
    history = np.array(history)
    settled = history[15:]  # after 0.3 s
    np.testing.assert_allclose(settled, np.broadcast_to(target, settled.shape), atol=0.02)
    overshoot = (history - target) * np.sign(target)  # the start pose is all zeros
    assert overshoot.max() < 0.04


def _upstream_model() -> mujoco.MjModel:
    path = meshes.provider_dir() / "assets" / "so101_new_calib.xml"
    return mujoco.MjModel.from_xml_path(str(path))


def test_gripper_site_matches_the_published_calibrated_model():
    upstream = _upstream_model()
    up_data = mujoco.MjData(upstream)
    env = gym.make("SoArm-v0", obs_type="environment_state_agent_pos")
    physics = env.unwrapped.physics
    rng = np.random.default_rng(0)
    lo, hi = physics.joint_range()
    yaw = math.radians(constants.ROBOT_BASE_YAW_DEG)
    rot = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    base = np.array(constants.ROBOT_BASE_POS_M)
    for _ in range(200):
        q = rng.uniform(lo, hi)
        up_data.qpos[:] = q
        mujoco.mj_kinematics(upstream, up_data)
        with physics.reset_context():
            physics.set_joint_angles(q)
        expected = base + rot @ up_data.site("gripperframe").xpos
        np.testing.assert_allclose(physics.gripper_position(), expected, atol=1e-5)
    env.close()


def test_home_keyframe_and_golden_model_sizes(state_env):
    physics = state_env.unwrapped.physics
    model = physics.model.ptr
    assert (model.nq, model.nv, model.nu) == (13, 12, 6)
    assert [model.actuator(i).name for i in range(6)] == list(constants.JOINT_NAMES)
    state_env.reset(seed=0)
    np.testing.assert_allclose(
        physics.gripper_position(), [1.12463e-05, 0.5413619, 0.2264687], atol=1e-6
    )


def test_a_closed_gripper_can_touch_the_cube_with_both_pads(state_env):
    """Teleport the open jaws around the cube, close them, and read the jaw contacts."""
    env = state_env.unwrapped
    env.reset(seed=0, options={"cube_grid_position": 4, "cube_rotation_deg": 0})
    physics = env.physics
    assert physics.jaw_contacts("cube") == (False, False)
    assert physics.object_height("cube") == pytest.approx(0.0, abs=1e-9)


def test_close_twice_and_use_after_close(make_env):
    env = make_env("SoArm-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8
    env.close()
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.unwrapped.render()
    with pytest.raises(RuntimeError, match="closed"):
        env.unwrapped.step(np.zeros(6))


def test_render_without_a_render_mode_warns_and_returns_none(make_env):
    env = make_env("SoArm-v0", obs_type="environment_state_agent_pos")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match=r'render_mode="rgb_array"') as caught:
        assert env.render() is None
    assert "SoArm-v0" in str(caught[0].message)


def test_rgb_array_render_returns_the_render_camera(make_env):
    env = make_env(
        "SoArm-v0",
        render_mode="rgb_array",
        render_camera="overview_camera",
        camera_config="all",
        **SMALL,
    )
    obs, _ = env.reset(seed=0)
    frame = env.render()
    np.testing.assert_array_equal(frame, obs["pixels"]["overview_camera"])
    assert not np.shares_memory(frame, obs["pixels"]["overview_camera"])


def test_state_observations_render_nothing(state_env):
    state_env.reset(seed=0)
    for _ in range(3):
        state_env.step(state_env.action_space.sample())
    assert state_env.unwrapped._observer.renderers == {}


def test_sparse_reward_is_the_success_flag(make_env):
    env = make_env("SoArm-v0", obs_type="environment_state_agent_pos", reward_type="sparse")
    env.reset(seed=0)
    for _ in range(5):
        _, reward, _, _, info = env.step(env.action_space.sample())
        assert reward == float(info["is_success"])


def test_dense_reward_is_the_weighted_sum_of_its_terms(state_env):
    weights = state_env.unwrapped.task_logic.weights.terms
    assert sum(weights.values()) == pytest.approx(1.0)
    state_env.reset(seed=4)
    for _ in range(10):
        _, reward, _, _, info = state_env.step(state_env.action_space.sample())
        terms = info["reward_terms"]
        assert all(0.0 <= v <= 1.0 for v in terms.values())
        assert reward == pytest.approx(sum(weights[k] * terms[k] for k in weights))


def test_a_cube_pressed_onto_the_table_does_not_sink_into_it(state_env):
    """40 N, about what a closing jaw can press with, sinks the cube less than a millimetre."""
    state_env.reset(seed=0, options={"cube_grid_position": 4, "cube_rotation_deg": 0})
    base = state_env.unwrapped
    physics = base.physics
    cube = physics.model.ptr.body("cube").id
    hold = physics.joint_angles().astype(np.float32)
    for _ in range(25):
        physics.data.xfrc_applied[cube, 2] = -40.0
        base.step(hold)
    assert -1e-3 < physics.object_height("cube") < 0.0
