"""``python -m gym_soarm.train --algo bc|dagger`` and ``--algo ppo --init`` with real
environments, experts and Stable-Baselines3 at tiny sizes: the files written, the data
set (DART labels clean, executed actions noisy), DAgger's aggregation, the PPO start
from an imitation policy, and every bad input refused before training (behaviour, never
success rates)."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

if os.environ.get("GYM_SOARM_REQUIRE_RL") != "1":
    pytest.importorskip(
        "stable_baselines3", reason='needs the rl extra: pip install "gym-soarm[rl]"'
    )
    pytest.importorskip("torch", reason='needs the rl extra: pip install "gym-soarm[rl]"')

from interrupt import interrupt_when
from paths import TESTS

from gym_soarm.expert import make_expert
from gym_soarm.rl.dagger import ImitationTrainer
from gym_soarm.rl.evaluation import TrainedPolicy, make_env, read_settings, score
from gym_soarm.rl.hyperparams import HYPERPARAMS, IMITATION, recipe
from gym_soarm.rl.imitation import Dataset, check_settings, train_imitation, training_seeds
from gym_soarm.rl.runs import VALIDATION_SEED, RunFolder
from gym_soarm.rl.training import train
from gym_soarm.tasks import get_task

pytestmark = pytest.mark.train

TINY = {"demos": 4, "epochs": 5, "batch_size": 64}
TINY_DAGGER = {**TINY, "rounds": 1, "episodes_per_round": 3, "round_epochs": 3}


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", *args], capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="module")
def bc_reach(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("imitation") / "bc"
    hyperparams = [f"{key}={value}" for key, value in TINY.items()]
    done = _cli(
        "gym_soarm.train", "--algo", "bc", "--task", "reach", "--seed", "2",
        "--eval-episodes", "2", "--out", str(out), "--hyperparams", *hyperparams,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "done:" in done.stdout and "success on the validation episodes" in done.stdout
    return out


def test_bc_writes_a_policy_folder_that_loads_and_acts(bc_reach):
    for name in ("model.zip", "settings.json", "curve.csv", "curve.png", "vecnormalize.pkl"):
        assert (bc_reach / name).is_file(), name
    settings = read_settings(bc_reach)
    assert settings["algo"] == "bc" and settings["task"] == "ReachTarget-v0"
    assert settings["env"] == recipe("bc", "ReachTarget-v0")["env"]
    assert settings["recipe"]["algo"]["demos"] == TINY["demos"]
    with open(bc_reach / "curve.csv") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 1 and rows[0]["round"] == "0" and rows[0]["episodes"] == "2"
    data = Dataset.load(bc_reach / "demos.npz")
    assert int(rows[0]["samples"]) == len(data) == int(rows[0]["env_steps"]) > 0
    assert sorted(set(data.episode.tolist())) == list(range(TINY["demos"]))

    policy = TrainedPolicy(bc_reach)
    env = make_env(policy.task, policy.settings["env"])
    try:
        obs, info = env.reset(seed=0)
        action = policy(obs, info)
    finally:
        env.close()
    assert action.shape == (6,) and np.all(np.abs(action) <= 1.0)
    first = score(policy.task, policy.settings["env"], policy, episodes=1)
    assert first == score(policy.task, policy.settings["env"], TrainedPolicy(bc_reach), 1)


def test_dart_labels_are_the_clean_expert_actions_and_the_executed_ones_noisy(tmp_path):
    out = tmp_path / "dart"
    hyperparams = {**TINY, "demos": 3, "epochs": 1, "dart_std": 0.2}
    result = train_imitation("bc", "reach", out, seed=0, eval_episodes=1, hyperparams=hyperparams)
    data = Dataset.load(out / "demos.npz")
    seeds = training_seeds(0, 0, 3)
    assert result.env_steps == len(data) > 0
    assert set(data.round.tolist()) == {0} and set(data.episode.tolist()) == {0, 1, 2}
    noise = (data.executed - data.actions)[np.abs(data.executed) < 1.0]
    assert 0.15 < noise.std() < 0.25 and abs(noise.mean()) < 0.05
    assert np.all(np.abs(data.executed) <= 1.0)
    # Replaying the executed actions of each episode, the expert asked again in each
    # state gives the recorded label: the labels are the clean expert's.
    replay = make_env("ReachTarget-v0", read_settings(out)["env"])
    try:
        expert = make_expert(replay)
        for k, seed in enumerate(seeds):
            rows = np.flatnonzero(data.episode == k)
            obs, info = replay.reset(seed=seed)
            expert.reset()
            for row in rows:
                np.testing.assert_allclose(obs, data.obs[row], atol=1e-6)
                label = np.clip(expert(obs, info), -1, 1)
                np.testing.assert_allclose(label, data.actions[row], atol=1e-6)
                obs, _, terminated, truncated, info = replay.step(data.executed[row])
            assert terminated or truncated  # the episode ended where the recording did
    finally:
        replay.close()
    assert min(training_seeds(0, 0, 1)) > 1000 + 10_000  # never a protocol seed
    assert not set(training_seeds(0, 1, 999)) & set(training_seeds(1, 0, 999))


def test_dagger_aggregates_the_states_the_learner_visits(tmp_path):
    out = tmp_path / "dagger"
    hyperparams = {**TINY_DAGGER, "beta0": 0.0, "dart_std": 0.0}
    result = train_imitation(
        "dagger", "reach", out, seed=1, eval_episodes=1, hyperparams=hyperparams
    )
    assert not result.interrupted
    with open(out / "curve.csv") as stream:
        rows = list(csv.DictReader(stream))
    assert [r["round"] for r in rows] == ["0", "1"]
    data = Dataset.load(out / "demos.npz")
    demos = data.round == 0
    assert int(rows[0]["samples"]) == demos.sum() < int(rows[1]["samples"]) == len(data)
    assert result.env_steps == len(data)
    assert set(data.episode[~demos].tolist()) == set(range(4, 7))
    # Round 1 with beta 0: the learner's actions were executed, the expert's recorded.
    learner = TrainedPolicy(out)
    assert read_settings(out)["algo"] == "dagger"
    assert not np.allclose(data.executed[~demos], data.actions[~demos])
    assert np.allclose(data.executed[demos], data.actions[demos])  # no DART noise
    action = learner(data.obs[~demos][0])
    assert action.shape == (6,)


class _ExpertStudent(ImitationTrainer):
    """A student that answers what the expert does: its validation must be the expert's."""

    def student_actions(self, run, mask):
        return np.clip(np.asarray(self.expert(run.obs, None), np.float32), -1.0, 1.0)[mask]


