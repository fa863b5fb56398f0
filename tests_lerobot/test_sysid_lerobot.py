"""The dynamics fit on a 30 fps dataset written by LeRobot's own ``LeRobotDataset``.

The dataset carries the real follower's feature names and robot_type, in degrees, at
``lerobot-record``'s default 30 fps. Its states come from the simulation run with known
dynamics (servo kp x0.7, kv x1.6, one step of control delay), sampled at the frames'
times as the replay samples them; ``python -m gym_soarm.sysid`` fits them back from the
model's own figures.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("lerobot")

from gym_soarm import constants
from gym_soarm.real import units
from gym_soarm.real.replay import SIM_FPS, frame_of_steps

FPS = 30
KP, KV = 998.0, 15.0
TRUE_KP, TRUE_KV, TRUE_DELAY = 0.7 * KP, 1.6 * KV, 1


def _has_toolbox() -> bool:
    import mujoco.sysid

    return hasattr(mujoco.sysid, "optimize")


pytestmark = pytest.mark.skipif(
    not _has_toolbox(), reason='MuJoCo\'s sysid toolbox: pip install "gym-soarm[sysid]"'
)


def _actions(frames: int, episode: int) -> np.ndarray:
    """Degrees (gripper 0-100): sweeps of every joint, with holds and sudden steps."""
    t = np.arange(frames) / FPS
    amplitude = np.array([35.0, 20.0, 25.0, 30.0, 50.0, 25.0])
    centre = np.array([0.0, -20.0, -20.0, 0.0, 0.0, 50.0])  # the jaws stay off the table
    wave = np.sin(2 * np.pi * (0.4 + 0.2 * episode) * t)[:, None]
    steps = np.sign(np.sin(2 * np.pi * 0.7 * t + episode))[:, None] * 0.25
    return (centre + amplitude * (wave + steps)).astype(np.float32)


def _simulated_states(env, actions: np.ndarray) -> np.ndarray:
    """The states a 30 fps recording of the simulated arm holds: 50 Hz steps, each
    sending the frame in force at its start, interpolated to the frames' times."""
    base = env.unwrapped
    env.reset(seed=0)
    physics = base.physics
    start = np.clip(base.joint_units.to_radians(actions[0]), *physics.control_range())
    physics.set_joint_angles(start)
    base.hold_servo_targets(start)
    physics.forward()
    frames = len(actions)
    steps = math.ceil((frames - 1) * SIM_FPS / FPS - 1e-9)
    positions = [base.joint_units.from_radians(physics.joint_angles())]
    for frame in frame_of_steps(steps, frames, FPS):
        obs, *_ = env.step(actions[frame])
        positions.append(obs["agent_pos"].astype(np.float64))
    positions = np.array(positions)
    step_times = np.arange(steps + 1) / SIM_FPS
    times = np.arange(frames) / FPS
    return np.stack(
        [np.interp(times, step_times, positions[:, j]) for j in range(6)], axis=1
    ).astype(np.float32)


@pytest.fixture(scope="module")
def lerobot_dataset(tmp_path_factory) -> tuple[Path, Path]:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    folder = tmp_path_factory.mktemp("sysid")
    true = folder / "true.json"
    joints = {name: {"kp": TRUE_KP, "kv": TRUE_KV} for name in constants.JOINT_NAMES}
    true.write_text(
        json.dumps(
            {
                "format": "gym_soarm.dynamics/1",
                "joints": joints,
                "control_delay_steps": TRUE_DELAY,
            }
        )
    )
    root = folder / "so101_sysid"
    joint = {"dtype": "float32", "shape": (6,), "names": list(units.FEATURE_NAMES)}
    dataset = LeRobotDataset.create(
        repo_id="local/so101_sysid",
        fps=FPS,
        root=root,
        robot_type="so101_follower",
        features={"action": joint, "observation.state": dict(joint)},
        use_videos=False,
    )
    env = gym.make(
        "gym_soarm/ReachTarget-v0",
        obs_type="environment_state_agent_pos",
        units="lerobot",
        dynamics=true,
    )
    try:
        for episode in range(2):
            actions = _actions(120, episode)
            states = _simulated_states(env, actions)
            for a, s in zip(actions, states, strict=True):
                dataset.add_frame({"action": a, "observation.state": s, "task": "excite"})
            dataset.save_episode()
    finally:
        env.close()
    dataset.finalize()
    return root, true


def test_the_fit_recovers_known_dynamics_from_a_lerobot_dataset(lerobot_dataset, tmp_path):
    root, _ = lerobot_dataset
    out, plot = tmp_path / "arm.json", tmp_path / "arm.png"
    result = subprocess.run(
        [sys.executable, "-m", "gym_soarm.sysid", "--root", str(root), "--out", str(out),
         "--plot", str(plot)],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    fitted = json.loads(out.read_text())
    assert fitted["control_delay_steps"] == TRUE_DELAY
    fit = fitted["fit"]
    assert fit["fps"] == FPS and fit["units"] == "lerobot"
    for name in constants.JOINT_NAMES:
        assert fitted["joints"][name]["kp"] == pytest.approx(TRUE_KP, rel=0.25), name
        assert fit["rms_after_deg"][name] < 0.5, name
    assert fit["overall_rms_after_deg"] <= fit["overall_rms_before_deg"] / 5
    assert plot.stat().st_size > 10_000
