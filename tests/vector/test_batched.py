"""The batched vector env: one ``mujoco.batch`` for every simulation, tasks scored as arrays.

It must give the episodes of single ``gym.make`` environments bit for bit (observations,
rewards, terminations, truncations and infos, batched as Gymnasium batches them) in
every autoreset mode and setting, refuse bad input before anything steps, and end a
diverged simulation's episode alone.
"""

from __future__ import annotations

import dataclasses
import os
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from same import assert_same

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.sim.arrays import SimArrays
from gym_soarm.tasks.registry import unregister_task
from gym_soarm.vector.batched import BatchedVectorEnv, wants_batched
from gym_soarm.vector.processes import SoArmVectorEnv

TASKS = gym_soarm.task_names()
STATE = {"obs_type": "state"}


def _vec(task: str, n: int, vector_env: str, **kwargs):
    return gym.make_vec(
        f"gym_soarm/{task}",
        num_envs=n,
        vectorization_mode="vector_entry_point",
        vector_env=vector_env,
        **kwargs,
    )


@pytest.mark.parametrize("task", TASKS)
def test_each_task_gives_the_episodes_of_single_envs_driven_by_their_experts(task):
    n, seed, steps = 2, 7, 90
    singles = [gym.make(f"gym_soarm/{task}", **STATE) for _ in range(n)]
    batched = _vec(task, n, "batched", **STATE)
    try:
        assert isinstance(batched, BatchedVectorEnv)
        obs, info = batched.reset(seed=seed)
        single_obs, experts = [], []
        for i, env in enumerate(singles):
            o, single_info = env.reset(seed=seed + i)
            single_obs.append(o)
            experts.append(make_expert(env))
            assert info["is_success"][i] == single_info["is_success"]
            assert info["reward_terms"]["_" + next(iter(single_info["reward_terms"]))][i]
        np.testing.assert_array_equal(obs, np.stack(single_obs))
        restart = [False] * n
        ended_any = False
        for _ in range(steps):
            actions = np.stack([expert(o) for expert, o in zip(experts, single_obs, strict=True)])
            obs, rewards, terminated, truncated, info = batched.step(actions)
            for i, env in enumerate(singles):
                if restart[i]:  # NEXT_STEP: the batched env reset it instead of stepping
                    o, single_info = env.reset()
                    experts[i] = make_expert(env)
                    r, term, trunc = 0.0, False, False
                else:
                    o, r, term, trunc, single_info = env.step(actions[i])
                single_obs[i] = o
                np.testing.assert_array_equal(obs[i], o)
                assert (rewards[i], terminated[i], truncated[i]) == (r, term, trunc)
                for key, value in single_info.items():
                    if isinstance(value, dict):
                        for name, term_value in value.items():
                            assert info[key][name][i] == term_value, (key, name)
                    else:
                        assert_same(info[key][i], value, key)
                restart[i] = term or trunc
                ended_any |= term
        if task in ("ReachTarget-v0", "LiftCube-v0", "OpenDrawer-v0", "PickColoredCube-v0"):
            assert ended_any  # a success was compared, and the autoreset after it
    finally:
        batched.close()
        for env in singles:
            env.close()


SETTINGS = [
    {"obs_type": "state", "control_mode": "ee_delta"},
    {"obs_type": "state", "control_mode": "joint_delta", "normalize_actions": False},
    {"obs_type": "state", "control_mode": "joint_pos", "normalize_actions": False},
    {"obs_type": "environment_state_agent_pos", "units": "lerobot"},
    {"obs_type": "state", "physics_randomization": "heavy", "visual_randomization": "light"},
    {"obs_type": "state", "servo_model": "sts3215", "reward_type": "sparse", "distractors": 2},
    {"obs_type": "pixels_agent_pos", "observation_height": 48, "observation_width": 64},
]


