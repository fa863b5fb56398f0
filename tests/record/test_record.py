"""Recording the scripted expert as a LeRobot dataset: content, units, seeds, DART, CLI."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from dataset_files import decode_video, psnr, read_dataset
from interrupt import interrupt_when

from gym_soarm.cli.record import main
from gym_soarm.expert import make_expert
from gym_soarm.real import units
from gym_soarm.record.record import (
    default_root,
    parse_size,
    record,
)

LIFT = "Pick up the blue cube and lift it 5 cm above the table."


@pytest.fixture(scope="module")
def lift_state(tmp_path_factory):
    """Two state-only lift episodes in LeRobot units (seed 0)."""
    root = tmp_path_factory.mktemp("rec") / "lift"
    summary = record(root, task="LiftCube-v0", episodes=2, seed=0, camera_config="none")
    return root, summary, read_dataset(root)


def _episode(ds, e: int, key: str) -> np.ndarray:
    row = ds.episodes[e]
    return ds.data[key][row["dataset_from_index"] : row["dataset_to_index"]]


def test_state_recording_content(lift_state):
    root, summary, ds = lift_state
    assert summary.episodes == 2 and summary.attempts == 2 and summary.successes == 2
    assert summary.frames == ds.info["total_frames"] == len(ds.data["index"])
    assert summary.bytes_on_disk == sum(p.stat().st_size for p in root.rglob("*") if p.is_file())
    assert "2 episodes" in summary.text() and "100.0 %" in summary.text()
    info = ds.info
    assert info["fps"] == 50 and info["robot_type"] == "so101_follower"
    features = info["features"]
    assert features["observation.state"]["names"] == list(units.FEATURE_NAMES)
    assert features["action"]["names"] == list(units.FEATURE_NAMES)
    # The layout comes from the task itself: the lift task has no goal pad.
    assert features["observation.environment_state"]["names"] == [
        *("cube_x", "cube_y", "cube_z", "cube_qw", "cube_qx", "cube_qy", "cube_qz"),
        *("gripper_x", "gripper_y", "gripper_z"),
    ]
    assert not any(k.startswith("observation.images") for k in features)
    assert ds.tasks == [{"task_index": 0, "task": LIFT}]
    for e in range(2):
        done = _episode(ds, e, "next.done")
        success = _episode(ds, e, "next.success")
        # The episode ends at the step that succeeds, and only there.
        assert done[-1] and not done[:-1].any()
        assert success[-1] and not success[:-1].any()
        # The state starts at the home pose: zero degrees, gripper 9.09 % open.
        np.testing.assert_allclose(
            _episode(ds, e, "observation.state")[0],
            units.radians_to_lerobot(np.zeros(6)),
            atol=1e-4,
        )


def test_replaying_the_recorded_actions_reproduces_the_states(lift_state):
    """Frame t holds the observation before step t and the action sent at step t."""
    _, _, ds = lift_state
    env = gym.make("gym_soarm/LiftCube-v0", obs_type="environment_state_agent_pos", units="lerobot")
    try:
        for e in range(2):
            states = _episode(ds, e, "observation.state")
            actions = _episode(ds, e, "action")
            env_states = _episode(ds, e, "observation.environment_state")
            obs, _ = env.reset(seed=e)
            for t in range(len(actions)):
                np.testing.assert_allclose(obs["agent_pos"], states[t], atol=1e-3)
                np.testing.assert_allclose(obs["environment_state"], env_states[t], atol=1e-5)
                obs, *_ = env.step(actions[t].astype(np.float32))
    finally:
        env.close()


def test_same_seed_same_data_other_seed_other_data(tmp_path, lift_state):
    _, _, first = lift_state
    record(tmp_path / "again", task="LiftCube-v0", episodes=2, seed=0, camera_config="none")
    again = read_dataset(tmp_path / "again")
    for key in ("action", "observation.state", "observation.environment_state", "next.reward"):
        np.testing.assert_array_equal(again.data[key], first.data[key])
    record(tmp_path / "other", task="LiftCube-v0", episodes=1, seed=7, camera_config="none")
    other = read_dataset(tmp_path / "other")
    assert not np.array_equal(
        other.data["observation.environment_state"][0],
        first.data["observation.environment_state"][0],
    )


def _one_lift_episode(root: Path, **options):
    """One state-only lift episode from seed 0 (the first of ``lift_state``), read back."""
    record(root, task="LiftCube-v0", episodes=1, seed=0, camera_config="none", **options)
    return read_dataset(root)


def test_units_of_the_recording(tmp_path, lift_state):
    _, _, lerobot_units = lift_state
    radians = _one_lift_episode(tmp_path / "rad", units="radians")
    assert radians.info["robot_type"] == "gym_soarm"
    n = radians.info["total_frames"]
    for key in ("observation.state", "action"):
        np.testing.assert_allclose(
            units.lerobot_to_radians(lerobot_units.data[key][:n]), radians.data[key], atol=1e-5
        )


def test_wrist_roll_offset_of_the_recording(tmp_path, lift_state):
    _, _, plain = lift_state
    shifted = _one_lift_episode(tmp_path / "offset", wrist_roll_offset_deg=-90.0)
    n = shifted.info["total_frames"]
    roll = units.FEATURE_NAMES.index("wrist_roll.pos")
    for key in ("observation.state", "action"):
        expected = plain.data[key][:n].astype(np.float64)
        expected[:, roll] = (expected[:, roll] - 90.0 + 180.0) % 360.0 - 180.0
        np.testing.assert_allclose(shifted.data[key], expected, atol=1e-3)


def test_dart_noise_perturbs_the_motion_but_not_the_labels(tmp_path, lift_state):
    _, _, clean = lift_state
    sigma = 0.01
    record(
        tmp_path / "dart",
        task="LiftCube-v0",
        episodes=1,
        seed=0,
        camera_config="none",
        units="radians",
        dart_noise=sigma,
        keep="all",
    )
    dart = read_dataset(tmp_path / "dart")
    n = min(dart.info["total_frames"], clean.episodes[0]["length"])
    # The executed noise moved the arm off the clean trajectory ...
    states = dart.data["observation.state"][:n, :5].astype(np.float64)
    clean_states = np.radians(clean.data["observation.state"][:n, :5])
    assert np.abs(states - clean_states).max() > 0.005
    # ... while each label is the expert's own action for the state the noise led to: the
    # episode played again with the recorder's noise (drawn from [seed, attempt]), the
    # expert asked afresh at every step, gives the recorded labels, never the executed
    # (noisy) actions.
    labels = dart.data["action"].astype(np.float64)
    env = gym.make("gym_soarm/LiftCube-v0", obs_type="environment_state_agent_pos")
    try:
        base = env.unwrapped
        noise = np.random.default_rng([0, 0])
        env.reset(seed=0)
        expert = make_expert(env)
        for t in range(len(labels)):
            label = expert.next_targets_radians()
            np.testing.assert_allclose(label, labels[t], atol=1e-5)
            executed = label + noise.normal(0.0, sigma, label.shape)
            assert np.abs(executed - labels[t]).max() > 1e-4
            env.step(base.control.action_for_targets(executed, base.commanded_targets))
    finally:
        env.close()
    # Same seed, same noise.
    record(
        tmp_path / "dart2",
        task="LiftCube-v0",
        episodes=1,
        seed=0,
        camera_config="none",
        units="radians",
        dart_noise=sigma,
        keep="all",
    )
    np.testing.assert_array_equal(
        read_dataset(tmp_path / "dart2").data["action"], dart.data["action"]
    )


def test_keep_success_drops_failed_attempts(tmp_path):
    # Enough executed noise makes the expert fail some attempts: the first noise level
    # (rad) that gives both outcomes over 10 attempts is used.
    for sigma in (0.02, 0.03, 0.05, 0.01):
        common = {"task": "LiftCube-v0", "seed": 0, "camera_config": "none", "dart_noise": sigma}
        everything = record(tmp_path / f"all{sigma}", episodes=10, keep="all", **common)
        every = read_dataset(tmp_path / f"all{sigma}")
        assert everything.episodes == everything.attempts == 10
        succeeded = [e for e in range(10) if _episode(every, e, "next.success")[-1]]
        assert len(succeeded) == everything.successes
        if 0 < len(succeeded) < 10:
            break
    else:
        pytest.fail("no noise level gave both successes and failures")
    kept = record(
        tmp_path / "kept", episodes=len(succeeded), keep="success", max_attempts=10, **common
    )
    ds = read_dataset(tmp_path / "kept")
    assert kept.episodes == ds.info["total_episodes"] == len(succeeded)
    assert kept.attempts == succeeded[-1] + 1 and kept.successes == len(succeeded)
    # The kept episodes are exactly the successful attempts, in order.
    for e, attempt in enumerate(succeeded):
        np.testing.assert_array_equal(
            _episode(ds, e, "observation.state"), _episode(every, attempt, "observation.state")
        )
        assert _episode(ds, e, "next.success")[-1]


def test_camera_recording(tmp_path):
    root = tmp_path / "cams"
    summary = record(
        root, task="LiftCube-v0", episodes=1, seed=3, camera_config="front_wrist", size=(48, 64)
    )
    ds = read_dataset(root)
    assert summary.episodes == 1
    for camera in ("front_camera", "wrist_camera"):
        key = f"observation.images.{camera}"
        assert ds.info["features"][key]["shape"] == [48, 64, 3]
        frames = decode_video(ds.video_path(key, 0))
        assert len(frames) == ds.info["total_frames"]
    env = gym.make(
        "gym_soarm/LiftCube-v0",
        camera_config="front_wrist",
        observation_height=48,
        observation_width=64,
    )
    try:
        obs, _ = env.reset(seed=3)
        first = decode_video(ds.video_path("observation.images.front_camera", 0))
        assert psnr(first[0], obs["pixels"]["front_camera"]) > 25
        assert (
            psnr(first[-1], obs["pixels"]["front_camera"])
            < psnr(first[0], obs["pixels"]["front_camera"]) - 3
        )
    finally:
        env.close()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"task": "Lift"}, "task must be a task"),
        ({"episodes": 0}, "episodes must be an int >= 1"),
        ({"units": "deg"}, "units must be one of"),
        ({"units": "radians", "wrist_roll_offset_deg": 90}, "applies to LeRobot's units"),
        ({"keep": "failed"}, "keep must be one of"),
        ({"dart_noise": -0.1}, "dart_noise must be"),
        ({"size": (47, 64)}, "even"),
        ({"camera_config": "top"}, "camera_config must be one of"),
    ],
)
def test_bad_arguments_write_nothing(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        record(tmp_path / "ds", **{"camera_config": "none", **kwargs})
    assert not (tmp_path / "ds").exists()


def test_parse_size_and_default_root(monkeypatch):
    assert parse_size("480x640") == (480, 640)
    for bad in ("480", "480x", "axb", "481x640", "8x8"):
        with pytest.raises(ValueError, match="size"):
            parse_size(bad)
    monkeypatch.setenv("HF_LEROBOT_HOME", "/data/lerobot")
    assert str(default_root("local/x")) == "/data/lerobot/local/x"
    monkeypatch.delenv("HF_LEROBOT_HOME")
    monkeypatch.setenv("HF_HOME", "/hf")
    assert str(default_root("local/x")) == "/hf/lerobot/local/x"


def test_cli(tmp_path, capsys):
    root = tmp_path / "cli"
    args = [
        "--task",
        "LiftCube-v0",
        "--episodes",
        "1",
        "--camera-config",
        "none",
        "--root",
        str(root),
        "--no-progress",
    ]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "1 episodes" in out and "MB on disk" in out and "frames/s" in out
    assert "--dataset.root=" in out
    with pytest.raises(SystemExit) as exc:
        main(args)  # the folder now holds a dataset
    assert exc.value.code == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite", "--seed", "4"]) == 0
    with pytest.raises(SystemExit):
        main([*args, "--size", "480x641"])
    assert "even" in capsys.readouterr().err


@pytest.mark.subprocess
def test_ctrl_c_keeps_the_finished_episodes(tmp_path):
    root = tmp_path / "interrupted"
    command = [
        sys.executable,
        "-m",
        "gym_soarm.record",
        "--episodes",
        "1000",
        "--camera-config",
        "none",
        "--root",
        str(root),
        "--no-progress",
    ]
    info = root / "meta/info.json"
    done = interrupt_when(
        command,
        lambda _: info.is_file() and '"total_episodes": 2' in info.read_text(),
        within_s=120,
        what="two saved episodes",
    )
    assert done.returncode == 130, done.stderr
    assert done.stdout.startswith("interrupted:")
    ds = read_dataset(root)
    assert ds.info["total_episodes"] >= 2
    assert len(ds.data["index"]) == ds.info["total_frames"] == sum(r["length"] for r in ds.episodes)
    assert not (root / ".writer-scratch").exists()
    assert os.listdir(root) and sorted(os.listdir(root)) == ["data", "meta"]
