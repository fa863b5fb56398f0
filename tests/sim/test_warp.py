"""vector_env="warp": the batched vector env on MuJoCo Warp, tested on Warp's CPU device
(``GYM_SOARM_WARP_DEVICE=cuda`` runs the same tests on a GPU: its CUDA-graph path).

Warp computes in float32, so a world is compared with C MuJoCo's float64 simulation of
the same actions (the batched env on ``mujoco.batch``) within tolerances, never bit for
bit. The first test in a fresh kernel cache compiles Warp's kernels (about a minute).
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm.sim.warp_backend import warp_available
from gym_soarm.tasks import BUILTIN_TASKS

if not warp_available():
    if os.environ.get("GYM_SOARM_REQUIRE_WARP") == "1":
        raise ImportError(
            'GYM_SOARM_REQUIRE_WARP=1 but MuJoCo Warp is not installed: pip install -e ".[warp]"'
        )
    pytest.skip('MuJoCo Warp: pip install "gym-soarm[warp]"', allow_module_level=True)

N = 3
DEVICE = os.environ.get("GYM_SOARM_WARP_DEVICE", "cpu")


def _make(task: str, vector_env: str, **kwargs):
    if vector_env == "warp":
        kwargs.setdefault("device", DEVICE)
    return gym.make_vec(
        f"gym_soarm/{task}",
        num_envs=N,
        vectorization_mode="vector_entry_point",
        vector_env=vector_env,
        obs_type="state",
        **kwargs,
    )


@pytest.mark.parametrize("task", BUILTIN_TASKS)
def test_every_task_steps_on_warp_as_on_mujoco(task):
    warp, ref = _make(task, "warp"), _make(task, "batched")
    try:
        obs_w, _ = warp.reset(seed=5)
        obs_c, _ = ref.reset(seed=5)
        np.testing.assert_array_equal(obs_w, obs_c)  # resets run on each env's own MjData
        rng = np.random.default_rng(0)
        for _ in range(4):
            actions = rng.uniform(-0.2, 0.2, (N, 6))
            obs_w, reward_w, term_w, _, info_w = warp.step(actions)
            obs_c, reward_c, term_c, _, _ = ref.step(actions)
            assert np.isfinite(obs_w).all()
            # Joint angles, targets and positions (not velocities) to 2 mm or mrad (float32; a drawer slides freely).
            names = warp.envs[0].observation_names
            still = [k for k, name in enumerate(names) if "vel" not in name]
            np.testing.assert_allclose(obs_w[:, still], obs_c[:, still], atol=2e-3)
            np.testing.assert_allclose(
                reward_w, reward_c, atol=2e-2
            )  # dense rewards in [0, 1]; a drawer drifts in float32
            np.testing.assert_array_equal(term_w, term_c)
            assert not info_w["physics_unstable"].any()
    finally:
        warp.close()
        ref.close()


def test_a_worlds_task_arrays_equal_the_numpy_task_code_on_its_state():
    warp = _make("LiftCube-v0", "warp")
    try:
        warp.reset(seed=1)
        rng = np.random.default_rng(1)
        for _ in range(3):
            obs, *_ = warp.step(rng.uniform(-0.3, 0.3, (N, 6)))
        for i in range(N):
            # World i copied into environment i's own MjData, scored there by the same task.
            single = warp.call_some([i], "observation")[i]
            np.testing.assert_allclose(single, obs[i], atol=1e-5)
    finally:
        warp.close()


def test_the_state_expert_lifts_the_cube_in_warp_worlds():
    import gym_soarm

    warp = _make("LiftCube-v0", "warp")
    try:
        warp.reset(seed=0)
        expert = gym_soarm.make_expert(warp)  # each world's state expert, one batch a call
        lifted = np.zeros(N, dtype=bool)
        for _ in range(warp.envs[0].step_limit):
            _, _, terminated, truncated, _ = warp.step(expert())
            lifted |= terminated
            if lifted.all() or truncated.any():
                break
        assert lifted.sum() >= N - 1, f"{lifted.sum()} of {N} Warp worlds lifted the cube"
    finally:
        warp.close()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"device": "tpu"}, "device must be"),
        ({"device": "cuda:7"}, "not on this machine"),
        ({"physics_randomization": "light"}, "physics_randomization='light'"),
    ],
)
def test_bad_devices_and_settings_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _make("LiftCube-v0", "warp", **kwargs)


def test_a_device_without_warp_is_refused():
    with pytest.raises(ValueError, match="vector_env='warp'"):
        _make("LiftCube-v0", "batched", device="cpu")


def test_the_warp_benchmark_reports_physics_env_and_batched_rates(tmp_path):
    from gym_soarm.cli import bench_warp

    out = tmp_path / "warp.json"
    bench_warp.main(
        [
            "--worlds",
            "2",
            "--device",
            "cpu",
            "--seconds",
            "0.2",
            "--repeats",
            "1",
            "--batched-worlds-max",
            "2",
            "--json",
            str(out),
        ]
    )
    import json

    report = json.loads(out.read_text())
    (row,) = report["rows"]
    assert row["worlds"] == 2 and row["physics"]["finite"]
    for key in ("physics", "env", "batched"):
        assert row[key]["rate"] > 0
    assert row["env_to_physics"] == row["env"]["rate"] / row["physics"]["rate"]
    from gym_soarm.bench.bench_warp import format_table

    assert "| 2 |" in format_table(report)


@pytest.mark.parametrize("worlds", ["0", "a,b", ""])
def test_the_warp_benchmark_refuses_bad_world_counts(worlds, capsys):
    from gym_soarm.cli import bench_warp

    with pytest.raises(SystemExit):
        bench_warp.main(["--worlds", worlds, "--device", "cpu"])
    assert "numbers of worlds" in capsys.readouterr().err