def test_validation_side_by_side_plays_the_episodes_one_environment_plays(tmp_path):
    # Seven episodes on four environments: three start where others ended, and spare
    # resets keep stepping without counting.
    settings = check_settings("dagger", recipe("dagger", "ReachTarget-v0"))
    folder = RunFolder(tmp_path, "").prepare()
    trainer = _ExpertStudent("dagger", get_task("ReachTarget-v0"), folder, 0, settings)
    trainer.venv = trainer.make_vector_env()
    try:
        trainer.expert = make_expert(trainer.venv)
        rate, mean_return = trainer.validate(7)
    finally:
        trainer.venv.close()
    one = score("ReachTarget-v0", settings["env"], None, 7, VALIDATION_SEED)
    assert rate == one["success_rate"]
    assert mean_return == pytest.approx(one["mean_return"], rel=1e-9)


def test_episode_weights_and_a_cosine_rate_change_the_state_fit_and_nothing_else(tmp_path):
    # The same demonstrations (same seed) fitted three ways: plain, each episode counting
    # alike, and with the rate annealed. The data is the same; the weights are not.
    weights = {}
    for name, extra in (
        ("plain", {}),
        ("weighted", {"episode_weighting": True}),
        ("cosine", {"lr_schedule": "cosine"}),
    ):
        out = tmp_path / name
        train_imitation("bc", "reach", out, seed=3, eval_episodes=1, hyperparams={**TINY, **extra})
        with zipfile.ZipFile(out / "model.zip") as archive:
            weights[name] = archive.read("policy.pth")
        data = Dataset.load(out / "demos.npz")
        if name == "plain":
            first = data
        else:
            assert np.array_equal(data.actions, first.actions)
    assert weights["weighted"] != weights["plain"]
    assert weights["cosine"] != weights["plain"]
    assert weights["cosine"] != weights["weighted"]
    assert read_settings(tmp_path / "weighted")["recipe"]["algo"]["episode_weighting"] is True


