"""Control modes: spaces and units, zero deltas hold still, the jaws' pose, IK, the expert."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import COMMON_INFO_KEYS
from dataset_files import read_dataset

from gym_soarm.bench.bench import BenchConfig
from gym_soarm.cli.record import build_parser
from gym_soarm.envs import control
from gym_soarm.expert import evaluation_resets, make_expert, run_episode
from gym_soarm.real import units
from gym_soarm.record.record import record
from gym_soarm.sim.kinematics import downward_rotation

LIFT = "gym_soarm/LiftCube-v0"
PICK = "gym_soarm/PickAndPlaceCube-v0"
LOW = np.array(units.SERVO_RANGE_LOW_RAD)
HIGH = np.array(units.SERVO_RANGE_HIGH_RAD)
# Base frame -> world: the base stands at (0, 0.15, 0), its x axis along world +y.
BASE_ORIGIN = np.array([0.0, 0.15, 0.0])
BASE_ROTATION = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _state_env(make_env, mode: str, env_id: str = LIFT, **kwargs) -> gym.Env:
    return make_env(env_id, obs_type="environment_state_agent_pos", control_mode=mode, **kwargs)


def _to_base(world: np.ndarray) -> np.ndarray:
    return BASE_ROTATION.T @ (world - BASE_ORIGIN)


def _snapshot(physics) -> dict[str, np.ndarray]:
    data = physics.data
    return {
        name: np.array(getattr(data, name), copy=True)
        for name in ("qpos", "qvel", "ctrl", "act", "qacc", "xpos", "site_xpos", "time")
    }


# --- spaces, names and units ---------------------------------------------------------------
def test_each_mode_has_its_space_names_and_units(make_env):
    spaces = {mode: _state_env(make_env, mode).action_space for mode in control.CONTROL_MODES}
    for space in spaces.values():
        assert space.shape == (6,) and space.dtype == np.float32
    np.testing.assert_allclose(spaces["joint_pos"].low, LOW, rtol=1e-6)
    np.testing.assert_allclose(spaces["joint_pos"].high, HIGH, rtol=1e-6)
    np.testing.assert_allclose(spaces["joint_delta"].high, np.full(6, 0.1), rtol=1e-6)
    np.testing.assert_allclose(spaces["joint_delta"].low, np.full(6, -0.1), rtol=1e-6)
    np.testing.assert_allclose(
        spaces["ee_delta"].high, [0.01, 0.01, 0.01, 0.1, 0.1, HIGH[5]], rtol=1e-6
    )
    np.testing.assert_allclose(
        spaces["ee_delta"].low, [-0.01, -0.01, -0.01, -0.1, -0.1, LOW[5]], rtol=1e-6
    )
    np.testing.assert_allclose(
        spaces["ee_pose"].low, [-0.35, -0.45, -0.25, -math.pi, -math.pi, LOW[5]], rtol=1e-6
    )
    np.testing.assert_allclose(
        spaces["ee_pose"].high, [0.50, 0.45, 0.55, math.pi, math.pi, HIGH[5]], rtol=1e-6
    )
    assert control.action_names("joint_pos") == units.FEATURE_NAMES
    assert control.action_names("joint_delta")[0] == "shoulder_pan.delta"
    assert control.action_names("ee_delta") == (
        *("ee.dx", "ee.dy", "ee.dz", "ee.d_pitch", "ee.d_roll"),
        "gripper.pos",
    )
    assert control.action_names("ee_pose") == (
        *("ee.x", "ee.y", "ee.z", "ee.pitch", "ee.roll"),
        "gripper.pos",
    )


def test_lerobot_units_scale_the_joint_modes_and_only_the_gripper_of_the_ee_modes(make_env):
    lerobot = units.joint_units("lerobot")
    delta = _state_env(make_env, "joint_delta", units="lerobot").action_space
    np.testing.assert_allclose(delta.high, 0.1 * lerobot.scale, rtol=1e-6)
    np.testing.assert_allclose(delta.high[:5], math.degrees(0.1), rtol=1e-6)
    for mode in ("ee_delta", "ee_pose"):
        radians = _state_env(make_env, mode).action_space
        percent = _state_env(make_env, mode, units="lerobot").action_space
        np.testing.assert_array_equal(percent.low[:5], radians.low[:5])  # metres, radians
        np.testing.assert_array_equal(percent.high[:5], radians.high[:5])
        assert (percent.low[5], percent.high[5]) == pytest.approx((0.0, 100.0))


def test_info_keys_of_each_mode(make_env):
    for mode in control.CONTROL_MODES:
        env = _state_env(make_env, mode)
        _, info = env.reset(seed=0)
        *_, step_info = env.step(_hold(env))
        ik_keys = {"ik_error_m", "ik_error_rad"} if mode.startswith("ee") else set()
        for keys in (info, step_info):
            assert COMMON_INFO_KEYS | ik_keys <= set(keys)
            assert not ({"ik_error_m", "ik_error_rad"} - ik_keys) & set(keys)
        if ik_keys:
            assert info["ik_error_m"] == info["ik_error_rad"] == 0.0


def test_the_commanded_targets_are_the_last_steps_or_the_resets(make_env):
    env = _state_env(make_env, "joint_pos")
    base = env.unwrapped
    env.reset(seed=0)
    np.testing.assert_array_equal(base.commanded_targets, base.physics.joint_targets())
    action = np.array([0.3, -0.2, 0.1, 5.0, 0.0, 0.5], np.float32)  # wrist_flex clipped
    env.step(action)
    expected = np.minimum(action.astype(np.float64), HIGH)
    np.testing.assert_allclose(base.commanded_targets, expected, atol=1e-5)
    base.commanded_targets[0] = 9.0  # a copy: nothing changes
    assert base.commanded_targets[0] == pytest.approx(0.3)


def _hold(env: gym.Env) -> np.ndarray:
    """The action that keeps the current targets, in the env's mode."""
    base = env.unwrapped
    return base.control.action_for_targets(base.commanded_targets, base.commanded_targets)


