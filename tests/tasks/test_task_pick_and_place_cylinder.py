"""``PickAndPlaceCylinder-v0``'s own checks: where the cylinder starts, what counts as
standing on the pad, and the expert's own heights.

The generic checks every task passes (expert, random actions, reward, cameras) are in
``test_tasks.py``.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.expert import ExpertConfig, make_expert
from gym_soarm.tasks import pick_and_place_cylinder as cyl
from gym_soarm.tasks.placement import yaw_quaternion

ENV_ID = "gym_soarm/PickAndPlaceCylinder-v0"


@pytest.fixture
def env():
    environment = gym.make(ENV_ID, obs_type="environment_state_agent_pos")
    yield environment
    environment.close()


def test_cylinder_starts_upright_in_the_region_clear_of_the_pad_and_the_arm(env):
    physics = env.unwrapped.physics
    (x0, x1), (y0, y1) = cyl.START_REGION_M
    px, py, _ = cyl.PAD_POSITION_M
    bx, by, _ = constants.ROBOT_BASE_POS_M
    starts = set()
    for seed in range(40):
        _, info = env.reset(seed=seed)
        x, y, z = physics.object_position("cylinder").tolist()
        assert [x, y] == list(info["cylinder_start_xy"])
        assert x0 <= x <= x1 and y0 <= y <= y1
        assert abs(x) >= cyl.ARM_SHADOW_HALF_WIDTH_M + cyl.CYLINDER_RADIUS_M
        assert math.hypot(x - px, y - py) >= cyl.PAD_RADIUS_M + cyl.CYLINDER_RADIUS_M
        assert math.hypot(x - bx, y - by) >= cyl.MIN_BASE_DISTANCE_M
        assert z == pytest.approx(cyl.CYLINDER_HALF_HEIGHT_M)
        assert info["cylinder_tilt_deg"] == pytest.approx(0.0, abs=1e-6)
        starts.add((round(x, 6), round(y, 6)))
    assert len(starts) == 40, "every seed draws its own start"
    assert any(x < 0 for x, _ in starts) and any(x > 0 for x, _ in starts)


def _settle(env, position, quaternion, steps: int = 30) -> bool:
    """Put the cylinder at a pose, let it settle with the arm still; the last success."""
    base = env.unwrapped
    physics = base.physics
    with physics.reset_context():
        physics.reset_to_home()
        physics.set_object_pose("cylinder", np.asarray(position), np.asarray(quaternion))
    hold = physics.joint_angles().astype(np.float32)
    success = False
    for _ in range(steps):
        _, _, success, _, _ = base.step(hold)
    return bool(success)


def test_success_needs_the_cylinder_upright_on_the_pad(env):
    env.reset(seed=0)
    px, py, _ = cyl.PAD_POSITION_M
    upright = yaw_quaternion(30.0)
    standing = [px + 0.02, py - 0.01, cyl.CYLINDER_HALF_HEIGHT_M]
    assert _settle(env, standing, upright)
    # Beside the pad.
    assert not _settle(env, [px + 0.06, py, cyl.CYLINDER_HALF_HEIGHT_M], upright)
    # Lying on its side on the pad.
    half = math.pi / 4
    lying = np.array([math.cos(half), math.sin(half), 0.0, 0.0])
    assert not _settle(env, [px, py, cyl.CYLINDER_RADIUS_M], lying)
    task = env.unwrapped.task_logic
    assert task.reward_terms(env.unwrapped.physics)["place"] == 0.0


def test_tilt_cosine():
    assert cyl.tilt_cosine(np.array([1.0, 0.0, 0.0, 0.0])) == pytest.approx(1.0)
    half = math.radians(20.0) / 2
    tilted = np.array([math.cos(half), 0.0, math.sin(half), 0.0])
    assert cyl.tilt_cosine(tilted) == pytest.approx(math.cos(math.radians(20.0)))


def test_expert_uses_the_cylinder_heights_unless_given_a_config(env):
    assert make_expert(env, kind="scripted").config is cyl.CYLINDER_EXPERT_CONFIG
    assert make_expert(env).config is cyl.CYLINDER_STATE_CONFIG
    assert cyl.CYLINDER_STATE_CONFIG.grasp_height_m == pytest.approx(0.03)
    assert cyl.CYLINDER_EXPERT_CONFIG.grasp_height_m == pytest.approx(0.03)
    own = ExpertConfig(carry_steps=70)
    assert make_expert(env, own).config is own


@pytest.mark.parametrize(
    ("position", "axis_yaw_deg"),
    [((0.09, 0.33), 30.0), ((-0.05, 0.40), 100.0)],  # lying across and along the arm
)
def test_the_state_expert_stands_a_lying_cylinder_up_then_places_it(position, axis_yaw_deg):
    # Lying on its side, out of the pad: grasped across its middle, turned upright by
    # pitching the jaws, set down standing, let go, picked up again and placed.
    env = gym.make(ENV_ID, obs_type="environment_state_agent_pos", max_episode_steps=600)
    try:
        env.reset(seed=0)
        base = env.unwrapped
        yaw = math.radians(axis_yaw_deg)
        # The body's z axis (the cylinder's) turned to horizontal at yaw: Rz(yaw) Ry(90).
        half = math.pi / 4
        lying = np.array(
            [
                math.cos(yaw / 2) * math.cos(half),
                -math.sin(yaw / 2) * math.sin(half),
                math.cos(yaw / 2) * math.sin(half),
                math.sin(yaw / 2) * math.cos(half),
            ]
        )
        _settle(env, [*position, cyl.CYLINDER_RADIUS_M], lying, steps=5)
        expert = make_expert(env)
        assert expert.tilt_deg() > 85.0
        stages, stood_alone = [], False
        for _ in range(600):
            _, _, terminated, truncated, info = env.step(expert())
            stages.append(expert.stage)
            physics = base.physics
            alone = not physics.grasped("cylinder") and expert.tilt_deg() < 5.0
            stood_alone |= alone and "let go" in stages and not terminated
            if terminated or truncated:
                break
        assert {"stand", "set down", "let go", "back away"} <= set(stages)
        assert stood_alone, "the cylinder never stood on the table by itself"
        assert info["is_success"], stages[-1]
    finally:
        env.close()


def test_a_cylinder_standing_on_its_other_end_is_upright(env):
    env.reset(seed=0)
    px, py, _ = cyl.PAD_POSITION_M
    upside_down = np.array([0.0, 1.0, 0.0, 0.0])  # half a turn about x
    assert cyl.tilt_cosine(upside_down) == pytest.approx(1.0)
    assert _settle(env, [px, py, cyl.CYLINDER_HALF_HEIGHT_M], upside_down)