@pytest.mark.parametrize("kwargs", SETTINGS, ids=lambda k: "-".join(map(str, k.values())))
@pytest.mark.parametrize("mode", list(AutoresetMode))
def test_every_setting_and_autoreset_mode_matches_the_process_env(kwargs, mode):
    n, limit = 3, 12
    common = dict(autoreset_mode=mode, max_episode_steps=limit, **kwargs)
    reference = _vec("LiftCube-v0", n, "processes", num_processes=1, **common)
    batched = _vec("LiftCube-v0", n, "batched", **common)
    try:
        assert_same(reference.reset(seed=3), batched.reset(seed=3))
        rng = np.random.default_rng(0)
        for _ in range(2 * limit + 3):
            if mode is AutoresetMode.DISABLED and reference._clock.ended.any():
                mask = reference._clock.ended.copy()
                options = {"reset_mask": mask}
                assert_same(reference.reset(options=options), batched.reset(options=options))
            actions = rng.uniform(-0.5, 0.5, reference.action_space.shape)
            assert_same(reference.step(actions), batched.step(actions))
    finally:
        reference.close()
        batched.close()


def test_auto_batches_state_and_leaves_pixels_and_process_arguments_to_processes():
    envs = []
    try:
        envs.append(
            gym.make_vec(
                "gym_soarm/LiftCube-v0",
                num_envs=2,
                vectorization_mode="vector_entry_point",
                **STATE,
            )
        )
        assert isinstance(envs[-1], BatchedVectorEnv)
        envs.append(_vec("LiftCube-v0", 2, "auto", num_processes=1, **STATE))
        assert isinstance(envs[-1], SoArmVectorEnv)
        envs.append(
            _vec(
                "LiftCube-v0",
                2,
                "auto",
                obs_type="pixels",
                observation_height=32,
                observation_width=32,
            )
        )
        assert isinstance(envs[-1], SoArmVectorEnv)
    finally:
        for env in envs:
            env.close()


def test_bad_input_is_refused_before_anything_steps():
    with pytest.raises(ValueError, match="vector_env must be one of"):
        _vec("LiftCube-v0", 2, "threads", **STATE)
    with pytest.raises(ValueError, match=r"num_processes .*vector_env='processes'"):
        _vec("LiftCube-v0", 2, "batched", num_processes=2, **STATE)
    with pytest.raises(ValueError, match="num_threads"):
        BatchedVectorEnv(2, num_threads=0, task="LiftCube-v0", **STATE)
    envs = _vec("LiftCube-v0", 3, "batched", **STATE)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            envs.step(np.zeros((3, 6)))
        envs.reset(seed=0)
        qpos = np.array(envs.unwrapped._sim.qpos)
        with pytest.raises(ValueError, match=r"shape \(3, 6\)"):
            envs.step(np.zeros((2, 6)))
        bad = np.zeros((3, 6))
        bad[1, 2] = np.nan
        with pytest.raises(ValueError, match=r"environments \[1\] hold NaN"):
            envs.step(bad)
        with pytest.raises(ValueError, match="real numbers"):
            envs.step(np.full((3, 6), "a"))
        np.testing.assert_array_equal(envs.unwrapped._sim.qpos, qpos)  # nothing stepped
        again, *_ = envs.step(np.zeros((3, 6)))
        reference = _vec("LiftCube-v0", 3, "batched", **STATE)
        reference.reset(seed=0)
        expected, *_ = reference.step(np.zeros((3, 6)))
        reference.close()
        np.testing.assert_array_equal(again, expected)
    finally:
        envs.close()
    with pytest.raises(RuntimeError, match="closed"):
        envs.step(np.zeros((3, 6)))
    envs.close()  # idempotent


def test_a_diverged_simulation_ends_its_own_episode_and_the_others_go_on():
    envs = _vec("LiftCube-v0", 3, "batched", **STATE)
    reference = _vec("LiftCube-v0", 3, "batched", **STATE)
    try:
        envs.reset(seed=4)
        reference.reset(seed=4)
        actions = np.zeros((3, 6))
        before, *_ = envs.step(actions)
        reference.step(actions)
        envs.unwrapped._sim.qvel[1, :] = 1e30  # environment 1 explodes
        with pytest.warns(RuntimeWarning, match="environment 1 diverged"):
            obs, rewards, terminated, truncated, info = envs.step(actions)
        expected = reference.step(actions)
        assert truncated.tolist() == [False, True, False] and not terminated[1]
        assert rewards[1] == 0.0 and info["physics_unstable"].tolist() == [False, True, False]
        assert set(info["reward_terms"][k][1] for k in ("reach", "grasp", "lift")) == {0.0}
        np.testing.assert_array_equal(obs[1], before[1])  # the last sound observation
        for i in (0, 2):
            np.testing.assert_array_equal(obs[i], expected[0][i])
            assert rewards[i] == expected[1][i]
        obs, rewards, *_, info = envs.step(actions)  # NEXT_STEP: environment 1 starts again
        assert rewards[1] == 0.0 and np.isfinite(obs).all() and not info["physics_unstable"][1]
    finally:
        envs.close()
        reference.close()


