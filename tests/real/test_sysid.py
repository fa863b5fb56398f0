"""Dynamics files and fitting them to a dataset (system identification), with real MuJoCo.

A recording made with known dynamics (servo kp x0.7, kv x1.6, one step of control
delay) is fitted back starting from the model's own figures.
"""

from __future__ import annotations

import json
import math
import os
import shutil

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.cli.sysid import main
from gym_soarm.real.dynamics import (
    FORMAT,
    JOINT_FIELDS,
    Dynamics,
    load_dynamics,
    read_model_dynamics,
    write_dynamics,
)
from gym_soarm.real.replay import read_replay_dataset, replay
from gym_soarm.record.record import SETTINGS_PATH, record

KP, KV = 998.0, 15.0  # the model's servo gains
TRUE_KP, TRUE_KV, TRUE_DELAY = 0.7 * KP, 1.6 * KV, 1
ENV = "gym_soarm/ReachTarget-v0"


def _has_toolbox() -> bool:
    import mujoco.sysid

    return hasattr(mujoco.sysid, "optimize")


needs_toolbox = pytest.mark.skipif(
    not _has_toolbox(), reason='MuJoCo\'s sysid toolbox: pip install "gym-soarm[sysid]"'
)


def _write(path, content) -> str:
    path.write_text(json.dumps(content))
    return str(path)


def _true_dynamics(folder) -> str:
    joints = {name: {"kp": TRUE_KP, "kv": TRUE_KV} for name in constants.JOINT_NAMES}
    return _write(
        folder / "true.json",
        {"format": FORMAT, "joints": joints, "control_delay_steps": TRUE_DELAY},
    )


def _model(**kwargs):
    env = gym.make(ENV, obs_type="environment_state_agent_pos", **kwargs)
    return env, env.unwrapped.physics.model.ptr


# --- dynamics files ---------------------------------------------------------------------
def test_a_file_round_trips_and_sets_the_model(tmp_path):
    joints = {
        "shoulder_pan": {"kp": 700.0, "kv": 20.0, "damping": 0.5, "armature": 0.03},
        "gripper": {"frictionloss": 0.2},
    }
    dynamics = Dynamics(joints, 2, {"note": "by hand"})
    path = tmp_path / "arm.json"
    write_dynamics(dynamics, path)
    loaded = load_dynamics(path)
    assert loaded.joints == joints and loaded.control_delay_steps == 2
    assert loaded.fit == {"note": "by hand"} and loaded.path == str(path)
    assert json.loads(path.read_text())["format"] == FORMAT

    env, model = _model(dynamics=path)
    try:
        figures = read_model_dynamics(model)
        assert figures["shoulder_pan"] == {**joints["shoulder_pan"], "frictionloss": 0.05}
        # Absent fields and joints keep the model's values.
        assert figures["gripper"] == {
            "kp": KP,
            "kv": KV,
            "damping": 0.6,
            "armature": 0.028,
            "frictionloss": 0.2,
        }
        assert figures["elbow_flex"]["kp"] == KP
        assert env.unwrapped.dynamics == str(path)
    finally:
        env.close()
    # Other environments keep the model's own figures.
    other, model = _model()
    try:
        assert read_model_dynamics(model)["shoulder_pan"]["kp"] == KP
    finally:
        other.close()


def test_the_delay_holds_each_action_back_that_many_steps(tmp_path):
    path = _write(tmp_path / "d.json", {"format": FORMAT, "control_delay_steps": 2})
    env = gym.make(ENV, obs_type="environment_state_agent_pos", dynamics=path)
    try:
        env.reset(seed=0)
        physics = env.unwrapped.physics
        home = physics.joint_targets().copy()
        actions = [np.full(6, 0.1 * (k + 1), np.float32) for k in range(4)]
        sent = []
        for action in actions:
            env.step(action)
            sent.append(physics.joint_targets().copy())
        np.testing.assert_allclose(sent[0], home)
        np.testing.assert_allclose(sent[1], home)
        np.testing.assert_allclose(sent[2], actions[0], rtol=1e-6)
        np.testing.assert_allclose(sent[3], actions[1], rtol=1e-6)
    finally:
        env.close()


def test_physics_randomisation_draws_around_the_fitted_figures(tmp_path):
    path = _write(
        tmp_path / "g.json",
        {
            "format": FORMAT,
            "joints": {"elbow_flex": {"kp": 500.0, "damping": 2.0}},
            "control_delay_steps": 1,
        },
    )
    env, model = _model(dynamics=path, physics_randomization="heavy")
    try:
        for seed in range(5):
            _, info = env.reset(seed=seed)
            figures = read_model_dynamics(model)["elbow_flex"]
            physics = info["variation"]["physics"]
            assert figures["kp"] == pytest.approx(
                500.0 * physics["kp_scale"]["elbow_flex"], rel=1e-5
            )
            assert figures["damping"] == pytest.approx(
                2.0 * physics["damping_scale"]["elbow_flex"], rel=1e-5
            )
            # The fitted delay plus the drawn one.
            assert env.unwrapped.servo_chain.delay_steps == 1 + physics["control_delay_steps"]
    finally:
        env.close()


