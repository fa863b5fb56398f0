"""The simulated follower as a LeRobot robot: driven by a leader, read back, recorded.

A real leader arm is replaced by ``fake_leader`` (beside this file), a LeRobot
teleoperator that sends what a calibrated SO-101 leader sends while it moves from the home
pose to a fixed pose. Everything else is LeRobot's own code: its robot factory, and
``lerobot-record`` run as a program.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from fake_leader import HOME, TARGET
from lerobot.datasets.lerobot_dataset import LeRobotDataset
from lerobot.robots.utils import make_robot_from_config
from lerobot.utils.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError

from gym_soarm.lerobot import SimSoArmFollower, SimSoArmFollowerConfig
from gym_soarm.real import units

HERE = Path(__file__).resolve().parent
NAMES = list(units.FEATURE_NAMES)
ROLL = NAMES.index("wrist_roll.pos")


def _robot(tmp_path: Path, **overrides) -> SimSoArmFollower:
    settings = {"steps_per_action": 5, **overrides}
    config = SimSoArmFollowerConfig(
        observation_height=48, observation_width=64, calibration_dir=tmp_path / "cal", **settings
    )
    robot = make_robot_from_config(config)  # LeRobot's factory finds our class
    assert isinstance(robot, SimSoArmFollower)
    return robot


def _values(observation: dict) -> np.ndarray:
    return np.array([observation[name] for name in NAMES])


def test_the_robot_follows_a_leader_and_reports_what_it_sent(tmp_path):
    robot = _robot(tmp_path)
    assert set(robot.observation_features) == {*NAMES, "front_camera", "wrist_camera"}
    assert robot.observation_features["front_camera"] == (48, 64, 3)
    assert set(robot.action_features) == set(NAMES)
    robot.connect()
    try:
        first = robot.get_observation()
        np.testing.assert_allclose(_values(first), list(HOME.values()), atol=0.01)
        for _ in range(40):
            sent = robot.send_action(TARGET)
        np.testing.assert_allclose([sent[n] for n in NAMES], list(TARGET.values()), atol=1e-6)
        moved = robot.get_observation()
        np.testing.assert_allclose(_values(moved), list(TARGET.values()), atol=1.0)
        for camera in ("front_camera", "wrist_camera"):
            image = moved[camera]
            assert image.shape == (48, 64, 3) and image.dtype == np.uint8
            assert np.abs(image.astype(int) - first[camera].astype(int)).mean() > 1.0
        # Beyond the servo's reach: clipped, and the clipped target is what comes back.
        sent = robot.send_action({**TARGET, "shoulder_pan.pos": 500.0})
        assert sent["shoulder_pan.pos"] == pytest.approx(110.0, abs=0.01)
    finally:
        robot.disconnect()
    assert not robot.is_connected


def test_the_wrist_roll_offset_maps_the_leader_onto_the_model(tmp_path):
    robot = _robot(tmp_path, wrist_roll_offset_deg=-90.0, camera_config="none")
    assert set(robot.observation_features) == set(NAMES)
    robot.connect()
    try:
        assert robot.get_observation()["wrist_roll.pos"] == pytest.approx(-90.0)  # model at 0
        for _ in range(40):
            robot.send_action({**HOME, "wrist_roll.pos": -30.0})
        angle = robot.env.physics.joint_angles()[ROLL]
        assert angle == pytest.approx(math.radians(60.0), abs=0.02)
    finally:
        robot.disconnect()


def test_bad_actions_and_calls_are_refused_before_anything_moves(tmp_path):
    robot = _robot(tmp_path, steps_per_action=0)  # wall-clock pacing
    with pytest.raises(DeviceNotConnectedError):
        robot.get_observation()
    robot.connect()
    try:
        with pytest.raises(DeviceAlreadyConnectedError):
            robot.connect()
        time_before = robot.env.physics.data.time
        partial = {name: value for name, value in TARGET.items() if name != "gripper.pos"}
        with pytest.raises(ValueError, match=r"missing \['gripper.pos'\]"):
            robot.send_action(partial)
        for bad in ("12", True, None, float("nan")):
            with pytest.raises(ValueError, match="must be finite numbers in lerobot units"):
                robot.send_action({**TARGET, "elbow_flex.pos": bad})
        assert robot.env.physics.data.time == time_before
        assert robot._last_action_time is None  # the wall-clock pacing did not start either
    finally:
        robot.disconnect()
    with pytest.raises(ValueError, match="steps_per_action must be an int >= 0"):
        SimSoArmFollowerConfig(steps_per_action=-1)
    with pytest.raises(ValueError, match="task must be one of"):
        SimSoArmFollowerConfig(task="Stack-v0")
    with pytest.raises(ValueError, match="camera_config"):
        SimSoArmFollowerConfig(camera_config="top_camera")
    for field, value, message in (
        ("seed", -1, "seed must be None or an int >= 0"),
        ("render_quality", "ultra", "render_quality must be one of"),
        ("observation_height", 8, "observation_height must be from 16 to 2048"),
    ):
        with pytest.raises(ValueError, match=message):
            SimSoArmFollowerConfig(**{field: value})


def test_lerobot_record_drives_the_simulated_arm_with_a_leader(tmp_path):
    """``lerobot-record`` with the sim robot and a (fake) leader writes a dataset."""
    root = tmp_path / "teleop"
    command = [
        str(Path(sys.executable).with_name("lerobot-record")),
        "--robot.discover_packages_path=gym_soarm.lerobot",
        "--robot.type=sim_soarm_follower",
        "--robot.observation_height=48",
        "--robot.observation_width=64",
        f"--robot.calibration_dir={tmp_path / 'calibration'}",
        "--teleop.discover_packages_path=fake_leader",
        "--teleop.type=fake_so101_leader",
        "--dataset.repo_id=local/soarm_teleop",
        f"--dataset.root={root}",
        "--dataset.single_task=Move the arm",
        "--dataset.num_episodes=1",
        "--dataset.episode_time_s=3",
        "--dataset.reset_time_s=0",
        "--dataset.fps=25",
        "--dataset.push_to_hub=false",
        "--play_sounds=false",
    ]
    pythonpath = os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")]))
    result = subprocess.run(
        command,
        env=dict(os.environ, PYTHONPATH=pythonpath, HF_HUB_OFFLINE="1"),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-4000:]

    dataset = LeRobotDataset("local/soarm_teleop", root=root, video_backend="pyav")
    assert dataset.meta.robot_type == "sim_soarm_follower"
    assert dataset.meta.features["observation.state"]["names"] == NAMES
    # 3 s at up to 25 fps; a loaded machine records fewer frames, which is no fault here.
    assert 10 <= dataset.num_frames <= 76
    last = dataset[dataset.num_frames - 1]
    # The leader reached its pose after 1 s; 2 s later the arm is there too (the robot
    # simulates the wall-clock time between actions, so a slow loop changes nothing).
    np.testing.assert_allclose(last["action"].numpy(), list(TARGET.values()), atol=0.01)
    np.testing.assert_allclose(last["observation.state"].numpy(), list(TARGET.values()), atol=1.0)
    first_state = dataset[0]["observation.state"].numpy()
    assert np.abs(first_state - np.array(list(TARGET.values()))).max() > 10.0  # it moved
    for camera in ("front_camera", "wrist_camera"):
        image = last[f"observation.images.{camera}"]
        assert tuple(image.shape) == (3, 48, 64) and float(image.std()) > 0.02