def test_call_and_get_attr_see_each_environment_as_the_batch_left_it():
    envs = _vec("PushCube-v0", 2, "batched", **STATE)
    single = gym.make("gym_soarm/PushCube-v0", **STATE)
    try:
        envs.reset(seed=11)
        single.reset(seed=12)
        rng = np.random.default_rng(1)
        for _ in range(5):
            actions = rng.uniform(-1, 1, (2, 6))
            envs.step(actions)
            single.step(actions[1])
        physics = envs.get_attr("physics")[1]
        np.testing.assert_array_equal(physics.data.qpos, single.unwrapped.physics.data.qpos)
        snapshot = envs.call("save_state")[1]
        after, *_ = envs.step(actions)
        single.reset(options={"state": snapshot})
        expected, *_ = single.step(actions[1])
        np.testing.assert_array_equal(after[1], expected)
        limit = gym_soarm.get_task("PushCube-v0").max_episode_steps
        assert envs.get_attr("_max_episode_steps") == (limit, limit)
    finally:
        envs.close()
        single.close()


TORCH = os.environ.get("GYM_SOARM_REQUIRE_RL") == "1"


@pytest.mark.parametrize("task", TASKS)
def test_the_tasks_array_code_runs_on_torch_tensors_as_on_numpy(task):
    torch = pytest.importorskip("torch") if not TORCH else __import__("torch")
    envs = _vec(task, 4, "batched", **STATE)
    try:
        envs.reset(seed=2)
        rng = np.random.default_rng(0)
        for _ in range(15):
            envs.step(rng.uniform(-1, 1, (4, 6)))
        inner = envs.unwrapped
        sim, logic = inner._sim, inner._task
        arrays = {
            name: getattr(sim, name)
            for name in ("qpos", "qvel", "qacc", "site_xpos", "geom_xpos", "sensordata")
        }
        as_torch = SimArrays(
            sim.index,
            {k: torch.from_numpy(np.array(v)) for k, v in arrays.items()},
            {k: torch.from_numpy(np.array(v)) for k, v in sim.episode.items()},
        )
        as_numpy = SimArrays(
            sim.index,
            {k: np.array(v) for k, v in arrays.items()},
            {k: np.array(v) for k, v in sim.episode.items()},
        )
        results = []
        for s in (as_numpy, as_torch):
            evaluation = logic.evaluate(s)
            results.append(
                {
                    "evaluation": evaluation,
                    "terms": logic.batch_reward_terms(evaluation),
                    "state": logic.batch_state(s),
                    "info": logic.compute_info(s, evaluation),
                    "episode": s.episode,
                }
            )
        numpy_result, torch_result = results
        assert isinstance(torch_result["state"], torch.Tensor)

        def check(a, b, path):
            if isinstance(a, dict):
                for key in a:
                    check(a[key], b[key], f"{path}/{key}")
            elif isinstance(a, list):
                assert a == b, path
            else:
                assert isinstance(b, torch.Tensor), path
                np.testing.assert_allclose(b.numpy(), a, rtol=1e-12, atol=1e-12, err_msg=path)

        check(numpy_result, torch_result, task)
    finally:
        envs.close()


def test_the_sb3_vector_env_of_the_trainer_is_the_batched_one_for_state():
    pytest.importorskip("stable_baselines3") if not TORCH else None
    from gym_soarm.rl.native import NativeVecEnv

    venv = NativeVecEnv("ReachTarget-v0", dict(STATE), 2)
    try:
        assert isinstance(venv.vector, BatchedVectorEnv)
        venv.seed(1)
        venv.reset()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            venv.step_async(np.zeros((2, 6), np.float32))
            venv.step_wait()
    finally:
        venv.close()


