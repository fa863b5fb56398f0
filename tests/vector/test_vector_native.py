"""The native vector env (worker processes) against N single environments, bit for bit."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np
import pytest
from conftest import SMALL
from gymnasium.vector import AutoresetMode
from interrupt import interrupt_when
from paths import ROOT
from same import assert_same, compare_with_sync

import gym_soarm
from gym_soarm.vector.processes import SoArmVectorEnv, WorkerDiedError

ENV_ID = "gym_soarm/LiftCube-v0"
STATE = {"obs_type": "environment_state_agent_pos"}


def test_every_id_has_the_vector_entry_point():
    for env_id in gym_soarm.TASK_ENV_IDS:
        assert gym.spec(env_id).vector_entry_point == "gym_soarm.vector.batched:make_vector_env"


def test_pixels_match_single_envs_bit_for_bit():
    dones = compare_with_sync(
        ENV_ID,
        2,
        9,
        5,
        AutoresetMode.NEXT_STEP,
        max_episode_steps=4,
        camera_config="front_wrist",
        **SMALL,
    )
    assert sum(d.all() for d in dones) == 2


def test_uneven_blocks_over_two_processes_match_single_envs_bit_for_bit():
    # 5 environments in 2 processes: this one steps 2, the worker 3.
    dones = compare_with_sync(
        ENV_ID, 5, 30, 11, AutoresetMode.SAME_STEP, max_episode_steps=7, num_processes=2, **STATE
    )
    assert sum(d.all() for d in dones) == 4


def test_every_environment_in_this_process_matches_single_envs_bit_for_bit():
    dones = compare_with_sync(
        ENV_ID, 3, 25, 2, AutoresetMode.NEXT_STEP, max_episode_steps=6, num_processes=1, **STATE
    )
    assert sum(d.all() for d in dones) >= 3


def test_infos_that_change_layout_mid_run_batch_as_sync_does():
    # With randomised physics a reset's info adds a "variation" dict. Environments
    # reset at different steps (a reset mask staggers them), so in next-step mode some
    # send reset infos while the others send step infos, within one worker too.
    kwargs = {"max_episode_steps": 4, "physics_randomization": "light", **STATE}
    native = gym.make_vec(
        ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", num_processes=2, **kwargs
    )
    sync = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="sync", **kwargs)
    mixed = 0
    try:
        assert_same(native.reset(seed=8), sync.reset(seed=8), "reset")
        zeros = np.zeros((4, 6), np.float32)
        assert_same(native.step(zeros), sync.step(zeros), "step 0")
        mask = {"reset_mask": np.array([True, False, False, True])}
        assert_same(native.reset(seed=9, options=mask), sync.reset(seed=9, options=mask), "mask")
        for t in range(12):
            actions = np.full((4, 6), 0.05 * t, np.float32)
            got = native.step(actions)
            assert_same(got, sync.step(actions), f"step {t}")
            present = got[4].get("_variation", np.zeros(4, bool))
            mixed += bool(present.any() and not present.all())
    finally:
        native.close()
        sync.close()
    assert mixed >= 2


def test_cameras_render_in_the_worker_processes():
    envs = gym.make_vec(
        ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", num_processes=2, **SMALL
    )
    single = gym.make(ENV_ID, **SMALL)
    try:
        inner = envs.unwrapped
        assert inner.num_processes == 2 and len(inner.worker_pids) == 1
        assert inner.worker_pids[0] != os.getpid()
        obs, _ = envs.reset(seed=4)
        want, _ = single.reset(seed=6)  # the worker's environment 2
        frames = envs.call("render_camera_image", "front_camera")
        assert all(frame.shape == (48, 64, 3) for frame in frames)
        assert np.array_equal(frames[2], single.unwrapped.render_camera_image("front_camera"))
        assert np.array_equal(obs["pixels"]["front_camera"][2], want["pixels"]["front_camera"])
        assert obs["pixels"]["front_camera"][2].std() > 5.0  # a real picture
    finally:
        envs.close()
        single.close()


def test_attributes_and_calls_reach_every_process():
    envs = SoArmVectorEnv(3, num_processes=2, task="LiftCube-v0", **STATE)
    try:
        assert envs.get_attr("control_mode") == ("joint_pos",) * 3
        assert envs.get_attr("_max_episode_steps") == (None,) * 3
        envs.set_attr("custom_tag", ["a", "b", "c"])
        assert envs.get_attr("custom_tag") == ("a", "b", "c")
        envs.set_attr("custom_tag", 7)
        assert envs.call("custom_tag") == (7, 7, 7)
        with pytest.raises(AttributeError, match="no_such_method"):
            envs.call("no_such_method")
        envs.reset(seed=0)  # the error left every process in step
        envs.step(np.zeros((3, 6), np.float32))
    finally:
        envs.close()


def test_bad_seeds_actions_and_arguments_are_refused_before_anything_changes():
    envs = SoArmVectorEnv(2, num_processes=2, task="LiftCube-v0", **STATE)
    reference = SoArmVectorEnv(2, num_processes=1, task="LiftCube-v0", **STATE)
    try:
        with pytest.raises(ValueError, match="seed must be an int >= 0"):
            envs.reset(seed=[0, -1])
        with pytest.raises(ValueError, match="seed must be None, an int >= 0 or a list"):
            envs.reset(seed=1.5)
        assert_same(envs.reset(seed=np.int64(3)), reference.reset(seed=3), "reset")
        bad = np.zeros((2, 6), np.float32)
        bad[1, 2] = np.nan
        with pytest.raises(ValueError, match=r"environments \[1\]"):
            envs.step(bad)
        for wrong in (np.full((2, 6), "x"), np.full((2, 6), 1j)):
            with pytest.raises(ValueError, match="real numbers"):
                envs.step(wrong)
        with pytest.raises(TypeError, match="cannot travel to the worker processes"):
            envs.set_attr("callback", lambda: None)
        good = np.full((2, 6), 0.1, np.float32)
        assert_same(envs.step(good), reference.step(good), "after the refused steps")
    finally:
        envs.close()
        reference.close()


def test_a_worker_that_dies_raises_a_clear_error_and_leaves_no_process():
    envs = SoArmVectorEnv(4, num_processes=2, task="LiftCube-v0", **STATE)
    envs.reset(seed=0)
    (pid,) = envs.worker_pids
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(
        WorkerDiedError, match=r"pid \d+, environments 2-3\) died with signal SIGKILL"
    ):
        envs.step(np.zeros((4, 6), np.float32))
    assert envs.closed
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((4, 6), np.float32))
    assert not _alive(pid)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_close_closes_every_env_and_ends_every_worker():
    envs = gym.make_vec(
        ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", num_processes=2, **SMALL
    )
    envs.reset(seed=0)
    inner = envs.unwrapped
    pids = inner.worker_pids
    assert len(pids) == 1 and _alive(pids[0])
    envs.close()
    assert envs.closed
    assert all(env._closed for env in inner._local.envs)
    deadline = time.monotonic() + 5.0
    while any(_alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in pids)
    envs.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((4, 6), np.float32))


def test_an_unclosed_vector_env_ends_its_workers_when_collected():
    envs = SoArmVectorEnv(2, num_processes=2, task="LiftCube-v0", **STATE)
    (pid,) = envs.worker_pids
    del envs
    import gc

    gc.collect()
    assert not _alive(pid)


def test_bad_arguments_name_what_was_expected():
    with pytest.raises(ValueError, match="num_envs"):
        SoArmVectorEnv(0, **STATE)
    with pytest.raises(ValueError, match="autoreset_mode"):
        SoArmVectorEnv(1, autoreset_mode="sometimes", **STATE)
    with pytest.raises(ValueError, match="num_processes"):
        SoArmVectorEnv(2, num_processes=0, **STATE)
    with pytest.raises(ValueError, match="start_method"):
        SoArmVectorEnv(2, start_method="fork", **STATE)
    with pytest.raises(ValueError, match="obs_type"):
        SoArmVectorEnv(2, num_processes=2, obs_type="telepathy")  # before any worker starts
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", **STATE)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            envs.step(np.zeros((2, 6), np.float32))
        envs.reset(seed=0)
        with pytest.raises(ValueError, match=r"shape \(2, 6\)"):
            envs.step(np.zeros(6, np.float32))
        with pytest.raises(ValueError, match="num_envs=2"):
            envs.reset(seed=[1, 2, 3])
    finally:
        envs.close()


@pytest.mark.subprocess
def test_the_vector_env_example_runs_as_a_user_runs_it():
    script = ROOT / "examples" / "vector_env.py"
    done = subprocess.run(
        [sys.executable, str(script), "--num-envs", "3", "--steps", "40"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "3 x gym_soarm/LiftCube-v0 in one mujoco.batch on" in done.stdout, done.stdout
    assert "vector env:" in done.stdout and "one env:" in done.stdout
    bad = subprocess.run(
        [sys.executable, str(script), "--num-envs", "0"], capture_output=True, text=True, timeout=60
    )
    assert bad.returncode == 2 and "--num-envs and --steps must be >= 1; got 0" in bad.stderr


def test_a_block_that_raises_leaves_the_others_readable():
    # The first step brings each block's info layout; the worker's block raises, this
    # process's block steps. The next step must still read this block's infos.
    envs = SoArmVectorEnv(4, num_processes=2, task="LiftCube-v0", **STATE)
    try:
        envs.reset(seed=0)
        assert envs.call_some([3], "__setattr__", "_check_open", None) == {3: None}
        with pytest.raises(TypeError, match="not callable"):
            envs.step(np.zeros((4, 6), np.float32))
        envs.call_some([3], "__delattr__", "_check_open")
        _, _, _, _, info = envs.step(np.zeros((4, 6), np.float32))
        assert info["_is_success"].all() and info["task"].shape == (4,)
        with pytest.raises(ValueError, match="index must be an int from 0 to 3"):
            envs.call_some([4], "task_description")
    finally:
        envs.close()


def test_a_step_that_raises_part_way_counts_only_the_steps_taken():
    # Rows 0 and 1 step here, 2 in the worker, then 3 raises there: the time limit's
    # count goes on for the three that stepped, not for the one that did not.
    envs = SoArmVectorEnv(4, num_processes=2, max_episode_steps=5, task="LiftCube-v0", **STATE)
    zeros = np.zeros((4, 6), np.float32)
    try:
        envs.reset(seed=0)
        envs.call_some([3], "__setattr__", "_check_open", None)
        with pytest.raises(TypeError, match="not callable"):
            envs.step(zeros)
        np.testing.assert_array_equal(envs._clock.elapsed, [1, 1, 1, 0])
        envs.call_some([3], "__delattr__", "_check_open")
        envs.step(zeros)
        np.testing.assert_array_equal(envs._clock.elapsed, [2, 2, 2, 1])
    finally:
        envs.close()


CTRL_C_SCRIPT = """
import sys, numpy as np
from gym_soarm.vector.processes import SoArmVectorEnv
if __name__ == "__main__":
    envs = SoArmVectorEnv(4, num_processes=2, task="LiftCube-v0", obs_type="state")
    envs.reset(seed=0)
    print("pids", *envs.worker_pids, flush=True)
    try:
        while True:
            envs.step(np.zeros((4, 6), np.float32))
    except KeyboardInterrupt:
        # Mid-call the vector env closes itself (its workers may still be writing);
        # between calls nothing is out of step and it goes on.
        if not envs.closed:
            envs.step(np.zeros((4, 6), np.float32))
        envs.close()
        print("interrupted and closed", flush=True)
"""


@pytest.mark.subprocess
def test_ctrl_c_in_the_middle_of_a_step_closes_the_vector_env(tmp_path):
    script = tmp_path / "ctrl_c.py"
    script.write_text(CTRL_C_SCRIPT)
    pids: list[int] = []

    def stepping(process) -> bool:  # the script's first line names its workers
        first = process.stdout.readline()
        pids.extend(int(p) for p in first.split()[1:])
        return first.startswith("pids")

    done = interrupt_when(
        [sys.executable, str(script)], stepping, within_s=120, then_s=0.5, what="its workers"
    )
    assert "interrupted and closed" in done.stdout, done.stderr
    assert done.returncode == 0, done.stderr
    assert pids and not any(_alive(pid) for pid in pids)
