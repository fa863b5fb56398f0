"""Files the package wrote keep loading: dynamics files under both format names, and a
recording's settings, kept in ``tests/data/formats`` as a release wrote them (real MuJoCo)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import gymnasium as gym
import pytest

from gym_soarm import constants
from gym_soarm.envs.settings import SETTINGS_FORMAT, EnvSettings
from gym_soarm.real.dynamics import (
    FORMAT,
    FORMATS,
    Dynamics,
    load_dynamics,
    read_model_dynamics,
    write_dynamics,
)
from gym_soarm.real.replay import replay
from gym_soarm.record.record import SETTINGS_PATH, read_recording_settings, record

FORMATS_DIR = Path(__file__).parent / "data" / "formats"
DYNAMICS_FILES = ["gym_soarm.dynamics-1.json", "gym_soarm.real.dynamics-1.json"]
FITTED_KP, FITTED_KV = 698.6, 24.0  # both files' servo gains


def test_dynamics_files_are_written_under_the_documented_name(tmp_path):
    assert FORMAT == "gym_soarm.dynamics/1"
    assert FORMATS == ("gym_soarm.dynamics/1", "gym_soarm.real.dynamics/1")
    path = tmp_path / "arm.json"
    write_dynamics(Dynamics({"gripper": {"kp": 500.0}}, 1), path)
    assert json.loads(path.read_text())["format"] == "gym_soarm.dynamics/1"


@pytest.mark.parametrize("name", DYNAMICS_FILES)
def test_a_dynamics_file_of_either_name_loads_records_and_replays(tmp_path, name):
    path = str(tmp_path / name)
    shutil.copy(FORMATS_DIR / name, path)
    dynamics = load_dynamics(path)
    assert dynamics.control_delay_steps == 1
    assert set(dynamics.joints) == set(constants.JOINT_NAMES)

    env = gym.make(
        "gym_soarm/ReachTarget-v0", obs_type="environment_state_agent_pos", dynamics=path
    )
    try:
        env.reset(seed=0)
        figures = read_model_dynamics(env.unwrapped.physics.model.ptr)
        assert figures["elbow_flex"]["kp"] == pytest.approx(FITTED_KP)
        assert figures["elbow_flex"]["kv"] == pytest.approx(FITTED_KV)
        assert figures["elbow_flex"]["damping"] == pytest.approx(0.6)
        assert env.unwrapped.servo_chain.delay_steps == 1
    finally:
        env.close()

    root = tmp_path / "reach"
    record(root, task="ReachTarget-v0", episodes=1, seed=0, camera_config="none", dynamics=path)
    stored = json.loads((root / SETTINGS_PATH).read_text())
    assert stored["dynamics"] == os.path.abspath(path)
    report = replay(root)
    assert report.settings.dynamics == os.path.abspath(path)
    assert max(row["max_abs"] for row in report.figures().values()) < 1e-4


@pytest.mark.parametrize("found", ["gym_soarm.dynamics/2", "gym_soarm.sim.dynamics/1", ""])
def test_an_unknown_dynamics_format_is_refused(tmp_path, found):
    path = tmp_path / "arm.json"
    path.write_text(json.dumps({"format": found, "control_delay_steps": 1}))
    with pytest.raises(ValueError) as error:
        load_dynamics(path)
    message = str(error.value)
    assert str(path) in message
    assert f"field 'format' is {found!r}" in message
    assert "expected 'gym_soarm.dynamics/1' or 'gym_soarm.real.dynamics/1'" in message
    assert "python -m gym_soarm.sysid" in message  # how to make a good one
    with pytest.raises(ValueError, match="field 'format'"):
        gym.make("gym_soarm/ReachTarget-v0", dynamics=str(path))


def test_a_recordings_settings_load(tmp_path):
    (tmp_path / "meta").mkdir()
    shutil.copy(FORMATS_DIR / "recording-meta-gym_soarm.json", tmp_path / SETTINGS_PATH)
    content = json.loads((tmp_path / SETTINGS_PATH).read_text())
    assert content["env"]["format"] == SETTINGS_FORMAT
    settings = read_recording_settings(tmp_path)
    assert settings is not None
    assert settings.task == "ReachTarget-v0" and settings.units == "lerobot"
    assert settings.camera_config == ("front_camera",)
    # A field the file predates keeps its default.
    assert settings.control_hz == EnvSettings().control_hz
