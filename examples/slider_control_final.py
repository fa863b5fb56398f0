"""Drive the SO-101 joint by joint with sliders and watch it from its three cameras.

    python examples/slider_control_final.py

Two windows open:

* "SO-101 joints": six trackbars, one per joint, spanning that joint's range and
  starting at the current pose, and a "Reset" trackbar (set it to 1 to reset the
  episode: the arm goes back to its home pose, all joints at 0 rad, and the sliders follow).
* "SO-101 camera": the selected camera with the joint angles in radians.

Keys (with either window focused):

    SPACE   step the simulation so that the arm moves to the sliders (1 s of sim time)
    r       reset the episode (home pose)
    1/2/3   overview / front / wrist camera
    ESC     quit (closing either window quits too)

Windows need the GUI build of OpenCV and a display (see docs/videos-and-teleop.md, Windows).
Every event is also printed, one line each, with the joint angles in radians.
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np

import gym_soarm
from gym_soarm import constants
from gym_soarm.render.display import DisplayUnavailableError, require_windows
from gym_soarm.render.viewer import CAMERA_KEYS, draw_text_block

CONTROL_WINDOW = "SO-101 joints"
CAMERA_WINDOW = "SO-101 camera"
RESET_TRACKBAR = "Reset"
SLIDER_STEPS = 1000  # trackbar positions across each joint's range
PANEL_HEIGHT = 110  # the help and target panel above the trackbars (Qt) or below (GTK)
PANEL_WIDTH = 480
WINDOW_GAP = 10
SPACE_KEY, ESC_KEY = 32, 27
RESET_KEYS = (ord("r"), ord("R"))
IDLE_WAIT_MS = 30
DEFAULT_STEPS_PER_PRESS = 50  # 1 s at 50 Hz: a full-range move settles in about 0.7 s


def format_joints(values: np.ndarray) -> str:
    """``name=+0.123`` for each joint, in radians."""
    return " ".join(
        f"{name}={value:+.3f}" for name, value in zip(constants.JOINT_NAMES, values, strict=True)
    )


class SliderTeleop:
    """The two windows, the slider state and the simulation they drive.

    Args:
        env: an environment made by ``gym.make`` with ``units="radians"``.
        camera: the camera shown first.
        steps_per_press: environment steps taken per SPACE press.
        grid_cell: the cube's grid cell on every reset, or None for a random cell.
        seed: seed of the first reset.
    """

    def __init__(
        self,
        env: gym.Env,
        camera: str,
        steps_per_press: int,
        grid_cell: int | None,
        seed: int | None,
    ) -> None:
        self.env = env
        self.sim = env.unwrapped
        self.camera = camera
        self.steps_per_press = steps_per_press
        self.reset_options = {"cube_grid_position": grid_cell}
        self.low = env.action_space.low.astype(np.float64)
        self.high = env.action_space.high.astype(np.float64)
        self.targets = np.zeros(len(constants.JOINT_NAMES))
        self._slider_positions = np.zeros(len(constants.JOINT_NAMES), dtype=int)
        self._seed = seed
        self._pending_keys: list[int] = []

    # --- sliders -----------------------------------------------------------------------
    def to_slider(self, radians: np.ndarray) -> np.ndarray:
        """Trackbar positions (0..SLIDER_STEPS) of joint angles."""
        fraction = (np.clip(radians, self.low, self.high) - self.low) / (self.high - self.low)
        return np.rint(fraction * SLIDER_STEPS).astype(int)

    def from_slider(self, positions: np.ndarray) -> np.ndarray:
        """Joint angles in radians of trackbar positions."""
        return self.low + np.asarray(positions, dtype=np.float64) / SLIDER_STEPS * (
            self.high - self.low
        )

    def set_sliders(self, radians: np.ndarray) -> None:
        """Move every joint trackbar to ``radians`` and make those the targets."""
        import cv2

        self.targets = np.array(radians, dtype=np.float64)
        self._slider_positions = self.to_slider(self.targets)
        for name, position in zip(constants.JOINT_NAMES, self._slider_positions, strict=True):
            cv2.setTrackbarPos(name, CONTROL_WINDOW, int(position))

    def read_sliders(self) -> bool:
        """Take the targets of the trackbars a person moved; True if any changed."""
        import cv2

        positions = np.array(
            [cv2.getTrackbarPos(name, CONTROL_WINDOW) for name in constants.JOINT_NAMES]
        )
        moved = positions != self._slider_positions
        if not moved.any():
            return False
        # Untouched sliders keep their exact targets (a slider position is rounded).
        self.targets[moved] = self.from_slider(positions)[moved]
        self._slider_positions = positions
        return True

    # --- windows -----------------------------------------------------------------------
    def open_windows(self) -> None:
        """Create the control window with its trackbars and the camera window."""
        import cv2

        flags = cv2.WINDOW_AUTOSIZE | cv2.WINDOW_GUI_NORMAL
        cv2.namedWindow(CONTROL_WINDOW, flags)
        for name in constants.JOINT_NAMES:
            cv2.createTrackbar(name, CONTROL_WINDOW, SLIDER_STEPS // 2, SLIDER_STEPS, _ignore)
        cv2.createTrackbar(RESET_TRACKBAR, CONTROL_WINDOW, 0, 1, _ignore)
        cv2.namedWindow(CAMERA_WINDOW, flags)
        # Side by side, so that neither hides the other.
        cv2.moveWindow(CONTROL_WINDOW, 0, 0)
        cv2.moveWindow(CAMERA_WINDOW, PANEL_WIDTH + WINDOW_GAP, 0)

    def windows_open(self) -> bool:
        """False once a person closed either window."""
        import cv2

        try:
            return all(
                cv2.getWindowProperty(name, cv2.WND_PROP_VISIBLE) >= 1
                for name in (CONTROL_WINDOW, CAMERA_WINDOW)
            )
        except cv2.error:
            return False  # Qt forgets its windows once the last one is closed

    def draw_panel(self) -> None:
        """The help text and the slider targets in radians."""
        import cv2

        panel = np.full((PANEL_HEIGHT, PANEL_WIDTH, 3), 40, dtype=np.uint8)
        white = (255, 255, 255)
        lines = [
            ("SPACE step   r reset   1/2/3 camera   ESC quit", white),
            ("targets (rad):", (180, 220, 255)),
        ]
        pairs = list(zip(constants.JOINT_NAMES, self.targets, strict=True))
        for left, right in zip(pairs[0::2], pairs[1::2], strict=True):
            lines.append((f"{left[0]:>13} {left[1]:+.3f}   {right[0]:>13} {right[1]:+.3f}", white))
        draw_text_block(panel, lines)
        cv2.imshow(CONTROL_WINDOW, panel)

    def draw_camera(self) -> None:
        """The selected camera with the joint angles in radians."""
        import cv2

        rgb = self.sim.render_camera_image(self.camera)
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        joints = self.sim.physics.joint_angles()
        lines = [(f"{self.camera}  t {float(self.sim.physics.data.time):.2f} s", (255, 255, 255))]
        lines += [
            (f"{name:>13} {value:+.3f} rad", (200, 255, 200))
            for name, value in zip(constants.JOINT_NAMES, joints, strict=True)
        ]
        draw_text_block(bgr, lines)
        cv2.imshow(CAMERA_WINDOW, bgr)

    # --- actions -----------------------------------------------------------------------
    def reset(self) -> None:
        """Start a new episode (home pose) and put the sliders on it."""
        self.env.reset(seed=self._seed, options=self.reset_options)
        self._seed = None  # later resets continue the seeded random stream
        self.set_sliders(self.sim.physics.joint_angles())
        self.report("reset")

    def step_to_sliders(self) -> None:
        """Step the simulation towards the slider targets, showing every frame."""
        import cv2

        self.read_sliders()  # a slider moved in the same event batch as the key press
        action = self.targets.astype(np.float32)
        for _ in range(self.steps_per_press):
            info = self.env.step(action)[-1]
            self.draw_camera()
            key = cv2.waitKey(1)
            if key >= 0:
                self._pending_keys.append(key & 0xFF)
                if key & 0xFF == ESC_KEY:
                    break
            if info.get("physics_unstable"):
                print("the simulation diverged; resetting", flush=True)
                self.reset()
                return
        self.report("step", with_targets=True)

    def report(self, event: str, with_targets: bool = False) -> None:
        """Print one line: the event and the joint angles in radians."""
        line = f"{event} joints {format_joints(self.sim.physics.joint_angles())}"
        if with_targets:
            line += f" targets {format_joints(self.targets)}"
        print(line, flush=True)

    def next_key(self, wait_ms: int) -> int:
        """A key pressed during the last steps, or one pressed now (-1 for none)."""
        import cv2

        if self._pending_keys:
            return self._pending_keys.pop(0)
        key = cv2.waitKey(wait_ms)
        return key & 0xFF if key >= 0 else -1

    def run(self) -> None:
        """Show the windows and react to keys and sliders until ESC or a window closes."""
        import cv2

        self.open_windows()
        self.reset()
        self.draw_panel()
        self.draw_camera()
        while True:
            key = self.next_key(IDLE_WAIT_MS)
            if key == ESC_KEY or not self.windows_open():
                break
            redraw = False
            if key == SPACE_KEY:
                self.step_to_sliders()
                redraw = True
            elif key in RESET_KEYS:
                self.reset()
                redraw = True
            elif key >= 0 and chr(key) in CAMERA_KEYS:
                self.camera = CAMERA_KEYS[chr(key)]
                print(f"camera {self.camera}", flush=True)
                redraw = True
            if cv2.getTrackbarPos(RESET_TRACKBAR, CONTROL_WINDOW) == 1:
                self.reset()
                cv2.setTrackbarPos(RESET_TRACKBAR, CONTROL_WINDOW, 0)
                redraw = True
            if self.read_sliders() or redraw:
                self.draw_panel()
                self.draw_camera()
        self.report("exit")
        cv2.destroyAllWindows()
        cv2.waitKey(1)


def _ignore(_position: int) -> None:
    """Trackbar callback: positions are polled in the main loop instead."""


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--camera",
        choices=constants.CAMERA_NAMES,
        default="front_camera",
        help="camera shown first (default: front_camera)",
    )
    parser.add_argument("--height", type=int, default=480, help="camera image height in pixels")
    parser.add_argument("--width", type=int, default=640, help="camera image width in pixels")
    parser.add_argument(
        "--steps-per-press",
        type=int,
        default=DEFAULT_STEPS_PER_PRESS,
        help=f"environment steps per SPACE press (default: {DEFAULT_STEPS_PER_PRESS}, 1 s)",
    )
    parser.add_argument("--grid-cell", type=int, choices=range(9), default=None, metavar="0-8")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first reset")
    parser.add_argument(
        "--quality", choices=("fast", "high"), default="fast", help="render quality"
    )
    args = parser.parse_args(argv)
    if args.steps_per_press < 1:
        parser.error(f"--steps-per-press must be at least 1; got {args.steps_per_press}")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        require_windows()
    except DisplayUnavailableError as error:
        print(error, file=sys.stderr)
        return 1
    env = gym.make(
        "SoArm-v0",
        obs_type="environment_state_agent_pos",
        observation_height=args.height,
        observation_width=args.width,
        render_quality=args.quality,
    )
    try:
        SliderTeleop(env, args.camera, args.steps_per_press, args.grid_cell, args.seed).run()
    finally:
        env.close()
    print(f"bye (gym_soarm {gym_soarm.__version__})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
