"""The SO-101 benchmark inside LeRobot: suites, the protocol's seeds, multi-task datasets.

``lerobot-eval`` here runs without ``--env.discover_packages_path``: the
``lerobot_env_soarm`` plugin (``plugins/lerobot_env_soarm``, installed by
``.ci/lerobot_job``) registers ``--env.type=soarm``.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from lerobot.datasets.lerobot_dataset import LeRobotDataset
from lerobot.envs.factory import make_env

from gym_soarm.lerobot import SoArmEnvConfig
from gym_soarm.record.record import record
from gym_soarm.tasks import get_task
from gym_soarm.tasks.suites import EVAL_SEED
from gym_soarm.vector.processes import SoArmVectorEnv

BIN = Path(sys.executable).parent  # LeRobot's command lines, beside this Python
CORE = ("ReachTarget-v0", "LiftCube-v0", "PickAndPlaceCube-v0", "PushCube-v0")


def pixels_config(task: str, **fields) -> SoArmEnvConfig:
    return SoArmEnvConfig(
        task=task, camera_config="front_only", observation_height=48, observation_width=64, **fields
    )


def test_a_suite_gives_one_vector_env_per_task_in_its_group():
    config = pixels_config("soarm_core,soarm_language,StackCube-v0", vector_env="processes")
    envs = make_env(config, n_envs=2)
    try:
        assert list(envs) == ["soarm_core", "soarm_language", "soarm"]
        assert list(envs["soarm_core"]) == [0, 1, 2, 3]
        for index, task in enumerate(CORE):
            vector = envs["soarm_core"][index]
            assert isinstance(vector, SoArmVectorEnv) and vector.num_envs == 2
            spec = get_task(task)
            assert vector.call("task_description")[0] == spec.instructions[0]
            assert vector.call("_max_episode_steps") == (spec.max_episode_steps,) * 2
        obs, info = envs["soarm"][0].reset(seed=[EVAL_SEED, EVAL_SEED + 1])
        assert obs["pixels"]["front_camera"].shape == (2, 48, 64, 3)
        assert info["is_success"].tolist() == [False, False]
    finally:
        for group in envs.values():
            for vector in group.values():
                vector.close()


@pytest.mark.parametrize(
    ("obs_type", "n_envs", "use_async_envs", "expected"),
    [
        ("environment_state_agent_pos", 2, True, "BatchedVectorEnv"),
        ("environment_state_agent_pos", 1, True, "SyncVectorEnv"),
        ("pixels_agent_pos", 2, True, "SoArmVectorEnv"),
        ("pixels_agent_pos", 2, False, "SoArmVectorEnv"),
        ("pixels_agent_pos", 1, True, "SyncVectorEnv"),
    ],
)
def test_auto_picks_the_fastest_vector_env_measured(obs_type, n_envs, use_async_envs, expected):
    config = pixels_config("LiftCube-v0", obs_type=obs_type)
    vector = make_env(config, n_envs=n_envs, use_async_envs=use_async_envs)["soarm"][0]
    try:
        assert type(vector).__name__ == expected
        obs, _ = vector.reset(seed=[EVAL_SEED + k for k in range(n_envs)])
        assert obs["agent_pos"].shape == (n_envs, 6)
    finally:
        vector.close()


def test_the_robust_suite_randomises_and_one_env_is_a_sync_vector_env():
    envs = make_env(pixels_config("soarm_robust"), n_envs=1)
    try:
        vector = envs["soarm_robust"][1]
        assert type(vector).__name__ == "SyncVectorEnv"
        _, info = vector.reset(seed=[EVAL_SEED])
        assert info["variation"]["visual_randomization"][0] == "heavy"
        assert info["variation"]["physics_randomization"][0] == "light"
    finally:
        for vector in envs["soarm_robust"].values():
            vector.close()


def test_the_processes_vector_env_gives_the_async_env_episodes():
    """Same seeds, same actions: the threaded env steps exactly as Gymnasium's do."""
    observations = {}
    for vector_env in ("processes", "async"):
        config = pixels_config("PushCube-v0", vector_env=vector_env)
        vector = make_env(config, n_envs=2)["soarm"][0]
        try:
            obs, _ = vector.reset(seed=[EVAL_SEED, EVAL_SEED + 1])
            rng = np.random.default_rng(0)
            frames = [obs["agent_pos"]]
            for _ in range(10):
                action = rng.uniform(vector.action_space.low, vector.action_space.high)
                obs, *_ = vector.step(action.astype(np.float32))
                frames.append(obs["agent_pos"])
            observations[vector_env] = (np.stack(frames), obs["pixels"]["front_camera"])
        finally:
            vector.close()
    np.testing.assert_array_equal(observations["processes"][0], observations["async"][0])
    np.testing.assert_array_equal(observations["processes"][1], observations["async"][1])


