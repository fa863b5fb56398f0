"""Policies that learn from the cameras (SPEC 25): the cameras frame the task, the pixel
student trains through ``python -m gym_soarm.train --obs-type pixels_agent_pos`` with real
rendering, its folder loads and acts on rendered observations, other cameras or sizes are
refused, and bad input fails before anything trains (behaviour, never success rates)."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

if os.environ.get("GYM_SOARM_REQUIRE_RL") != "1":
    pytest.importorskip("torch", reason='needs the rl extra: pip install "gym-soarm[rl]"')
    pytest.importorskip(
        "stable_baselines3", reason='needs the rl extra: pip install "gym-soarm[rl]"'
    )

import torch

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.rl.evaluation import TrainedPolicy, make_env, score
from gym_soarm.rl.hyperparams import pixel_recipe
from gym_soarm.rl.imitation import train_imitation
from gym_soarm.rl.pixels import (
    PIXEL_MODEL_FILE,
    FrameStore,
    PixelPolicy,
    check_pixel_settings,
    command_map,
    demos_within_store,
    proprioception,
    random_shift,
    store_bound,
)
from gym_soarm.tasks import BUILTIN_TASKS, get_task
from gym_soarm.tasks.scripted import ScriptedExpert
from gym_soarm.tasks.state_expert import StateExpert

pytestmark = [pytest.mark.gl, pytest.mark.train]

PIXELS = ["--obs-type", "pixels_agent_pos", "--camera-config", "front_wrist"]
SIZE = ["--observation-height", "48", "--observation-width", "64"]
TINY = ["demos=2", "epochs=1", "batch_size=32", "channels=[4,4,4,4]", "hidden=[16]"]


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run(
        [sys.executable, "-m", *args], capture_output=True, text=True, timeout=timeout, env=env
    )


# --------------------------------------------------------------------------- the teacher


def test_package_make_expert_gives_the_state_expert_unless_the_script_is_asked_for():
    env = gym.make("gym_soarm/LiftCube-v0")
    try:
        assert isinstance(gym_soarm.make_expert(env), StateExpert)
        assert isinstance(gym_soarm.make_expert(env, kind="scripted"), ScriptedExpert)
        with pytest.raises(ValueError, match="kind"):
            gym_soarm.make_expert(env, kind="timed")
    finally:
        env.close()


def test_shove_is_random_absolute_targets_mid_episode_and_counted_only_in_reach():
    from gym_soarm.expert.perturbed import evaluate_perturbed

    results = evaluate_perturbed("LiftCube-v0", 3, ["shove"])
    assert [r.perturbation for r in results] == ["shove"] * 3
    assert all(isinstance(r.applied, bool) for r in results)
    # Reach has no object: every shove that ends before the episode counts.
    reach = evaluate_perturbed("ReachTarget-v0", 2, ["shove"])
    assert len(reach) == 2


# --------------------------------------------------------------------------- cameras


def _front_pixels(task: str, seed: int, name: str) -> int:
    env = gym.make(
        task,
        obs_type="pixels",
        camera_config="front_wrist",
        observation_height=96,
        observation_width=128,
        image_modalities=("rgb", "segmentation"),
    )
    try:
        obs, _ = env.reset(seed=seed)
        segment = env.unwrapped.segmentation_ids[name]
        return int((obs["segmentation"]["front_camera"] == segment).sum())
    finally:
        env.close()


@pytest.mark.parametrize("seed", [0, 3])
def test_front_camera_shows_the_cube_large_enough_to_learn_from(seed):
    assert _front_pixels("gym_soarm/LiftCube-v0", seed, "cube") >= 64


def test_front_camera_is_mostly_table_and_the_wrist_camera_looks_past_the_jaws():
    env = gym.make(
        "gym_soarm/LiftCube-v0",
        obs_type="pixels",
        camera_config="front_wrist",
        observation_height=96,
        observation_width=128,
        image_modalities=("segmentation",),
    )
    try:
        obs, _ = env.reset(seed=1)
        ids = env.unwrapped.segmentation_ids
        front = obs["segmentation"]["front_camera"]
        assert (front == ids["table"]).mean() > 0.5
        wrist = obs["segmentation"]["wrist_camera"]
        # The gripper's own body fills no more than a third of the wrist view.
        assert (wrist == ids["robot"]).mean() < 0.34
    finally:
        env.close()


# --------------------------------------------------------------------------- pieces


def test_random_shift_crops_the_edge_padded_image_at_integer_offsets():
    images = torch.arange(2 * 3 * 6 * 8, dtype=torch.float32).view(2, 3, 6, 8)
    shifted = random_shift(images, 2, torch.Generator().manual_seed(0))
    padded = torch.nn.functional.pad(images, (2, 2, 2, 2), mode="replicate")
    for n in range(2):
        windows = [
            (dy, dx)
            for dy in range(5)
            for dx in range(5)
            if torch.equal(padded[n, :, dy : dy + 6, dx : dx + 8], shifted[n])
        ]
        assert windows, "each shifted image is one window of the padded image"
    assert torch.equal(random_shift(images, 0, torch.Generator()), images)


def test_frame_store_keeps_uint8_frames_and_refuses_past_its_bound():
    store = FrameStore(("front_camera",), 4, 5, 6, max_samples=3)
    obs = {"pixels": {"front_camera": np.full((4, 5, 3), 7, np.uint8)}, "agent_pos": np.ones(6)}
    for k in range(3):
        store.add(obs, np.zeros(6), np.zeros(6), np.full(6, k), np.zeros(6), 0, 0)
    assert store.frames["front_camera"].dtype == np.uint8 and len(store) == 3
    assert np.array_equal(store.labels[:3, 0], [0, 1, 2])
    assert store.proprio.shape[1] == len(proprioception(np.ones(6), np.ones(6), np.ones(6)))
    with pytest.raises(ValueError, match="frame store is full"):
        store.add(obs, np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6), 0, 0)


@pytest.mark.parametrize("task", [t for t in BUILTIN_TASKS if get_task(t).max_episode_steps <= 400])
def test_the_default_pixel_dagger_recipe_fits_its_memory_bound(task):
    # The recipe a user gets by default must start on every task of up to 400 steps:
    # every episode at its step limit, front + wrist at 96 x 128, within max_memory_gb.
    settings = check_pixel_settings("dagger", pixel_recipe("dagger", task))
    *_, worst, budget = store_bound("dagger", get_task(task), settings)
    assert 0 < worst <= budget
    settings["algo"]["demos"] += budget  # more episodes than the bound holds steps: refused
    with pytest.raises(ValueError, match="max_memory_gb"):
        store_bound("dagger", get_task(task), settings)


@pytest.mark.parametrize("task", [t for t in BUILTIN_TASKS if get_task(t).max_episode_steps <= 400])
def test_drawn_looks_double_the_demonstrations_within_the_memory_bound(task):
    # Under light or heavy looks the DAgger recipe gathers 300 demonstrations where the
    # default gathers 150, as many as max_memory_gb holds on the longer tasks (a warning),
    # never fewer than without the looks.
    plain = pixel_recipe("dagger", task)
    floor = plain["algo"]["demos"]
    for looks in ("light", "heavy"):
        settings = check_pixel_settings("dagger", pixel_recipe("dagger", task, looks))
        demos = settings["algo"]["demos"]
        assert demos == (floor if task == "ReachTarget-v0" else 300)
        spec = get_task(task)
        *_, budget = store_bound("dagger", spec, settings, check=False)
        fits = budget // spec.max_episode_steps - 120
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            demos_within_store("dagger", spec, settings, floor)
        messages = [str(w.message) for w in caught if "max_memory_gb" in str(w.message)]
        assert settings["algo"]["demos"] == min(demos, max(fits, floor))
        assert len(messages) == (fits < demos)
        if messages:
            assert f"gathering {settings['algo']['demos']}. To keep them pass " in messages[0]
        *_, worst, budget = store_bound("dagger", spec, settings)
        assert worst <= budget
    assert pixel_recipe("bc", task, "light") == pixel_recipe("bc", task)
    with pytest.raises(ValueError, match="visual_randomization must be one of"):
        pixel_recipe("dagger", task, "Light")


def test_only_the_drawn_looks_demonstrations_are_lowered_never_a_users(tmp_path):
    # Everything here is refused before anything is gathered or written.
    env = {"obs_type": "pixels_agent_pos", "camera_config": "front_wrist",
           "observation_height": 48, "observation_width": 64}  # fmt: skip
    per_sample = FrameStore.bytes_per_sample(2, 48, 64)
    steps = get_task("LiftCube-v0").max_episode_steps
    small = (200 * steps) * per_sample / 2**30  # room for 200 episodes: 150 + 6 x 20 do not fit
    light = {**env, "visual_randomization": "light"}
    cases = [
        (light, {"demos": 3, "rounds": 10, "max_memory_gb": small / 20}),  # the user's demos
        (light, {"max_memory_gb": small}),  # lowered from 300, but not below 150: refused
        (env, {"rounds": 14, "max_memory_gb": small}),  # no drawn looks: never lowered
    ]
    for k, (keywords, hyperparams) in enumerate(cases):
        with pytest.raises(ValueError, match="over max_memory_gb"):
            train_imitation("dagger", "lift", tmp_path / str(k), env=keywords,
                            hyperparams=hyperparams)  # fmt: skip
        assert not (tmp_path / str(k)).exists()


def test_command_map_gives_the_action_that_holds_the_joints_where_they_are():
    env = gym.make("gym_soarm/LiftCube-v0", normalize_actions=True, control_mode="joint_pos")
    try:
        _obs, _ = env.reset(seed=0)
        scale, offset = command_map(env)
        q = env.unwrapped.physics.joint_angles()
        held = q * scale + offset
        for _ in range(10):
            env.step(held.astype(np.float32))
        assert np.allclose(env.unwrapped.physics.joint_angles()[:5], q[:5], atol=0.02)
    finally:
        env.close()


# --------------------------------------------------------------------------- training


@pytest.fixture(scope="module")
def dagger_lift(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("pixels") / "dagger"
    done = _cli(
        "gym_soarm.train", "--algo", "dagger", "--task", "lift", "--seed", "1",
        *PIXELS, *SIZE, "--eval-episodes", "1", "--out", str(out),
        "--hyperparams", *TINY, "rounds=1", "episodes_per_round=1", "round_epochs=1",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "done:" in done.stdout
    return out


def test_pixel_dagger_writes_a_folder_with_its_image_settings(dagger_lift):
    for name in (PIXEL_MODEL_FILE, "settings.json", "curve.csv", "curve.png"):
        assert (dagger_lift / name).is_file(), name
    settings = json.loads((dagger_lift / "settings.json").read_text())
    assert settings["policy"] == "pixels"
    assert settings["cameras"] == ["front_camera", "wrist_camera"]
    assert settings["image_size"] == [48, 64]
    assert settings["env"]["obs_type"] == "pixels_agent_pos"
    rows = (dagger_lift / "curve.csv").read_text().splitlines()
    assert rows[0].startswith("round,") and len(rows) == 3  # header, rounds 0 and 1
    # The auxiliary head (what the expert reads: the jaws, the cube from them, its yaw)
    # is saved with the network and its estimate feeds the action's MLP.
    import torch

    layout = torch.load(dagger_lift / PIXEL_MODEL_FILE, weights_only=True)["layout"]
    assert layout["aux_dim"] == 8 and layout["aux_input"] is True


def test_a_pixel_model_without_the_auxiliary_head_still_loads_and_acts(tmp_path):
    # model.pt as the package wrote it before the auxiliary targets: no aux keys.
    import torch

    from gym_soarm.rl.pixels import build_network

    cameras = ["front_camera", "wrist_camera"]
    net = build_network(cameras, 6, (4, 4, 4, 4), (16,), downsample=2)
    layout = {"cameras": cameras, "height": 48, "width": 64, "act_dim": 6,
              "channels": [4, 4, 4, 4], "hidden": [16], "downsample": 2}  # fmt: skip
    scale_offset = torch.stack([torch.ones(6), torch.zeros(6)])
    torch.save(
        {"layout": layout, "weights": net.state_dict(), "mean": torch.zeros(18),
         "std": torch.ones(18), "command_of_pos": scale_offset},
        tmp_path / PIXEL_MODEL_FILE,
    )  # fmt: skip
    policy = PixelPolicy.load(tmp_path)
    obs = {
        "pixels": {camera: np.full((48, 64, 3), 90, np.uint8) for camera in cameras},
        "agent_pos": np.zeros(6, np.float32),
    }
    action = policy(obs)
    assert action.shape == (6,) and np.all(np.abs(action) <= 1.0)
    assert policy.net.aux is None


@pytest.mark.subprocess
def test_pixel_dagger_stops_once_its_evaluation_stops_rising(tmp_path):
    out = tmp_path / "patience"
    done = _cli(
        "gym_soarm.train", "--algo", "dagger", "--task", "lift", "--seed", "0",
        *PIXELS, *SIZE, "--eval-episodes", "1", "--out", str(out),
        "--hyperparams", *TINY, "rounds=4", "patience=1", "episodes_per_round=1",
        "round_epochs=1",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    with open(out / "curve.csv") as stream:
        rates = [float(row["success_rate"]) for row in csv.DictReader(stream)]
    # Round r runs while the best so far is under 100 % and the last round beat it.
    expected = 1
    while (
        expected <= 4
        and max(rates[:expected]) < 1.0
        and (expected == 1 or rates[expected - 1] > max(rates[: expected - 1]))
    ):
        expected += 1
    assert len(rates) == min(expected, 5) < 5


@pytest.mark.subprocess
def test_pixel_policy_acts_on_rendered_observations_and_is_scored(dagger_lift):
    policy = TrainedPolicy(dagger_lift)
    env = make_env(policy.task, policy.settings["env"])
    try:
        obs, info = env.reset(seed=5)
        policy.reset()
        first = policy(obs, info)
        assert first.shape == (6,) and first.dtype == np.float32
        assert np.all(np.abs(first) <= 1.0)
        # Deterministic: the same observation after a reset gives the same action.
        policy.reset()
        assert np.array_equal(policy(obs, info), first)
    finally:
        env.close()
    result = score(policy.task, policy.settings["env"], policy, 1)
    assert result["episodes"] == 1 and 0.0 <= result["success_rate"] <= 1.0
    done = _cli("gym_soarm.evaluate", "--policy", str(dagger_lift), "--episodes", "1")
    assert done.returncode == 0, done.stderr
    assert "LiftCube-v0: success" in done.stdout


def test_pixel_policy_refuses_other_cameras_or_sizes_naming_both(dagger_lift):
    policy = PixelPolicy.load(dagger_lift)
    other = {
        "pixels": {"front_camera": np.zeros((96, 128, 3), np.uint8)},
        "agent_pos": np.zeros(6, np.float32),
    }
    with pytest.raises(ValueError, match=r"front_camera', 'wrist_camera'\] at 48x64.*96x128"):
        policy(other)
    with pytest.raises(ValueError, match="pixels_agent_pos"):
        policy(np.zeros(34, np.float32))


def test_interrupted_before_training_keeps_no_model_and_says_so(tmp_path):
    # A run folder whose Ctrl-C flag is already set: nothing is collected, nothing saved.
    from gym_soarm.rl.hyperparams import pixel_recipe
    from gym_soarm.rl.pixel_training import PixelTrainer
    from gym_soarm.rl.pixels import check_pixel_settings
    from gym_soarm.rl.runs import RunFolder
    from gym_soarm.tasks import get_task

    settings = check_pixel_settings("bc", pixel_recipe("bc", "LiftCube-v0"))
    folder = RunFolder(tmp_path, "interrupted").prepare()
    folder.stop.interrupted = True
    result = PixelTrainer("bc", get_task("lift"), folder, 0, settings).run()
    assert result.env_steps == 0 and result.success_rate is None and result.interrupted
    assert not (tmp_path / PIXEL_MODEL_FILE).exists()


def test_privileged_targets_are_what_the_expert_reads_relative_to_the_jaws():
    from gym_soarm.rl.pixels import privileged_targets

    env = make_env("LiftCube-v0", {"obs_type": "state"})
    try:
        _, info = env.reset(seed=3, options={"cube_rotation_deg": 30.0})
    finally:
        env.close()
    targets = privileged_targets(info)
    gripper, cube = np.asarray(info["gripper_pos"]), np.asarray(info["cube_pos"])
    # the jaws, the cube relative to them, then the yaw's (cos, sin) of four times it
    assert targets.shape == (8,) and targets.dtype == np.float32
    np.testing.assert_allclose(targets[:3], gripper, atol=1e-6)
    np.testing.assert_allclose(targets[3:6], cube - gripper, atol=1e-6)
    np.testing.assert_allclose(targets[6:], [np.cos(np.deg2rad(120)), np.sin(np.deg2rad(120))])
    push = {"gripper_pos": np.zeros(3), "cube_pos": np.ones(3), "cube_lifted": True}
    assert privileged_targets(push).tolist() == [0, 0, 0, 1, 1, 1, 1]


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("env", "hyperparams", "message"),
    [
        ({"obs_type": "pixels"}, None, "pixels_agent_pos"),
        ({"obs_type": "pixels_agent_pos", "control_mode": "joint_delta"}, None, "control_mode"),
        ({"obs_type": "pixels_agent_pos", "camera_config": ["sky_camera"]}, None, "sky_camera"),
        ({"obs_type": "pixels_agent_pos", "observation_height": 0}, None, "observation_height"),
        ({"obs_type": "pixels_agent_pos"}, {"max_memory_gb": 0.001}, "max_memory_gb"),
        ({"obs_type": "pixels_agent_pos"}, {"channels": [8, 8]}, "channels"),
        ({"obs_type": "pixels_agent_pos"}, {"shift_px": -1}, "shift_px"),
    ],
)
def test_bad_pixel_settings_are_refused_before_anything_is_written(
    tmp_path, env, hyperparams, message
):
    out = tmp_path / "run"
    with pytest.raises((ValueError, TypeError), match=message):
        train_imitation("bc", "lift", out, env=env, hyperparams=hyperparams)
    assert not out.exists()


@pytest.mark.parametrize(
    ("hyperparams", "message"),
    [
        ({"round_learning_rate": 0}, "round_learning_rate must be a finite number > 0"),
        ({"round_learning_rate": "fast"}, "round_learning_rate must be a finite number"),
        ({"patience": 0}, "patience must be an int"),
    ],
)
def test_bad_dagger_round_settings_are_refused_before_anything_is_written(
    tmp_path, hyperparams, message
):
    out = tmp_path / "run"
    env = {"obs_type": "pixels_agent_pos"}
    with pytest.raises((ValueError, TypeError), match=message):
        train_imitation("dagger", "lift", out, env=env, hyperparams=hyperparams)
    assert not out.exists()


def test_a_task_without_a_state_expert_is_refused(tmp_path):
    from gym_soarm.rl.imitation import check_pixel_student
    from gym_soarm.tasks import get_task

    scripted_only = dataclasses.replace(get_task("lift"), state_expert=None)
    with pytest.raises(ValueError, match="state expert"):
        check_pixel_student(scripted_only, {"obs_type": "pixels_agent_pos"})


@pytest.mark.subprocess
def test_cli_refuses_cameras_for_rl_and_a_gpu_for_state_policies(tmp_path):
    done = _cli(
        "gym_soarm.train", "--algo", "ppo", "--task", "lift", *PIXELS, "--out", str(tmp_path / "a")
    )
    assert done.returncode != 0 and "learns from the state vector" in done.stderr
    done = _cli(
        "gym_soarm.train", "--algo", "bc", "--task", "lift", "--device", "cuda",
        "--out", str(tmp_path / "b"),
    )  # fmt: skip
    assert done.returncode != 0 and "state policies train on the CPU" in done.stderr
    done = _cli(
        "gym_soarm.train", "--algo", "bc", "--task", "lift", *PIXELS, "--device", "tpu",
        "--out", str(tmp_path / "c"),
    )  # fmt: skip
    assert done.returncode != 0 and "device must be" in done.stderr
    assert not any((tmp_path / name).exists() for name in "abc")


def test_expert_labels_pixel_states_from_the_simulation():
    env = gym.make(
        "gym_soarm/LiftCube-v0",
        obs_type="pixels_agent_pos",
        observation_height=48,
        observation_width=64,
        normalize_actions=True,
        control_mode="joint_pos",
    )
    try:
        obs, info = env.reset(seed=0)
        expert = make_expert(env)
        action = expert(obs, info)
        assert action.shape == (6,) and np.all(np.abs(action) <= 1.0)
    finally:
        env.close()
