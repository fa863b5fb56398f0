"""control_hz: any control rate whose period whole physics steps fill (SPEC section 28)."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.record.record import record
from gym_soarm.sim.timing import control_rates, control_timing


def test_the_default_rate_is_fifty_hertz_of_two_millisecond_steps():
    env = gym.make("gym_soarm/LiftCube-v0", obs_type="state")
    base = env.unwrapped
    assert base.control_hz == 50 and env.metadata["render_fps"] == 50
    assert base.dt == pytest.approx(0.02)
    assert base.physics.model.opt.timestep == 0.002
    env.close()


def test_thirty_hertz_steps_twenty_physics_steps_of_a_six_hundredth():
    env = gym.make("gym_soarm/LiftCube-v0", obs_type="state", control_hz=30)
    base = env.unwrapped
    assert env.metadata["render_fps"] == 30 and base.metadata["render_fps"] == 30
    assert base.dt == pytest.approx(1 / 30)
    assert base.physics.model.opt.timestep == pytest.approx(1 / 600)
    assert (base.timing.physics_hz, base.timing.substeps) == (600, 20)
    env.reset(seed=0)
    for _ in range(30):
        env.step(env.action_space.sample())
    assert base.physics.data.time == pytest.approx(1.0)  # 30 steps are one second
    # The class's metadata is not touched: another env keeps its own rate.
    assert gym_soarm.SoArmEnv.metadata["render_fps"] == 50
    env.close()


def test_the_rates_that_work():
    rates = control_rates()
    assert {10, 20, 25, 30, 50, 60, 100} <= set(rates)
    assert 33 not in rates and 7 not in rates
    for hz in rates:
        timing = control_timing(hz)
        assert timing.substeps * hz == timing.physics_hz


@pytest.mark.parametrize("bad", [33, 0, -30, 30.5, 1000, "30", True, None])
def test_a_rate_the_physics_cannot_divide_is_refused_naming_the_ones_that_work(bad):
    with pytest.raises((ValueError, TypeError), match="Rates that work: 1, 2, 3") as caught:
        gym.make("gym_soarm/LiftCube-v0", obs_type="state", control_hz=bad)
    assert "30" in str(caught.value) and "50" in str(caught.value)


def test_the_expert_lifts_the_cube_at_thirty_hertz_in_the_same_time():
    seconds = {}
    for hz in (50, 30):
        env = gym.make("gym_soarm/LiftCube-v0", obs_type="state", control_hz=hz)
        expert = gym_soarm.make_expert(env)
        obs, info = env.reset(seed=4)
        steps = 0
        while not info.get("is_success") and steps < 250:
            obs, _, _, _, info = env.step(expert(obs, info))
            steps += 1
        assert info["is_success"]
        seconds[hz] = steps / hz
        env.close()
    # The expert's speeds are per second, not per step: the lift takes about as long.
    assert seconds[30] == pytest.approx(seconds[50], rel=0.25)


def test_the_batched_env_at_thirty_hertz_matches_single_envs():
    kwargs = {"obs_type": "state", "control_hz": 30}
    envs = gym.make_vec(
        "gym_soarm/LiftCube-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs
    )
    singles = [gym.make("gym_soarm/LiftCube-v0", **kwargs) for _ in range(2)]
    assert envs.metadata["render_fps"] == 30
    obs, _ = envs.reset(seed=[3, 4])
    for env, seed in zip(singles, (3, 4), strict=True):
        env.reset(seed=seed)
    rng = np.random.default_rng(0)
    for _ in range(5):
        actions = rng.uniform(envs.action_space.low, envs.action_space.high).astype(np.float32)
        obs, *_ = envs.step(actions)
        for i, env in enumerate(singles):
            single, *_ = env.step(actions[i])
            np.testing.assert_array_equal(obs[i], single)
    envs.close()
    for env in singles:
        env.close()


def test_a_recording_at_thirty_hertz_has_thirty_frames_a_second(tmp_path):
    root = tmp_path / "rec30"
    settings = EnvSettings(task="LiftCube-v0", control_hz=30, units="lerobot")
    summary = record(root, episodes=1, seed=0, camera_config="none", settings=settings)
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["fps"] == 30 and summary.episodes == 1
    import pyarrow.parquet as pq

    table = pq.read_table(next((root / "data").rglob("*.parquet")))
    stamps = np.asarray(table.column("timestamp"))
    np.testing.assert_allclose(np.diff(stamps), 1 / 30, rtol=1e-5)
