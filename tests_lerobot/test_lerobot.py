"""gym_soarm with LeRobot itself: the record, train and evaluate commands of docs/lerobot.md.

Needs LeRobot (Python >= 3.12): ``pip install -e ".[lerobot,test]"``, then
``python -m pytest tests_lerobot``. ``.ci/lerobot_job`` builds that environment and runs
this folder; the default test run (``tests/``) never needs LeRobot.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("lerobot")

from lerobot.datasets.lerobot_dataset import LeRobotDataset
from lerobot.envs.factory import make_env
from lerobot.envs.utils import env_to_policy_features, preprocess_observation

from gym_soarm.lerobot import SoArmEnvConfig
from gym_soarm.real import units

ROOT = Path(__file__).resolve().parents[1]
# Where the documentation lives; the command block is looked up in all of it.
DOCUMENTATION = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
REPO_ID = "local/soarm_lift"
DATASET = "datasets/soarm_lift"
CHECKPOINT = "outputs/train/act_soarm_lift/checkpoints/last/pretrained_model"
EVAL_DIR = "outputs/eval/act_soarm_lift"


def documented_commands() -> str:
    """The LeRobot command block (docs/lerobot.md), wherever the documentation holds it."""
    pattern = r"<!-- lerobot-commands:start -->\s*```bash\n(.*?)```\s*<!-- lerobot-commands:end -->"
    blocks = [m for p in DOCUMENTATION for m in re.findall(pattern, p.read_text(), re.DOTALL)]
    assert len(blocks) == 1, (
        f"the documentation should hold one LeRobot command block, not {len(blocks)}"
    )
    return blocks[0]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """An empty folder in which the three documented commands ran, in order."""
    folder = tmp_path_factory.mktemp("lerobot_commands")
    env = dict(os.environ, HF_LEROBOT_HOME=str(folder / "lerobot_home"), WANDB_MODE="disabled")
    result = subprocess.run(
        ["bash", "-euo", "pipefail", "-c", documented_commands()],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=3600,
    )
    (folder / "commands.log").write_text(result.stdout + "\n" + result.stderr)
    assert result.returncode == 0, result.stdout[-3000:] + "\n" + result.stderr[-6000:]
    return folder


def test_the_documented_block_records_trains_and_evaluates():
    commands = documented_commands()
    assert "python -m gym_soarm.record" in commands
    assert "lerobot-train" in commands and "lerobot-eval" in commands
    assert "--env.type=soarm" in commands and "HF_HUB_OFFLINE=1" in commands


def test_lerobot_loads_the_recorded_dataset(workdir):
    dataset = LeRobotDataset(REPO_ID, root=workdir / DATASET, video_backend="pyav")
    assert dataset.num_episodes == 2
    assert dataset.fps == 50 and dataset.meta.robot_type == "so101_follower"
    assert dataset.meta.features["action"]["names"] == list(units.FEATURE_NAMES)
    task = "Pick up the blue cube and lift it 5 cm above the table."
    env = gym.make(
        "gym_soarm/LiftCube-v0",
        camera_config="front_wrist",
        observation_height=96,
        observation_width=128,
        units="lerobot",
    )
    try:
        for episode in range(2):
            start = dataset.meta.episodes[episode]["dataset_from_index"]
            length = dataset.meta.episodes[episode]["length"]
            obs, _ = env.reset(seed=episode)  # the recorder's attempt k uses seed 0 + k
            for t in range(length):
                item = dataset[start + t]
                assert int(item["episode_index"]) == episode and int(item["frame_index"]) == t
                assert item["task"] == task
                # Replaying the recorded actions gives back the recorded states and images.
                state = item["observation.state"].numpy()
                np.testing.assert_allclose(state, obs["agent_pos"], atol=1e-3)
                for camera in ("front_camera", "wrist_camera"):
                    image = item[f"observation.images.{camera}"].numpy()
                    assert image.shape == (3, 96, 128) and 0 <= image.min() <= image.max() <= 1
                    rendered = obs["pixels"][camera].astype(np.float64) / 255
                    error = np.abs(np.moveaxis(image, 0, -1) - rendered).mean()
                    assert error < 0.03, (episode, t, camera, error)
                obs, *_ = env.step(item["action"].numpy())
            assert bool(dataset[start + length - 1]["next.success"])
    finally:
        env.close()


def test_lerobot_train_wrote_a_checkpoint(workdir):
    checkpoint = workdir / CHECKPOINT
    assert (checkpoint / "model.safetensors").is_file()
    config = json.loads((checkpoint / "config.json").read_text())
    assert config["type"] == "act"
    assert set(config["input_features"]) == {
        "observation.state",
        "observation.images.front_camera",
        "observation.images.wrist_camera",
    }


def test_lerobot_eval_reports_a_success_rate(workdir):
    info = json.loads((workdir / EVAL_DIR / "eval_info.json").read_text())
    overall = info["overall"]
    assert overall["n_episodes"] == 1
    assert 0.0 <= overall["pc_success"] <= 100.0
    assert (workdir / overall["video_paths"][0]).is_file()  # relative to the working folder


@pytest.mark.parametrize(
    ("obs_type", "camera_config", "expected"),
    [
        (
            "pixels_agent_pos",
            "front_wrist",
            {
                "observation.state",
                "observation.images.front_camera",
                "observation.images.wrist_camera",
            },
        ),
        (
            "pixels_agent_pos",
            "all",
            {
                "observation.state",
                "observation.images.overview_camera",
                "observation.images.front_camera",
                "observation.images.wrist_camera",
            },
        ),
        ("pixels", "wrist_camera", {"observation.images.wrist_camera"}),
        (
            "environment_state_agent_pos",
            "front_wrist",
            {"observation.state", "observation.environment_state"},
        ),
    ],
)
def test_env_config_features_match_what_the_env_gives(obs_type, camera_config, expected):
    config = SoArmEnvConfig(
        task="LiftCube-v0",
        obs_type=obs_type,
        camera_config=camera_config,
        observation_height=48,
        observation_width=64,
    )
    assert config.type == "soarm" and config.gym_id == "gym_soarm/LiftCube-v0"
    features = env_to_policy_features(config)
    assert set(features) == expected | {"action"}
    envs = make_env(config, n_envs=1)
    vector = envs["soarm"][0]
    try:
        obs, info = vector.reset(seed=0)
        batch = preprocess_observation(obs)
        for key in expected:
            assert tuple(batch[key].shape[1:]) == tuple(features[key].shape), key
        assert vector.call("task_description")[0].startswith("Pick up the blue cube")
        assert vector.call("_max_episode_steps")[0] == 250
        assert info["is_success"].tolist() == [False]
        low = vector.single_action_space.low
        np.testing.assert_allclose(low[:5], np.degrees(units.SERVO_RANGE_LOW_RAD[:5]), rtol=1e-5)
    finally:
        vector.close()


def test_env_config_forwards_the_wrist_roll_offset():
    config = SoArmEnvConfig(
        task="LiftCube-v0", obs_type="environment_state_agent_pos", wrist_roll_offset_deg=-90
    )
    assert config.gym_kwargs["wrist_roll_offset_deg"] == -90.0
    vector = make_env(config, n_envs=1)["soarm"][0]
    try:
        obs, _ = vector.reset(seed=0)
        roll = units.FEATURE_NAMES.index("wrist_roll.pos")
        assert obs["agent_pos"][0, roll] == pytest.approx(-90.0)  # the model's 0 rad
    finally:
        vector.close()


def test_env_config_forwards_the_control_mode():
    config = SoArmEnvConfig(
        task="LiftCube-v0", obs_type="environment_state_agent_pos", control_mode="ee_delta"
    )
    assert config.gym_kwargs["control_mode"] == "ee_delta"
    assert tuple(config.features["action"].shape) == (6,)
    vector = make_env(config, n_envs=1)["soarm"][0]
    try:
        vector.reset(seed=0)
        space = vector.single_action_space
        assert space.shape == (6,)
        np.testing.assert_allclose(space.high[:3], 0.01, rtol=1e-6)  # metres per step
    finally:
        vector.close()


def test_bad_env_config_values():
    with pytest.raises(ValueError, match="control_mode must be one of"):
        SoArmEnvConfig(control_mode="cartesian")
    with pytest.raises(ValueError, match="units must be one of"):
        SoArmEnvConfig(units="deg")
    with pytest.raises(ValueError, match="applies to LeRobot's units"):
        SoArmEnvConfig(units="radians", wrist_roll_offset_deg=90.0)
    with pytest.raises(ValueError, match="obs_type must be one of"):
        SoArmEnvConfig(obs_type="state")
    with pytest.raises(ValueError, match="camera_config"):
        SoArmEnvConfig(camera_config="top_camera")


def test_env_config_takes_a_task_defined_outside_the_library():
    """The task of tests/tasks/test_registry.py, registered here: LeRobot reads its layout."""
    import sys

    import gym_soarm

    tests = Path(__file__).resolve().parents[1] / "tests"
    sys.path[:0] = [str(tests / "tasks"), str(tests)]
    import test_registry

    gym_soarm.register_task(test_registry.SPEC)
    config = SoArmEnvConfig(
        task="lift_block",
        obs_type="environment_state_agent_pos",
        observation_height=48,
        observation_width=64,
    )
    assert config.task == "LiftBlock-v0" and config.gym_id == "gym_soarm/LiftBlock-v0"
    features = env_to_policy_features(config)
    assert tuple(features["observation.environment_state"].shape) == (4,)
    vector = make_env(config, n_envs=1)["soarm"][0]
    try:
        obs, _ = vector.reset(seed=0)
        assert obs["environment_state"].shape == (1, 4)
        assert vector.call("task_description")[0] == "Lift the yellow block 3 cm."
        assert vector.call("state_layout")[0] == (("block_pos", 3), ("block_yaw", 1))
    finally:
        vector.close()


def test_env_config_forwards_the_variation_keywords():
    config = SoArmEnvConfig(
        task="StackCube-v0",
        obs_type="environment_state_agent_pos",
        visual_randomization="light",
        physics_randomization="light",
        servo_model="sts3215",
        distractors=2,
    )
    kwargs = config.gym_kwargs
    assert kwargs["distractors"] == 2 and kwargs["servo_model"] == "sts3215"
    vector = make_env(config, n_envs=1)["soarm"][0]
    try:
        obs, _ = vector.reset(seed=0)
        assert obs["environment_state"].shape[0] == 1
        assert vector.call("distractors")[0] == 2
    finally:
        vector.close()
    with pytest.raises(ValueError, match="distractors"):
        SoArmEnvConfig(distractors=9)
    with pytest.raises(ValueError, match="object_placement"):
        SoArmEnvConfig(task="StackCube-v0", object_placement="grid")
