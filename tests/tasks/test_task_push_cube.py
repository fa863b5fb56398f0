"""PushCube-v0: pushable layouts, a lifted cube cannot succeed, the expert pushes without lifting."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.tasks import push_cube
from gym_soarm.tasks.lift_cube import LiftExpert

ENV_ID = gym_soarm.get_task("PushCube-v0").env_id


@pytest.fixture
def env():
    env = gym.make(ENV_ID, obs_type="environment_state_agent_pos")
    yield env
    env.close()


def test_layouts_are_pushable_and_move_the_square(env):
    (cx0, cx1), (cy0, cy1) = push_cube.CUBE_REGION_M
    (tx0, tx1), (ty0, ty1) = push_cube.TARGET_REGION_M
    squares = set()
    for seed in range(30):
        _, info = env.reset(seed=seed)
        cube, square = np.array(info["cube_pos"]), np.array(info["target_pos"])
        assert cx0 <= cube[0] <= cx1 and cy0 <= cube[1] <= cy1
        assert tx0 <= square[0] <= tx1 and ty0 <= square[1] <= ty1
        distance = math.hypot(*(square[:2] - cube[:2]))
        assert push_cube.PUSH_DISTANCE_M[0] <= distance <= push_cube.PUSH_DISTANCE_M[1]
        assert not info["is_success"] and not info["cube_lifted"]
        squares.add(tuple(square))
    assert len(squares) == 30


def test_the_expert_pushes_without_lifting_and_lets_go(env):
    expert = make_expert(env, kind="scripted")
    obs, info = env.reset(seed=4)
    expert.reset()
    phases = set()
    steps = 0
    while True:
        phases.add(expert.phase)
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        steps += 1
        if terminated or truncated:
            break
    # The success step pays 1 and the most the steps left could have paid.
    left = env.spec.max_episode_steps - steps
    assert info["is_success"] and reward == 1.0 + left and not info["cube_lifted"]
    assert {"touch", "push"} <= phases
    physics = env.unwrapped.physics
    assert not physics.touched_by_jaws("cube") and physics.object_height("cube") < 1e-3


def test_a_lifted_cube_can_no_longer_succeed(env):
    """Grasp and lift the cube (the lift task's expert), then put it on the square."""
    lift = LiftExpert(env)
    obs, info = env.reset(seed=0)
    lift.reset()
    while not info["cube_lifted"]:
        obs, _, terminated, truncated, info = env.step(lift(obs, info))
        assert not (terminated or truncated), "the lift never raised the cube 1 cm"
    assert info["reward_terms"]["push"] == 0.0
    physics = env.unwrapped.physics
    task = env.unwrapped.task_logic
    # Set the cube down at rest on the square's centre (a test-only teleport).
    square = physics.fixture_position(push_cube.TARGET.name)
    physics.set_object_pose(
        "cube",
        np.array([square[0], square[1], push_cube.CUBE_HALF_M]),
        np.array([1.0, 0.0, 0.0, 0.0]),
    )
    physics.forward()
    assert not physics.touched_by_jaws("cube")
    assert not task.is_success(physics)
    assert task.reward_terms(physics)["push"] == 0.0
