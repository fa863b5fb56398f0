"""Long runs under hostile actions: random, pinned at the joint limits, and far out of range.

State observations keep these runs fast; the physics is the same with pixels.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm import constants
from gym_soarm.tasks import cube

STEPS = 3_000
JOINT_LIMIT_SLACK_RAD = 0.05
FLOOR_Z_M = -0.75  # the floor plane of scene.xml, 0.75 m below the table top
TABLE_CENTRE_XY_M = (0.0, 0.3)  # scene.xml body "table"
# Contacts are soft: a cube landing from the table at ~4 m/s dents the floor for a few
# steps, but once at rest it sits on its support within this.
REST_SPEED_M_S = 0.01
REST_PENETRATION_M = 0.002
OUT_OF_RANGE_FACTOR = 3.0
MODES = ("random", "limits", "out_of_range")
MAX_BLOCK_STEPS = 40


def _hostile_actions(space: gym.spaces.Box, rng: np.random.Generator):
    """Yield (mode, action) forever: blocks of 1 to MAX_BLOCK_STEPS steps per mode, in turn.

    Short blocks flip the targets every step (bang-bang); long ones press the joints
    against their limits until the servos settle there.
    """
    low, high = space.low.astype(np.float64), space.high.astype(np.float64)
    while True:
        for mode in MODES:
            for _ in range(int(rng.integers(1, MAX_BLOCK_STEPS + 1))):
                at_high = rng.random(low.shape) < 0.5
                if mode == "random":
                    action = rng.uniform(low, high)
                elif mode == "limits":
                    action = np.where(at_high, high, low)
                else:
                    action = OUT_OF_RANGE_FACTOR * np.where(at_high, np.abs(high), -np.abs(low))
                yield mode, action.astype(np.float32)


def _over_table(centre: np.ndarray) -> bool:
    """Whether the cube is at table height, well inside the table's footprint."""
    half_x, half_y = (size / 2 - cube.CUBE_SIZE_M for size in constants.TABLE_SIZE_M)
    return (
        abs(centre[0] - TABLE_CENTRE_XY_M[0]) < half_x
        and abs(centre[1] - TABLE_CENTRE_XY_M[1]) < half_y
        and centre[2] > constants.TABLE_TOP_Z_M - cube.CUBE_SIZE_M
    )


@pytest.mark.parametrize(("env_id", "seed"), [("SoArm-v0", 7), ("gym_soarm/LiftCube-v0", 8)])
def test_hostile_actions_for_3000_steps_keep_the_simulation_sound(env_id, seed):
    # One episode as long as the run: no reset ever rescues the state.
    env = gym.make(env_id, obs_type="environment_state_agent_pos", max_episode_steps=STEPS)
    try:
        physics = env.unwrapped.physics
        lo, hi = physics.joint_range()
        ctrl_lo, ctrl_hi = physics.control_range()
        rng = np.random.default_rng(seed)
        actions = _hostile_actions(env.action_space, rng)
        obs, _ = env.reset(seed=seed)
        lowest_cube_bottom = np.inf
        resting = []
        extremes = np.array([np.full(len(lo), np.inf), np.full(len(lo), -np.inf)])
        modes_seen = set()
        for step in range(STEPS):
            mode, action = next(actions)
            modes_seen.add(mode)
            obs, reward, terminated, truncated, info = env.step(action)
            where = f"step {step} ({mode} action {action.tolist()})"
            assert all(np.isfinite(v).all() for v in obs.values()), where
            assert np.isfinite(reward) and 0.0 <= reward <= 1.0, where
            assert env.observation_space.contains(obs), where
            assert info["physics_unstable"] is False, where
            assert truncated is (step == STEPS - 1), where
            # Targets are the actions clipped to the servo ranges.
            np.testing.assert_array_equal(
                physics.joint_targets(), np.clip(action.astype(np.float64), ctrl_lo, ctrl_hi)
            )
            angles = physics.joint_angles()
            assert (angles >= lo - JOINT_LIMIT_SLACK_RAD).all(), (where, angles.tolist())
            assert (angles <= hi + JOINT_LIMIT_SLACK_RAD).all(), (where, angles.tolist())
            extremes[0] = np.minimum(extremes[0], angles)
            extremes[1] = np.maximum(extremes[1], angles)
            # Nothing falls through the floor: the cube never sinks halfway into it...
            centre, bottom = physics.object_position("cube"), physics.object_height("cube")
            assert centre[2] > FLOOR_Z_M - cube.CUBE_HALF_M, (where, centre.tolist())
            lowest_cube_bottom = min(lowest_cube_bottom, bottom)
            # ...and at rest it sits on the floor or the table top, not in them.
            if np.linalg.norm(physics.object_velocity("cube")) < REST_SPEED_M_S:
                resting.append(centre)
                assert bottom > FLOOR_Z_M - REST_PENETRATION_M, (where, bottom)
                if _over_table(centre):
                    assert bottom > constants.TABLE_TOP_Z_M - REST_PENETRATION_M, (where, bottom)
            if terminated:
                obs, _ = env.reset()
        assert modes_seen == set(MODES)
        # The run swept every joint over most of its range (the table stops some).
        coverage = (extremes[1] - extremes[0]) / (hi - lo)
        assert (coverage > 0.6).all(), coverage.tolist()
        assert np.isfinite(lowest_cube_bottom)
        assert len(resting) > STEPS // 10, "the rest checks hardly ever ran"
    finally:
        env.close()


def test_registered_ids_are_the_ones_under_test():
    assert {"SoArm-v0", "gym_soarm/LiftCube-v0"} <= set(gym_soarm.ENV_IDS)