def test_what_a_call_changes_in_an_environment_reaches_the_batch():
    def run(vector_env: str, **kwargs) -> list[np.ndarray]:
        envs = _vec("LiftCube-v0", 2, vector_env, **kwargs, **STATE)
        try:
            envs.reset(seed=0)
            envs.step(np.zeros((2, 6)))
            envs.call_some([1], "hold_servo_targets", np.full(6, 0.2))  # env 1's servos move
            return [envs.step(np.full((2, 6), 0.1))[0] for _ in range(3)]
        finally:
            envs.close()

    expected, got = run("processes", num_processes=1), run("batched")
    for a, b in zip(expected, got, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(got[-1][0], got[-1][1])  # the call changed environment 1 only


def test_a_divergence_right_after_reset_returns_the_reset_info_and_the_env_refuses_to_go_on():
    results = {}
    for vector_env, extra in (("processes", {"num_processes": 1}), ("batched", {})):
        envs = _vec("LiftCube-v0", 2, vector_env, **extra, **STATE)
        try:
            envs.reset(seed=3)
            if vector_env == "batched":
                envs.unwrapped._sim.qvel[1, :] = 1e30
            else:
                envs.unwrapped._local.envs[1].physics.data.qvel[:] = 1e30
            with pytest.warns(RuntimeWarning, match="diverged"):
                results[vector_env] = envs.step(np.zeros((2, 6)))
            with pytest.raises(RuntimeError, match="physics diverged"):
                envs.call_some([1], "save_state")
        finally:
            envs.close()
    expected, got = results["processes"], results["batched"]
    for key in ("cube_pos", "gripper_pos", "cube_grid_position", "is_success"):
        assert_same(expected[4][key], got[4][key], key)
    np.testing.assert_array_equal(expected[0], got[0])


def test_settings_changed_per_environment_and_calls_after_close():
    envs = _vec("LiftCube-v0", 2, "batched", **STATE)
    reference = _vec("LiftCube-v0", 2, "processes", num_processes=1, **STATE)
    try:
        for vec in (envs, reference):
            vec.reset(seed=0)
            vec.set_attr("reward_type", ["dense", "sparse"])
        actions = np.full((2, 6), 0.05)
        assert_same(reference.step(actions), envs.step(actions))
        single = gym.make("gym_soarm/LiftCube-v0", **STATE)
        single.reset(seed=0)
        single.step(actions[0])
        inner = envs.get_attr("physics")[0]  # copied back: what a step leaves, sensors too
        np.testing.assert_array_equal(
            inner.data.sensordata, single.unwrapped.physics.data.sensordata
        )
        np.testing.assert_array_equal(inner.data.qacc, single.unwrapped.physics.data.qacc)
        single.close()
    finally:
        envs.close()
        reference.close()
    for call in (
        lambda: envs.call("task_description"),
        lambda: envs.call_some([0], "task_description"),
        lambda: envs.set_attr("reward_type", "sparse"),
        lambda: envs.get_attr("reward_type"),
    ):
        with pytest.raises(RuntimeError, match="closed"):
            call()


def test_a_task_that_steps_its_own_physics_is_left_to_the_process_env():
    from gym_soarm.tasks.lift_cube import LiftTask

    class NudgingLift(LiftTask):
        def before_step(self, action, physics):
            physics.set_joint_targets(action * 0.5)

    spec = dataclasses.replace(
        gym_soarm.get_task("LiftCube-v0"), name="NudgingLift-v0", task=NudgingLift, aliases=()
    )
    gym_soarm.register_task(spec)
    try:
        assert wants_batched({"task": "LiftCube-v0", **STATE})
        assert not wants_batched({"task": "NudgingLift-v0", **STATE})  # auto: processes
        with pytest.raises(ValueError, match=r"overrides before_step.*vector_env='processes'"):
            _vec("NudgingLift-v0", 2, "batched", **STATE)
    finally:
        unregister_task("NudgingLift-v0")
