"""``PlaceInBin-v0``: the bin's shape, where the cube starts, what counts as in the bin.

The generic checks (expert success, random actions, reward terms, rest at reset,
determinism, cameras) run for every task in ``test_tasks.py``.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.tasks import placement
from gym_soarm.tasks.cube import CUBE_HALF_M
from gym_soarm.tasks.place_in_bin import (
    BIN_CLEARANCE_M,
    BIN_FLOOR_M,
    BIN_INNER_HALF_M,
    BIN_POSITION_M,
    BIN_RIM_Z_M,
    BIN_WALL_M,
    START_REGION_M,
)
from gym_soarm.tasks.placement import ARM_SHADOW_HALF_WIDTH_M


@pytest.fixture
def env():
    env = gym.make("gym_soarm/PlaceInBin-v0", obs_type="environment_state_agent_pos")
    yield env
    env.close()


def _hold(env: gym.Env, steps: int) -> dict:
    physics = env.unwrapped.physics
    hold = physics.joint_angles().astype(np.float32)
    info: dict = {}
    for _ in range(steps):
        _, _, _, _, info = env.unwrapped.step(hold)
    return info


def _place_cube(env: gym.Env, x: float, y: float, z: float, yaw_deg: float = 0.0) -> None:
    physics = env.unwrapped.physics
    # Test set-up only: move the cube at rest and recompute positions and contacts.
    physics.set_object_pose("cube", np.array([x, y, z]), placement.yaw_quaternion(yaw_deg))
    physics.forward()


def test_the_bin_is_an_open_box_of_the_declared_size(env):
    env.reset(seed=0)
    physics = env.unwrapped.physics
    model, data = physics.model.ptr, physics.data.ptr
    body = model.body("bin").id
    geoms = np.flatnonzero(model.geom_bodyid == body)
    assert len(geoms) == 5 and all(model.geom_contype[g] for g in geoms)
    centre = np.array(BIN_POSITION_M)
    lows = np.array([data.geom_xpos[g] - model.geom_size[g] for g in geoms]) - centre
    highs = np.array([data.geom_xpos[g] + model.geom_size[g] for g in geoms]) - centre
    outer = BIN_INNER_HALF_M + BIN_WALL_M
    assert lows.min(0)[:2] == pytest.approx([-outer, -outer])
    assert highs.max(0) == pytest.approx([outer, outer, BIN_RIM_Z_M])
    assert lows[:, 2].min() == pytest.approx(0.0)
    walls = [g for g in geoms if model.geom_size[g][2] > BIN_FLOOR_M]
    assert len(walls) == 4
    for wall in walls:
        # A wall is thin across one axis; its inner face lies on the inner footprint's edge.
        axis = int(np.argmin(model.geom_size[wall][:2]))
        offset = abs(data.geom_xpos[wall][axis] - centre[axis])
        assert offset - model.geom_size[wall][axis] == pytest.approx(BIN_INNER_HALF_M)
        assert 2 * model.geom_size[wall][axis] == pytest.approx(BIN_WALL_M)
    assert physics.fixture_position("bin")[2] == pytest.approx(BIN_FLOOR_M)


def test_the_cube_starts_in_reach_clear_of_the_bin_and_in_view(env):
    physics = env.unwrapped.physics
    (x0, x1), (y0, y1) = START_REGION_M
    bin_radius = math.hypot(BIN_INNER_HALF_M + BIN_WALL_M, BIN_INNER_HALF_M + BIN_WALL_M)
    for seed in range(40):
        env.reset(seed=seed)
        x, y, z = physics.object_position("cube").tolist()
        assert x0 <= x <= x1 and y0 <= y <= y1 and z == pytest.approx(CUBE_HALF_M)
        assert abs(x) >= ARM_SHADOW_HALF_WIDTH_M
        clear = math.hypot(x - BIN_POSITION_M[0], y - BIN_POSITION_M[1])
        assert clear >= bin_radius + math.hypot(CUBE_HALF_M, CUBE_HALF_M) + BIN_CLEARANCE_M
        assert 0.0 <= math.degrees(physics.object_yaw("cube")) < 90.0 + 1e-6


def test_a_cube_resting_in_the_bin_is_a_success(env):
    env.reset(seed=0)
    bx, by, _ = BIN_POSITION_M
    _place_cube(env, bx + 0.01, by - 0.01, BIN_FLOOR_M + CUBE_HALF_M + 1e-4, yaw_deg=30.0)
    info = _hold(env, 25)
    assert info["is_success"]
    assert set(info["reward_terms"].values()) == {1.0}
    for key in ("cube_pos", "target_pos"):
        assert np.shape(info[key]) == (3,) and np.isfinite(info[key]).all()


def test_a_cube_beside_or_above_the_bin_is_not(env):
    env.reset(seed=0)
    bx, by, _ = BIN_POSITION_M
    _place_cube(env, bx - 0.08, by, CUBE_HALF_M)
    info = _hold(env, 10)
    assert not info["is_success"] and info["reward_terms"]["place"] == 0.0
    # Over the bin's middle, but its top above the rim: not in the bin yet.
    _place_cube(env, bx, by, BIN_RIM_Z_M)
    info = _hold(env, 1)
    assert not info["is_success"] and info["reward_terms"]["place"] == 0.0


def test_the_expert_never_touches_the_bin_and_leaves_the_cube_in_it(env):
    physics = env.unwrapped.physics
    model = physics.model.ptr
    base_body = model.body("base").id

    def on_robot(geom: int) -> bool:
        body = int(model.geom_bodyid[geom])
        while body != 0:
            if body == base_body:
                return True
            body = int(model.body_parentid[body])
        return False

    robot = {g for g in range(model.ngeom) if on_robot(g)}
    bin_geoms = set(np.flatnonzero(model.geom_bodyid == model.body("bin").id).tolist())
    expert = make_expert(env)
    obs, info = env.reset(seed=5)
    expert.reset()
    for _ in range(gym_soarm.get_task("PlaceInBin-v0").max_episode_steps):
        if expert.phase == "done":
            break
        obs, _, _, _, info = env.unwrapped.step(expert(obs, info))
        data = physics.data.ptr
        for g1, g2 in data.contact.geom[: data.ncon].tolist():
            assert not ({g1, g2} & robot and {g1, g2} & bin_geoms), "the arm hit the bin"
    assert expert.phase == "done"
    assert _hold(env, 25)["is_success"]