BAD_FILES = [
    ({"format": "gym_soarm.real.dynamics/2"}, "field 'format' is 'gym_soarm.real.dynamics/2'"),
    ({"joints": {}}, "field 'format' is None"),
    ({"format": FORMAT, "joints": {"elbow": {"kp": 1.0}}}, "unknown joint 'elbow'"),
    ({"format": FORMAT, "joints": {"elbow_flex": {"kp": -5.0}}}, r"joints\.elbow_flex\.kp must be a positive gain"),
    ({"format": FORMAT, "joints": {"elbow_flex": {"kp": 0}}}, r"joints\.elbow_flex\.kp must be a positive gain"),
    ({"format": FORMAT, "joints": {"gripper": {"kv": -1}}}, r"joints\.gripper\.kv must be >= 0"),
    ({"format": FORMAT, "joints": {"gripper": {"damping": "0.6"}}}, r"joints\.gripper\.damping must be a number"),
    ({"format": FORMAT, "joints": {"gripper": {"armature": True}}}, r"joints\.gripper\.armature must be a number"),
    ({"format": FORMAT, "joints": {"gripper": {"stiffness": 1}}}, "unknown field 'stiffness'"),
    ({"format": FORMAT, "joints": {"gripper": [1, 2]}}, r"joints\.gripper is a list"),
    ({"format": FORMAT, "joints": [1]}, "field 'joints' is a list"),
    ({"format": FORMAT, "control_delay_steps": -1}, "'control_delay_steps' must be 0 to 50"),
    ({"format": FORMAT, "control_delay_steps": 1.5}, "'control_delay_steps' must be an integer"),
    ({"format": FORMAT, "control_delay_steps": True}, "'control_delay_steps' must be an integer"),
    ({"format": FORMAT, "delay": 1}, "unknown key 'delay'"),
    ([1, 2], "holds a list, not an object"),
]  # fmt: skip


@pytest.mark.parametrize(("content", "message"), BAD_FILES)
def test_a_bad_file_is_refused_naming_the_file_and_the_field(tmp_path, content, message):
    path = _write(tmp_path / "bad.json", content)
    with pytest.raises(ValueError, match=message) as error:
        load_dynamics(path)
    assert path in str(error.value)
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, dynamics=path)


def test_nan_missing_unreadable_and_wrong_type(tmp_path):
    nan = tmp_path / "nan.json"
    nan.write_text(json.dumps({"format": FORMAT, "joints": {"gripper": {"kp": math.nan}}}))
    with pytest.raises(ValueError, match=r"joints\.gripper\.kp must be finite"):
        load_dynamics(nan)
    with pytest.raises(ValueError, match="no such file"):
        load_dynamics(tmp_path / "none.json")
    text = tmp_path / "text.json"
    text.write_text("kp = 3")
    with pytest.raises(ValueError, match="is not JSON"):
        load_dynamics(text)
    with pytest.raises(TypeError, match="dynamics must be the path"):
        load_dynamics(3)
    # A bad file is refused before anything is written.
    target = tmp_path / "nothing.json"
    with pytest.raises(ValueError, match="positive gain"):
        write_dynamics(Dynamics({"gripper": {"kp": -1.0}}), target)
    assert not target.exists()


def test_the_recorder_refuses_a_bad_file_before_writing(tmp_path):
    bad = _write(tmp_path / "bad.json", {"format": FORMAT, "joints": {"elbow_flex": {"kp": -1}}})
    root = tmp_path / "data"
    with pytest.raises(ValueError, match=r"joints\.elbow_flex\.kp"):
        record(root, task="ReachTarget-v0", episodes=1, camera_config="none", dynamics=bad)
    assert not root.exists()


def test_the_programs_take_dynamics(tmp_path, capsys):
    from gym_soarm.cli import record as record_cli
    from gym_soarm.cli import teleop as teleop_cli

    assert teleop_cli.build_parser().parse_args(["--dynamics", "a.json"]).dynamics == "a.json"
    bad = _write(tmp_path / "bad.json", {"format": FORMAT, "joints": {"wrist": {}}})
    root = tmp_path / "data"
    with pytest.raises(SystemExit) as exit_info:
        record_cli.main(
            ["--task", "ReachTarget-v0", "--episodes", "1", "--camera-config", "none",
             "--root", str(root), "--dynamics", bad]
        )  # fmt: skip
    assert exit_info.value.code == 2
    assert "unknown joint 'wrist'" in capsys.readouterr().err
    assert not root.exists()


# --- the fit ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Reach episodes recorded with known dynamics, in LeRobot units (seed 0)."""
    folder = tmp_path_factory.mktemp("sysid")
    true = _true_dynamics(folder)
    root = folder / "reach"
    record(root, task="ReachTarget-v0", episodes=3, seed=0, camera_config="none", dynamics=true)
    return root, true


@pytest.fixture(scope="module")
def fitted(recorded, tmp_path_factory):
    root, _ = recorded
    folder = tmp_path_factory.mktemp("fit")
    out, plot = folder / "arm.json", folder / "fit.png"
    assert main(["--root", str(root), "--out", str(out), "--plot", str(plot)]) == 0
    return out, plot


