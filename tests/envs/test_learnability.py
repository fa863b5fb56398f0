"""RL-ready environments (SPEC 18): the state observation, normalised actions, a reward
under which success beats hovering, and ``ee_delta`` along straight lines."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.envs.control import CONTROL_MODES, EE_DELTA_LIMIT_M
from gym_soarm.expert import evaluation_resets, make_expert
from gym_soarm.validation import ArgumentTypeError

TASKS = gym_soarm.task_names()
GAMMAS = (0.9, 0.99, 0.999, 1.0)


def _make(task: str, **kwargs) -> gym.Env:
    return gym.make(gym_soarm.get_task(task).env_id, **kwargs)


@pytest.mark.parametrize("task", TASKS)
def test_state_observation_holds_what_its_names_say(task):
    env = _make(task, obs_type="state")
    reference = _make(task, obs_type="environment_state_agent_pos")
    try:
        base = env.unwrapped
        names = base.observation_names
        assert len(set(names)) == len(names)
        assert env.observation_space.shape == (len(names),)
        assert env.observation_space.dtype == np.float32
        # The task's progress comes last (sort's tests check what it says).
        progress = [n for f in base.task_logic.progress_fields for n in f.names]
        assert list(names[len(names) - len(progress) :]) == progress
        seed, options = evaluation_resets(task)[0]
        obs, info = env.reset(seed=seed, options=options)
        ref_obs, _ = reference.reset(seed=seed, options=options)
        expert = make_expert(env)
        expert.reset()
        for step in range(40):
            assert obs.dtype == np.float32 and env.observation_space.contains(obs), step
            physics = base.physics
            index = {name: i for i, name in enumerate(names)}

            def values(*keys: str, obs=obs, index=index) -> np.ndarray:
                return obs[[index[k] for k in keys]]

            joints = gym_soarm.constants.JOINT_NAMES
            np.testing.assert_array_equal(
                values(*(f"{j}.pos" for j in joints)), physics.joint_angles().astype(np.float32)
            )
            np.testing.assert_array_equal(
                values(*(f"{j}.vel" for j in joints)),
                physics.joint_velocities().astype(np.float32),
            )
            np.testing.assert_array_equal(
                values(*(f"{j}.target" for j in joints)),
                base.commanded_targets.astype(np.float32),
            )
            jaw = physics.grasp_center()
            np.testing.assert_array_equal(values("jaw_x", "jaw_y", "jaw_z"), jaw.astype(np.float32))
            # The task's state is the environment_state of the same episode.
            np.testing.assert_array_equal(
                values(*base.state_names), ref_obs["environment_state"].astype(np.float32)
            )
            for name in names:
                if name.startswith("jaw_to_") and name.endswith("_x") and name not in progress:
                    prefix = name[len("jaw_to_") : -2]
                    where = values(*(f"{prefix}_{a}" for a in "xyz")).astype(np.float64)
                    np.testing.assert_allclose(
                        values(name, name[:-1] + "y", name[:-1] + "z"), where - jaw, atol=1e-6
                    )
            action = expert(obs, info)
            obs, _, terminated, _, info = env.step(action)
            ref_obs, *_ = reference.step(action)
            if terminated:
                break
    finally:
        env.close()
        reference.close()


def test_state_observation_has_object_to_goal_vectors():
    env = _make("PickAndPlaceCube-v0", obs_type="state")
    try:
        obs, _ = env.reset(seed=3)
        names = env.unwrapped.observation_names
        at = {n: i for i, n in enumerate(names)}
        cube = obs[[at["cube_x"], at["cube_y"], at["cube_z"]]]
        goal = obs[[at["goal_x"], at["goal_y"], at["goal_z"]]]
        vector = obs[[at["cube_to_goal_x"], at["cube_to_goal_y"], at["cube_to_goal_z"]]]
        np.testing.assert_allclose(vector, goal - cube, atol=1e-6)
        assert np.linalg.norm(vector) > 0.05  # the cube starts away from the pad
    finally:
        env.close()


def test_state_observation_is_reproducible_bit_for_bit():
    runs = []
    for _ in range(2):
        env = _make("PushCube-v0", obs_type="state", normalize_actions=True)
        env.action_space.seed(5)
        obs, _ = env.reset(seed=11)
        trace = [obs]
        for _ in range(30):
            obs, *_ = env.step(env.action_space.sample())
            trace.append(obs)
        env.close()
        runs.append(np.stack(trace))
    assert runs[0].tobytes() == runs[1].tobytes()


@pytest.mark.parametrize("mode", CONTROL_MODES)
def test_normalized_actions_map_onto_the_native_box(mode):
    normalized = _make("LiftCube-v0", obs_type="state", control_mode=mode, normalize_actions=True)
    native = _make("LiftCube-v0", obs_type="state", control_mode=mode)
    try:
        space = normalized.action_space
        assert space == gym.spaces.Box(-1.0, 1.0, (6,), np.float32)
        low, high = native.action_space.low, native.action_space.high
        control = normalized.unwrapped.control
        np.testing.assert_allclose(control.to_native(-np.ones(6)), low, rtol=1e-6)
        np.testing.assert_allclose(control.to_native(np.ones(6)), high, rtol=1e-6)
        normalized.reset(seed=2)
        native.reset(seed=2)
        rng = np.random.default_rng(0)
        for _ in range(15):
            action = rng.uniform(-1.0, 1.0, 6)
            mapped = low + (action + 1.0) / 2.0 * (high - low)
            obs_n, *_ = normalized.step(action.astype(np.float32))
            obs_r, *_ = native.step(mapped)
            np.testing.assert_allclose(obs_n, obs_r, atol=1e-4)
        # Beyond [-1, 1] is clipped, like the native Box.
        normalized.reset(seed=4)
        native.reset(seed=4)
        obs_n, *_ = normalized.step(np.full(6, 7.0, np.float32))
        obs_r, *_ = native.step(high)
        np.testing.assert_allclose(obs_n, obs_r, atol=1e-4)
    finally:
        normalized.close()
        native.close()


@pytest.mark.parametrize("mode", ["joint_delta", "ee_delta"])
def test_the_expert_answers_in_normalized_actions(mode):
    env = _make("ReachTarget-v0", obs_type="state", control_mode=mode, normalize_actions=True)
    try:
        expert = make_expert(env)
        successes = 0
        for seed in range(3):
            obs, info = env.reset(seed=seed)
            expert.reset()
            while True:
                action = expert(obs, info)
                assert env.action_space.contains(action)
                obs, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    break
            successes += info["is_success"]
        assert successes == 3
    finally:
        env.close()


def test_normalize_actions_refuses_what_is_not_a_bool():
    with pytest.raises(ArgumentTypeError, match="normalize_actions must be True or False"):
        _make("ReachTarget-v0", normalize_actions="yes")


def _returns(rewards: list[float], start: int) -> dict[float, float]:
    """Returns from step ``start`` on (both episodes share the steps before it: comparing
    from there orders the whole returns alike, without discounting them below float
    precision)."""
    return {g: float(sum(r * g**t for t, r in enumerate(rewards[start:]))) for g in GAMMAS}


@pytest.mark.parametrize("task", TASKS)
def test_success_pays_more_than_hovering_short_of_it(task):
    """Follow the expert to success; follow it again but stop k steps short and hold
    the targets to the step limit: the successful episode returns more, undiscounted
    and discounted."""
    seed, options = evaluation_resets(task)[0]
    env = _make(task, obs_type="state")
    try:
        limit = env.spec.max_episode_steps
        expert = make_expert(env)
        obs, info = env.reset(seed=seed, options=options)
        expert.reset()
        actions, rewards = [], []
        while True:
            action = expert(obs, info)
            obs, reward, terminated, truncated, info = env.step(action)
            actions.append(action)
            rewards.append(reward)
            if terminated or truncated:
                break
        assert info["is_success"], "the expert must succeed for this comparison"
        assert rewards[-1] == 1.0 + limit - len(rewards)

        control = env.unwrapped.control
        compared = 0
        for short in (1, 3, 10, 30, 60):
            if short >= len(actions):
                break
            env.reset(seed=seed, options=options)
            hover_rewards = []
            for action in actions[: len(actions) - short]:
                _, reward, terminated, _, info = env.step(action)
                hover_rewards.append(reward)
                assert not terminated
            truncated = terminated = False
            while not (terminated or truncated):
                held = env.unwrapped.commanded_targets
                _, reward, terminated, truncated, info = env.step(
                    control.action_for_targets(held, held)
                )
                hover_rewards.append(reward)
            if terminated:
                continue  # it drifted into success: not hovering
            assert len(hover_rewards) == limit and max(hover_rewards) < 1.0
            shared = len(actions) - short
            assert hover_rewards[:shared] == rewards[:shared]
            success, hover = _returns(rewards, shared), _returns(hover_rewards, shared)
            for gamma in GAMMAS:
                assert success[gamma] > hover[gamma], (task, short, gamma)
            compared += 1
        assert compared >= 2, f"{task}: the arm held short of success drifted into it"
    finally:
        env.close()


def test_sparse_reward_stays_the_success_flag():
    env = _make("ReachTarget-v0", obs_type="state", reward_type="sparse")
    try:
        expert = make_expert(env)
        obs, info = env.reset(seed=0)
        expert.reset()
        while True:
            obs, reward, terminated, truncated, info = env.step(expert(obs, info))
            assert reward == float(info["is_success"])
            if terminated or truncated:
                break
        assert reward == 1.0
    finally:
        env.close()


def _straight_line_episode(seed: int) -> dict:
    env = _make("ReachTarget-v0", obs_type="state", control_mode="ee_delta")
    try:
        base = env.unwrapped
        at = base.observation_names.index("jaw_to_target_x")
        to_base = base.control.kinematics.base_rotation.T
        obs, info = env.reset(seed=seed)
        start = base.control.pose(base.commanded_targets)
        closed = env.action_space.low[5]
        for _ in range(env.spec.max_episode_steps):
            towards = to_base @ obs[at : at + 3].astype(np.float64)
            move = towards * min(1.0, EE_DELTA_LIMIT_M / max(np.abs(towards).max(), 1e-12))
            obs, _, terminated, truncated, info = env.step(
                np.array([*move, 0.0, 0.0, closed], np.float32)
            )
            if terminated or truncated:
                break
        info["start_pose"] = start
        info["end_pose"] = base.control.pose(base.commanded_targets)
        return info
    finally:
        env.close()


@pytest.mark.parametrize("seed", [2, 3, 9, 10])
def test_ee_delta_straight_line_reaches_targets_that_need_the_pitch_to_yield(seed):
    # From the home pose (jaws level, pointing out), these low, near targets are out of
    # reach at the commanded pitch: holding it stalled 5 to 6 cm short; position first
    # lets the pitch yield and the jaws arrive.
    info = _straight_line_episode(seed)
    assert info["is_success"], info["target_distance"]
    assert abs(info["end_pose"][3] - info["start_pose"][3]) > 0.05  # the pitch yielded


@pytest.mark.parametrize("seed", [0, 16, 43, 103, 106, 113])
def test_ee_delta_straight_line_does_not_fold_into_a_corner(seed):
    # Holding the level pitch on the way to these low, near targets folded the elbow
    # and the wrist onto their limits; the way on was a 2.7 rad swing that the servos
    # lagged behind, the commanded pose ran off through the table, and the jaws stalled
    # 2 to 8 cm short. The pitch now yields before the joints come within
    # JOINT_MARGIN_RAD of their limits, and the jaws arrive.
    info = _straight_line_episode(seed)
    assert info["is_success"], info["target_distance"]


def test_ee_delta_keeps_the_pitch_where_it_can():
    env = _make("ReachTarget-v0", obs_type="state", control_mode="ee_delta")
    try:
        base = env.unwrapped
        env.reset(seed=0)
        before = base.control.pose(base.commanded_targets)
        for _ in range(5):
            _, _, _, _, info = env.step(np.array([-0.005, 0.0, -0.005, 0, 0, 0], np.float32))
            assert info["ik_error_m"] < 1e-4 and info["ik_error_rad"] < 1e-3
        after = base.control.pose(base.commanded_targets)
        np.testing.assert_allclose(after[:3] - before[:3], [-0.025, 0.0, -0.025], atol=1e-4)
        assert abs(after[3] - before[3]) < 1e-3 and abs(after[4] - before[4]) < 1e-3
    finally:
        env.close()
