"""Calibration files and replay against LeRobot itself.

The calibration: LeRobot's own SO-101 follower (``SOFollower``, never connected) writes
and reads the calibration file, and its Feetech motor bus normalises random raw readings;
gym_soarm's conversion of the same file must give the same values. The replay: a dataset
written by LeRobot's ``LeRobotDataset`` API with the real follower's feature names, replayed
by ``python -m gym_soarm.replay``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("scservo_sdk")  # lerobot[feetech]: the follower's motor bus

from lerobot.motors import MotorCalibration
from lerobot.robots.so_follower import SOFollower, SOFollowerRobotConfig

from gym_soarm import constants
from gym_soarm.real import units
from gym_soarm.real.calibration import calibrated_units

NAMES = constants.JOINT_NAMES
LOW = np.array(units.SERVO_RANGE_LOW_RAD)
HIGH = np.array(units.SERVO_RANGE_HIGH_RAD)

# Ranges swept by hand (not centred on 2047); wrist_roll gets the whole turn.
RANGES = {
    "shoulder_pan": (758, 3292),
    "shoulder_lift": (612, 3241),
    "elbow_flex": (869, 3097),
    "wrist_flex": (860, 3200),
    "wrist_roll": (0, 4095),
    "gripper": (1450, 2680),
}


def _follower(folder: Path, use_degrees: bool) -> SOFollower:
    config = SOFollowerRobotConfig(
        port="/dev/null", id="follower", calibration_dir=folder, use_degrees=use_degrees
    )
    return SOFollower(config)


@pytest.fixture(scope="module", params=[0, 1], ids=["drive_mode0", "drive_mode1"])
def calibration_file(request, tmp_path_factory) -> Path:
    """A calibration file that LeRobot's follower itself saved (drive modes as the param)."""
    folder = tmp_path_factory.mktemp("calibration")
    robot = _follower(folder, use_degrees=True)
    robot.calibration = {
        name: MotorCalibration(
            id=i + 1,
            drive_mode=request.param if name in ("elbow_flex", "gripper") else 0,
            homing_offset=100 * i - 250,
            range_min=RANGES[name][0],
            range_max=RANGES[name][1],
        )
        for i, name in enumerate(NAMES)
    }
    robot._save_calibration()
    return robot.calibration_fpath


@pytest.mark.parametrize("use_degrees", [True, False])
def test_conversion_equals_lerobots_bus_normalisation(calibration_file, use_degrees):
    robot = _follower(calibration_file.parent, use_degrees)  # loads the file itself
    bus = robot.bus
    assert not bus.is_connected and bus.calibration == robot.calibration
    ours = calibrated_units("lerobot" if use_degrees else "lerobot_range", calibration_file)
    assert json.loads(calibration_file.read_text()) == ours.calibration.to_json()
    rng = np.random.default_rng(0)
    ids = [bus.motors[name].id for name in NAMES]

    # Random raw readings: the same values, bit for bit (the same float operations).
    ticks = rng.integers(0, 4096, size=(2000, 6))
    theirs = np.array(
        [[bus._normalize({i: int(t)})[i] for i, t in zip(ids, row, strict=True)] for row in ticks]
    )
    np.testing.assert_array_equal(ours.normalize(ticks), theirs)

    # Radians: our value is the bus's value of our ticks (unrounded ticks, as the bus
    # itself takes any number).
    radians = rng.uniform(LOW - 0.3, HIGH + 0.3, size=(2000, 6))
    our_ticks = ours.radians_to_ticks(radians)
    theirs = np.array(
        [
            [bus._normalize({i: float(t)})[i] for i, t in zip(ids, row, strict=True)]
            for row in our_ticks
        ]
    )
    np.testing.assert_array_equal(ours.from_radians(radians), theirs)

    # Back: the bus truncates to whole ticks (int); we keep the fraction, so our ticks
    # truncated are the bus's, and our radians are within one tick of its.
    values = ours.from_radians(radians)
    theirs = np.array(
        [
            [bus._unnormalize({i: float(v)})[i] for i, v in zip(ids, row, strict=True)]
            for row in values
        ]
    )
    np.testing.assert_array_equal(ours.unnormalize(values).astype(np.int64), theirs)
    back = ours.to_radians(values)
    ticks_back = ours.radians_to_ticks(back)
    assert np.abs(ticks_back - theirs).max() < 1.0 + 1e-9
    # Inside the recorded ranges (everywhere in degrees) the round trip is exact.
    inside = (our_ticks >= ours.range_min) & (our_ticks <= ours.range_max) | ours.degrees
    np.testing.assert_allclose(back[inside], radians[inside], atol=1e-9)
    assert inside.mean() > 0.5 and (use_degrees or not inside.all())


