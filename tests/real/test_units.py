"""Joint units of LeRobot's SO-101 follower: conversions, LeRobot's own formulas, the env option."""

from __future__ import annotations

import math
import re

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.real import units
from gym_soarm.sim.physics import SoArmPhysics

LOW = np.array(units.SERVO_RANGE_LOW_RAD)
HIGH = np.array(units.SERVO_RANGE_HIGH_RAD)
GRIPPER = constants.JOINT_NAMES.index("gripper")
WRIST_ROLL = constants.JOINT_NAMES.index("wrist_roll")
BODY = [i for i in range(6) if i != GRIPPER]

# LeRobot's Feetech STS3215 servos: 12-bit position, calibrated so the middle pose reads 2047.
MAX_RES = 4095
MID_TICK = 2047
TICKS_PER_RAD = MAX_RES / (2 * math.pi)


def _random_radians(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(LOW, HIGH, size=(n, 6))


def test_servo_ranges_are_the_models_actuator_ranges():
    low, high = SoArmPhysics.from_scene().control_range()
    np.testing.assert_allclose(low, LOW, atol=1e-9)
    np.testing.assert_allclose(high, HIGH, atol=1e-9)


def test_feature_names_follow_lerobot():
    assert units.FEATURE_NAMES == (
        "shoulder_pan.pos",
        "shoulder_lift.pos",
        "elbow_flex.pos",
        "wrist_flex.pos",
        "wrist_roll.pos",
        "gripper.pos",
    )


@pytest.mark.parametrize("name", units.UNITS)
def test_round_trip(name):
    rad = _random_radians(1000)
    back = units.units_to_radians(units.radians_to_units(rad, name), name)
    np.testing.assert_allclose(back, rad, rtol=0, atol=1e-12)
    values = units.radians_to_units(rad, name)
    np.testing.assert_allclose(units.radians_to_units(back, name), values, atol=1e-9)


def test_radians_are_the_identity_bit_for_bit():
    rad = _random_radians(100)
    conversion = units.joint_units("radians")
    np.testing.assert_array_equal(conversion.from_radians(rad), rad)
    np.testing.assert_array_equal(conversion.to_radians(rad), rad)


def test_lerobot_table_values():
    one = units.radians_to_lerobot(np.ones(6))
    np.testing.assert_allclose(one[BODY], 57.29578, atol=1e-5)
    np.testing.assert_allclose(units.radians_to_lerobot(LOW)[GRIPPER], 0.0, atol=1e-9)
    np.testing.assert_allclose(units.radians_to_lerobot(HIGH)[GRIPPER], 100.0, atol=1e-9)
    np.testing.assert_allclose(units.radians_to_lerobot(np.zeros(6))[GRIPPER], 9.0908, atol=1e-4)
    np.testing.assert_allclose(units.radians_to_lerobot(HIGH)[0], 110.0, atol=1e-3)
    # 15 % open is 0.113 rad, not deg2rad(15) = 0.262 rad.
    np.testing.assert_allclose(
        units.lerobot_to_radians(np.full(6, 15.0))[GRIPPER], 0.11345, atol=1e-5
    )


def test_lerobot_range_table_values():
    conv = units.joint_units("lerobot_range")
    low, high = conv.from_radians(LOW), conv.from_radians(HIGH)
    symmetric = [i for i in BODY if i != WRIST_ROLL]
    np.testing.assert_allclose(low[symmetric], -100.0, atol=1e-9)
    np.testing.assert_allclose(high[symmetric], 100.0, atol=1e-9)
    np.testing.assert_allclose(conv.from_radians(np.full(6, math.pi))[WRIST_ROLL], 100.0)
    np.testing.assert_allclose([low[GRIPPER], high[GRIPPER]], [0.0, 100.0], atol=1e-9)


@pytest.mark.parametrize("bad", ["degrees", "Radians", None, 3])
def test_bad_units_name_the_valid_values(bad):
    with pytest.raises(ValueError, match="'radians', 'lerobot', 'lerobot_range'"):
        units.joint_units(bad)


# --- LeRobot's own normalisation, re-derived from a synthetic calibration --------------------
# LeRobot's follower calibration: every joint held at the middle of its range reads MID_TICK;
# the body joints and the gripper are swept through their range (range_min/max recorded);
# wrist_roll gets the full turn 0..MAX_RES. The model's zero is the middle of each body joint's
# range, so a sim angle maps to ticks = MID_TICK + (rad - middle) * TICKS_PER_RAD.
def _calibration() -> dict[str, tuple[int, int, float]]:
    """joint -> (range_min, range_max, sim angle held at MID_TICK)."""
    calibration = {}
    for i, joint in enumerate(constants.JOINT_NAMES):
        if joint == "wrist_roll":
            calibration[joint] = (0, MAX_RES, 0.0)
            continue
        middle = (LOW[i] + HIGH[i]) / 2
        half = (HIGH[i] - LOW[i]) / 2 * TICKS_PER_RAD
        calibration[joint] = (round(MID_TICK - half), round(MID_TICK + half), middle)
    return calibration


def _ticks(rad: float, middle: float) -> int:
    return round(MID_TICK + (rad - middle) * TICKS_PER_RAD)


def _lerobot_degrees(ticks: int, range_min: int, range_max: int) -> float:
    return (ticks - (range_min + range_max) / 2) * 360 / MAX_RES


def _lerobot_range_m100_100(ticks: int, range_min: int, range_max: int) -> float:
    bounded = min(range_max, max(range_min, ticks))
    return (bounded - range_min) / (range_max - range_min) * 200 - 100


def _lerobot_range_0_100(ticks: int, range_min: int, range_max: int) -> float:
    bounded = min(range_max, max(range_min, ticks))
    return (bounded - range_min) / (range_max - range_min) * 100


@pytest.mark.parametrize("mode", ["lerobot", "lerobot_range"])
def test_matches_lerobot_normalisation_within_one_servo_tick(mode):
    calibration = _calibration()
    rad = np.concatenate([_random_radians(500, seed=1), LOW[None], HIGH[None], np.zeros((1, 6))])
    ours = units.radians_to_units(rad, mode)
    for i, joint in enumerate(constants.JOINT_NAMES):
        range_min, range_max, middle = calibration[joint]
        if joint == "gripper":
            formula, per_tick = _lerobot_range_0_100, 100 / (range_max - range_min)
        elif mode == "lerobot":
            formula, per_tick = _lerobot_degrees, 360 / MAX_RES
        else:
            formula, per_tick = _lerobot_range_m100_100, 200 / (range_max - range_min)
        theirs = np.array([formula(_ticks(r, middle), range_min, range_max) for r in rad[:, i]])
        error_ticks = np.abs(ours[:, i] - theirs) / per_tick
        assert error_ticks.max() <= 1.0, (joint, error_ticks.max())
        # The check can fail: a conversion off by 2 % would show as many ticks.
        assert np.abs(ours[:, i] * 1.02 - theirs).max() / per_tick > 1.0


# --- the env's units option ------------------------------------------------------------------
def _state_env(u: str, wrist_roll_offset_deg: float = 0.0) -> gym.Env:
    return gym.make(
        "gym_soarm/LiftCube-v0",
        obs_type="environment_state_agent_pos",
        units=u,
        wrist_roll_offset_deg=wrist_roll_offset_deg,
    )


@pytest.mark.parametrize("name", ["lerobot", "lerobot_range"])
def test_env_bounds_actions_and_agent_pos_agree(name):
    conv = units.joint_units(name)
    env_rad, env_units = _state_env("radians"), _state_env(name)
    try:
        assert env_units.unwrapped.units == name
        np.testing.assert_allclose(env_units.action_space.low, conv.from_radians(LOW), rtol=1e-6)
        np.testing.assert_allclose(env_units.action_space.high, conv.from_radians(HIGH), rtol=1e-6)
        assert env_units.observation_space["agent_pos"].contains(
            conv.from_radians(LOW)
        ) and env_units.observation_space["agent_pos"].contains(conv.from_radians(HIGH))
        obs_rad, _ = env_rad.reset(seed=5)
        obs_units, _ = env_units.reset(seed=5)
        rng = np.random.default_rng(0)
        for step in range(30):
            action_rad = rng.uniform(LOW, HIGH)
            if step == 20:
                action_rad = HIGH + 0.5  # beyond the bounds: both clip to the servo range
            obs_rad, *_ = env_rad.step(action_rad)
            obs_units, *_ = env_units.step(conv.from_radians(action_rad))
            np.testing.assert_allclose(
                obs_units["agent_pos"], conv.from_radians(obs_rad["agent_pos"]), atol=1e-6
            )
            assert env_units.observation_space.contains(obs_units)
        # The arm moved, so equal agent_pos is not the home pose twice.
        assert np.abs(obs_rad["agent_pos"]).max() > 0.1
    finally:
        env_rad.close()
        env_units.close()


def test_env_lerobot_degrees_move_the_arm_by_degrees():
    env = _state_env("lerobot")
    try:
        env.reset(seed=0)
        target = np.array([30.0, -20.0, 25.0, 10.0, 45.0, 50.0])
        for _ in range(100):
            obs, *_ = env.step(target)
        np.testing.assert_allclose(obs["agent_pos"][BODY], target[BODY], atol=1.0)
        np.testing.assert_allclose(
            env.unwrapped.physics.joint_angles()[BODY], np.radians(target[BODY]), atol=0.02
        )
    finally:
        env.close()


@pytest.mark.parametrize("bad", ["degrees", "LeRobot", None, 1])
def test_env_rejects_bad_units(bad):
    with pytest.raises(
        ValueError, match=r"units must be one of 'radians', 'lerobot', 'lerobot_range'"
    ):
        gym.make("SoArm-v0", obs_type="environment_state_agent_pos", units=bad)


# --- wrist_roll offset -----------------------------------------------------------------------
def _wrap_deg(degrees: np.ndarray) -> np.ndarray:
    return (np.asarray(degrees) + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("offset", [-90.0, 10.0, 120.0, -180.0, 180.0])
@pytest.mark.parametrize("name", ["lerobot", "lerobot_range"])
def test_wrist_roll_offset_shifts_wraps_and_round_trips(name, offset):
    conv = units.joint_units(name, offset)
    plain = units.joint_units(name)
    rad = _random_radians(500, seed=3)
    values = conv.from_radians(rad)
    # Every other joint is untouched, bit for bit.
    others = [i for i in range(6) if i != WRIST_ROLL]
    np.testing.assert_array_equal(values[:, others], plain.from_radians(rad)[:, others])
    # wrist_roll reads the shifted angle, wrapped to half a turn either way.
    per_degree = 1.0 if name == "lerobot" else 100.0 / 180.0
    expected = _wrap_deg(np.degrees(rad[:, WRIST_ROLL]) + offset) * per_degree
    np.testing.assert_allclose(values[:, WRIST_ROLL], expected, atol=1e-9)
    assert np.all(np.abs(values[:, WRIST_ROLL]) <= 180.0 * per_degree)
    np.testing.assert_allclose(conv.to_radians(values), rad, atol=1e-12)
    # The model at 0 rad reads the offset (wrapped).
    assert conv.from_radians(np.zeros(6))[WRIST_ROLL] == pytest.approx(
        _wrap_deg(offset) * per_degree, abs=1e-9
    )


def test_zero_offset_is_the_plain_conversion():
    for name in units.UNITS:
        assert units.joint_units(name, 0.0) is units.joint_units(name)


def test_wrist_roll_values_outside_the_range_go_to_the_nearest_end():
    conv = units.joint_units("lerobot", -90.0)
    low_deg, high_deg = np.degrees(LOW[WRIST_ROLL]), np.degrees(HIGH[WRIST_ROLL])
    # The model's range shifted by -90 degrees reads high_deg - 90 at its upper end and
    # wraps at -180; readings between the two ends are out of the servo's reach.
    gap = (high_deg - 90.0, low_deg - 90.0 + 360.0)
    for reading, end in (
        (gap[0] + 5.0, HIGH[WRIST_ROLL]),
        (gap[1] - 5.0, LOW[WRIST_ROLL]),
    ):
        values = np.zeros(6)
        values[WRIST_ROLL] = reading
        rad = np.clip(conv.to_radians(values), LOW, HIGH)
        assert rad[WRIST_ROLL] == pytest.approx(end)


@pytest.mark.parametrize(
    ("offset", "wraps"), [(10.0, False), (-20.0, False), (-90.0, True), (45.0, True)]
)
def test_env_spaces_with_a_wrist_roll_offset(offset, wraps):
    # The servo range shifted by the offset, or the whole turn when that crosses +-180.
    if wraps:
        low, high = -180.0, 180.0
    else:
        low, high = np.degrees([LOW[WRIST_ROLL], HIGH[WRIST_ROLL]]) + offset
    env = _state_env("lerobot", offset)
    try:
        assert env.unwrapped.wrist_roll_offset_deg == offset
        assert env.action_space.low[WRIST_ROLL] == pytest.approx(low, abs=1e-4)
        assert env.action_space.high[WRIST_ROLL] == pytest.approx(high, abs=1e-4)
        agent_pos = env.observation_space["agent_pos"]
        assert (agent_pos.low[WRIST_ROLL], agent_pos.high[WRIST_ROLL]) == (-180.0, 180.0)
        obs, _ = env.reset(seed=0)
        assert obs["agent_pos"][WRIST_ROLL] == pytest.approx(_wrap_deg(offset))  # home: 0 rad
        # A reading moves the model's wrist_roll to the reading minus the offset.
        reading = _wrap_deg(offset + 40.0)
        action = np.array([0.0, 0.0, 0.0, 0.0, reading, 50.0])
        for _ in range(60):
            obs, *_ = env.step(action)
        physics = env.unwrapped.physics
        assert physics.joint_targets()[WRIST_ROLL] == pytest.approx(math.radians(40.0))
        assert physics.joint_angles()[WRIST_ROLL] == pytest.approx(math.radians(40.0), abs=0.02)
        assert obs["agent_pos"][WRIST_ROLL] == pytest.approx(reading, abs=1.0)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_wrist_roll_actions_beyond_the_box_clip_to_its_nearer_bound():
    """With or without an offset, a value past a bound goes to that bound's servo end."""
    for offset, value, end in ((0.0, -179.0, LOW), (1e-6, -179.0, LOW), (10.0, 200.0, HIGH)):
        env = _state_env("lerobot", offset)
        try:
            env.reset(seed=0)
            action = np.array([0.0, 0.0, 0.0, 0.0, value, 50.0])
            env.step(action)
            target = env.unwrapped.physics.joint_targets()[WRIST_ROLL]
            assert target == pytest.approx(end[WRIST_ROLL]), (offset, value)
        finally:
            env.close()


def test_the_conversion_helpers_take_the_offset():
    rad = _random_radians(20, seed=4)
    values = units.radians_to_units(rad, "lerobot", wrist_roll_offset_deg=-90.0)
    np.testing.assert_allclose(values, units.joint_units("lerobot", -90.0).from_radians(rad))
    back = units.units_to_radians(values, "lerobot", wrist_roll_offset_deg=-90.0)
    np.testing.assert_allclose(back, rad, atol=1e-12)


def test_expert_speaks_the_offset_units():
    from gym_soarm import make_expert

    env = _state_env("lerobot", -45.0)  # not a quarter turn, which the cube would hide
    try:
        expert = make_expert(env)
        obs, info = env.reset(seed=1, options={"cube_grid_position": 2, "cube_rotation_deg": 45})
        expert.reset()
        for _ in range(250):
            obs, _, terminated, truncated, info = env.step(expert(obs, info))
            if terminated or truncated:
                break
        assert info["is_success"]
    finally:
        env.close()


@pytest.mark.parametrize(
    ("units_name", "offset", "error", "fragment"),
    [
        (
            "radians",
            -90.0,
            ValueError,
            "applies to LeRobot's units; got -90.0 with units='radians'",
        ),
        ("lerobot", 270.0, ValueError, "between -180 and 180 degrees; got 270.0"),
        ("lerobot", float("nan"), ValueError, "between -180 and 180 degrees; got nan"),
        ("lerobot", "-90", TypeError, "must be a real number of degrees; got '-90' (str)"),
        ("lerobot", True, TypeError, "must be a real number of degrees; got True (bool)"),
    ],
)
def test_bad_wrist_roll_offsets_are_refused(units_name, offset, error, fragment):
    with pytest.raises(error, match=re.escape(fragment)):
        units.joint_units(units_name, offset)
    with pytest.raises(error, match=re.escape(fragment)):
        gym.make(
            "SoArm-v0",
            obs_type="environment_state_agent_pos",
            units=units_name,
            wrist_roll_offset_deg=offset,
        )