# --- deltas apply to the targets -------------------------------------------------------
@pytest.mark.parametrize("mode", ["joint_delta", "ee_delta"])
def test_a_zero_delta_holds_the_arm_still(make_env, mode):
    env = _state_env(make_env, mode)
    physics = env.unwrapped.physics
    env.reset(seed=3)
    move = np.zeros(6, np.float32)
    if mode == "ee_delta":
        move[[2, 3, 4, 5]] = (-0.004, 0.03, 0.05, 0.5)  # down, tilt, turn, open
    else:
        move[[0, 2, 3, 5]] = (0.02, 0.03, 0.05, 0.05)
    for _ in range(12):
        env.step(move)
    zero = np.zeros(6, np.float32)
    if mode == "ee_delta":
        zero[5] = move[5]  # the gripper is an absolute target there
    for _ in range(40):  # let the servos settle
        env.step(zero)
    targets, angles = env.unwrapped.commanded_targets, physics.joint_angles().copy()
    np.testing.assert_array_equal(physics.joint_targets(), targets)
    assert np.abs(targets - np.zeros(6)).max() > 0.1  # the moves above did move the targets
    jaws = physics.grasp_center()
    for _ in range(50):
        env.step(zero)
    np.testing.assert_allclose(env.unwrapped.commanded_targets, targets, atol=1e-12)
    np.testing.assert_allclose(physics.joint_targets(), targets, atol=1e-12)
    np.testing.assert_allclose(physics.joint_angles(), angles, atol=1e-4)
    np.testing.assert_allclose(physics.grasp_center(), jaws, atol=1e-4)


def test_deltas_change_the_commanded_targets_under_the_servo_model(make_env):
    """With ``servo_model="sts3215"`` the servos lag; the deltas still add to what was asked."""
    env = _state_env(make_env, "joint_delta", servo_model="sts3215")
    base = env.unwrapped
    env.reset(seed=0)
    change = np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0], np.float32)
    for _ in range(5):
        env.step(change)
    np.testing.assert_allclose(base.commanded_targets[0], 0.5, atol=1e-6)
    assert base.physics.joint_targets()[0] < 0.5  # 0.094 rad a step at most
    for _ in range(30):
        env.step(np.zeros(6, np.float32))
    np.testing.assert_allclose(base.commanded_targets[0], 0.5, atol=1e-6)
    # The servo's own target gets there, to a tick and its 1 degree of backlash.
    assert base.physics.joint_targets()[0] == pytest.approx(0.5, abs=0.02)


def test_ee_delta_moves_the_jaws_target_by_the_action_in_the_base_frame(make_env):
    env = _state_env(make_env, "ee_delta")
    base = env.unwrapped
    env.reset(seed=0)
    for _ in range(5):  # away from the stretched home posture
        env.step(np.array([-0.01, 0.0, -0.01, -0.1, 0.0, 0.6], np.float32))
    before = base.control.pose(base.commanded_targets)
    action = np.array([0.006, -0.004, 0.003, 0.05, -0.07, 0.6], np.float32)
    _, _, _, _, info = env.step(action)
    after = base.control.pose(base.commanded_targets)
    np.testing.assert_allclose(after - before, action[:5], atol=2e-5)
    assert info["ik_error_m"] < 1e-5 and info["ik_error_rad"] < 1e-4
    # Base x is world +y, base y is world -x.
    world_before = BASE_ORIGIN + BASE_ROTATION @ before[:3]
    world_after = BASE_ORIGIN + BASE_ROTATION @ after[:3]
    np.testing.assert_allclose(world_after - world_before, [0.004, 0.006, 0.003], atol=2e-5)