def test_ppo_starts_from_the_imitation_policy(tmp_path, bc_reach):
    out = tmp_path / "ppo"
    train("ppo", "reach", out, seed=0, steps=256, eval_every=256, eval_episodes=1,
          hyperparams={"n_steps": 32, "batch_size": 64, "learning_rate": 0.0},
          vec_env="dummy", init=bc_reach)  # fmt: skip
    settings = read_settings(out)
    assert settings["algo"] == "ppo" and settings["init"] == str(bc_reach)
    assert settings["recipe"]["init"]["log_std"] == -3.0
    ppo = TrainedPolicy(out).model.policy.state_dict()
    bc = TrainedPolicy(bc_reach).model.policy.state_dict()
    assert ppo.keys() == bc.keys()
    for key, value in bc.items():  # learning rate 0: the BC weights kept
        if key != "log_std":
            assert np.array_equal(value.numpy(), ppo[key].numpy()), key
    assert np.allclose(ppo["log_std"].numpy(), -3.0)


def test_ppo_from_a_pretrained_actor_first_trains_only_its_critic(tmp_path, bc_reach):
    # A PPO update or two, within the recipe's critic warm-up: the actor stays as BC left it
    # (the BC term waits too), the value branch learns.
    out = tmp_path / "ppo"
    train("ppo", "reach", out, seed=0, steps=256, eval_every=256, eval_episodes=1,
          hyperparams={"n_steps": 16, "batch_size": 32, "n_epochs": 2},
          vec_env="dummy", init=bc_reach)  # fmt: skip
    assert read_settings(out)["recipe"]["init"]["critic_warmup"] >= 1
    bc = TrainedPolicy(bc_reach).model.policy.state_dict()
    ppo = TrainedPolicy(out).model.policy.state_dict()
    actor = [k for k in bc if k.startswith(("mlp_extractor.policy_net", "action_net"))]
    critic = [k for k in bc if k.startswith(("mlp_extractor.value_net", "value_net"))]
    assert actor and critic
    for key in actor:
        assert np.array_equal(bc[key].numpy(), ppo[key].numpy()), key
    assert np.allclose(ppo["log_std"].numpy(), -3.0)
    assert any(not np.array_equal(bc[k].numpy(), ppo[k].numpy()) for k in critic)


def test_init_from_another_task_is_refused_naming_both(tmp_path, bc_reach):
    with pytest.raises(ValueError, match="for ReachTarget-v0; got --task LiftCube-v0"):
        train("ppo", "lift", tmp_path / "a", init=bc_reach)
    with pytest.raises(ValueError, match="starts PPO only"):
        train("sac", "reach", tmp_path / "b", init=bc_reach)
    with pytest.raises(ValueError, match="is not a gym-soarm policy folder"):
        train("ppo", "reach", tmp_path / "c", init=tmp_path)
    edited = tmp_path / "edited"
    edited.mkdir()
    for name in ("model.zip", "vecnormalize.pkl"):
        (edited / name).write_bytes((bc_reach / name).read_bytes())
    settings = json.loads((bc_reach / "settings.json").read_text())
    settings["observation_names"] = settings["observation_names"][:-1]
    (edited / "settings.json").write_text(json.dumps(settings))
    with pytest.raises(ValueError, match="another observation layout"):
        train("ppo", "reach", tmp_path / "d", init=edited)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["edited"]


@pytest.mark.parametrize(
    ("algo", "hyperparams", "message"),
    [
        ("bc", {"demos": 0}, "demos must be an int from 1 to 999; got 0"),
        ("bc", {"dart_std": -0.1}, "dart_std must be a finite number >= 0"),
        ("bc", {"epochs": 1.5}, "epochs must be an int"),
        ("bc", {"learning_rate": 0}, "learning_rate must be a finite number > 0"),
        ("bc", {"policy_kwargs": {"net_arch": [0]}}, "net_arch"),
        ("bc", {"rounds": 2}, r"hyperparams \['rounds'\] are not keys of the bc recipe"),
        ("dagger", {"rounds": 0}, "rounds must be an int from 1 to 99"),
        ("dagger", {"beta0": 1.5}, "beta0 must be a number from 0 to 1"),
        ("dagger", {"episodes_per_round": 1000}, "episodes_per_round must be an int"),
        ("dagger", {"patience": 0}, "patience must be an int"),
        ("bc", {"lr_schedule": "linear"}, "lr_schedule is 'constant' or 'cosine'; got 'linear'"),
        ("dagger", {"episode_weighting": 1}, "episode_weighting must be true or false"),
    ],
)
def test_bad_numbers_are_refused_before_training(tmp_path, algo, hyperparams, message):
    with pytest.raises(ValueError, match=message):
        train_imitation(algo, "reach", tmp_path / "run", hyperparams=hyperparams)
    assert not (tmp_path / "run").exists()