def test_the_recording_says_which_dynamics_it_moved_with(recorded):
    root, true = recorded
    settings = json.loads((root / SETTINGS_PATH).read_text())
    assert settings["dynamics"] == os.path.abspath(true)
    # Replayed with the same file, the simulation reproduces the recording.
    report = replay(root, dynamics=true)
    assert max(row["max_abs"] for row in report.figures().values()) < 1e-4
    # Replayed without arguments, too: the replay reads the recording's settings back.
    report = replay(root)
    assert report.settings.dynamics == os.path.abspath(true)
    assert max(row["max_abs"] for row in report.figures().values()) < 1e-4


@needs_toolbox
def test_known_dynamics_are_fitted_back(recorded, fitted):
    root, _ = recorded
    out, plot = fitted
    dynamics = load_dynamics(out)
    assert dynamics.control_delay_steps == TRUE_DELAY
    fit = dynamics.fit
    states = np.concatenate([s for _, s in read_replay_dataset(root).episodes.values()])
    for j, name in enumerate(constants.JOINT_NAMES):
        figures = dynamics.joints[name]
        assert set(figures) == set(JOINT_FIELDS)
        # A joint that hardly moves cannot tell its gain (reach leaves wrist_roll alone).
        if np.ptp(states[:, j]) > 5.0:
            assert figures["kp"] == pytest.approx(TRUE_KP, rel=0.25), name
        before, after = fit["rms_before_deg"][name], fit["rms_after_deg"][name]
        assert after < 0.5, name
        if before > 0.05:
            assert after <= before / 5, name
    assert fit["overall_rms_after_deg"] < 0.5
    assert fit["overall_rms_after_deg"] <= fit["overall_rms_before_deg"] / 5
    assert min(fit["delay_rms_deg"], key=fit["delay_rms_deg"].get) == str(TRUE_DELAY)
    assert fit["episodes"] == [0, 1, 2] and fit["fps"] == 50
    assert plot.stat().st_size > 10_000
    # The environment loads the fit, and replaying with it tracks the recording.
    report = replay(root, dynamics=out)
    rms_deg = [row["rms"] for key, row in report.figures().items() if key != "gripper.pos"]
    assert max(rms_deg) < 0.5
    before = replay(root, settings={"dynamics": None})  # the model's own
    assert before.figures()["wrist_flex.pos"]["rms"] > 5 * report.figures()["wrist_flex.pos"]["rms"]


def _edit_info(root, folder, edit):
    shutil.copytree(root, folder)
    info_path = folder / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    edit(info)
    info_path.write_text(json.dumps(info))
    return folder


@needs_toolbox
def test_a_bad_dataset_is_refused_and_nothing_is_written(recorded, tmp_path, capsys):
    root, _ = recorded
    out = tmp_path / "out.json"

    def refused(dataset, message, *extra):
        with pytest.raises(SystemExit) as exit_info:
            main(["--root", str(dataset), "--out", str(out), *extra])
        assert exit_info.value.code == 2
        assert message in capsys.readouterr().err
        assert not out.exists()

    no_action = _edit_info(root, tmp_path / "a", lambda info: info["features"].pop("action"))
    refused(no_action, "no 'action' feature")
    no_state = _edit_info(
        root, tmp_path / "s", lambda info: info["features"].pop("observation.state")
    )
    refused(no_state, "no 'observation.state' feature")
    other_robot = _edit_info(
        root,
        tmp_path / "r",
        lambda info: info["features"]["action"].update(names=[f"joint{i}" for i in range(6)]),
    )
    refused(other_robot, "'action' has the values ['joint0'")
    refused(root, "A fit needs at least 2 s", "--episodes", "0")
    refused(root, "no episode 9", "--episodes", "9")
    refused(tmp_path / "nowhere", "no such folder")
    with pytest.raises(SystemExit):
        main(["--root", str(root), "--out", str(tmp_path / "x.txt")])
    assert "--out must name a .json file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--root", str(root), "--out", str(tmp_path / "no" / "x.json")])
    assert "does not exist" in capsys.readouterr().err


@needs_toolbox
def test_a_fit_that_cannot_improve_keeps_the_model_s_own_figures(tmp_path, capsys):
    # Recorded by the simulation's own model, the start is exact: the result may not be worse.
    root = tmp_path / "own"
    record(root, task="ReachTarget-v0", episodes=6, seed=3, camera_config="none")
    out = tmp_path / "arm.json"
    assert main(["--root", str(root), "--out", str(out), "--iterations", "2"]) == 0
    fit = load_dynamics(out).fit
    assert fit["overall_rms_after_deg"] <= fit["overall_rms_before_deg"]
    for name in constants.JOINT_NAMES:
        assert fit["rms_after_deg"][name] <= fit["rms_before_deg"][name] + 1e-9, name
    if fit["kept_model_values"]:
        assert load_dynamics(out).control_delay_steps == 0
        assert "they are kept" in capsys.readouterr().out