# --- the jaws' pose --------------------------------------------------------------------
def test_pitch_and_roll_follow_the_joints_and_pitch_zero_is_the_experts_downward_jaws(make_env):
    env = _state_env(make_env, "ee_pose")
    ctl = env.unwrapped.control
    rng = np.random.default_rng(0)
    for _ in range(50):
        q = rng.uniform(LOW, HIGH)
        _, _, _, pitch, roll = ctl.pose(q)
        assert math.remainder(pitch - (math.pi / 2 - q[1] - q[2] - q[3]), math.tau) == (
            pytest.approx(0.0, abs=1e-9)
        )
        assert roll == pytest.approx(q[4] - 0.048679514853, abs=1e-9)
    # Jaws down: the site's rotation is downward_rotation(bearing + roll), the bearing
    # being the direction the arm faces (world +y at pan 0; the pan turns clockwise).
    for pan, roll in ((0.0, 0.0), (0.4, 0.3), (-0.7, -1.2)):
        q = np.array([pan, 0.3, 0.5, math.pi / 2 - 0.8, roll + 0.048679514853])
        _, rotation = ctl.kinematics.site_pose(q)
        np.testing.assert_allclose(rotation, downward_rotation(math.pi / 2 - pan + roll), atol=1e-9)
        assert ctl.pose(q)[3:] == pytest.approx([0.0, roll], abs=1e-9)


def test_ee_pose_reaches_a_reachable_target(make_env):
    env = _state_env(make_env, "ee_pose")
    base = env.unwrapped
    env.reset(seed=0)
    target = np.array([0.22, 0.06, 0.08, 0.25, 0.5, 0.4], np.float32)
    for _ in range(60):
        _, _, _, _, info = env.step(target)
    assert info["ik_error_m"] < 1e-5 and info["ik_error_rad"] < 1e-4
    reached = _to_base(base.physics.grasp_center())
    assert np.linalg.norm(reached - target[:3]) < 0.002
    measured = base.control.pose(base.physics.joint_angles())
    np.testing.assert_allclose(measured[:3], reached, atol=1e-9)
    np.testing.assert_allclose(measured[3:], target[3:5], atol=0.02)
    assert base.physics.joint_targets()[5] == pytest.approx(0.4, abs=1e-6)


def test_an_unreachable_target_is_reported_and_the_ik_never_touches_the_env(make_env):
    env = _state_env(make_env, "ee_pose")
    base = env.unwrapped
    ctl, physics = base.control, base.physics
    env.reset(seed=0)
    far = np.array([0.45, -0.3, 0.45, 0.0, 0.0, 0.0], np.float32)  # 0.6 m from the shoulder
    before = _snapshot(physics)
    targets = ctl.targets(far.astype(np.float64), base.commanded_targets)
    for name, value in _snapshot(physics).items():
        np.testing.assert_array_equal(value, before[name], err_msg=name)
    assert np.all((targets >= LOW - 1e-6) & (targets <= HIGH + 1e-6))
    _, _, _, _, info = env.step(far)
    reached = ctl.pose(base.commanded_targets)
    assert info["ik_error_m"] == pytest.approx(np.linalg.norm(reached[:3] - far[:3]), abs=1e-9)
    assert info["ik_error_m"] > 0.1
    # As close as the limits allow: nearer than where the arm started.
    start = ctl.pose(np.zeros(6))
    assert info["ik_error_m"] < np.linalg.norm(start[:3] - far[:3])


# --- the scripted expert answers in every mode ----------------------------------------------
EXPERT_CASES = [
    ("LiftCube-v0", "radians"),
    ("PickAndPlaceCube-v0", "radians"),
    ("LiftCube-v0", "lerobot"),
]


@pytest.mark.parametrize(("task", "unit"), EXPERT_CASES)
def test_the_expert_succeeds_in_every_mode_as_in_joint_pos(make_env, task, unit):
    resets = evaluation_resets(task, 1)[::9]  # four cells, every yaw once
    outcomes = {}
    for mode in control.CONTROL_MODES:
        env = _state_env(make_env, mode, f"gym_soarm/{task}", units=unit)
        expert = make_expert(env)
        results = [run_episode(env, expert, seed, options) for seed, options in resets]
        outcomes[mode] = [(r.success, r.steps) for r in results]
    for mode, results in outcomes.items():
        assert all(success for success, _ in results), (mode, results)
        steps = np.array([s for _, s in results])
        reference = np.array([s for _, s in outcomes["joint_pos"]])
        # The state expert re-reads the state each step: the modes' float rounding (and
        # ee_delta's round trip through the IK) may shift an episode by a few steps, never
        # its outcome.
        assert (np.abs(steps - reference) <= np.maximum(5, 0.1 * reference)).all(), (
            mode,
            steps,
            reference,
        )


