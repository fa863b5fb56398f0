"""The scripted expert: success over every cell and yaw, reward stages, grip, any obs type."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import SMALL

import gym_soarm
from gym_soarm.cli.expert import main
from gym_soarm.expert import (
    ExpertConfig,
    evaluation_resets,
    make_expert,
    run_episode,
)
from gym_soarm.tasks import cube, pick_and_place_cube, placement

TASK_ENV_IDS = {"pick_and_place": "gym_soarm/PickAndPlaceCube-v0", "lift": "gym_soarm/LiftCube-v0"}
TASK_NAMES = {"pick_and_place": "PickAndPlaceCube-v0", "lift": "LiftCube-v0"}

# Success floors over 9 cells x 4 yaws x 3 seeds (SPEC section 8).
SUCCESS_FLOORS = {"pick_and_place": 0.95, "lift": 0.98}
MAX_SLIP_M = 0.005
# Phases of each reward stage, in the order the stages must score.
STAGES = {
    "reach": ("approach", "descend"),
    "grasp": ("close",),
    "lift": ("lift",),
    "place": ("carry", "lower", "release", "retreat"),
}


def _state_env(make_env, task: str, **kwargs) -> gym.Env:
    return make_env(TASK_ENV_IDS[task], obs_type="environment_state_agent_pos", **kwargs)


def _expert_trace(env: gym.Env, cell: int, yaw: float) -> list[dict]:
    """One expert episode, step by step: phase, reward, info and grasp geometry."""
    expert = make_expert(env)
    physics = env.unwrapped.physics
    obs, info = env.reset(seed=0, options={"cube_grid_position": cell, "cube_rotation_deg": yaw})
    expert.reset()
    trace = []
    while True:
        phase = expert.phase
        obs, reward, terminated, truncated, info = env.step(expert(obs, info))
        site_rotation = physics.data.site_xmat[physics.model.name2id("grasp_center", "site")]
        trace.append(
            {
                "phase": phase,
                "reward": reward,
                "info": info,
                "grasped": physics.grasped("cube"),
                "cube": physics.object_position("cube"),
                "cube_in_site": site_rotation.reshape(3, 3).T
                @ (physics.object_position("cube") - physics.grasp_center()),
            }
        )
        if terminated or truncated:
            return trace


@pytest.mark.slow
@pytest.mark.parametrize("task", list(TASK_ENV_IDS))
def test_random_policy_never_succeeds_over_the_same_resets(make_env, task):
    env = _state_env(make_env, task)
    low, high = env.action_space.low, env.action_space.high
    successes, steps = 0, 0
    for seed, options in evaluation_resets(TASK_NAMES[task]):
        rng = np.random.default_rng(seed)
        env.reset(seed=seed, options=options)
        while True:
            _, _, terminated, truncated, info = env.step(rng.uniform(low, high))
            steps += 1
            if terminated or truncated:
                break
        successes += info["is_success"]
    assert successes == 0
    assert steps == 108 * gym.spec(TASK_ENV_IDS[task]).max_episode_steps


@pytest.mark.parametrize("task", list(TASK_ENV_IDS))
def test_dense_reward_rises_through_the_stages_of_an_expert_episode(make_env, task):
    env = _state_env(make_env, task)
    weights = env.unwrapped.task_logic.weights.terms
    trace = _expert_trace(env, cell=8, yaw=60.0)
    limit = env.spec.max_episode_steps
    for index, step in enumerate(trace):
        terms = step["info"]["reward_terms"]
        assert set(terms) == set(weights)
        assert all(0.0 <= value <= 1.0 for value in terms.values())
        total = sum(weights[k] * terms[k] for k in weights)
        if step["info"]["is_success"]:
            # The success step pays 1 and the most the steps left could have paid.
            assert step["reward"] == 1.0 + limit - (index + 1)
            step["reward"] = total
        assert step["reward"] == pytest.approx(total)
    stage_best = []
    for stage, phases in STAGES.items():
        rewards = [s["reward"] for s in trace if s["phase"] in phases]
        if stage in weights:
            assert rewards, f"no step of the {stage} stage"
            stage_best.append(max(rewards))
    assert stage_best == sorted(stage_best) and len(set(stage_best)) == len(stage_best), (
        f"stage maxima {stage_best} do not rise"
    )
    rewards = np.array([s["reward"] for s in trace])
    assert (np.maximum.accumulate(rewards) - rewards).max() < 0.01, "the reward fell back"
    assert trace[-1]["info"]["is_success"] and rewards[-1] == 1.0
    assert rewards[:-1].max() < 1.0


@pytest.mark.parametrize("task", list(TASK_ENV_IDS))
def test_sparse_reward_is_the_success_flag_along_an_expert_episode(make_env, task):
    env = _state_env(make_env, task, reward_type="sparse")
    trace = _expert_trace(env, cell=0, yaw=30.0)
    assert [s["reward"] for s in trace] == [float(s["info"]["is_success"]) for s in trace]
    assert trace[-1]["reward"] == 1.0


@pytest.mark.parametrize("cell, yaw", [(0, 0.0), (2, 45.0), (6, 30.0), (8, 60.0)])
def test_grasped_cube_follows_the_grasp_site_while_lifted_and_carried(make_env, cell, yaw):
    env = _state_env(make_env, "pick_and_place")
    trace = _expert_trace(env, cell, yaw)
    held = [s for s in trace if s["phase"] in ("lift", "carry")]
    assert held and all(s["grasped"] for s in held), "the cube left the jaws"
    carried = np.linalg.norm(held[-1]["cube"] - held[0]["cube"])
    assert carried > 0.1, f"the cube moved only {carried:.3f} m"
    in_site = np.array([s["cube_in_site"] for s in held])
    slip = np.linalg.norm(in_site - in_site[0], axis=1).max()
    assert slip <= MAX_SLIP_M, f"the cube slipped {slip * 1000:.1f} mm in the jaws"
    assert np.linalg.norm(in_site, axis=1).max() <= MAX_SLIP_M  # centred on grasp_center
    assert trace[-1]["info"]["is_success"]


@pytest.mark.parametrize("obs_type", ["pixels", "pixels_agent_pos"])
def test_expert_works_with_pixel_observations(make_env, obs_type):
    env = make_env(TASK_ENV_IDS["lift"], obs_type=obs_type, **SMALL)
    result = run_episode(env, make_expert(env), seed=3, options={"cube_grid_position": 5})
    assert result.success


def test_expert_works_in_lerobot_units(make_env):
    env = _state_env(make_env, "lift", units="lerobot")
    expert = gym_soarm.make_expert(env)
    # Radians read as degrees would barely move the arm: success needs the right units.
    result = run_episode(env, expert, seed=0, options={"cube_grid_position": 7})
    assert result.success


def test_expert_actions_are_smooth_and_never_touch_the_simulation(make_env):
    env = _state_env(make_env, "pick_and_place")
    physics = env.unwrapped.physics
    expert = make_expert(env)
    obs, info = env.reset(seed=1, options={"cube_grid_position": 3, "cube_rotation_deg": 45})
    expert.reset()
    previous = obs["agent_pos"]
    while True:
        before = (physics.data.qpos.copy(), physics.data.qvel.copy(), physics.data.ctrl.copy())
        action = expert(obs, info)
        after = (physics.data.qpos, physics.data.qvel, physics.data.ctrl)
        for old, new in zip(before, after, strict=True):
            np.testing.assert_array_equal(old, new)
        assert action in env.action_space
        assert np.abs(action[:5] - previous[:5]).max() < 0.1  # rad per 20 ms step
        previous = action
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["is_success"]


def test_expert_grasps_again_when_the_cube_slips_away(make_env):
    env = _state_env(make_env, "lift")
    physics = env.unwrapped.physics
    expert = make_expert(env, kind="scripted")
    obs, info = env.reset(seed=0, options={"cube_grid_position": 4, "cube_rotation_deg": 0})
    expert.reset()
    moved = False
    while True:
        if expert.phase == "close" and not moved:
            # Shove the cube 4 cm sideways just as the jaws start to close.
            position, quaternion = physics.object_pose("cube")
            physics.set_object_pose("cube", position + np.array([0.04, 0.0, 0.0]), quaternion)
            moved = True
        obs, _, terminated, truncated, info = env.step(expert(obs, info))
        if terminated or truncated:
            break
    assert moved and expert.regrasps == 1
    assert info["is_success"]


def test_expert_restarts_by_itself_after_an_env_reset(make_env):
    env = _state_env(make_env, "lift")
    expert = make_expert(env)
    first = run_episode(env, expert, seed=0, options={"cube_grid_position": 1})
    obs, info = env.reset(seed=0, options={"cube_grid_position": 1})  # no expert.reset()
    steps = 0
    while True:
        obs, _, terminated, truncated, info = env.step(expert(obs, info))
        steps += 1
        if terminated or truncated:
            break
    assert info["is_success"] and steps == first.steps


def test_make_expert_rejects_other_environments_and_configs(make_env):
    env = gym.make("CartPole-v1")
    with pytest.raises(TypeError, match="gym_soarm"):
        make_expert(env)
    env.close()
    with pytest.raises(TypeError, match="ExpertConfig"):
        make_expert(_state_env(make_env, "lift"), config={"carry_steps": 80})


@pytest.mark.parametrize(
    "field, value, fragment",
    [
        (
            "carry_steps",
            0,
            r"carry_steps must be an int >= 1; got 0\. Pass e\.g\. carry_steps=\d+ \(the default\)",
        ),
        ("lift_steps", 2.5, "lift_steps must be an int >= 1"),
        ("max_regrasps", -1, "max_regrasps must be an int >= 0"),
        ("lift_reach_m", (0.2, 0.1), "lift_reach_m must be"),
        ("approach_speed_rad_per_step", 0.0, "approach_speed_rad_per_step must be > 0"),
    ],
)
def test_expert_config_rejects_bad_figures(field, value, fragment):
    with pytest.raises(ValueError, match=fragment):
        ExpertConfig(**{field: value})


def test_cli_prints_the_success_rate(capsys):
    main(["--task", "lift", "--seeds", "1"])
    out = capsys.readouterr().out
    assert out.startswith("LiftCube-v0: 36/36 = 100.0 % success")


def test_cli_measures_either_kind_of_expert(capsys):
    # The timed script takes its fixed phases (72-78 steps on reach); the state expert
    # heads straight for the ball and arrives sooner.
    main(["--task", "reach", "--seeds", "5", "--kind", "scripted"])
    scripted = capsys.readouterr().out
    main(["--task", "reach", "--seeds", "5"])
    state = capsys.readouterr().out
    assert scripted.startswith("ReachTarget-v0: 5/5 = 100.0 % success")
    assert state.startswith("ReachTarget-v0: 5/5 = 100.0 % success")
    median = lambda out: int(out.split("(median ")[1].split(")")[0])  # noqa: E731
    assert median(state) < median(scripted)
    with pytest.raises(SystemExit):
        main(["--task", "reach", "--kind", "timed"])
    assert "invalid choice: 'timed'" in capsys.readouterr().err


def test_goal_pad_is_clear_of_every_start_cell_and_seen_by_both_scene_cameras(make_env):
    env = make_env("SoArm-v0", obs_type="pixels", camera_config="all", **SMALL)
    env.reset(seed=0, options={"cube_grid_position": 6})
    goal = env.unwrapped.physics.fixture_position("goal")[:2]
    cube_reach = cube.CUBE_HALF_M * np.sqrt(2.0)  # centre to a corner, any yaw
    for cell in range(placement.NUM_GRID_CELLS):
        gap = np.linalg.norm(np.array(placement.grid_cell_position(cell)) - goal)
        assert gap > pick_and_place_cube.GOAL_RADIUS_M + cube_reach, f"the pad overlaps cell {cell}"
    for camera in ("overview_camera", "front_camera"):
        image = env.unwrapped.render_camera_image(camera, 120, 160).astype(int)
        r, g, b = image[..., 0], image[..., 1], image[..., 2]
        assert ((g > 120) & (g > r + 50) & (g > b + 50)).sum() > 10, f"no pad in {camera}"


def test_expert_picks_the_cube_up_again_after_dropping_it(make_env):
    env = make_env(
        TASK_ENV_IDS["pick_and_place"],
        obs_type="environment_state_agent_pos",
        max_episode_steps=700,
    )
    physics = env.unwrapped.physics
    expert = make_expert(env, kind="scripted")
    obs, info = env.reset(seed=0, options={"cube_grid_position": 0, "cube_rotation_deg": 0})
    expert.reset()
    carry_steps = 0
    while True:
        if expert.phase == "carry":
            carry_steps += 1
            if carry_steps == 10:  # take the cube out of the jaws and put it back on the table
                x, y = placement.grid_cell_position(4)
                physics.set_object_pose(
                    "cube",
                    np.array([x, y, cube.CUBE_HALF_M]),
                    np.array([np.cos(0.17), 0.0, 0.0, np.sin(0.17)]),
                )
        obs, _, terminated, truncated, info = env.step(expert(obs, info))
        if terminated or truncated:
            break
    assert carry_steps > 10 and expert.regrasps == 1
    assert info["is_success"]


def test_a_phase_that_sets_no_gripper_target_keeps_the_last_one(make_env):
    """After the release, the retreat keeps the jaws open (it sets no gripper target)."""
    env = _state_env(make_env, "pick_and_place")
    base = env.unwrapped  # stepped on past success, through the retreat
    expert = make_expert(env, kind="scripted")
    base.reset(seed=0, options={"cube_grid_position": 4, "cube_rotation_deg": 0})
    expert.reset()
    gripper = {}
    while expert.phase != "done":
        phase = expert.phase
        gripper.setdefault(phase, []).append(float(expert.next_targets_radians()[-1]))
        base.step(base.joint_units.from_radians(np.array(expert._command)).astype(np.float32))
    opened = expert.config.gripper_open_rad
    assert gripper["release"][-1] == pytest.approx(opened)
    assert gripper["retreat"] == pytest.approx([opened] * len(gripper["retreat"]))
