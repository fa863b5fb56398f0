"""python -m gym_soarm.teleop in a real window under Xvfb, driven with real key presses.

The program prints one line per event (reset, start, save, discard, exit) with the
measured jaw centre in the robot's base frame; the recorded dataset is read back with
pyarrow and ffmpeg. The gamepad's mapping is tested as the pure functions it is.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from dataset_files import read_dataset
from mp4 import read_video
from xwindows import (
    EventProgram,
    close_window,
    press,
    require_window_tools,
    wait_for,
    wait_for_window,
)

from gym_soarm.cli.teleop import main
from gym_soarm.teleop import (
    GamepadLayout,
    KeyboardInput,
    TeleopSpeeds,
    gamepad_commands,
    gamepad_motion,
)
from gym_soarm.teleop.input import DISCARD, GRIPPER, QUIT, SAVE
from gym_soarm.teleop.session import WINDOW_TITLE

pytestmark = [pytest.mark.window, pytest.mark.gl]

HEIGHT, WIDTH = 96, 128
INSTRUCTION = "Pick up the blue cube and lift it 5 cm above the table."
KEY_GAP_S = 0.15  # longer than a press's hold: every press moves at least one more step
MIN_MOVE_M = 0.006  # five presses move at least five 2 mm steps (0.1 m/s); the arm lags
OFF_AXIS = 0.25  # motion along the other axes, at most this fraction of the pressed one's
_JAW = re.compile(r"jaw x=([+-]\d+\.\d+) y=([+-]\d+\.\d+) z=([+-]\d+\.\d+)")


def jaw(line: str) -> np.ndarray:
    """The jaw centre (x, y, z) in metres of an event line."""
    match = _JAW.search(line)
    assert match, f"no jaw position in {line!r}"
    return np.array([float(v) for v in match.groups()])


class TeleopProcess(EventProgram):
    """The teleop running in its own process, its window and its event lines."""

    name = "teleop"

    def __init__(self, tmp_path: Path, *args: str, env: dict[str, str] | None = None) -> None:
        size = ["--size", f"{HEIGHT}x{WIDTH}"]
        command = [sys.executable, "-u", "-m", "gym_soarm.teleop", *size, *args]
        self.start(command, tmp_path, env)
        self.window = self._wait_for_window()

    def _wait_for_window(self) -> int:
        def running_then_window() -> bool:
            self.check_running("the first reset")
            return bool(self.lines("reset"))

        wait_for(running_then_window, "the first reset")
        return wait_for_window(WINDOW_TITLE)

    def keys(self, *keys: str, gap_s: float = KEY_GAP_S) -> None:
        for key in keys:
            press(self.window, key)
            time.sleep(gap_s)


@pytest.fixture
def start_teleop(tmp_path):
    require_window_tools()
    started: list[TeleopProcess] = []

    def _start(*args: str, env: dict[str, str] | None = None) -> TeleopProcess:
        started.append(TeleopProcess(tmp_path, *args, env=env))
        return started[-1]

    yield _start
    for process in started:
        process.stop()


def _episode_rows(ds, key: str, episode: int) -> np.ndarray:
    return ds.data[key][ds.data["episode_index"] == episode]


def test_keys_move_the_jaws_save_discard_and_ctrl_c_keeps_saved_episodes(start_teleop, tmp_path):
    root = tmp_path / "teleop"
    teleop = start_teleop("--root", str(root), "--episodes", "5", "--control-mode", "ee_pose")
    home = jaw(teleop.wait_for_event("reset", 1))
    assert INSTRUCTION in teleop.lines("reset")[0]

    # W moves the jaw centre forward (base +x); nothing steps before the first key.
    time.sleep(0.5)
    assert not teleop.lines("start")
    teleop.keys(*"wwwww")
    teleop.wait_for_event("start", 1)
    teleop.keys("Return")
    saved = teleop.wait_for_event("saved", 1)
    moved = jaw(saved) - home
    assert moved[0] > MIN_MOVE_M, saved
    assert np.abs(moved[1:]).max() < OFF_AXIS * moved[0], saved
    frames_0 = int(re.search(r"frames (\d+)", saved).group(1))

    # R moves it up (+z), A to the robot's left (+y); SPACE opens the gripper.
    start_1 = jaw(teleop.wait_for_event("reset", 2))
    teleop.keys(*"rrrrr", "space", *"aaaaa")
    assert teleop.wait_for_event("gripper", 1) == "gripper opens"
    teleop.keys("Return")
    saved = teleop.wait_for_event("saved", 2)
    moved = jaw(saved) - start_1
    assert moved[2] > MIN_MOVE_M and moved[1] > MIN_MOVE_M, saved
    assert abs(moved[0]) < OFF_AXIS * min(moved[1], moved[2]), saved
    frames_1 = int(re.search(r"frames (\d+)", saved).group(1))

    # BACKSPACE drops an episode; Ctrl-C drops the one under way and keeps the saved ones.
    teleop.wait_for_event("reset", 3)
    teleop.keys("d", "d", "BackSpace")
    discarded = teleop.wait_for_event("discarded", 1)
    assert discarded.startswith("discarded episode 2")
    teleop.wait_for_event("reset", 4)
    teleop.keys("f", "f")
    teleop.wait_for_event("start", 4)
    teleop.process.send_signal(signal.SIGINT)
    assert teleop.wait_for_exit() == 130
    assert teleop.wait_for_event("exit", 1).startswith("exit episodes 2 ")

    ds = read_dataset(root)
    assert ds.info["total_episodes"] == 2
    assert ds.info["total_frames"] == frames_0 + frames_1
    assert len(ds.data["index"]) == frames_0 + frames_1
    assert [row["length"] for row in ds.episodes] == [frames_0, frames_1]
    assert [row["task"] for row in ds.tasks] == [INSTRUCTION]
    assert ds.info["features"]["action"]["names"][:3] == ["ee.x", "ee.y", "ee.z"]
    assert not (root / ".writer-scratch").exists()

    # The recorded actions are the jaw targets the keys set: forward, then up and left.
    action_0 = _episode_rows(ds, "action", 0)
    forward = action_0[-1, 0] - action_0[0, 0]
    assert forward > MIN_MOVE_M
    assert np.all(np.diff(action_0[:, 0]) >= -1e-3)  # never backwards
    assert np.abs(action_0[:, 1:3] - action_0[0, 1:3]).max() < OFF_AXIS * forward
    action_1 = _episode_rows(ds, "action", 1)
    assert action_1[-1, 2] - action_1[0, 2] > MIN_MOVE_M
    assert action_1[-1, 1] - action_1[0, 1] > MIN_MOVE_M
    assert action_1[-1, 5] > action_1[0, 5] + 10.0  # the gripper opened (percent)
    for episode in (0, 1):
        done = _episode_rows(ds, "next.done", episode).ravel()
        assert done[-1] and not done[:-1].any()  # ENTER ended it on its last frame
        assert not _episode_rows(ds, "next.success", episode).any()  # nothing was lifted
    for camera in ("front_camera", "wrist_camera"):
        key = f"observation.images.{camera}"
        frames, _ = read_video(ds.video_path(key, 0))
        assert frames.shape == (frames_0 + frames_1, HEIGHT, WIDTH, 3)


def test_closing_the_window_keeps_the_saved_episode(start_teleop, tmp_path):
    root = tmp_path / "state"
    teleop = start_teleop("--root", str(root), "--camera-config", "none", "--units", "radians")
    home = jaw(teleop.wait_for_event("reset", 1))
    teleop.keys(*"sssss", "Return")
    saved = teleop.wait_for_event("saved", 1)
    assert jaw(saved)[0] < home[0] - MIN_MOVE_M, saved  # S: backwards
    teleop.wait_for_event("reset", 2)
    close_window(teleop.window)
    assert teleop.wait_for_exit() == 0
    assert teleop.wait_for_event("window", 1) == "window closed"

    ds = read_dataset(root)
    frames = int(re.search(r"frames (\d+)", saved).group(1))
    assert ds.info["total_episodes"] == 1 and ds.info["total_frames"] == frames
    assert "observation.environment_state" in ds.info["features"]
    assert not (root / "videos").exists()
    # Backwards in the base frame is towards the robot: world -y for the gripper site.
    names = ds.info["features"]["observation.environment_state"]["names"]
    gripper_y = ds.data["observation.environment_state"][:, names.index("gripper_y")]
    assert gripper_y[-1] < gripper_y[0] - MIN_MOVE_M / 2
    assert ds.info["features"]["action"]["names"][0] == "shoulder_pan.pos"


def test_without_a_root_it_only_drives_and_esc_quits(start_teleop, tmp_path):
    home = tmp_path / "lerobot_home"
    env = {**os.environ, "HF_LEROBOT_HOME": str(home)}
    teleop = start_teleop("--task", "ReachTarget-v0", env=env)
    start = jaw(teleop.wait_for_event("reset", 1))
    teleop.keys(*"fffff", "Return")
    ended = teleop.wait_for_event("ended", 1)
    assert jaw(ended)[2] < start[2] - MIN_MOVE_M, ended  # F: down
    teleop.wait_for_event("reset", 2)
    press(teleop.window, "Escape", window_may_close=True)
    assert teleop.wait_for_exit() == 0
    assert teleop.wait_for_event("exit", 1).startswith("exit episodes 1 ")
    assert not home.exists()  # nothing recorded anywhere
    assert "recording" not in teleop.stdout_path.read_text()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--size", "95x128"], "even"),
        (["--speed", "0"], "--speed must be above 0 and at most 0.5 m/s"),
        (["--turn-speed", "9"], "--turn-speed must be above 0 and at most 5 rad/s"),
        (["--episodes", "0"], "--episodes must be an int >= 1"),
        (["--max-steps", "0"], "--max-steps must be an int >= 1"),
        (["--camera-config", "side_camera"], "side_camera"),
        (["--task", "Juggle-v0"], "got 'Juggle-v0'"),
        (["--control-mode", "torque"], "invalid choice: 'torque'"),
    ],
)
def test_bad_arguments_are_refused_with_the_fix(args, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "usage: python -m gym_soarm.teleop" in err
    assert message in err


def test_an_existing_dataset_needs_overwrite(tmp_path, capsys):
    require_window_tools()  # the folder is checked once windows are known to work
    root = tmp_path / "taken"
    root.mkdir()
    (root / "notes.txt").write_text("mine")
    with pytest.raises(SystemExit) as exc:
        main(["--root", str(root), "--size", f"{HEIGHT}x{WIDTH}"])
    assert exc.value.code == 2
    assert "not empty" in capsys.readouterr().err
    assert (root / "notes.txt").read_text() == "mine"


@pytest.mark.subprocess
def test_gamepad_without_pygame_names_the_install(tmp_path):
    # A pygame that fails to import stands for one that is not installed.
    (tmp_path / "pygame.py").write_text("raise ImportError(\"No module named 'pygame'\")\n")
    path = os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])
    result = subprocess.run(
        [sys.executable, "-m", "gym_soarm.teleop", "--gamepad"],
        env={**os.environ, "PYTHONPATH": path},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 2
    assert "pip install pygame" in result.stderr
    assert "gym-soarm[teleop]" in result.stderr


@pytest.mark.subprocess
def test_without_a_display_it_explains_and_exits():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run(
        [sys.executable, "-m", "gym_soarm.teleop"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 1
    assert "Cannot open a window" in result.stderr
    assert "xvfb-run" in result.stderr


# --- the input mapping, without a device -----------------------------------------------------
def test_a_key_press_moves_for_its_hold_and_at_least_one_step():
    keyboard = KeyboardInput(hold_s=0.1)
    assert keyboard.press(ord("w"), now_s=10.0) is None
    np.testing.assert_array_equal(keyboard.motion(10.05), [1, 0, 0, 0, 0])
    np.testing.assert_array_equal(keyboard.motion(10.2), [0, 0, 0, 0, 0])  # released
    keyboard.press(ord("R"), now_s=20.0)  # upper case works the same
    np.testing.assert_array_equal(keyboard.motion(25.0), [0, 0, 1, 0, 0])  # one step, late
    np.testing.assert_array_equal(keyboard.motion(25.01), [0, 0, 0, 0, 0])
    keyboard.press(ord("a"), 30.0)
    keyboard.press(ord("d"), 30.01)  # the opposite key reverses at once
    np.testing.assert_array_equal(keyboard.motion(30.02), [0, -1, 0, 0, 0])
    keyboard.press(ord("i"), 30.03)
    keyboard.press(ord("l"), 30.03)
    np.testing.assert_array_equal(keyboard.motion(30.04), [0, -1, 0, 1, -1])
    keyboard.clear()
    np.testing.assert_array_equal(keyboard.motion(30.05), [0, 0, 0, 0, 0])
    keyboard.press(65362, 40.0)  # the Up arrow: forward
    np.testing.assert_array_equal(keyboard.motion(40.0), [1, 0, 0, 0, 0])


def test_command_keys():
    keyboard = KeyboardInput()
    codes = {ord(" "): GRIPPER, 13: SAVE, 8: DISCARD, 27: QUIT, ord("q"): QUIT}
    for code, command in codes.items():
        assert keyboard.press(code, 0.0) == command
    assert keyboard.press(ord("z"), 0.0) is None
    np.testing.assert_array_equal(keyboard.motion(0.0), np.zeros(5))


def test_gamepad_sticks_and_buttons_map_to_motions_and_commands():
    layout = GamepadLayout()
    axes = [0.0] * 6
    buttons = [False] * 11
    np.testing.assert_array_equal(gamepad_motion(axes, buttons, layout), np.zeros(5))
    # Left stick pushed fully up and half left; right stick down; RB held.
    axes[layout.x_axis], axes[layout.y_axis], axes[layout.z_axis] = -1.0, -0.575, 0.5
    axes[layout.roll_axis] = 0.1  # inside the dead zone
    buttons[layout.pitch_up_button] = True
    motion = gamepad_motion(axes, buttons, layout)
    np.testing.assert_allclose(motion, [1.0, 0.5, -(0.5 - 0.15) / 0.85, 1.0, 0.0])
    buttons[layout.pitch_down_button] = True  # both shoulder buttons cancel
    assert gamepad_motion(axes, buttons, layout)[3] == 0.0

    previous = [False] * 11
    pressed = list(previous)
    pressed[layout.gripper_button] = pressed[layout.save_button] = True
    assert gamepad_commands(previous, pressed, layout) == [GRIPPER, SAVE]
    assert gamepad_commands(pressed, pressed, layout) == []  # held, not pressed again
    pressed[layout.discard_button] = True
    assert gamepad_commands(previous, pressed, layout)[-1] == DISCARD

    with pytest.raises(ValueError, match="needs 5 axes and 8 buttons; got 2 axes"):
        gamepad_motion([0.0, 0.0], buttons, layout)
    with pytest.raises(ValueError, match="dead_zone"):
        GamepadLayout(dead_zone=1.0)
    with pytest.raises(
        ValueError, match=r"x_axis must be an int >= 0; got -1\. Pass e\.g\. x_axis=1 "
    ):
        GamepadLayout(x_axis=-1)


def test_speeds_scale_a_motion_into_an_ee_delta_action():
    speeds = TeleopSpeeds(linear_m_s=0.1, angular_rad_s=1.0, step_s=0.02)
    action = speeds.ee_delta(np.array([1.0, -1.0, 0.5, 1.0, -2.0]), gripper=0.7)
    np.testing.assert_allclose(action, [0.002, -0.002, 0.001, 0.02, -0.02, 0.7])
    np.testing.assert_array_equal(speeds.ee_delta(np.zeros(5), 0.0), np.zeros(6))
    with pytest.raises(ValueError, match=r"linear_m_s must be above 0 and at most 0\.5"):
        TeleopSpeeds(linear_m_s=0.6)
    with pytest.raises(ValueError, match="angular_rad_s"):
        TeleopSpeeds(angular_rad_s=0.0)
    with pytest.raises(ValueError, match="step_s must be above 0"):
        TeleopSpeeds(step_s=0.0)
    with pytest.raises(TypeError, match="step_s must be a finite number"):
        TeleopSpeeds(step_s="x")
