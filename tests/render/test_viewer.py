"""render_mode='human': a real OpenCV window under Xvfb, driven with real key presses.

Window tests skip only when no display or no GUI build of OpenCV exists, and fail
instead when GYM_SOARM_REQUIRE_WINDOWS=1 (CI). The error tests run everywhere.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from xwindows import (
    close_window,
    grab,
    press,
    require_window_tools,
    skip_or_fail,
    wait_for,
    wait_for_window,
    window_size,
)

import gym_soarm
from gym_soarm.render.display import opencv_gui_backend

pytestmark = [pytest.mark.window, pytest.mark.gl]

HEIGHT, WIDTH = 120, 160  # small, and above Qt's minimum window size


@pytest.fixture
def windows():
    require_window_tools()


@pytest.fixture
def human_env(windows):
    env = gym.make(
        "SoArm-v0",
        render_mode="human",
        obs_type="environment_state_agent_pos",
        observation_height=HEIGHT,
        observation_width=WIDTH,
    )
    yield env
    env.close()


def _hold(obs) -> np.ndarray:
    return np.asarray(obs["agent_pos"], dtype=np.float32)


def _wait_until_shown(env, window: int) -> np.ndarray:
    """Re-show the current state until the window's pixels equal the viewer's frame."""
    viewer = env.unwrapped.viewer

    def shown() -> np.ndarray | None:
        assert env.render() is None
        pixels = grab(window)
        if pixels is not None and np.array_equal(pixels, viewer.last_frame):
            return pixels
        return None

    return wait_for(shown, "the window to show the viewer's last frame")


def _difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).mean())


def test_window_shows_the_camera_and_keys_switch_it(human_env):
    env = human_env
    obs, _ = env.reset(seed=0, options={"cube_grid_position": 4})
    viewer = env.unwrapped.viewer
    window = wait_for_window(viewer.window_name)
    assert window_size(window) == (WIDTH, HEIGHT)
    assert viewer.camera == "front_camera"

    renders = {
        camera: env.unwrapped.render_camera_image(camera)
        for camera in gym_soarm.constants.CAMERA_NAMES
    }
    # The overlay covers the top of the frame; below it the window shows the camera.
    below_overlay = slice(HEIGHT // 2, None)

    def check_window_shows(camera: str) -> None:
        pixels = _wait_until_shown(env, window)
        assert pixels.shape == (HEIGHT, WIDTH, 3)
        shown = pixels[below_overlay]
        assert _difference(shown, renders[camera][below_overlay]) < 1.0
        for other, image in renders.items():
            if other != camera:
                assert _difference(shown, image[below_overlay]) > 5.0, other

    check_window_shows("front_camera")
    for key, camera in (("3", "wrist_camera"), ("1", "overview_camera"), ("2", "front_camera")):
        press(window, key)
        wait_for(lambda camera=camera: env.render() is None and viewer.camera == camera, camera)
        check_window_shows(camera)

    # Stepping updates the picture (the arm moves) and the env works as usual.
    before = viewer.last_frame.copy()
    target = _hold(obs)
    target[0] += 0.8  # shoulder_pan
    for _ in range(20):
        obs, *_ = env.step(target)
    assert obs["agent_pos"][0] == pytest.approx(target[0], abs=0.05)
    after = _wait_until_shown(env, window)
    assert _difference(after, before) > 1.0
    assert viewer.is_open


def test_q_closes_the_viewer_and_the_env_keeps_working(human_env):
    env = human_env
    obs, _ = env.reset(seed=1)
    viewer = env.unwrapped.viewer
    window = wait_for_window(viewer.window_name)
    press(window, "q", window_may_close=True)
    wait_for(lambda: env.step(_hold(obs)) and not viewer.is_open, "q to close the viewer")
    wait_for(lambda: window_size(window) is None, "the window to disappear")

    obs, _, _, _, info = env.step(_hold(obs))
    assert obs["agent_pos"].shape == (6,)
    assert env.render() is None
    obs, info = env.reset(seed=2)
    assert "is_success" in info
    env.close()
    env.close()


def test_closing_the_window_closes_the_viewer(human_env):
    env = human_env
    obs, _ = env.reset(seed=0)
    viewer = env.unwrapped.viewer
    window = wait_for_window(viewer.window_name)
    close_window(window)  # what a window manager's close button sends
    wait_for(lambda: env.render() is None and not viewer.is_open, "the viewer to notice")
    wait_for(lambda: window_size(window) is None, "the window to disappear")
    # The viewer does not come back on later steps.
    for _ in range(3):
        obs, *_ = env.step(_hold(obs))
    assert not viewer.is_open
    assert window_size(window) is None


def test_two_human_envs_get_two_windows(windows):
    envs = [
        gym.make(
            "SoArm-v0",
            render_mode="human",
            obs_type="environment_state_agent_pos",
            observation_height=HEIGHT,
            observation_width=WIDTH,
        )
        for _ in range(2)
    ]
    try:
        for env in envs:
            env.reset(seed=0)
        names = [env.unwrapped.viewer.window_name for env in envs]
        assert names[0] != names[1]
        ids = [wait_for_window(name) for name in names]
        assert ids[0] != ids[1]
        with pytest.raises(ValueError, match="camera must be one of"):
            envs[0].unwrapped.viewer.set_camera("side_camera")
        envs[0].unwrapped.viewer.set_camera("wrist_camera")
        envs[0].render()
        assert envs[0].unwrapped.viewer.camera == "wrist_camera"
    finally:
        for env in envs:
            env.close()
    for window in ids:
        wait_for(lambda window=window: window_size(window) is None, "close() to remove windows")


# --- no windows: a clear error, never a Qt abort or a hang ------------------------------
_MAKE_HUMAN_ENV = """
import json, gymnasium as gym, gym_soarm
try:
    gym.make("SoArm-v0", render_mode="human", obs_type="environment_state_agent_pos")