# --- replay of a dataset written by LeRobot's own API ---------------------------------------------
FPS = 30  # lerobot-record's default frame rate: the replay resamples it to 50 Hz


@pytest.fixture(scope="module")
def lerobot_dataset(tmp_path_factory) -> tuple[Path, list[np.ndarray]]:
    """Two episodes written by ``LeRobotDataset.create`` as ``lerobot-record`` would.

    The follower's feature names, robot_type ``so101_follower``, 30 fps, degrees: the
    action is a smooth sweep of every joint, and the state follows it one frame late.
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path_factory.mktemp("lerobot") / "so101_sweep"
    joint = {"dtype": "float32", "shape": (6,), "names": list(units.FEATURE_NAMES)}
    dataset = LeRobotDataset.create(
        repo_id="local/so101_sweep",
        fps=FPS,
        root=root,
        robot_type="so101_follower",
        features={"action": joint, "observation.state": dict(joint)},
        use_videos=False,
    )
    amplitude = np.array([40.0, 30.0, 35.0, 30.0, 60.0, 35.0])
    centre = np.array([0.0, -10.0, 20.0, 10.0, 0.0, 40.0])
    written = []
    for episode in range(2):
        t = np.arange(60) / FPS
        phase = np.pi * (t / 2.0 + episode / 3)
        action = (centre + amplitude * np.sin(phase)[:, None] * [1, 1, -1, 1, 1, 1]).astype(
            np.float32
        )
        state = np.concatenate([action[:1], action[:-1]])
        for a, s in zip(action, state, strict=True):
            dataset.add_frame({"action": a, "observation.state": s, "task": "sweep the joints"})
        dataset.save_episode()
        written.append(state)
    dataset.finalize()
    return root, written


def test_replay_reads_lerobots_dataset_and_tracks_it(lerobot_dataset, tmp_path):
    from gym_soarm.real.replay import read_replay_dataset

    root, states = lerobot_dataset
    read = read_replay_dataset(root)
    assert read.fps == FPS and read.robot_type == "so101_follower" and read.units == "lerobot"
    for episode, expected in enumerate(states):
        np.testing.assert_array_equal(read.episodes[episode][1], expected)

    out_json, out_png = tmp_path / "replay.json", tmp_path / "replay.png"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "gym_soarm.replay",
            "--root",
            str(root),
            "--json",
            str(out_json),
            "--plot",
            str(out_png),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    assert "tracking error over 2 episode(s), 118 frames at 30 fps" in result.stdout
    figures = json.loads(out_json.read_text())
    assert figures["units"] == "lerobot" and figures["fps"] == FPS
    assert [e["frames_compared"] for e in figures["episodes"]] == [59, 59]
    body = [name for name in units.FEATURE_NAMES if name != "gripper.pos"]
    # The sim's servos follow a smooth 0.25 Hz sweep: within a few degrees of a state
    # that lags one frame (4.7 degrees a frame at most), never far off.
    for name in body:
        assert 0.01 < figures["overall"][name]["rms"] < 6.0, (name, figures["overall"][name])
    assert out_png.stat().st_size > 10_000
