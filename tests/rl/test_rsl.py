"""PPO on RSL-RL (``--vector-env batched|warp``): the adapter to RSL-RL's ``VecEnv`` over the
package's own vector envs, a short real training run saved, reloaded and evaluated, and
every bad input refused before anything trains (behaviour, never success rates)."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

if os.environ.get("GYM_SOARM_REQUIRE_RL") != "1":
    pytest.importorskip("rsl_rl", reason='needs the rl extra: pip install "gym-soarm[rl]"')

import torch
from gymnasium.vector import AutoresetMode

from gym_soarm.rl.evaluation import TrainedPolicy, read_settings, score
from gym_soarm.rl.hyperparams import rsl_recipe
from gym_soarm.rl.imitation import train_imitation
from gym_soarm.rl.rsl import make_rsl_env
from gym_soarm.rl.rsl_policy import RSL_LIBRARY
from gym_soarm.rl.training import train
from gym_soarm.tasks.suites import EVAL_SEED
from gym_soarm.vector.batched import make_vector_env

pytestmark = pytest.mark.train

STATE = {"obs_type": "state", "normalize_actions": True, "control_mode": "joint_delta"}
SMOKE = {"num_steps_per_env": 8, "num_mini_batches": 2}


def test_adapter_gives_rsl_rl_the_batched_env_as_tensors_with_time_outs():
    env = make_rsl_env("ReachTarget-v0", STATE, 3, "batched", "cpu", seed=5)
    reference = make_vector_env(
        3,
        vector_env="batched",
        max_episode_steps=120,
        autoreset_mode=AutoresetMode.SAME_STEP,
        task="ReachTarget-v0",
        **STATE,
    )
    try:
        obs = env.get_observations()
        expected, _ = reference.reset(seed=[5, 6, 7])
        assert list(obs.keys()) == ["policy"] and tuple(obs.batch_size) == (3,)
        assert obs["policy"].dtype == torch.float32
        np.testing.assert_array_equal(obs["policy"].numpy(), expected.astype(np.float32))
        rng = np.random.default_rng(0)
        for _step in range(1, 121):
            action = rng.uniform(-1, 1, (3, env.num_actions)).astype(np.float32)
            obs, rewards, dones, extras = env.step(torch.as_tensor(action))
            expected, ref_rewards, terminated, truncated, info = reference.step(action)
            # The same simulation: observations (the next episode's first after a reset
            # inside step), rewards and dones, bit for bit in float32.
            np.testing.assert_array_equal(obs["policy"].numpy(), expected.astype(np.float32))
            np.testing.assert_array_equal(rewards.numpy(), ref_rewards.astype(np.float32))
            np.testing.assert_array_equal(dones.numpy(), (terminated | truncated).astype(int))
            np.testing.assert_array_equal(
                extras["time_outs"].numpy(), (truncated & ~terminated).astype(np.float32)
            )
            assert dones.dtype == torch.long and rewards.shape == (3,)
            ended = (terminated | truncated).astype(bool)
            np.testing.assert_array_equal(
                env.episode_length_buf.numpy()[ended], np.zeros(int(ended.sum()))
            )
            if ended.any():
                success = np.asarray(info["final_info"]["is_success"])[ended]
                assert extras["log"]["/success"] == pytest.approx(float(success.mean()))
        # Random actions never reach the target: every episode ran to the time limit.
        assert _step == 120 and bool(truncated.all()) and float(extras["time_outs"].sum()) == 3
    finally:
        env.close()
        reference.close()


def test_ppo_on_rsl_rl_trains_saves_and_evaluates(tmp_path):
    out = tmp_path / "rsl"
    result = train(
        "ppo",
        "reach",
        out,
        seed=2,
        steps=2 * 64 * 8,
        eval_every=64 * 8,
        eval_episodes=2,
        hyperparams=SMOKE,
        vector_env="batched",
    )
    assert result.env_steps == 2 * 64 * 8 and not result.interrupted
    for name in ("model.pt", "settings.json", "curve.csv", "curve.png"):
        assert (out / name).is_file(), name
    settings = read_settings(out)
    assert settings["library"] == RSL_LIBRARY and settings["algo"] == "ppo"
    assert settings["recipe"]["vector_env"] == "batched"
    assert settings["recipe"]["algo"]["num_steps_per_env"] == 8
    with open(out / "curve.csv") as stream:
        rows = list(csv.DictReader(stream))
    assert [int(r["env_steps"]) for r in rows] == [512, 1024]
    # The folder's actor acts without RSL-RL's runner, and scores what the run scored.
    policy = TrainedPolicy(out)
    again = score("ReachTarget-v0", settings["env"], policy, 2, EVAL_SEED)
    assert again["success_rate"] == float(rows[-1]["success_rate"])
    assert round(again["mean_return"], 4) == pytest.approx(float(rows[-1]["mean_return"]))
    # The checkpoint is RSL-RL's: a run goes on from it.
    more = train(
        "ppo",
        "reach",
        tmp_path / "more",
        steps=64 * 8,
        eval_every=64 * 8,
        eval_episodes=1,
        hyperparams=SMOKE,
        vector_env="batched",
        init=out,
    )
    assert more.env_steps == 512
    saved = torch.load(tmp_path / "more" / "model.pt", weights_only=False)
    first = torch.load(out / "model.pt", weights_only=False)
    assert saved["actor_state_dict"].keys() == first["actor_state_dict"].keys()


@pytest.mark.subprocess
def test_the_program_trains_with_rsl_rl_and_evaluate_reads_the_folder(tmp_path):
    out = tmp_path / "cli"
    run = subprocess.run(
        [
            sys.executable, "-m", "gym_soarm.train", "--algo", "ppo", "--task", "reach",
            "--vector-env", "batched", "--steps", "512", "--eval-every", "512",
            "--eval-episodes", "1", "--hyperparams", "num_steps_per_env=8", "--out", str(out),
        ],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "done: 512 steps" in run.stdout
    evaluated = subprocess.run(
        [sys.executable, "-m", "gym_soarm.evaluate", "--policy", str(out), "--episodes", "1",
         "--json", str(tmp_path / "e.json")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads((tmp_path / "e.json").read_text())["episodes"] == 1


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"hyperparams": {"n_steps": 8}}, "not keys of the ppo (RSL-RL) recipe; valid: "),
        ({"device": "cuda"}, "vector_env 'batched' steps on the CPU"),
        ({"device": "gpu", "vector_env": "warp"}, "device must be 'cpu', 'cuda' or 'cuda:N'"),
        ({"vector_env": "gpu"}, "vector_env must be one of"),
        ({"vec_env": "dummy"}, "not both"),
        ({"env": {"obs_type": "pixels_agent_pos"}}, "learns from state observations"),
    ],
)
def test_bad_input_is_refused_before_anything_trains(tmp_path, kwargs, message):
    kwargs = {"vector_env": "batched", **kwargs}
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        train("ppo", "reach", tmp_path / "out", steps=512, **kwargs)
    assert not (tmp_path / "out").exists()


def test_cuda_without_a_gpu_and_folders_it_cannot_start_from_are_refused(tmp_path):
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="torch sees no CUDA device"):
            train("ppo", "reach", tmp_path / "x", vector_env="warp", device="cuda")
    sb3 = tmp_path / "sb3"
    sb3.mkdir()
    settings = {
        "format": "gym_soarm.policy/1", "algo": "ppo", "task": "ReachTarget-v0",
        "env": rsl_recipe("ReachTarget-v0")["env"], "observation_names": [],
    }  # fmt: skip
    (sb3 / "settings.json").write_text(json.dumps(settings))
    (sb3 / "model.zip").write_bytes(b"")
    with pytest.raises(ValueError, match="another observation layout"):
        train("ppo", "reach", tmp_path / "y", vector_env="batched", init=sb3)
    settings.update(algo="sac")
    (sb3 / "settings.json").write_text(json.dumps(settings))
    with pytest.raises(ValueError, match="needs a PPO-class policy"):
        train("ppo", "reach", tmp_path / "y", vector_env="batched", init=sb3)
    with pytest.raises(ValueError, match="trains PPO \\(RSL-RL\\) only"):
        train("sac", "reach", tmp_path / "z", vector_env="warp")
    assert not any((tmp_path / name).exists() for name in ("x", "y", "z"))


def test_ppo_on_rsl_rl_starts_from_a_bc_folder_acting_as_it_did(tmp_path):
    """--init with a BC folder: the RSL-RL actor is the BC actor (same actions), its
    observation statistics stay frozen, and the critic learns alone first."""
    bc = tmp_path / "bc"
    hyperparams = {"demos": 2, "epochs": 2, "policy_kwargs": {"net_arch": [32, 16]}}
    train_imitation("bc", "reach", bc, seed=1, eval_episodes=1, hyperparams=hyperparams)
    warmup = rsl_recipe("ReachTarget-v0")["init"]["critic_warmup"]
    out = tmp_path / "rsl"
    result = train(
        "ppo", "reach", out, steps=1, eval_every=64 * 8, eval_episodes=2,
        hyperparams=SMOKE, vector_env="batched", init=bc,
    )  # fmt: skip
    assert result.env_steps == warmup * 64 * 8  # the critic's warm-up, then nothing more
    settings = read_settings(out)
    assert settings["init"] == str(bc) and settings["recipe"]["frozen_actor_normalizer"]
    assert settings["recipe"]["algo"]["hidden_dims"] == [32, 16]
    assert settings["recipe"]["algo"]["activation"] == "tanh"
    # The warm-up moved the critic, not the actor: the folder acts as BC does.
    teacher, student = TrainedPolicy(bc), TrainedPolicy(out)
    env = make_vector_env(1, vector_env="batched", task="ReachTarget-v0", **STATE)
    obs, _ = env.reset(seed=[EVAL_SEED])
    for _ in range(20):
        action = teacher(obs[0], {})
        np.testing.assert_allclose(student(obs[0], {}), action, atol=1e-5)
        obs, *_ = env.step(action[None])
    env.close()
    with open(out / "curve.csv") as stream:
        rows = list(csv.DictReader(stream))
    assert [int(r["env_steps"]) for r in rows] == [0, warmup * 64 * 8]
    assert rows[0]["success_rate"] == rows[1]["success_rate"]
    # Training on moves the actor; its normaliser stays the BC folder's.
    more = tmp_path / "more"
    train(
        "ppo", "reach", more, steps=64 * 8, eval_every=64 * 8, eval_episodes=1,
        hyperparams=SMOKE, vector_env="batched", init=out,
    )  # fmt: skip
    before = torch.load(out / "model.pt", weights_only=False)["actor_state_dict"]
    after = torch.load(more / "model.pt", weights_only=False)["actor_state_dict"]
    for name in ("obs_normalizer._mean", "obs_normalizer._std"):
        torch.testing.assert_close(after[name], before[name], rtol=0, atol=0)
    assert not torch.equal(after["mlp.0.weight"], before["mlp.0.weight"])
    assert read_settings(more)["recipe"]["algo"]["hidden_dims"] == [32, 16]


def test_ppo_from_a_bc_folder_keeps_cloning_its_demonstrations(tmp_path):
    """After the critic's warm-up, each PPO update is followed by behaviour cloning on the
    folder's demonstrations, with a weight that decays."""
    from gym_soarm.rl.imitation import DEMOS_FILE, Dataset
    from gym_soarm.rl.rsl import RslTrainer
    from gym_soarm.rl.runs import RunFolder
    from gym_soarm.rl.training import _check_rsl_init
    from gym_soarm.tasks import get_task

    bc = tmp_path / "bc"
    hyperparams = {"demos": 2, "epochs": 2, "policy_kwargs": {"net_arch": [32, 16]}}
    train_imitation("bc", "reach", bc, seed=1, eval_episodes=1, hyperparams=hyperparams)
    settings = rsl_recipe("ReachTarget-v0")
    settings["algo"].update(SMOKE)
    settings.update(vector_env="batched", device="cpu", library=RSL_LIBRARY)
    settings["init"].update(critic_warmup=1, bc_coef=0.5, bc_decay=0.5)
    _check_rsl_init(bc, "ReachTarget-v0", settings)
    folder = RunFolder(tmp_path / "rsl", "test", ("env_steps",)).prepare()
    trainer = RslTrainer(get_task("reach"), folder, 0, settings, "cpu", bc)
    try:
        alg = trainer.runner.alg
        demos = Dataset.load(bc / DEMOS_FILE)
        assert alg.demo_obs.shape == demos.obs.shape and alg.bc_coef == 0.5
        trainer.warm_critic(1)
        assert alg.bc_coef == 0.5  # the warm-up leaves the actor and the term alone
        trainer.iterate(2)
        assert alg.bc_coef == 0.125  # two updates, each with its cloning steps
    finally:
        trainer.close()