except gym_soarm.DisplayUnavailableError as error:
    print(json.dumps({"runtime_error": isinstance(error, RuntimeError), "message": str(error)}))
else:
    print(json.dumps({"message": None}))
"""


def _make_human_env_in_subprocess(display: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    if display is not None:
        env["DISPLAY"] = display
    result = subprocess.run(
        [sys.executable, "-c", _MAKE_HUMAN_ENV],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert result.returncode == 0, result.stderr  # no abort
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.subprocess
def test_no_display_raises_display_unavailable_error():
    outcome = _make_human_env_in_subprocess(display=None)
    message = outcome["message"]
    assert message is not None, "human mode without a display must raise"
    assert outcome["runtime_error"]
    assert "DISPLAY is not set" in message
    assert "xvfb-run" in message
    headless = opencv_gui_backend() is None
    assert ("headless build" in message) == headless
    if headless:
        assert "pip install --force-reinstall --no-deps" in message
        assert "opencv-python==" in message


@pytest.mark.subprocess
def test_unreachable_display_raises_instead_of_aborting():
    outcome = _make_human_env_in_subprocess(display=":7913")
    message = outcome["message"]
    assert message is not None
    assert "DISPLAY=':7913' cannot be reached" in message
    assert "xvfb-run" in message


@pytest.mark.subprocess
def test_with_a_display_only_the_headless_build_is_refused():
    display = os.environ.get("DISPLAY")
    if not display:
        skip_or_fail("no display (pytest-xvfb starts one when Xvfb is installed)")
    message = _make_human_env_in_subprocess(display=display)["message"]
    if opencv_gui_backend() is not None:
        assert message is None, "GUI OpenCV and a display: human mode must construct"
        return
    assert message is not None, "a headless OpenCV build must be refused"
    assert "headless build" in message
    assert "pip install --force-reinstall --no-deps" in message
    assert "opencv-python==" in message
    assert "DISPLAY" not in message  # the display is fine: only the build is named
