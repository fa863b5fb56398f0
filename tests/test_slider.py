"""examples/slider_control_final.py in real windows under Xvfb, driven like a person would.

The trackbars are moved with mouse clicks (a middle click sets a Qt slider to the
clicked position), keys are real key presses, and the arm's motion is read back from
the script's event lines (one per SPACE, reset and exit, joint angles in radians).
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from xwindows import (
    EventProgram,
    click,
    close_window,
    find_windows,
    grab,
    press,
    require_window_tools,
    wait_for,
    window_size,
)

from gym_soarm import constants

pytestmark = [pytest.mark.window, pytest.mark.gl]

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "slider_control_final.py"
HEIGHT, WIDTH = 240, 320
RESET_ROW = len(constants.JOINT_NAMES)  # the Reset trackbar comes after the six joints
MIDDLE_BUTTON = 2
AT_TARGET_RAD = 0.02
_JOINT_VALUE = re.compile(r"(\w+)=([+-]\d+\.\d+)")


def _load_script():
    spec = importlib.util.spec_from_file_location("slider_control_final", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


slider = _load_script()


class SliderProcess(EventProgram):
    """The script running in its own process, its windows and its event lines."""

    name = "the script"

    def __init__(self, tmp_path: Path, *extra: str) -> None:
        size = ["--height", str(HEIGHT), "--width", str(WIDTH)]
        self.start([sys.executable, "-u", str(SCRIPT), *size, *extra], tmp_path)
        self.control = self._wait_for_window(slider.CONTROL_WINDOW)
        self.camera = self._wait_for_window(slider.CAMERA_WINDOW)
        # Windows appear before their content; wait for the final layout.
        wait_for(
            lambda: (
                window_size(self.camera) == (WIDTH, HEIGHT)
                and window_size(self.control)[0] == slider.PANEL_WIDTH
            ),
            "the windows to take their final size",
        )

    def _wait_for_window(self, name: str) -> int:
        def mapped() -> int | None:
            self.check_running(f"window {name!r}")
            return next((w for w in find_windows(name) if window_size(w) is not None), None)

        return int(wait_for(mapped, f"a window titled {name!r}"))

    def trackbar_center_y(self, row: int) -> int:
        # Qt lays the panel image out on top and the seven trackbar rows below it.
        _, height = window_size(self.control)
        row_height = (height - slider.PANEL_HEIGHT) / (RESET_ROW + 1)
        assert 15 <= row_height <= 60, f"unexpected trackbar layout: {height=}"
        return round(slider.PANEL_HEIGHT + row_height * (row + 0.5))

    def set_trackbar(self, row: int, fraction: float) -> None:
        """Middle-click a trackbar at ``fraction`` of the window width."""
        width, _ = window_size(self.control)
        click(self.control, round(width * fraction), self.trackbar_center_y(row), MIDDLE_BUTTON)


def parse(line: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Joint angles and, for step lines, slider targets (rad) from an event line."""
    joints_text, _, targets_text = line.partition(" targets ")

    def values(text: str) -> np.ndarray:
        pairs = dict(_JOINT_VALUE.findall(text))
        return np.array([float(pairs[name]) for name in constants.JOINT_NAMES])

    return values(joints_text), (values(targets_text) if targets_text else None)


@pytest.fixture
def teleop(tmp_path):
    require_window_tools()
    process = SliderProcess(tmp_path, "--seed", "0")
    yield process
    process.stop()


def test_sliders_space_reset_keys_and_esc(teleop):
    home, _ = parse(teleop.wait_for_event("reset", 1))
    np.testing.assert_allclose(home, 0.0, atol=1e-6)  # the home keyframe: all joints 0 rad

    # Move shoulder_pan's slider well right of the middle, then SPACE: the arm goes there.
    teleop.set_trackbar(row=0, fraction=0.8)
    press(teleop.camera, "space")
    joints, targets = parse(teleop.wait_for_event("step", 1))
    assert targets[0] > 0.3, "the click did not move the shoulder_pan slider"
    np.testing.assert_allclose(targets[1:], 0.0, atol=1e-6)  # untouched sliders stay exact
    np.testing.assert_allclose(joints, targets, atol=AT_TARGET_RAD)

    # Camera keys: the camera window switches to the wrist camera.
    below_overlay = slice(HEIGHT * 3 // 4, None)
    before = wait_for(lambda: grab(teleop.camera), "camera pixels")[below_overlay]
    press(teleop.camera, "3")
    assert teleop.wait_for_event("camera", 1) == "camera wrist_camera"

    def switched() -> bool:
        pixels = grab(teleop.camera)
        return pixels is not None and np.abs(pixels[below_overlay] - before.astype(int)).mean() > 5

    wait_for(switched, "the camera window to show another camera")

    # The Reset trackbar: back to the home pose, sliders included.
    teleop.set_trackbar(row=RESET_ROW, fraction=0.99)
    joints, _ = parse(teleop.wait_for_event("reset", 2))
    np.testing.assert_allclose(joints, 0.0, atol=1e-6)
    press(teleop.camera, "space")
    joints, targets = parse(teleop.wait_for_event("step", 2))
    np.testing.assert_allclose(targets, 0.0, atol=1e-6)
    np.testing.assert_allclose(joints, 0.0, atol=AT_TARGET_RAD)

    # Move elbow_flex (row 2) left, step, then R resets.
    teleop.set_trackbar(row=2, fraction=0.55)
    press(teleop.camera, "space")
    joints, targets = parse(teleop.wait_for_event("step", 3))
    assert targets[2] < -0.1, "the click did not move the elbow_flex slider"
    np.testing.assert_allclose(joints, targets, atol=AT_TARGET_RAD)
    press(teleop.camera, "r")
    joints, _ = parse(teleop.wait_for_event("reset", 3))
    np.testing.assert_allclose(joints, 0.0, atol=1e-6)

    press(teleop.camera, "Escape", window_may_close=True)
    assert teleop.wait_for_exit() == 0
    exit_joints, _ = parse(teleop.wait_for_event("exit", 1))
    np.testing.assert_allclose(exit_joints, 0.0, atol=1e-6)


def test_closing_a_window_exits_cleanly(teleop):
    teleop.wait_for_event("reset", 1)
    close_window(teleop.camera)
    assert teleop.wait_for_exit() == 0
    teleop.wait_for_event("exit", 1)


@pytest.mark.subprocess
def test_without_a_display_it_explains_and_exits():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run(
        [sys.executable, str(SCRIPT)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert result.returncode == 1
    assert "Cannot open a window" in result.stderr
    assert "DISPLAY is not set" in result.stderr
    assert "xvfb-run" in result.stderr
