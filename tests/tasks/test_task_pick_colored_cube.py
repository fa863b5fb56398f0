"""PickColoredCube-v0: the instruction names a colour drawn per episode, and it is the one lifted."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm.expert import make_expert
from gym_soarm.tasks.pick_colored_cube import COLOURS, CUBE_NAMES, LIFT_HEIGHT_M

SEEDS = range(12)


@pytest.fixture
def env():
    env = gym.make("gym_soarm/PickColoredCube-v0", obs_type="environment_state_agent_pos")
    yield env
    env.close()


def test_instruction_varies_with_the_seed_and_matches_the_info(env):
    colours = []
    for seed in SEEDS:
        _, info = env.reset(seed=seed)
        colour = info["target_colour"]
        assert colour in COLOURS
        assert info["task"] == env.unwrapped.task_description == f"Pick up the {colour} cube."
        target = env.unwrapped.physics.object_position(f"{colour}_cube")
        assert np.array_equal(info["target_pos"], target)
        colours.append(colour)
    assert set(colours) == set(COLOURS), f"every colour is drawn over {len(SEEDS)} seeds"
    env.reset(seed=SEEDS[0])
    assert env.unwrapped.task_description == f"Pick up the {colours[0]} cube."


def test_the_expert_lifts_the_cube_the_instruction_names(env):
    physics = env.unwrapped.physics
    expert = make_expert(env)
    for seed in SEEDS[:6]:
        obs, info = env.reset(seed=seed)
        expert.reset()
        named = f"{info['task'].split()[3]}_cube"
        while True:
            obs, _, terminated, truncated, info = env.step(expert(obs, info))
            if terminated or truncated:
                break
        assert info["is_success"], f"seed {seed}: {info['task']!r} failed"
        lifted = [name for name in CUBE_NAMES if physics.object_height(name) >= LIFT_HEIGHT_M]
        assert lifted == [named] and physics.grasped(named)


def test_holding_a_wrong_cube_earns_nothing_and_fails(env):
    """Lift the wrong cube with the expert's own motion: no reward, no success."""
    _, info = env.reset(seed=0)
    logic = env.unwrapped.task_logic
    wrong = logic.others[0]
    expert = make_expert(env)
    expert.grasp_object = lambda: wrong  # the same script, aimed at another cube
    expert.reset()
    obs = None
    for _ in range(env.spec.max_episode_steps - 1):
        obs, reward, _, _, info = env.step(expert(obs, info))
        assert not info["is_success"]
        if env.unwrapped.physics.grasped(wrong):
            assert reward == 0.0
    assert env.unwrapped.physics.object_height(wrong) >= LIFT_HEIGHT_M
