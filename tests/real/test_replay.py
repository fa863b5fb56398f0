"""Replaying a dataset's actions in the simulation: tracking error, JSON, plot, CLI, bad input."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.cli.replay import main
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.real.replay import plot_replay, read_replay_dataset, replay
from gym_soarm.real.units import FEATURE_NAMES
from gym_soarm.record.record import SETTINGS_PATH, record


@pytest.fixture(scope="module")
def lift(tmp_path_factory):
    """Two state-only lift episodes in LeRobot units, seed 0."""
    root = tmp_path_factory.mktemp("replay") / "lift"
    record(root, task="LiftCube-v0", episodes=2, seed=0, camera_config="none")
    return root


def test_replay_in_the_recorded_scene_reproduces_the_states(lift):
    # The recording lists each episode's task and seed: no need to give them.
    report = replay(lift)
    assert report.task == "LiftCube-v0"
    assert report.units == "lerobot" and report.fps == 50 and report.robot_type == "so101_follower"
    dataset = read_replay_dataset(lift)
    assert [e.episode_index for e in report.episodes] == [0, 1]
    for episode in report.episodes:
        _, states = dataset.episodes[episode.episode_index]
        assert len(episode.times_s) == len(states) - 1
        np.testing.assert_array_equal(episode.recorded, states[1:])
        # The simulation is deterministic and the recorded states are float32: the
        # simulated ones match them to the float32 rounding (half a unit in the last place).
        ulp = np.spacing(np.abs(episode.recorded).astype(np.float32)).astype(np.float64)
        assert (np.abs(episode.error) <= ulp).all()
        assert np.ptp(episode.recorded, axis=0).max() > 10  # the arm moved
    overall = report.figures()
    assert set(overall) == set(FEATURE_NAMES)
    assert max(row["max_abs"] for row in overall.values()) < 1e-5


def test_replay_without_the_cube_shows_the_grasp_in_the_gripper(lift):
    # The default scene has no cube: the jaws close further than they did on it.
    figures = replay(lift, episodes=[1], task="ReachTarget-v0").figures()
    assert figures["gripper.pos"]["max_abs"] > 5.0
    assert figures["shoulder_pan.pos"]["max_abs"] < 1.0


def test_cli_writes_table_json_and_plot(lift, tmp_path, capsys):
    out_json, out_png = tmp_path / "r.json", tmp_path / "r.png"
    code = main(
        [
            "--root",
            str(lift),
            "--episode",
            "1",
            "--task",
            "lift",
            "--json",
            str(out_json),
            "--plot",
            str(out_png),
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "tracking error over 1 episode(s)" in printed and "gripper.pos" in printed
    figures = json.loads(out_json.read_text())
    assert figures["units"] == "lerobot" and figures["task"] == "LiftCube-v0"
    assert [e["episode_index"] for e in figures["episodes"]] == [1]
    assert figures["overall"] == figures["episodes"][0]["joints"]
    assert figures["overall"]["wrist_flex.pos"]["max_abs"] < 1e-5
    image = cv2.imread(str(out_png))
    assert image is not None and image.shape[2] == 3 and image.shape[0] > 400
    # Two colours of curves were drawn on the white background.
    assert (np.abs(image.astype(int) - (30, 120, 230)).sum(axis=2) < 60).sum() > 500
    assert (np.abs(image.astype(int) - (40, 40, 40)).sum(axis=2) < 30).sum() > 500


@pytest.mark.subprocess
def test_replay_module_runs_as_a_script(lift):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "gym_soarm.replay",
            "--root",
            str(lift),
            "--episode",
            "0",
            "--task",
            "lift",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "shoulder_pan.pos" in result.stdout


def test_resampled_replay_of_a_30_fps_copy(lift, tmp_path):
    # The same frames declared at 30 fps: the replay steps at 50 Hz and interpolates.
    copy = tmp_path / "slow"
    shutil.copytree(lift, copy)
    info_path = copy / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["fps"] = 30
    info_path.write_text(json.dumps(info))
    report = replay(copy, episodes=[0], task="LiftCube-v0")
    episode = report.episodes[0]
    assert report.fps == 30
    np.testing.assert_allclose(episode.times_s, np.arange(1, len(episode.times_s) + 1) / 30)
    # Each action now lasts 33 ms instead of 20: the arm runs ahead of the recording's
    # timing, so the error is real but bounded.
    assert 0.1 < report.figures()["shoulder_pan.pos"]["max_abs"] < 40


def _edit_info(root, folder, edit):
    copy = folder
    shutil.copytree(root, copy)
    info_path = copy / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    edit(info)
    info_path.write_text(json.dumps(info))
    return copy


def test_bad_input_is_refused(lift, tmp_path, capsys):
    with pytest.raises(ValueError, match="no such folder"):
        replay(tmp_path / "nowhere")
    with pytest.raises(ValueError, match=r"no meta/info\.json"):
        replay(tmp_path)
    with pytest.raises(ValueError, match=r"no episode 7; it has 2 episode\(s\), indices 0 to 1"):
        replay(lift, episodes=[7])
    without_action = _edit_info(
        lift, tmp_path / "no_action", lambda info: info["features"].pop("action")
    )
    with pytest.raises(ValueError, match="no 'action' feature"):
        replay(without_action)
    renamed = _edit_info(
        lift,
        tmp_path / "renamed",
        lambda info: info["features"]["observation.state"].update(names=list("abcdef")),
    )
    with pytest.raises(ValueError, match=r"'observation.state' has the values \['a'"):
        replay(renamed)
    with pytest.raises(ValueError, match="got it with units='radians'"):
        replay(lift, units="radians", calibration=tmp_path / "x.json")
    with pytest.raises(ValueError, match="units must be one of"):
        replay(lift, units="degrees")
    with pytest.raises(ValueError, match=r"must end in \.png"):
        plot_replay(replay(lift, episodes=[0]), tmp_path / "plot.jpg")
    with pytest.raises(SystemExit) as exit_info:
        main(["--root", str(lift), "--episode", "5"])
    assert exit_info.value.code == 2
    assert "no episode 5" in capsys.readouterr().err


def test_a_multi_task_recording_replays_each_episode_in_its_task(tmp_path):
    """Task i's episode k was reset with seed + k; the replay finds both, and the units
    (lerobot_range, a wrist offset) that the recording wrote down."""
    root = tmp_path / "pair"
    record(root, task="ReachTarget-v0,LiftCube-v0", episodes=1, seed=3, camera_config="front_only",
           size=(48, 64), units="lerobot_range", wrist_roll_offset_deg=-90.0)  # fmt: skip
    report = replay(root)
    assert report.units == "lerobot_range" and report.task == "ReachTarget-v0,LiftCube-v0"
    assert max(row["max_abs"] for row in report.figures().values()) < 1e-4
    # Read as degrees without the offset, the same values track badly.
    wrong = replay(root, units="lerobot", wrist_roll_offset_deg=0.0)
    assert max(row["max_abs"] for row in wrong.figures().values()) > 1.0


def _dynamics_file(path):
    joints = {name: {"kp": 700.0, "kv": 20.0} for name in constants.JOINT_NAMES}
    content = {"format": "gym_soarm.dynamics/1", "joints": joints, "control_delay_steps": 1}
    path.write_text(json.dumps(content))
    return str(path)


@pytest.fixture(scope="module")
def varied(tmp_path_factory):
    """A reach recording made with fitted dynamics, the STS3215 servo model and physics
    randomisation: settings the replay has to read back to reproduce it."""
    folder = tmp_path_factory.mktemp("varied")
    settings = EnvSettings(
        task="ReachTarget-v0",
        units="lerobot",
        servo_model="sts3215",
        physics_randomization="light",
        dynamics=_dynamics_file(folder / "arm.json"),
    )
    root = folder / "reach"
    record(
        root, task="ReachTarget-v0", episodes=1, camera_config="none", keep="all", settings=settings
    )
    return root, settings


def test_a_replay_reads_the_recording_settings_back(varied):
    root, recorded = varied
    stored = json.loads((root / SETTINGS_PATH).read_text())["env"]
    assert EnvSettings.from_dict(stored).servo_model == "sts3215"
    report = replay(root)
    assert report.settings.dynamics == os.path.abspath(recorded.dynamics)
    assert report.settings.servo_model == "sts3215"
    assert report.settings.physics_randomization == "light"
    # The recording's motion (to the rounding of the float32 state it starts from).
    assert max(r["max_abs"] for r in report.figures().values()) < 1e-4
    # Without them (each given explicitly), the simulated arm moves otherwise.
    plain = replay(
        root, settings={"dynamics": None, "servo_model": "ideal", "physics_randomization": "none"}
    )
    assert max(r["max_abs"] for r in plain.figures().values()) > 1.0


def test_replay_flags_override_the_recording_settings(varied, tmp_path, capsys):
    root, _ = varied
    out = tmp_path / "replay.json"
    assert main(["--root", str(root), "--servo-model", "ideal", "--json", str(out)]) == 0
    capsys.readouterr()
    figures = json.loads(out.read_text())["overall"]
    assert max(row["max_abs"] for row in figures.values()) > 1e-3
