"""Experts that act from the state (SPEC section 22): Markov, finishing from perturbed
states, smooth, in every control mode."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.cli import expert as expert_cli
from gym_soarm.expert import (
    ExpertConfig,
    StateExpert,
    StateExpertConfig,
    make_expert,
    run_episode,
)
from gym_soarm.expert.perturbed import evaluate_perturbed
from gym_soarm.tasks.scripted import ScriptedExpert

GRASP_TASKS = ("LiftCube-v0", "PickAndPlaceCube-v0")


def _env(task: str, **kwargs) -> gym.Env:
    return gym.make(
        gym_soarm.get_task(task).env_id, obs_type="environment_state_agent_pos", **kwargs
    )


def test_make_expert_gives_state_experts_and_the_script_on_request():
    env = _env("LiftCube-v0")
    try:
        assert isinstance(make_expert(env), StateExpert)
        assert isinstance(make_expert(env, kind="scripted"), ScriptedExpert)
        assert isinstance(make_expert(env, ExpertConfig(carry_steps=70)), ScriptedExpert)
        own = StateExpertConfig(line_speed_m=0.002)
        assert make_expert(env, own).config is own
        with pytest.raises(ValueError, match="kind"):
            make_expert(env, kind="clock")
        with pytest.raises(TypeError, match="StateExpertConfig"):
            make_expert(env, {"line_speed_m": 0.002})
        with pytest.raises(ValueError, match="joint_speed_rad must be a number > 0"):
            StateExpertConfig(joint_speed_rad=0.0)
        with pytest.raises(ValueError, match="relax_speed_rad must be a number > 0") as error:
            StateExpertConfig(relax_speed_rad=-0.1)
        assert "Pass e.g. relax_speed_rad=0.15 (the default)" in str(error.value)
    finally:
        env.close()


@pytest.mark.parametrize("task", ("ReachTarget-v0", *GRASP_TASKS))
def test_same_state_same_action_whatever_the_history(task):
    """An expert that lived through an episode and one made fresh on its restored
    snapshot answer alike, step after step, and the episodes stay identical."""
    lived_env, fresh_env = _env(task), _env(task)
    try:
        lived = make_expert(lived_env)
        obs, info = lived_env.reset(seed=7)
        lived_env.action_space.seed(7)
        for step in range(45):  # random actions first: a history no expert episode has
            action = lived_env.action_space.sample() if step < 8 else lived(obs, info)
            obs, *_, info = lived_env.step(action)
        fresh_env.reset(options={"state": lived_env.unwrapped.save_state()})
        fresh = make_expert(fresh_env)
        for _ in range(30):
            a, b = lived(), fresh()
            np.testing.assert_array_equal(a, b)
            first = lived_env.step(a)
            second = fresh_env.step(b)
            np.testing.assert_array_equal(first[0]["agent_pos"], second[0]["agent_pos"])
            if first[2] or first[3]:
                break
    finally:
        lived_env.close()
        fresh_env.close()


def test_asking_the_expert_changes_nothing():
    """A call is a pure function of the state: asking twice gives the same action."""
    env = _env("PickAndPlaceCube-v0")
    try:
        expert = make_expert(env)
        obs, info = env.reset(seed=3)
        for _ in range(60):
            first = expert(obs, info)
            np.testing.assert_array_equal(first, expert(obs, info))
            obs, *_, info = env.step(first)
    finally:
        env.close()


def test_the_jaws_come_down_on_a_face_that_clears_the_other_cubes():
    # Seed 66 of pick the named cube puts another cube where the open moving jaw of the
    # least-roll face would land; the expert grasps from a face whose pads clear it and
    # finishes (with that face it pressed on the other cube until the step limit).
    env = _env("PickColoredCube-v0")
    try:
        expert = make_expert(env)
        env.reset(seed=66)
        physics, c = env.unwrapped.physics, expert.config
        name = expert.grasp_object()
        grasp = physics.object_position(name)
        yaws = expert.grasp_yaws(name)
        clear = expert.clear_yaws(name, grasp, yaws)
        assert 0 < len(clear) < len(yaws)
        others = [physics.object_position(o)[:2] for o in physics.object_names if o != name]

        def room(yaw):  # the nearest any open pad comes to another cube's centre
            axis = np.array([np.cos(yaw), np.sin(yaw)])
            centre = grasp[:2] - c.fixed_jaw_clearance_m * axis
            return min(np.hypot(*(centre + a * axis - o)) for a in c.open_pads_m for o in others)

        for yaw in yaws:
            assert (room(yaw) > c.pad_clear_m) == (yaw in clear)
        assert run_episode(env, expert, 66, None).success
        # No face clear (every pad within a metre of a cube): the one with the most room.
        crowded = make_expert(env, StateExpertConfig(pad_clear_m=1.0))
        env.reset(seed=66)
        grasp = physics.object_position(name)
        (only,) = crowded.clear_yaws(name, grasp, yaws)
        assert room(only) == max(room(yaw) for yaw in yaws) and len(set(map(room, yaws))) > 1
    finally:
        env.close()
    lone = _env("LiftCube-v0")
    try:
        expert = make_expert(lone)
        lone.reset(seed=0)
        yaws = expert.grasp_yaws("cube")
        assert (
            expert.clear_yaws("cube", lone.unwrapped.physics.object_position("cube"), yaws) == yaws
        )
    finally:
        lone.close()


def test_jaws_left_stretched_out_at_the_table_rise_towards_home_and_the_grasp_follows():
    # A shove can leave the jaws pointing out, 40 cm from the pan axis, at the table;
    # a straight line up barely moves them there (they stayed at the table for 300
    # steps), so the expert rises towards the home posture first, then grasps.
    env = _env("LiftCube-v0")
    try:
        base = env.unwrapped
        obs, info = env.reset(seed=0)
        stretched = np.array([0.43, 1.14, -0.16, -0.88, 2.03, 0.8])
        for _ in range(40):
            commanded = np.asarray(base.commanded_targets)
            obs, *_, info = env.step(base.control.action_for_targets(stretched, commanded))
        assert base.physics.grasp_center()[2] < 0.03
        expert = make_expert(env)
        kinds = []
        for _ in range(200):
            kinds.append(expert.decide(np.asarray(base.commanded_targets)).kind)
            obs, _, terminated, truncated, info = env.step(expert(obs, info))
            if terminated or truncated:
                break
        assert "posture" in kinds[:20], kinds[:20]
        assert info["is_success"]
    finally:
        env.close()


def test_targets_far_from_the_joints_come_back_at_the_relax_speed():
    env = _env("LiftCube-v0")
    try:
        env.reset(seed=0)
        measured = env.unwrapped.physics.joint_angles()[:5]
        flung = measured + np.array([1.0, -0.5, 0.0, 0.2, 0.0])
        for hz, expected in ((50, 0.15), (30, 0.25)):
            expert = make_expert(env, StateExpertConfig().at_rate(hz))
            step = expert.relaxed(flung) - flung
            np.testing.assert_allclose(np.abs(step).max(), expected)
            np.testing.assert_allclose(step / np.abs(step).max(), (measured - flung) / 1.0)
        near = measured + 0.1  # within one step: there at once
        np.testing.assert_allclose(make_expert(env).relaxed(near), measured)
    finally:
        env.close()


@pytest.mark.parametrize("task", GRASP_TASKS)
def test_the_expert_finishes_from_perturbed_states(task):
    results = evaluate_perturbed(task, episodes=1)
    assert {r.perturbation for r in results} == {"random", "push", "drop", "jaws", "shove"}
    assert all(r.applied for r in results if r.perturbation != "shove")
    counted = [r for r in results if r.applied]
    assert all(r.success for r in counted), [r for r in counted if not r.success]


def test_servo_targets_move_within_the_speed_limits():
    env = _env("PickAndPlaceCube-v0")
    try:
        expert = make_expert(env)
        config = expert.config
        env.reset(seed=11)
        before = env.unwrapped.commanded_targets.copy()
        changes = []
        while True:
            _, _, terminated, truncated, info = env.step(expert())
            after = env.unwrapped.commanded_targets.copy()
            changes.append(np.abs(after - before))
            before = after
            if terminated or truncated:
                break
        assert info["is_success"]
        changes = np.array(changes)
        assert changes[:, :5].max() <= config.joint_speed_rad + 1e-6  # float32 actions
        assert changes[:, 5].max() <= config.gripper_speed_rad + 1e-6
        # Speed builds up: no step starts from rest at full speed.
        assert changes[0, :5].max() <= config.joint_accel_rad + 1e-6
    finally:
        env.close()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"control_mode": "joint_delta", "normalize_actions": True},
        {"control_mode": "ee_delta"},
        {"control_mode": "ee_pose", "normalize_actions": True},
        {"units": "lerobot"},
    ],
)
def test_the_expert_succeeds_in_every_control_mode_and_unit(kwargs):
    env = _env("LiftCube-v0", **kwargs)
    try:
        result = run_episode(env, make_expert(env), seed=4, options=None)
        assert result.success
    finally:
        env.close()


def test_the_perturbed_report_names_each_perturbation(capsys):
    expert_cli.main(["--perturbed", "1", "--task", "ReachTarget-v0"])
    out = capsys.readouterr().out
    assert out.startswith("ReachTarget-v0: 3/3 = 100.0 % success from perturbed states")
    assert "random 1/1" in out and "jaws 1/1" in out and "shove 1/1" in out
    assert "push" not in out
    with pytest.raises(SystemExit):
        expert_cli.main(["--perturbed", "0"])