def test_state_policies_need_one_state_layout():
    with pytest.raises(ValueError, match="one task at a time"):
        SoArmEnvConfig(task="soarm_core", obs_type="environment_state_agent_pos")
    with pytest.raises(ValueError, match="they differ"):  # 13 values each, other meanings
        SoArmEnvConfig(
            task="PickAndPlaceCube-v0,PushCube-v0", obs_type="environment_state_agent_pos"
        )
    with pytest.raises(ValueError, match="soarm_core"):
        SoArmEnvConfig(task="soarm_cor")
    with pytest.raises(ValueError, match="vector_env must be one of"):
        SoArmEnvConfig(vector_env="threads")


def test_the_protocol_seed_is_lerobot_evals_default():
    from lerobot.configs.eval import EvalPipelineConfig

    assert EvalPipelineConfig.__dataclass_fields__["seed"].default == EVAL_SEED


def test_lerobot_loads_a_multi_task_dataset(tmp_path):
    root = tmp_path / "core"
    record(root, task="soarm_core", episodes=1, camera_config="front_only", size=(48, 64))
    dataset = LeRobotDataset("local/soarm_core", root=root, video_backend="pyav")
    assert dataset.num_episodes == 4 and len(dataset.meta.tasks) == 4
    for episode, task in enumerate(CORE):
        start = dataset.meta.episodes[episode]["dataset_from_index"]
        assert dataset[start]["task"] == get_task(task).instructions[0]


def test_lerobot_eval_scores_a_suite_on_the_protocol_through_the_plugin(tmp_path):
    """A barely trained policy (two steps) on soarm_core and soarm_language: lerobot-eval
    finds --env.type=soarm through the plugin, reports every task and suite, and two runs
    on the protocol's seeds give the same numbers."""
    try:
        importlib.metadata.distribution("lerobot_env_soarm")
    except importlib.metadata.PackageNotFoundError:
        pytest.fail("install the plugin: pip install -e plugins/lerobot_env_soarm")
    env = dict(os.environ, HF_HUB_OFFLINE="1", WANDB_MODE="disabled")
    data = tmp_path / "data"
    record(data, task="soarm_core", episodes=1, camera_config="front_only", size=(48, 64))
    train = tmp_path / "train"
    train_command = [
        str(BIN / "lerobot-train"), "--dataset.repo_id=local/soarm_core", f"--dataset.root={data}",
        "--dataset.video_backend=pyav", "--policy.type=act", "--policy.device=cpu",
        "--policy.pretrained_backbone_weights=null", "--policy.push_to_hub=false",
        "--policy.dim_model=64", "--policy.dim_feedforward=128", "--policy.chunk_size=10",
        "--policy.n_action_steps=10", "--wandb.enable=false", "--steps=2",
        "--batch_size=2", "--num_workers=0", f"--output_dir={train}",
    ]  # fmt: skip
    eval_command = [
        str(BIN / "lerobot-eval"), "--env.type=soarm", "--env.task=soarm_core,soarm_language",
        "--env.camera_config=front_only", "--env.observation_height=48",
        "--env.observation_width=64", "--env.episode_length=15",
        f"--policy.path={train}/checkpoints/last/pretrained_model", "--policy.device=cpu",
        "--eval.n_episodes=2", "--eval.batch_size=2",
    ]  # fmt: skip
    runs = []
    for command in (train_command, [*eval_command, f"--output_dir={tmp_path / 'eval1'}"],
                    [*eval_command, f"--output_dir={tmp_path / 'eval2'}"]):  # fmt: skip
        result = subprocess.run(
            command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1200
        )
        assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-4000:]
    for name in ("eval1", "eval2"):
        runs.append(json.loads((tmp_path / name / "eval_info.json").read_text()))
    info = runs[0]
    assert set(info["per_group"]) == {"soarm_core", "soarm_language"}
    assert info["overall"]["n_episodes"] == 10
    tasks = {(entry["task_group"], entry["task_id"]) for entry in info["per_task"]}
    assert tasks == {("soarm_core", i) for i in range(4)} | {("soarm_language", 0)}
    rewards = [
        sorted(
            (e["task_group"], e["task_id"], e["metrics"]["sum_rewards"]) for e in run["per_task"]
        )
        for run in runs
    ]
    assert rewards[0] == rewards[1]
    # Episodes differ from one another (seeds 1000 and 1001 give different scenes).
    assert any(len(set(e["metrics"]["sum_rewards"])) == 2 for e in info["per_task"])
