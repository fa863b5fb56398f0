"""SortCubes-v0: a cube counts on its own pad only, and the expert sorts them one by one."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.expert import make_expert
from gym_soarm.tasks.placement import yaw_quaternion
from gym_soarm.tasks.sort_cubes import COLOURS, CUBE_HALF_M, cube_name, pad_name


@pytest.fixture
def env():
    env = gym.make("gym_soarm/SortCubes-v0", obs_type="environment_state_agent_pos")
    yield env
    env.close()


def _put_cubes_on_pads(env, pads: dict[str, str]) -> dict:
    """Rest each cube (by colour) on the pad named by ``pads``; return the settled info."""
    physics = env.unwrapped.physics
    with physics.reset_context():
        for colour, pad_colour in pads.items():
            x, y, _ = physics.fixture_position(pad_name(pad_colour))
            physics.set_object_pose(
                cube_name(colour), np.array([x, y, CUBE_HALF_M]), yaw_quaternion(20.0)
            )
    hold = physics.joint_angles().astype(np.float32)
    for _ in range(10):
        _, _, _, _, info = env.step(hold)
    return info


def test_cubes_on_their_own_pads_succeed(env):
    env.reset(seed=0)
    info = _put_cubes_on_pads(env, {colour: colour for colour in COLOURS})
    assert info["is_success"] and info["cubes_sorted"] == len(COLOURS)
    assert all(v == 1.0 for v in info["reward_terms"].values())


def test_a_cube_on_another_colour_s_pad_does_not_count(env):
    env.reset(seed=0)
    red, green, blue = COLOURS
    info = _put_cubes_on_pads(env, {red: blue, green: green, blue: red})
    terms = info["reward_terms"]
    assert not info["is_success"] and info["cubes_sorted"] == 1
    assert terms[f"{green}_sorted"] == 1.0
    assert terms[f"{red}_sorted"] == terms[f"{blue}_sorted"] == 0.0


def test_the_expert_sorts_one_cube_after_another_and_none_comes_undone(env):
    expert = make_expert(env)
    obs, info = env.reset(seed=3)
    expert.reset()
    order: list[str] = []
    while True:
        obs, _, terminated, truncated, info = env.step(expert(obs, info))
        sorted_now = [c for c in COLOURS if info["reward_terms"][f"{c}_sorted"] == 1.0]
        assert set(order) <= set(sorted_now), f"{order} were sorted; now only {sorted_now}"
        order += [c for c in sorted_now if c not in order]
        if terminated or truncated:
            break
    assert info["is_success"]
    assert order == list(COLOURS)


def test_each_cube_is_let_go_with_the_wrist_unrolled_whatever_face_it_was_taken_by(env):
    """The arm leaves every pad in the one posture of that pad, as it leaves home for the
    first cube: the held cube turns on the way so that the wrist arrives unrolled."""
    expert = make_expert(env)
    wrist_roll = constants.JOINT_NAMES.index("wrist_roll")
    obs, info = env.reset(seed=3)
    expert.reset()
    grasp_rolls, release_rolls = {}, {}
    while True:
        action = expert(obs, info)
        stage, name = expert.stage, expert.grasp_object()
        commanded = env.unwrapped.commanded_targets
        if stage == "close":
            grasp_rolls.setdefault(name, float(commanded[wrist_roll]))
        if stage == "release":
            release_rolls.setdefault(name, float(commanded[wrist_roll]))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["is_success"]
    assert sorted(release_rolls) == sorted(cube_name(c) for c in COLOURS)
    assert max(abs(r) for r in grasp_rolls.values()) > 0.2, grasp_rolls  # faces that roll it
    assert all(abs(r) < 0.1 for r in release_rolls.values()), release_rolls


def test_the_state_observation_tells_the_cube_worked_on_as_the_expert_takes_them():
    """``obs_type="state"`` ends with sort's progress: the sorted flags, the cube worked
    on now (the expert's, the first unsorted one), the jaws to it and it to its pad."""
    env = gym.make("gym_soarm/SortCubes-v0", obs_type="state")
    names = list(env.unwrapped.observation_names)
    at = {name: names.index(name) for name in names}
    flags = [at[f"{c}_sorted"] for c in COLOURS]
    current = [at[f"current_is_{c}"] for c in COLOURS]
    jaw_to = [at[f"jaw_to_current_cube_{a}"] for a in "xyz"]
    to_pad = [at[f"current_cube_to_pad_{a}"] for a in "xyz"]
    assert names[-12:] == [names[i] for i in flags + current + jaw_to + to_pad]
    expert = make_expert(env)
    obs, info = env.reset(seed=2)
    physics = env.unwrapped.physics
    seen = []
    while True:
        action = expert(obs, info)
        colour = expert.grasp_object().removesuffix("_cube")
        done = env.unwrapped.task_logic.unsorted(physics)
        assert env.observation_space.contains(obs)
        np.testing.assert_array_equal(obs[flags], [c not in done for c in COLOURS])
        np.testing.assert_array_equal(obs[current], [c == colour for c in COLOURS])
        cube = physics.object_position(cube_name(colour))
        pad = physics.fixture_position(pad_name(colour))
        np.testing.assert_allclose(obs[jaw_to], cube - physics.grasp_center(), atol=1e-6)
        np.testing.assert_allclose(obs[to_pad], pad - cube, atol=1e-6)
        if not seen or seen[-1] != colour:
            seen.append(colour)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    env.close()
    assert info["is_success"]
    assert seen == list(COLOURS)
