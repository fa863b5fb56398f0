"""Real-arm calibration files: LeRobot's normalisation restated, the env option, bad files."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.real import units
from gym_soarm.real.calibration import (
    HOMING_POSE_RAD,
    HOMING_TICKS,
    TICKS_PER_RAD,
    calibrated_units,
    load_calibration,
)
from gym_soarm.record.record import record

LOW = np.array(units.SERVO_RANGE_LOW_RAD)
HIGH = np.array(units.SERVO_RANGE_HIGH_RAD)
NAMES = constants.JOINT_NAMES
GRIPPER = NAMES.index("gripper")
WRIST_ROLL = NAMES.index("wrist_roll")
BODY = [i for i in range(6) if i != GRIPPER]

# A follower's file as lerobot-calibrate writes it: ranges swept by hand, so not centred
# on 2047; wrist_roll gets the whole turn.
ARM = {
    "shoulder_pan": (1, 0, -1470, 758, 3292),
    "shoulder_lift": (2, 0, 1205, 612, 3241),
    "elbow_flex": (3, 0, -1089, 869, 3097),
    "wrist_flex": (4, 0, 502, 860, 3200),
    "wrist_roll": (5, 0, -1937, 0, 4095),
    "gripper": (6, 0, 1388, 1450, 2680),
}
FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")


def _content(arm: dict[str, tuple[int, ...]]) -> dict[str, dict[str, int]]:
    return {name: dict(zip(FIELDS, values, strict=True)) for name, values in arm.items()}


def _write(path: Path, content: object) -> Path:
    path.write_text(json.dumps(content, indent=4), encoding="utf-8")
    return path


def _centred(half_widths: list[float], drive_mode: int = 0) -> dict[str, dict[str, int]]:
    arm = {}
    for i, name in enumerate(NAMES):
        half = round(half_widths[i])
        arm[name] = (i + 1, drive_mode, 0, HOMING_TICKS - half, HOMING_TICKS + half)
    return _content(arm)


# The model's range of each joint in ticks, as a centred calibration would record it.
MODEL_HALF_WIDTHS = [(h - lo) / 2 * TICKS_PER_RAD for lo, h in zip(LOW, HIGH, strict=True)]


@pytest.fixture
def arm_file(tmp_path) -> Path:
    return _write(tmp_path / "follower.json", _content(ARM))


def _random_radians(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(LOW, HIGH, size=(n, 6))


# --- LeRobot's MotorsBus._normalize / _unnormalize, restated per value -----------------------
def _lerobot_normalize(ticks: float, mode: str, low: int, high: int, drive: int) -> float:
    if mode == "degrees":
        return (ticks - (low + high) / 2) * 360 / 4095
    bounded = min(high, max(low, ticks))
    if mode == "m100":
        norm = (((bounded - low) / (high - low)) * 200) - 100
        return -norm if drive else norm
    norm = ((bounded - low) / (high - low)) * 100
    return 100 - norm if drive else norm


def _lerobot_unnormalize(value: float, mode: str, low: int, high: int, drive: int) -> int:
    if mode == "degrees":
        return int((value * 4095 / 360) + (low + high) / 2)
    if mode == "m100":
        value = -value if drive else value
        bounded = min(100.0, max(-100.0, value))
        return int(((bounded + 100) / 200) * (high - low) + low)
    value = 100 - value if drive else value
    bounded = min(100.0, max(0.0, value))
    return int((bounded / 100) * (high - low) + low)


def _modes(unit: str) -> list[str]:
    body = "degrees" if unit == "lerobot" else "m100"
    return [("p100" if i == GRIPPER else body) for i in range(6)]


# --- the conversion -----------------------------------------------------------------------------
def test_homing_pose_is_the_models_zero_and_the_grippers_middle():
    assert HOMING_POSE_RAD[:5] == (0.0,) * 5
    assert HOMING_POSE_RAD[GRIPPER] == pytest.approx((LOW[GRIPPER] + HIGH[GRIPPER]) / 2)


def test_a_centred_calibration_gives_the_default_degrees(tmp_path):
    # Any widths: degrees count from the middle of the range, which is 2047 here.
    widths = [1000, 1100, 900, 1200, 2047, MODEL_HALF_WIDTHS[GRIPPER]]
    conv = calibrated_units("lerobot", _write(tmp_path / "c.json", _centred(widths)))
    default = units.joint_units("lerobot")
    rad = _random_radians(2000)
    ours = conv.from_radians(rad)
    np.testing.assert_allclose(ours[:, BODY], default.from_radians(rad)[:, BODY], atol=1e-9)
    # The gripper's 0..100 spans the recorded range: the model's 1251.2 ticks as 1252.
    np.testing.assert_allclose(ours[:, GRIPPER], default.from_radians(rad)[:, GRIPPER], atol=0.05)
    np.testing.assert_allclose(conv.scale[BODY], default.scale[BODY], rtol=1e-12)
    back = conv.to_radians(default.from_radians(rad))
    np.testing.assert_allclose(back[:, BODY], rad[:, BODY], atol=1e-12)
    np.testing.assert_allclose(back[:, GRIPPER], rad[:, GRIPPER], atol=1e-3)


def test_a_centred_calibration_over_the_models_ranges_gives_the_default_percent(tmp_path):
    widths = list(MODEL_HALF_WIDTHS)
    widths[WRIST_ROLL] = 2047  # the whole turn, centred on 2047 (0 to 4094)
    conv = calibrated_units("lerobot_range", _write(tmp_path / "c.json", _centred(widths)))
    default = units.joint_units("lerobot_range")
    rad = _random_radians(2000, seed=1)
    # Whole ticks: at most half a tick of each range's width apart.
    np.testing.assert_allclose(conv.from_radians(rad), default.from_radians(rad), atol=0.05)


def test_an_asymmetric_range_moves_that_joints_zero(arm_file):
    conv = calibrated_units("lerobot", arm_file)
    default = units.joint_units("lerobot")
    middle = (758 + 3292) / 2  # shoulder_pan's recorded middle: 22 ticks below 2047
    shift_deg = (HOMING_TICKS - middle) * 360 / 4095
    assert shift_deg == pytest.approx(1.934, abs=1e-3)
    rad = _random_radians(500, seed=2)
    np.testing.assert_allclose(
        conv.from_radians(rad)[:, 0], default.from_radians(rad)[:, 0] + shift_deg, atol=1e-9
    )
    # The arm's 0 degrees is the model's -1.934 degrees.
    zero = conv.to_radians(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 50.0]))
    assert math.degrees(zero[0]) == pytest.approx(-shift_deg, abs=1e-9)
    # wrist_roll's whole turn has its middle half a tick above 2047.
    np.testing.assert_allclose(
        conv.from_radians(rad)[:, WRIST_ROLL],
        default.from_radians(rad)[:, WRIST_ROLL] - 0.5 * 360 / 4095,
        atol=1e-9,
    )


@pytest.mark.parametrize("unit", ["lerobot", "lerobot_range"])
@pytest.mark.parametrize("drive_mode", [0, 1])
def test_restated_lerobot_normalisation_over_random_ticks(tmp_path, unit, drive_mode):
    content = _content(ARM)
    for name in ("elbow_flex", "gripper"):
        content[name]["drive_mode"] = drive_mode
    conv = calibrated_units(unit, _write(tmp_path / "arm.json", content))
    rng = np.random.default_rng(3)
    ticks = rng.integers(0, 4096, size=(3000, 6)).astype(np.float64)
    values = conv.normalize(ticks)
    modes = _modes(unit)
    for i, name in enumerate(NAMES):
        _, _, _, low, high = ARM[name]
        drive = content[name]["drive_mode"]
        expected = [_lerobot_normalize(t, modes[i], low, high, drive) for t in ticks[:, i]]
        np.testing.assert_array_equal(values[:, i], expected)  # the same float operations
        back = conv.unnormalize(values[:, i : i + 1].repeat(6, axis=1))[:, i]
        truncated = [_lerobot_unnormalize(v, modes[i], low, high, drive) for v in values[:, i]]
        np.testing.assert_array_equal(back.astype(np.int64), truncated)  # LeRobot's int()
        inside = (ticks[:, i] >= low) & (ticks[:, i] <= high)
        if modes[i] == "degrees":
            inside[:] = True  # degrees are not bounded
        np.testing.assert_allclose(back[inside], ticks[inside, i], atol=1e-9)
    # Ticks and radians agree with the homing pose: 2047 is the held pose.
    np.testing.assert_allclose(conv.radians_to_ticks(np.array(HOMING_POSE_RAD)), HOMING_TICKS)
    rad = _random_radians(1000, seed=4)
    np.testing.assert_allclose(conv.ticks_to_radians(conv.radians_to_ticks(rad)), rad, atol=1e-12)
    np.testing.assert_array_equal(
        conv.from_radians(rad), conv.normalize(conv.radians_to_ticks(rad))
    )


def test_drive_mode_one_mirrors_ticks_and_degrees_but_not_range_values(tmp_path):
    plain = _centred([1300, 1300, 1300, 1300, 2047, 700])
    mirrored = _centred([1300, 1300, 1300, 1300, 2047, 700], drive_mode=1)
    rad = _random_radians(500, seed=5)
    for unit in ("lerobot", "lerobot_range"):
        a = calibrated_units(unit, _write(tmp_path / "a.json", plain))
        b = calibrated_units(unit, _write(tmp_path / "b.json", mirrored))
        np.testing.assert_allclose(
            b.radians_to_ticks(rad) - HOMING_TICKS,
            HOMING_TICKS - a.radians_to_ticks(rad),
            atol=1e-9,
        )
        # Range values are negated back (as the Feetech bus does); degrees are not.
        sign = np.where(np.array(_modes(unit)) == "degrees", -1.0, 1.0)
        centre = np.where(np.array(_modes(unit)) == "p100", 50.0, 0.0)
        np.testing.assert_allclose(
            b.from_radians(rad) - centre, sign * (a.from_radians(rad) - centre), atol=1e-9
        )
        np.testing.assert_allclose(b.to_radians(b.from_radians(rad)), rad, atol=1e-9)


def test_range_values_stop_at_the_recorded_range_and_degrees_do_not(arm_file):
    beyond = np.array([HIGH[0], LOW[1], HIGH[2], LOW[3], 0.0, HIGH[GRIPPER]]) * 1.5
    ranged = calibrated_units("lerobot_range", arm_file)
    np.testing.assert_array_equal(ranged.from_radians(beyond)[[0, 1, 2, 3]], [100, -100, 100, -100])
    assert ranged.from_radians(beyond)[GRIPPER] == 100.0
    np.testing.assert_array_equal(ranged.to_radians([150.0] * 6), ranged.to_radians([100.0] * 6))
    degrees = calibrated_units("lerobot", arm_file)
    assert degrees.from_radians(beyond)[0] > degrees.from_radians(HIGH)[0] + 50
    low, high = ranged.bounds(LOW, HIGH)
    assert (low >= -100).all() and (high <= 100).all() and (low < high).all()


def test_wrist_roll_offset_moves_the_held_pose(tmp_path):
    widths = [1000, 1000, 1000, 1000, 2047, MODEL_HALF_WIDTHS[GRIPPER]]
    path = _write(tmp_path / "c.json", _centred(widths))
    conv = calibrated_units("lerobot", path, wrist_roll_offset_deg=-90.0)
    default = units.joint_units("lerobot", wrist_roll_offset_deg=-90.0)
    assert conv.homing_rad[WRIST_ROLL] == pytest.approx(math.radians(90.0))
    rad = _random_radians(2000, seed=6)
    ours, theirs = conv.from_radians(rad), default.from_radians(rad)
    np.testing.assert_allclose(ours[:, BODY], theirs[:, BODY], atol=1e-9)
    np.testing.assert_allclose(conv.to_radians(ours), rad, atol=1e-9)
    np.testing.assert_allclose(conv.bounds(LOW, HIGH)[0][WRIST_ROLL], -180.0, atol=1e-9)


# --- the env, the recorder and bad input ------------------------------------------------------
def _state_env(**options) -> gym.Env:
    return gym.make("gym_soarm/LiftCube-v0", obs_type="environment_state_agent_pos", **options)


@pytest.mark.parametrize("unit", ["lerobot", "lerobot_range"])
def test_env_speaks_the_calibrated_arms_values(arm_file, unit):
    conv = calibrated_units(unit, arm_file)
    env = _state_env(units=unit, calibration=arm_file)
    try:
        assert env.unwrapped.calibration == str(arm_file)
        low_rad, high_rad = env.unwrapped.physics.control_range()
        low, high = conv.bounds(low_rad, high_rad)
        np.testing.assert_allclose(env.action_space.low, low, rtol=1e-6)
        np.testing.assert_allclose(env.action_space.high, high, rtol=1e-6)
        obs, _ = env.reset(seed=0)
        rng = np.random.default_rng(7)
        for _ in range(5):
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            obs, *_ = env.step(action)
            targets = env.unwrapped.physics.joint_targets()
            np.testing.assert_allclose(
                targets, np.clip(conv.to_radians(action), low_rad, high_rad), atol=1e-9
            )
            angles = env.unwrapped.physics.joint_angles()
            np.testing.assert_allclose(obs["agent_pos"], conv.from_radians(angles), atol=1e-4)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_env_without_calibration_is_unchanged(arm_file):
    plain, calibrated = (
        _state_env(units="lerobot"),
        _state_env(units="lerobot", calibration=arm_file),
    )
    try:
        assert plain.unwrapped.calibration is None
        obs_plain, _ = plain.reset(seed=1)
        obs_cal, _ = calibrated.reset(seed=1)
        conv = calibrated.unwrapped.joint_units
        np.testing.assert_array_equal(
            obs_plain["agent_pos"], units.radians_to_lerobot(plain.unwrapped.physics.joint_angles())
        )
        # The same pose reads differently on the calibrated arm (shoulder_pan +1.93 deg).
        assert obs_cal["agent_pos"][0] == pytest.approx(obs_plain["agent_pos"][0] + 1.934, abs=1e-3)
        np.testing.assert_allclose(
            obs_cal["agent_pos"],
            conv.from_radians(plain.unwrapped.physics.joint_angles()),
            atol=1e-6,
        )
    finally:
        plain.close()
        calibrated.close()


def test_joint_delta_with_a_mirrored_joint_has_a_valid_box(tmp_path):
    content = _content(ARM)
    content["elbow_flex"]["drive_mode"] = 1
    path = _write(tmp_path / "mirrored.json", content)
    env = _state_env(units="lerobot", calibration=path, control_mode="joint_delta")
    try:
        assert (env.action_space.low < env.action_space.high).all()
        env.reset(seed=0)
        before = env.unwrapped.physics.joint_targets().copy()
        action = np.zeros(6, np.float32)
        action[NAMES.index("elbow_flex")] = 2.0  # mirrored degrees: the joint goes down
        env.step(action)
        change = env.unwrapped.physics.joint_targets() - before
        assert change[NAMES.index("elbow_flex")] == pytest.approx(-math.radians(2.0))
    finally:
        env.close()


def test_recorder_writes_the_calibrated_arms_values(tmp_path, arm_file):
    from dataset_files import read_dataset

    options = {"task": "LiftCube-v0", "episodes": 1, "seed": 0, "camera_config": "none"}
    record(tmp_path / "rad", units="radians", **options)
    record(tmp_path / "cal", units="lerobot", calibration=arm_file, **options)
    radians, calibrated = read_dataset(tmp_path / "rad"), read_dataset(tmp_path / "cal")
    conv = calibrated_units("lerobot", arm_file)
    for key in ("observation.state", "action"):
        expected = conv.from_radians(radians.data[key].astype(np.float64))
        np.testing.assert_allclose(calibrated.data[key], expected, atol=1e-3)


def _bad(content_edit) -> dict:
    content = _content(ARM)
    content_edit(content)
    return content


BAD_FILES = [
    ("not JSON", "{shoulder_pan: 1", r"is not JSON"),
    ("a list", [1, 2], r"holds a list, not an object of motors"),
    ("missing motor", _bad(lambda c: c.pop("elbow_flex")), r"motor 'elbow_flex' is missing"),
    ("unknown motor", _bad(lambda c: c.update(elbow=c["elbow_flex"])), r"unknown motor 'elbow'"),
    ("motor not object", _bad(lambda c: c.update(gripper=[1])), r"motor 'gripper' is a list"),
    (
        "missing field",
        _bad(lambda c: c["elbow_flex"].pop("range_max")),
        r"motor 'elbow_flex' has no 'range_max'",
    ),
    (
        "unknown field",
        _bad(lambda c: c["wrist_flex"].update(offset=3)),
        r"motor 'wrist_flex' has an unknown field 'offset'",
    ),
    (
        "float field",
        _bad(lambda c: c["shoulder_pan"].update(range_min=758.5)),
        r"motor 'shoulder_pan' field 'range_min' must be an integer; got 758.5",
    ),
    (
        "string field",
        _bad(lambda c: c["shoulder_lift"].update(homing_offset="12")),
        r"motor 'shoulder_lift' field 'homing_offset' must be an integer; got '12'",
    ),
    (
        "bool field",
        _bad(lambda c: c["gripper"].update(drive_mode=True)),
        r"motor 'gripper' field 'drive_mode' must be an integer; got True",
    ),
    (
        "drive mode 2",
        _bad(lambda c: c["gripper"].update(drive_mode=2)),
        r"motor 'gripper' field 'drive_mode' must be 0 or 1; got 2",
    ),
    (
        "range above 4095",
        _bad(lambda c: c["wrist_roll"].update(range_max=4096)),
        r"motor 'wrist_roll' field 'range_max' must be 0 to 4095 ticks; got 4096",
    ),
    (
        "negative range",
        _bad(lambda c: c["wrist_roll"].update(range_min=-1)),
        r"motor 'wrist_roll' field 'range_min' must be 0 to 4095 ticks; got -1",
    ),
    (
        "empty range",
        _bad(lambda c: c["elbow_flex"].update(range_min=3097)),
        r"motor 'elbow_flex' has range_min 3097 >= range_max 3097",
    ),
]


@pytest.mark.parametrize(("case", "content", "message"), BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_malformed_files_name_the_file_and_the_field(tmp_path, case, content, message):
    path = tmp_path / "bad.json"
    if isinstance(content, str):
        path.write_text(content, encoding="utf-8")
    else:
        _write(path, content)
    expected = re.escape(f"calibration file {path}: ") + message
    with pytest.raises(ValueError, match=expected):
        load_calibration(path)
    with pytest.raises(ValueError, match=expected):
        _state_env(units="lerobot", calibration=path)


def test_missing_file_and_wrong_types(tmp_path, arm_file):
    missing = tmp_path / "nowhere.json"
    with pytest.raises(ValueError, match=re.escape(f"calibration file {missing}: no such file")):
        _state_env(units="lerobot", calibration=missing)
    with pytest.raises(TypeError, match="calibration must be the path of a LeRobot calibration"):
        _state_env(units="lerobot", calibration=3)
    with pytest.raises(ValueError, match="got it with units='radians'"):
        _state_env(units="radians", calibration=arm_file)
    with pytest.raises(ValueError, match="got it with units='radians'"):
        units.joint_units("radians", calibration=arm_file)
    root = tmp_path / "never"
    with pytest.raises(ValueError, match="no such file"):
        record(root, episodes=1, camera_config="none", calibration=missing)
    assert not root.exists()
    assert load_calibration(arm_file).to_json() == _content(ARM)
