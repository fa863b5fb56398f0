"""object_placement and distractors: where objects start, and extra objects on the table."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import make_expert, run_episode
from gym_soarm.record.record import record
from gym_soarm.tasks.cube import UNIFORM_REGION_M
from gym_soarm.tasks.distractors import DISTRACTORS

STATE = {"obs_type": "environment_state_agent_pos"}


@pytest.mark.parametrize("task", gym_soarm.task_names())
def test_four_distractors_rest_clear_of_the_task_and_of_each_other(task):
    env = gym.make(gym_soarm.get_task(task).env_id, distractors=4, **STATE)
    try:
        physics = env.unwrapped.physics
        names = [d.name for d in DISTRACTORS]
        assert physics.object_names[-4:] == tuple(names)
        for seed in range(3):
            _, info = env.reset(seed=seed)
            placed = info["variation"]["distractors"]
            assert len(placed) == 4
            json.dumps(info["variation"])  # plain numbers
            for item in DISTRACTORS:
                others = [n for n in physics.object_names if n != item.name]
                xy = physics.object_position(item.name)[:2]
                for other in others:
                    gap = np.linalg.norm(physics.object_position(other)[:2] - xy)
                    assert gap > item.footprint_radius_m, (task, item.name, other)
            start = {n: physics.object_position(n) for n in physics.object_names}
            hold = physics.joint_angles().astype(np.float32)
            for _ in range(30):
                env.step(hold)
            for name, position in start.items():
                assert np.abs(physics.object_position(name) - position).max() < 1e-3, name
    finally:
        env.close()


def test_distractors_are_drawn_from_the_seed_and_never_touch_success():
    def positions(seed: int) -> np.ndarray:
        env = gym.make("gym_soarm/LiftCube-v0", distractors=2, **STATE)
        try:
            env.reset(seed=seed)
            physics = env.unwrapped.physics
            return np.array([physics.object_position(d.name) for d in DISTRACTORS[:2]])
        finally:
            env.close()

    np.testing.assert_array_equal(positions(5), positions(5))
    assert not np.array_equal(positions(5), positions(6))
    env = gym.make("gym_soarm/PickAndPlaceCube-v0", distractors=4, **STATE)
    try:
        expert = make_expert(env)
        assert all(run_episode(env, expert, seed, None).success for seed in range(3))
        segments = env.unwrapped.segmentation_ids
        assert all(d.name in segments for d in DISTRACTORS)
    finally:
        env.close()


@pytest.mark.parametrize("value", [5, -1, True, 1.5, "2"])
def test_bad_distractor_counts_are_refused_before_anything_is_built(value):
    with pytest.raises(ValueError, match="distractors must be an int from 0 to 4"):
        gym.make("gym_soarm/LiftCube-v0", distractors=value)


def test_uniform_placement_puts_the_grid_tasks_cube_anywhere_in_the_grid_box():
    env = gym.make("gym_soarm/LiftCube-v0", object_placement="uniform", **STATE)
    try:
        seen = set()
        for seed in range(8):
            _, info = env.reset(seed=seed)
            x, y, _ = info["cube_pos"]
            (x0, x1), (y0, y1) = UNIFORM_REGION_M
            assert x0 <= x <= x1 and y0 <= y <= y1
            assert info["cube_grid_position"] is None and 0.0 <= info["cube_rotation_deg"] < 90.0
            assert info["variation"]["object_placement"] == "uniform"
            seen.add((round(x, 4), round(y, 4)))
        assert len(seen) == 8  # continuous, not the nine cells
        _, info = env.reset(seed=0, options={"cube_rotation_deg": 12.5})
        assert info["cube_rotation_deg"] == 12.5
        with pytest.raises(ValueError, match="object_placement='grid'"):
            env.reset(seed=0, options={"cube_grid_position": 4})
        expert = make_expert(env)
        assert all(run_episode(env, expert, seed, None).success for seed in range(3))
    finally:
        env.close()


def test_placement_a_task_does_not_support_is_refused():
    with pytest.raises(ValueError, match="object_placement must be one of 'uniform'"):
        gym.make("gym_soarm/StackCube-v0", object_placement="grid")
    with pytest.raises(ValueError, match="object_placement must be one of"):
        gym.make("gym_soarm/LiftCube-v0", object_placement="scattered")
    env = gym.make("gym_soarm/LiftCube-v0", **STATE)
    try:
        _, info = env.reset(seed=0)
        assert "variation" not in info and isinstance(info["cube_grid_position"], int)
    finally:
        env.close()


def test_the_recorder_stores_each_episodes_variation(tmp_path):
    root = tmp_path / "ds"
    summary = record(
        root,
        task="LiftCube-v0",
        episodes=2,
        camera_config="none",
        variation={"distractors": 1, "object_placement": "uniform"},
    )
    assert summary.episodes == 2
    lines = [json.loads(s) for s in (root / "meta" / "variation.jsonl").read_text().splitlines()]
    assert [line["episode_index"] for line in lines] == [0, 1]
    assert [line["seed"] for line in lines] == [0, 1]
    assert all(len(line["distractors"]) == 1 for line in lines)
    assert lines[0]["distractors"] != lines[1]["distractors"]
    with pytest.raises(ValueError, match="variation takes the keywords"):
        record(tmp_path / "bad", task="LiftCube-v0", episodes=1, variation={"gravity": 0})
    assert not (tmp_path / "bad").exists()