def test_the_experts_ee_actions_stay_in_the_box_and_a_larger_move_is_split(make_env):
    env = _state_env(make_env, "ee_delta")
    base = env.unwrapped
    env.reset(seed=0)
    far = np.zeros(6)  # the home targets ...
    far[1] = 0.5  # ... with the shoulder lifted: the jaws drop by far more than 1 cm
    action = base.control.action_for_targets(far, base.commanded_targets)
    assert env.action_space.contains(action)
    assert np.abs(action[:3]).max() == pytest.approx(0.01)
    for _ in range(30):
        env.step(base.control.action_for_targets(far, base.commanded_targets))
    np.testing.assert_allclose(base.commanded_targets, far, atol=1e-4)


# --- bad input ---------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["cartesian", "JOINT_POS", 3, None])
def test_an_unknown_mode_is_refused(bad):
    with pytest.raises(ValueError, match="control_mode must be one of 'joint_pos', 'joint_delta'"):
        gym.make(LIFT, obs_type="environment_state_agent_pos", control_mode=bad)


@pytest.mark.parametrize(
    ("mode", "words"),
    [
        ("joint_pos", "absolute servo targets"),
        ("joint_delta", "changes of the servo targets"),
        ("ee_delta", "[dx, dy, dz, d_pitch, d_roll, gripper]"),
        ("ee_pose", "[x, y, z, pitch, roll, gripper]"),
    ],
)
def test_a_wrong_shape_names_the_modes_shape_and_units_and_steps_nothing(make_env, mode, words):
    env = _state_env(make_env, mode)
    physics = env.unwrapped.physics
    env.reset(seed=0)
    before = _snapshot(physics)
    for action in (np.zeros(5), np.zeros((2, 6)), [0.0] * 7):
        with pytest.raises(ValueError) as excinfo:
            env.step(action)
        message = str(excinfo.value)
        assert "shape (6,)" in message and f"control_mode={mode!r}" in message
        assert words in message and ("radians" in message or "rad" in message)
    nan = np.zeros(6)
    nan[0] = np.nan
    with pytest.raises(ValueError, match=control.action_names(mode)[0].replace(".", r"\.")):
        env.step(nan)
    for name, value in _snapshot(physics).items():
        np.testing.assert_array_equal(value, before[name], err_msg=name)


# --- determinism ---------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["joint_delta", "ee_delta", "ee_pose"])
def test_the_same_seed_and_actions_replay_bit_for_bit(make_env, mode):
    traces = []
    for _ in range(2):
        env = _state_env(make_env, mode)
        rng = np.random.default_rng(7)
        obs, info = env.reset(seed=5)
        trace = [obs["agent_pos"]]
        for _ in range(60):
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            obs, _, _, _, info = env.step(action)
            trace += [obs["agent_pos"], obs["environment_state"]]
            if "ik_error_m" in info:
                trace.append(np.array([info["ik_error_m"], info["ik_error_rad"]]))
        traces.append(np.concatenate(trace))
    np.testing.assert_array_equal(traces[0], traces[1])


# --- recorder, command line, benchmark -----------------------------------------------------
def test_a_recording_in_ee_delta_replays_and_names_its_action(tmp_path, make_env):
    root = tmp_path / "ee"
    summary = record(
        root, task="LiftCube-v0", episodes=1, camera_config="none", control_mode="ee_delta"
    )
    assert summary.successes == 1
    ds = read_dataset(root)
    assert ds.info["features"]["action"]["names"] == list(control.EE_DELTA_NAMES)
    assert ds.info["features"]["action"]["shape"] == [6]
    assert ds.info["features"]["observation.state"]["names"] == list(units.FEATURE_NAMES)
    env = _state_env(make_env, "ee_delta", units="lerobot")
    obs, _ = env.reset(seed=0)
    for action, state in zip(ds.data["action"], ds.data["observation.state"], strict=True):
        np.testing.assert_allclose(obs["agent_pos"], state, atol=1e-3)
        obs, _, terminated, _, info = env.step(action.astype(np.float32))
    assert terminated and info["is_success"]
    assert build_parser().parse_args(["--control-mode", "ee_pose"]).control_mode == "ee_pose"
    with pytest.raises(ValueError, match="control_mode must be one of"):
        record(tmp_path / "never", episodes=1, camera_config="none", control_mode="xyz")
    assert not (tmp_path / "never").exists()


def test_the_benchmark_takes_a_control_mode():
    config = BenchConfig.parse("state", control_mode="ee_delta")
    assert config.env_kwargs()["control_mode"] == "ee_delta"
    assert BenchConfig.parse("front_wrist_64x48").env_kwargs()["control_mode"] == "joint_pos"
    with pytest.raises(ValueError, match="control_mode must be one of"):
        BenchConfig.parse("state", control_mode="ik")
