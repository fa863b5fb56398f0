"""``OpenDrawer-v0``'s own checks: where the cabinet stands, that the drawer rests closed at
reset and stays where it is left, and how opening the drawer is scored.

The generic checks every task passes (expert, random actions, reward, cameras) are in
``test_tasks.py``.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.expert import make_expert
from gym_soarm.tasks import open_drawer

ENV_ID = "gym_soarm/OpenDrawer-v0"
TABLE_CENTRE_Y_M = 0.30


@pytest.fixture
def env():
    environment = gym.make(ENV_ID, obs_type="environment_state_agent_pos", max_episode_steps=1000)
    yield environment
    environment.close()


def _cabinet_pose(physics) -> tuple[np.ndarray, float]:
    body = physics.model.ptr.body(open_drawer.CABINET.name)
    w, _, _, z = body.quat.tolist()
    return body.pos.copy(), 2.0 * math.atan2(z, w)


def test_cabinet_stands_on_the_table_facing_the_arm(env):
    physics = env.unwrapped.physics
    half_x, half_y = constants.TABLE_SIZE_M[0] / 2, constants.TABLE_SIZE_M[1] / 2
    axis = np.array([*constants.PAN_AXIS_XY_M, 0.0])
    for seed in range(20):
        _, info = env.reset(seed=seed)
        position, yaw = _cabinet_pose(physics)
        rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                corner = position[:2] + rotation @ np.array(
                    [sx * open_drawer.CABINET_HALF_WIDTH_M, sy * open_drawer.CABINET_HALF_DEPTH_M]
                )
                assert abs(corner[0]) < half_x and abs(corner[1] - TABLE_CENTRE_Y_M) < half_y
        handle = physics.fixture_position(open_drawer.DRAWER.name)
        radial = handle - axis
        radial[2] = 0.0
        radius = float(np.linalg.norm(radial))
        low, high = open_drawer.HANDLE_RADIUS_M
        assert low - 1e-9 <= radius <= high + 1e-9
        bearing = math.degrees(math.atan2(radial[1], radial[0]))
        low, high = open_drawer.HANDLE_BEARING_DEG
        assert low - 1e-6 <= bearing <= high + 1e-6
        # The drawer opens straight towards the shoulder pan axis.
        slide = open_drawer.slide_direction(physics)
        assert float(slide @ (-radial / radius)) > 0.9999
        assert handle[2] == pytest.approx(open_drawer.HANDLE_HEIGHT_M)
        assert info["drawer_opening_m"] == 0.0
        assert info["cabinet_yaw_deg"] == pytest.approx(math.degrees(yaw))


def test_same_seed_same_cabinet_other_seeds_elsewhere(env):
    physics = env.unwrapped.physics
    poses = {}
    for seed in (3, 4, 3):
        env.reset(seed=seed)
        position, yaw = _cabinet_pose(physics)
        if seed in poses:
            assert np.array_equal(poses[seed][0], position) and poses[seed][1] == yaw
        poses[seed] = (position, yaw)
    assert not np.allclose(poses[3][0], poses[4][0])


def test_drawer_rests_closed_and_untouched_at_reset(env):
    physics = env.unwrapped.physics
    for seed in range(3):
        env.reset(seed=seed)
        hold = physics.joint_angles().astype(np.float32)
        for _ in range(50):
            _, _, terminated, _, _ = env.step(hold)
            assert not terminated
            # The drawer fits its cabinet with clearance and floats above the table.
            assert not physics.touching(open_drawer.DRAWER.name, open_drawer.CABINET.name)
            assert not physics.touching(open_drawer.DRAWER.name, "table")
        assert abs(physics.fixture_joint_position(open_drawer.DRAWER.name)) < 1e-6


def test_drawer_stays_where_the_expert_leaves_it(env):
    base = env.unwrapped
    physics = base.physics
    expert = make_expert(env, kind="scripted")
    obs, info = env.reset(seed=5)
    expert.reset()
    first_success = None
    steps = 0
    # Step past the success (which ends the episode) to the end of the script and beyond.
    while expert.phase != "done":
        obs, _, terminated, _, info = base.step(expert(obs, info))
        steps += 1
        if terminated and first_success is None:
            first_success = steps
    assert first_success is not None and first_success < steps
    left_at = physics.fixture_joint_position(open_drawer.DRAWER.name)
    assert left_at >= open_drawer.OPEN_SUCCESS_M
    assert not any(physics.jaw_contacts_with(open_drawer.handle_geoms(physics)))
    for _ in range(100):
        obs, _, _, _, info = base.step(expert(obs, info))
    assert abs(physics.fixture_joint_position(open_drawer.DRAWER.name) - left_at) < 1e-3
    assert info["is_success"]


def _set_opening(physics, opening: float) -> None:
    with physics.reset_context():
        physics.reset_to_home()
        physics.named.data.qpos[open_drawer.DRAWER.name] = opening


def test_opening_scores_and_credits_the_earlier_stages(env):
    physics = env.unwrapped.physics
    task = env.unwrapped.task_logic
    env.reset(seed=0)
    terms = task.reward_terms(physics)
    assert terms["grasp"] == 0.0 and terms["open"] == 0.0 and 0.0 < terms["reach"] < 1.0
    _set_opening(physics, 0.03)
    assert task.reward_terms(physics) == {"reach": 1.0, "grasp": 1.0, "open": pytest.approx(0.5)}
    assert not task.is_success(physics)
    _set_opening(physics, open_drawer.OPEN_SUCCESS_M)
    assert task.is_success(physics)
    assert task.reward_terms(physics) == {"reach": 1.0, "grasp": 1.0, "open": 1.0}


def test_handle_geoms_are_the_bar_and_its_posts(env):
    physics = env.unwrapped.physics
    env.reset(seed=0)
    model = physics.model.ptr
    sizes = sorted(
        tuple(np.round(model.geom_size[g], 4)) for g in open_drawer.handle_geoms(physics)
    )
    bar = tuple(np.round(open_drawer.HANDLE_HALF_M, 4))
    assert bar in sizes and len(sizes) == 3
    assert all(
        model.geom_bodyid[g] == model.body("drawer").id for g in open_drawer.handle_geoms(physics)
    )