@pytest.mark.subprocess
def test_bad_input_is_refused_in_python_and_on_the_command_line(tmp_path):
    with pytest.raises(ValueError, match="NoSuch"):
        train_imitation("bc", "NoSuch-v0", tmp_path / "a")
    with pytest.raises(ValueError, match="train_imitation trains bc, dagger"):
        train_imitation("ppo", "reach", tmp_path / "b")
    with pytest.raises(ValueError, match="imitation trainer"):
        train("bc", "reach", tmp_path / "c")
    with pytest.raises(ValueError, match="eval_episodes must be an int >= 1"):
        train_imitation("bc", "reach", tmp_path / "d", eval_episodes=0)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        train_imitation("bc", "reach", tmp_path / "file")
    done = _cli("gym_soarm.train", "--algo", "bc", "--task", "reach", "--steps", "10",
                "--out", str(tmp_path / "e"))  # fmt: skip
    assert done.returncode != 0 and "--steps does not apply to --algo bc" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_the_imitation_recipes_are_complete():
    for algo in IMITATION:
        for task, row in HYPERPARAMS[algo].items():
            settings = recipe(algo, task if task != "default" else "ReachTarget-v0")
            assert settings["env"] == recipe("ppo", "ReachTarget-v0")["env"]
            assert set(row) <= set(HYPERPARAMS[algo]["default"]), (algo, task)
    assert set(recipe("bc", "LiftCube-v0")["algo"]) < set(recipe("dagger", "LiftCube-v0")["algo"])
    # Stack's and push's rows double the demonstrations and keep the rest of the recipe,
    # but push's, which anneals its learning rate.
    for algo in IMITATION:
        lift = recipe(algo, "LiftCube-v0")
        for task in ("StackCube-v0", "PushCube-v0"):
            twice = recipe(algo, task)
            assert (twice["algo"]["demos"], lift["algo"]["demos"]) == (400, 200)
            schedule = "cosine" if task == "PushCube-v0" else lift["algo"]["lr_schedule"]
            assert twice["algo"]["lr_schedule"] == schedule
            assert {**twice["algo"], "demos": 200, "lr_schedule": "constant"} == lift["algo"]


@pytest.mark.subprocess
def test_ctrl_c_keeps_the_last_checkpoint_and_curve(tmp_path):
    out = tmp_path / "run"
    done = interrupt_when(
        [
            sys.executable, "-m", "gym_soarm.train", "--algo", "dagger", "--task", "reach",
            "--eval-episodes", "1", "--out", str(out), "--hyperparams", "demos=3", "epochs=2",
            "rounds=99", "episodes_per_round=2", "round_epochs=50",
        ],
        lambda _: (out / "curve.csv").is_file(),
        within_s=120,
        then_s=0.5,
        what="a checkpoint",
    )  # fmt: skip
    assert done.returncode == 130, done.stderr
    assert "interrupted" in done.stdout
    for name in ("model.zip", "curve.csv", "curve.png", "settings.json", "demos.npz"):
        assert (out / name).is_file(), name
    TrainedPolicy(out)  # the kept checkpoint loads


def test_a_policy_trained_before_the_observation_gained_values_still_acts(tmp_path):
    """A sort policy of the 81 values before its progress was added reads those values, by
    name, from today's 93; a layout that lacks values it was trained on is refused."""
    from gymnasium import spaces
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    settings = json.loads(
        (TESTS / "data/formats/policy-settings-sort-before-progress.json").read_text()
    )
    names = settings["observation_names"]
    assert len(names) == 81
    env = make_env("SortCubes-v0", settings["env"])
    now = list(env.unwrapped.observation_names)
    assert len(now) == 93 and set(names) < set(now)

    class Old(gym.Env):  # the spaces the policy was trained with
        observation_space = spaces.Box(-np.inf, np.inf, (81,), np.float32)
        action_space = env.action_space

    model = PPO("MlpPolicy", DummyVecEnv([Old]), seed=0, device="cpu", n_steps=64)
    model.save(tmp_path / "model.zip")
    (tmp_path / "settings.json").write_text(json.dumps(settings))
    policy = TrainedPolicy(tmp_path)
    obs, _ = env.reset(seed=1000)
    columns = [now.index(name) for name in names]
    expected, _ = model.predict(obs[columns], deterministic=True)
    np.testing.assert_array_equal(policy(obs), expected)
    obs, *_ = env.step(policy(obs))
    env.close()

    settings["observation_names"] = [*names[:-1], "not_a_value"]
    (tmp_path / "settings.json").write_text(json.dumps(settings))
    with pytest.raises(ValueError, match=r"another observation layout.*not_a_value.*retrain"):
        TrainedPolicy(tmp_path)
