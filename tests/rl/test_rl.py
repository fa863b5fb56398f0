"""``python -m gym_soarm.train`` and ``python -m gym_soarm.evaluate`` with real
Stable-Baselines3: a few thousand steps of PPO and SAC, saved, reloaded and evaluated
(behaviour, never success rates), and every bad input refused before training."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

if os.environ.get("GYM_SOARM_REQUIRE_RL") != "1":
    pytest.importorskip(
        "stable_baselines3", reason='needs the rl extra: pip install "gym-soarm[rl]"'
    )

from interrupt import interrupt_when

from gym_soarm.rl.evaluation import TrainedPolicy, read_settings, score
from gym_soarm.rl.hyperparams import ALGORITHMS, HYPERPARAMS, recipe
from gym_soarm.rl.training import train

pytestmark = pytest.mark.train

SMOKE = {
    "ppo": {"steps": 2048, "hyperparams": {"n_steps": 128, "batch_size": 256}},
    "sac": {"steps": 1200, "hyperparams": {"learning_starts": 200}},
}


def _cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", *args], capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.subprocess
@pytest.mark.parametrize("algo", ALGORITHMS)
def test_train_save_reload_and_evaluate(tmp_path, algo):
    out = tmp_path / algo
    result = train(
        algo,
        "reach",
        out,
        seed=1,
        steps=SMOKE[algo]["steps"],
        eval_every=1024,
        eval_episodes=2,
        hyperparams=SMOKE[algo]["hyperparams"],
    )
    assert not result.interrupted and result.env_steps >= SMOKE[algo]["steps"]
    for name in ("model.zip", "settings.json", "curve.csv", "curve.png"):
        assert (out / name).is_file(), name
    assert (out / "vecnormalize.pkl").is_file() is recipe(algo, "ReachTarget-v0")["normalize"]
    with open(out / "curve.csv") as stream:
        rows = list(csv.DictReader(stream))
    assert int(rows[0]["env_steps"]) >= 1024
    assert int(rows[-1]["env_steps"]) == result.env_steps
    assert all(0.0 <= float(r["success_rate"]) <= 1.0 and r["episodes"] == "2" for r in rows)
    assert [float(r["wall_s"]) for r in rows] == sorted(float(r["wall_s"]) for r in rows)
    settings = read_settings(out)
    assert settings["task"] == "ReachTarget-v0" and settings["algo"] == algo
    assert settings["env"]["obs_type"] == "state" and settings["env"]["normalize_actions"]

    policy = TrainedPolicy(out)
    first = score(policy.task, policy.settings["env"], policy, episodes=2)
    again = score(policy.task, policy.settings["env"], TrainedPolicy(out), episodes=2)
    assert first["seeds"] == [1000, 1001] and first["episodes"] == 2
    assert first == again  # deterministic actions from the reloaded checkpoint

    report = tmp_path / "eval.json"
    done = _cli(
        "gym_soarm.evaluate", "--policy", str(out), "--episodes", "2", "--json", str(report)
    )
    assert done.returncode == 0, done.stderr
    written = json.loads(report.read_text())
    assert written["success_rate"] == first["success_rate"]
    assert written["seeds"] == [1000, 1001] and written["episodes"] == 2


@pytest.mark.parametrize("algo", ALGORITHMS)
def test_the_native_vector_env_trains_exactly_as_sb3s_own(tmp_path, algo):
    # The same seeds give the same episodes in gym_soarm's worker processes as in SB3's
    # DummyVecEnv, so the same run learns the very same weights.
    import torch

    weights = {}
    for vec_env in ("native", "dummy"):
        out = tmp_path / vec_env
        train(algo, "reach", out, seed=3, steps=SMOKE[algo]["steps"] // 2, eval_every=10**6,
              eval_episodes=1, hyperparams=SMOKE[algo]["hyperparams"], vec_env=vec_env)  # fmt: skip
        assert read_settings(out)["recipe"]["vec_env"] == vec_env
        weights[vec_env] = TrainedPolicy(out).model.policy.state_dict()
    assert weights["native"].keys() == weights["dummy"].keys()
    for key, value in weights["native"].items():
        assert torch.equal(value, weights["dummy"][key]), key


@pytest.mark.subprocess
def test_evaluate_the_expert_on_the_protocol(tmp_path):
    report = tmp_path / "expert.json"
    done = _cli(
        "gym_soarm.evaluate", "--policy", "expert", "--task", "reach", "--episodes", "3",
        "--first-seed", "1000", "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    written = json.loads(report.read_text())
    assert written["success_rate"] == 1.0 and written["seeds"] == [1000, 1001, 1002]
    assert "ReachTarget-v0: success 100 %" in done.stdout


def test_the_recipes_are_complete():
    for algo in ALGORITHMS:
        for task, row in HYPERPARAMS[algo].items():
            settings = recipe(algo, task if task != "default" else "ReachTarget-v0")
            assert settings["env"]["obs_type"] == "state"
            assert settings["env"]["normalize_actions"] is True
            assert set(row) <= set(HYPERPARAMS[algo]["default"]), (algo, task)


@pytest.mark.subprocess
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--algo", "dqn", "--task", "reach"], "invalid choice: 'dqn'"),
        (["--algo", "ppo", "--task", "NoSuchTask-v0"], "NoSuchTask-v0"),
        (["--algo", "ppo", "--task", "reach", "--steps", "0"], "expected an int >= 1; got 0"),
        (["--algo", "sac", "--task", "reach", "--hyperparams", "gamma"], "KEY=VALUE"),
        (["--algo", "sac", "--task", "reach", "--hyperparams", "n_epochs=3"], "n_epochs"),
    ],
)
def test_train_refuses_bad_input_before_training(tmp_path, args, message):
    out = tmp_path / "run"
    done = _cli("gym_soarm.train", *args, "--out", str(out), timeout=120)
    assert done.returncode != 0
    assert message in done.stderr
    assert not out.exists()  # nothing was written


def test_train_refuses_bad_values_in_python(tmp_path):
    with pytest.raises(ValueError, match="algo must be one of ppo, sac"):
        train("a2c", "reach", tmp_path / "a")
    with pytest.raises(ValueError, match="steps must be an int >= 1"):
        train("ppo", "reach", tmp_path / "b", steps=0)
    with pytest.raises(ValueError, match="NoSuch"):
        train("ppo", "NoSuch-v0", tmp_path / "c")
    with pytest.raises(ValueError, match="vec_env must be one of 'native'"):
        train("ppo", "reach", tmp_path / "d", vec_env="threads")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        train("ppo", "reach", tmp_path / "file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


@pytest.fixture(scope="module")
def trained_reach(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("policy") / "ppo"
    train("ppo", "reach", out, steps=1024, eval_every=1024, eval_episodes=1,
          hyperparams={"n_steps": 128, "batch_size": 256})  # fmt: skip
    return out


@pytest.mark.subprocess
def test_evaluate_refuses_what_is_not_our_policy(tmp_path, trained_reach):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match="is not a gym-soarm policy folder"):
        TrainedPolicy(empty)
    with pytest.raises(ValueError, match="is not a folder"):
        TrainedPolicy(tmp_path / "missing")

    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "model.zip").write_bytes((trained_reach / "model.zip").read_bytes())
    (foreign / "settings.json").write_text(json.dumps({"format": "rl_zoo/1"}))
    with pytest.raises(ValueError, match=r"its format must be 'gym_soarm\.policy/1'"):
        TrainedPolicy(foreign)

    done = _cli("gym_soarm.evaluate", "--policy", str(trained_reach), "--task", "lift")
    assert done.returncode != 0
    assert "was trained for ReachTarget-v0; got --task LiftCube-v0" in done.stderr

    edited = tmp_path / "edited"
    edited.mkdir()
    for name in ("model.zip", "vecnormalize.pkl"):
        (edited / name).write_bytes((trained_reach / name).read_bytes())
    settings = json.loads((trained_reach / "settings.json").read_text())
    settings["observation_names"] = settings["observation_names"][:-3]
    (edited / "settings.json").write_text(json.dumps(settings))
    with pytest.raises(ValueError, match="another observation layout"):
        TrainedPolicy(edited)

    done = _cli("gym_soarm.evaluate", "--policy", "expert")
    assert done.returncode != 0 and "--policy expert needs --task" in done.stderr


@pytest.mark.subprocess
def test_ctrl_c_keeps_the_last_checkpoint_and_curve(tmp_path):
    out = tmp_path / "run"
    done = interrupt_when(
        [
            sys.executable, "-m", "gym_soarm.train", "--algo", "ppo", "--task", "reach",
            "--steps", "10000000", "--eval-every", "2048", "--eval-episodes", "1",
            "--out", str(out), "--no-progress",
        ],
        lambda _: (out / "curve.csv").is_file(),
        within_s=300,
        then_s=1.0,
        answer_s=120,
        what="a checkpoint",
    )  # fmt: skip
    assert done.returncode == 130, done.stderr
    assert "interrupted" in done.stdout
    for name in ("model.zip", "curve.csv", "curve.png", "settings.json"):
        assert (out / name).is_file(), name
    TrainedPolicy(out)  # the kept checkpoint loads


@pytest.mark.parametrize("vector_env", ["batched", "processes"])
def test_the_sb3_view_of_the_native_vector_env_honours_indices(vector_env):
    from gym_soarm.rl.native import NativeVecEnv

    env_kwargs = recipe("ppo", "ReachTarget-v0")["env"]
    processes = 2 if vector_env == "processes" else None
    venv = NativeVecEnv(
        "ReachTarget-v0", env_kwargs, 3, num_processes=processes, vector_env=vector_env
    )
    try:
        venv.seed(5)
        obs = venv.reset()
        assert obs.shape == (3, len(venv.get_attr("observation_names")[0]))
        assert [set(info) >= {"is_success", "reward_terms"} for info in venv.reset_infos] == [
            True
        ] * 3
        venv.set_attr("tag", "b", indices=[1])
        assert venv.get_attr("tag", indices=1) == ["b"]
        assert venv.env_method("__getattribute__", "tag", indices=[1]) == ["b"]
        with pytest.raises(AttributeError, match="tag"):
            venv.get_attr("tag", indices=[0])  # only environment 1 has it
        venv.set_attr("tag", "all")
        assert venv.get_attr("tag") == ["all"] * 3
        venv.step_async(np.zeros((3, 6), np.float32))
        _, rewards, dones, infos = venv.step_wait()
        assert rewards.dtype == np.float32 and dones.shape == (3,) and len(infos) == 3
        venv.set_options([{"a": 1}, None, None])
        with pytest.raises(ValueError, match="same options"):
            venv.reset()
    finally:
        venv.close()
