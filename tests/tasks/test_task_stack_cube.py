"""``StackCube-v0``: where the cubes start, what counts as a stack, and that the stack stands.

The generic checks (expert success, random actions, reward terms, rest at reset,
determinism, cameras) run for every task in ``test_tasks.py``.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.constants import PAN_AXIS_XY_M
from gym_soarm.expert import make_expert
from gym_soarm.sim.kinematics import ArmKinematics
from gym_soarm.tasks import placement
from gym_soarm.tasks.placement import ARM_SHADOW_HALF_WIDTH_M
from gym_soarm.tasks.stack_cube import (
    BLUE_CUBE,
    CUBE_HALF_M,
    CUBE_SIZE_M,
    MIN_PAN_DISTANCE_M,
    RED_CUBE,
    START_GAP_M,
    START_REGION_M,
)

RED, BLUE = RED_CUBE.name, BLUE_CUBE.name


@pytest.fixture
def env():
    env = gym.make("gym_soarm/StackCube-v0", obs_type="environment_state_agent_pos")
    yield env
    env.close()


def _hold(env: gym.Env, steps: int) -> dict:
    """Hold the arm where it is for ``steps`` steps; the last info."""
    physics = env.unwrapped.physics
    hold = physics.joint_angles().astype(np.float32)
    info: dict = {}
    for _ in range(steps):
        _, _, _, _, info = env.unwrapped.step(hold)
    return info


def _place(env: gym.Env, name: str, x: float, y: float, z: float, yaw_deg: float = 0.0) -> None:
    physics = env.unwrapped.physics
    # Test set-up only: move the object at rest and recompute positions and contacts.
    physics.set_object_pose(name, np.array([x, y, z]), placement.yaw_quaternion(yaw_deg))
    physics.forward()


def test_pan_axis_is_the_arm_s():
    env = gym.make("gym_soarm/StackCube-v0", obs_type="environment_state_agent_pos")
    try:
        anchor = ArmKinematics(env.unwrapped.physics.model.ptr).cylindrical_point(0.0, 0.0, 0.0)
    finally:
        env.close()
    assert anchor[:2] == pytest.approx(PAN_AXIS_XY_M, abs=1e-3)


def test_cubes_start_apart_in_reach_and_in_view(env):
    physics = env.unwrapped.physics
    (x0, x1), (y0, y1) = START_REGION_M
    for seed in range(40):
        env.reset(seed=seed)
        spots = {}
        for name in (RED, BLUE):
            x, y, z = physics.object_position(name).tolist()
            assert x0 <= x <= x1 and y0 <= y <= y1
            assert z == pytest.approx(CUBE_HALF_M)
            assert abs(x) >= ARM_SHADOW_HALF_WIDTH_M
            assert math.hypot(x - PAN_AXIS_XY_M[0], y - PAN_AXIS_XY_M[1]) >= MIN_PAN_DISTANCE_M
            yaw = math.degrees(physics.object_yaw(name))
            assert 0.0 <= yaw < 90.0 + 1e-6
            spots[name] = (x, y)
        apart = math.dist(spots[RED], spots[BLUE])
        assert apart >= 2 * RED_CUBE.footprint_radius_m + START_GAP_M


def test_a_red_cube_set_on_the_blue_one_is_a_stack(env):
    env.reset(seed=0)
    physics = env.unwrapped.physics
    bx, by, bz = physics.object_position(BLUE).tolist()
    _place(env, RED, bx + 0.005, by, bz + CUBE_SIZE_M + 1e-4, yaw_deg=20.0)
    info = _hold(env, 25)
    assert info["is_success"]
    assert set(info["reward_terms"].values()) == {1.0}
    for key in ("red_cube_pos", "blue_cube_pos", "target_pos"):
        assert np.shape(info[key]) == (3,) and np.isfinite(info[key]).all()


def test_a_red_cube_beside_the_blue_one_or_above_it_is_not(env):
    env.reset(seed=0)
    physics = env.unwrapped.physics
    bx, by, bz = physics.object_position(BLUE).tolist()
    _place(env, RED, bx + 0.05, by, CUBE_HALF_M)
    info = _hold(env, 10)
    assert not info["is_success"] and info["reward_terms"]["place"] == 0.0
    # Over the blue cube but not yet on it: falling, so not at rest, and not touching it.
    _place(env, RED, bx, by, bz + CUBE_SIZE_M + 0.004)
    info = _hold(env, 1)
    assert not physics.touching(RED, BLUE) and not info["is_success"]


def test_the_expert_leaves_the_stack_standing(env):
    """After the release the jaws stay open and move off: the stack still stands."""
    expert = make_expert(env)
    obs, info = env.reset(seed=3)
    expert.reset()
    base = env.unwrapped
    for _ in range(gym_soarm.get_task("StackCube-v0").max_episode_steps):
        if expert.phase == "done":
            break
        obs, _, _, _, info = base.step(expert(obs, info))
    assert expert.phase == "done"
    info = _hold(env, 25)
    assert info["is_success"]
    physics = base.physics
    assert physics.object_position(RED)[2] > CUBE_SIZE_M
