"""The contract of every vector env of the package (``vector_env``: ``batched``,
``processes``, ``warp``), one suite run against each.

The reference is Gymnasium's ``SyncVectorEnv`` of single ``gym.make`` environments: the
same spaces, metadata, time limit, autoreset in its three modes (``final_obs`` and
``final_info`` in ``SAME_STEP``), reset masks, and the same refusals before anything
steps. The batched and process envs give its episodes bit for bit; the Warp worlds
(float32 physics on Warp's CPU device here) give the same structure, ends and resets,
their floating-point values within 0.05 (velocities included; ``tests/sim/test_warp.py``
holds positions to 2 mm).
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from same import assert_same

from gym_soarm.sim.warp_backend import warp_available

ENV_ID = "gym_soarm/ReachTarget-v0"
STATE = {"obs_type": "state"}
N = 3


# Warp is an extra: skipped without it, unless GYM_SOARM_REQUIRE_WARP=1 (CI) says it
# must be there, when the tests fail instead.
_NO_WARP = not warp_available() and os.environ.get("GYM_SOARM_REQUIRE_WARP") != "1"
VECTOR_ENVS = [
    "batched",
    "processes",
    pytest.param(
        "warp",
        marks=pytest.mark.skipif(_NO_WARP, reason='MuJoCo Warp: pip install "gym-soarm[warp]"'),
    ),
]


def _make(vector_env: str, n: int = N, **kwargs):
    if vector_env == "warp":
        kwargs["device"] = "cpu"
    if vector_env == "processes":
        kwargs["num_processes"] = 2
    return gym.make_vec(
        ENV_ID,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        vector_env=vector_env,
        **STATE,
        **kwargs,
    )


def _sync(n: int = N, mode: AutoresetMode = AutoresetMode.NEXT_STEP, **kwargs):
    return gym.make_vec(
        ENV_ID,
        num_envs=n,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        **STATE,
        **kwargs,
    )


def _like(got, want, vector_env: str, where: str) -> None:
    """Exactly the reference's values; Warp's floating-point values within 0.05."""
    assert_same(got, want, where, atol=5e-2 if vector_env == "warp" else 0.0)


def _run_beside_sync(vector_env: str, mode: AutoresetMode, steps: int, limit: int):
    """Step the vector env and the reference with the same actions; each step's ends."""
    envs = _make(vector_env, autoreset_mode=mode, max_episode_steps=limit)
    sync = _sync(mode=mode, max_episode_steps=limit)
    ends = []
    try:
        assert envs.metadata["autoreset_mode"] == mode
        assert envs.observation_space == sync.observation_space
        assert envs.action_space == sync.action_space
        got, want = envs.reset(seed=7), sync.reset(seed=7)
        assert_same(got, want, "reset")  # every env resets on its own MjData
        rng = np.random.default_rng(7)
        for t in range(steps):
            actions = rng.uniform(-1.0, 1.0, (N, 6)).astype(np.float32)
            got, want = envs.step(actions), sync.step(actions)
            for name, x, y in zip(("obs", "rew", "term", "trunc"), got, want, strict=False):
                _like(x, y, vector_env, f"step {t} {name}")
            info = {k: v for k, v in got[4].items() if k not in ("final_obs", "final_info")}
            expected = {k: v for k, v in want[4].items() if k not in ("final_obs", "final_info")}
            _like(info, expected, vector_env, f"step {t} info")
            assert ("final_obs" in got[4]) == ("final_obs" in want[4]), t
            if "final_obs" in want[4]:
                assert_same(got[4]["_final_obs"], want[4]["_final_obs"], f"step {t} mask")
                for i in np.flatnonzero(want[4]["_final_obs"]):
                    _like(got[4]["final_obs"][i], want[4]["final_obs"][i], vector_env, "final")
            assert got[1].dtype == np.float64 and got[2].dtype == got[3].dtype == np.bool_
            ends.append(got[2] | got[3])
    finally:
        envs.close()
        sync.close()
    return ends


@pytest.mark.parametrize("vector_env", VECTOR_ENVS)
def test_next_step_autoreset_and_time_limit_as_single_envs(vector_env):
    ends = _run_beside_sync(vector_env, AutoresetMode.NEXT_STEP, steps=14, limit=6)
    # Truncated at step 6, reset on step 7 instead of stepping, truncated again at 13.
    assert [int(e.sum()) for e in ends].count(N) >= 2


@pytest.mark.parametrize("vector_env", VECTOR_ENVS)
def test_same_step_autoreset_hands_the_final_obs_and_info(vector_env):
    ends = _run_beside_sync(vector_env, AutoresetMode.SAME_STEP, steps=10, limit=4)
    assert [int(e.sum()) for e in ends].count(N) == 2


@pytest.mark.parametrize("vector_env", VECTOR_ENVS)
def test_disabled_mode_refuses_an_ended_episode_until_its_reset(vector_env):
    envs = _make(vector_env, n=2, autoreset_mode="Disabled", max_episode_steps=3)
    try:
        envs.reset(seed=1)
        zeros = np.zeros((2, 6), np.float32)
        for _ in range(3):
            *_, truncated, _ = envs.step(zeros)
        assert truncated.all()
        with pytest.raises(RuntimeError, match="reset_mask"):
            envs.step(zeros)
        _, info = envs.reset(options={"reset_mask": np.array([True, False])})
        assert info["_is_success"].tolist() == [True, False]
        with pytest.raises(RuntimeError, match=r"\[1\]"):
            envs.step(zeros)
        envs.reset(options={"reset_mask": np.array([False, True])})
        *_, truncated, _ = envs.step(zeros)
        assert not truncated.any()
    finally:
        envs.close()


@pytest.mark.parametrize("vector_env", VECTOR_ENVS)
def test_bad_actions_are_refused_before_anything_steps(vector_env):
    envs, sync = _make(vector_env), _sync()
    try:
        with pytest.raises(RuntimeError, match=r"reset\(\) before step\(\)"):
            envs.step(np.zeros((N, 6), np.float32))
        envs.reset(seed=3)
        sync.reset(seed=3)
        with pytest.raises(ValueError, match=r"shape \(3, 6\)"):
            envs.step(np.zeros((N, 5), np.float32))
        nan = np.zeros((N, 6), np.float32)
        nan[1, 2] = np.nan
        with pytest.raises(ValueError, match=r"NaN|finite"):
            envs.step(nan)
        actions = np.full((N, 6), 0.1, np.float32)
        got, want = envs.step(actions), sync.step(actions)  # as if nothing had been sent
        _like(got[0], want[0], vector_env, "obs after refusals")
    finally:
        envs.close()
        sync.close()


@pytest.mark.parametrize("vector_env", VECTOR_ENVS)
def test_attributes_calls_and_close(vector_env):
    envs = _make(vector_env, max_episode_steps=5)
    envs.reset(seed=0)
    try:
        assert envs.get_attr("_max_episode_steps") == (5,) * N
        descriptions = envs.call("task_description")
        assert len(descriptions) == N and all(isinstance(d, str) and d for d in descriptions)
        envs.set_attr("spec_note", ["a", "b", "c"])
        assert envs.get_attr("spec_note") == ("a", "b", "c")
        assert envs.render() is None  # no render_mode asked
    finally:
        envs.close()
    envs.close()  # twice is fine
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((N, 6), np.float32))
