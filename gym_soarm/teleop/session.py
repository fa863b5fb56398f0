"""The teleoperation window: keys (and a gamepad) drive the jaws, episodes go to a dataset.

:class:`TeleopSession` runs one OpenCV window over an environment made by ``gym.make``.
The simulation waits at each episode's start until the first key (so no still frames
lead the episode), then steps in real time, at the environment's 50 Hz or as fast as
rendering allows. Every step's command is a jaw motion in the robot's base frame (an
``ee_delta`` of :mod:`gym_soarm.envs.control`), solved into six servo targets by the
environment's inverse kinematics and sent, and recorded, as the environment's own
control mode's action (``env.unwrapped.control.action_for_targets``), as the recorder
does for the scripted expert.

An episode ends when the user saves it (ENTER), when the task succeeds (the
environment terminates) or at the step limit; a recording then saves it (with
``keep="success"`` only if the task succeeded). BACKSPACE drops its frames and starts
it again; a diverged simulation does too.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.data import LeRobotDatasetWriter
from gym_soarm.envs.control import EE_DELTA, make_control
from gym_soarm.real.units import joint_units
from gym_soarm.render.display import require_windows
from gym_soarm.render.viewer import draw_text_block
from gym_soarm.teleop.input import (
    DISCARD,
    GRIPPER,
    QUIT,
    SAVE,
    KeyboardInput,
    TeleopSpeeds,
)
from gym_soarm.validation import check_choice, check_int

WINDOW_TITLE = "gym_soarm teleop"
KEEP_CHOICES: tuple[str, ...] = ("all", "success")
GRIPPER_OPEN_RAD = 1.0
"""The gripper's target when open (rad): jaws about 6 cm apart, room round a 3 cm cube."""
GRIPPER_CLOSED_RAD = -0.17453
"""The gripper's target when closed (rad): its lower limit, squeezing what it holds."""
GRIPPER_SPEED_RAD_S = 4.0
"""How fast the gripper's target moves to open or closed (rad/s)."""
IDLE_WAIT_MS = 30
MIN_PANEL_WIDTH = 640
_MAX_KEYS_PER_STEP = 32
_N_ARM = len(constants.ARM_JOINT_NAMES)
_WHITE, _GREEN, _RED, _GREY = (255, 255, 255), (80, 220, 80), (80, 80, 255), (200, 200, 200)
_HELP_LINES = (
    "W/S x  A/D y  R/F z  I/K pitch  J/L roll  SPACE gripper",
    "ENTER save episode  BACKSPACE discard  ESC/Q quit",
)


@dataclasses.dataclass
class TeleopSummary:
    """What a teleoperation session did.

    Attributes:
        episodes: episodes saved to the dataset (ended ones when not recording).
        frames: frames saved.
        attempts: episodes started, saved or not.
        successes: episodes that ended with the task's success.
        interrupted: Ctrl-C stopped the session.
    """

    episodes: int = 0
    frames: int = 0
    attempts: int = 0
    successes: int = 0
    interrupted: bool = False


class TeleopSession:
    """One window that drives an environment's jaws and records its episodes.

    Args:
        env: an environment made with ``gym.make`` (any control mode; pixel
            observations are shown, otherwise ``cameras`` are rendered for the window).
        writer: where saved episodes go, with the features of
            :func:`gym_soarm.record.record.dataset_features` for ``env``; None to drive
            without recording.
        cameras: the cameras the window shows side by side (and, with pixel
            observations, the ones recorded).
        episodes: stop after saving this many episodes (recording only).
        seed: attempt ``k`` resets with ``seed + k``.
        keep: ``"all"`` saves every ended episode, ``"success"`` only successful ones.
        speeds: how fast a full motion moves the jaws.
        gamepad: a :class:`gym_soarm.teleop.gamepad.Gamepad`, or None.
        report: called with one line per event (reset, start, save, discard, exit).

    Raises:
        DisplayUnavailableError: no window can be opened here (the message says why).
    """

    def __init__(
        self,
        env: gym.Env,
        writer: LeRobotDatasetWriter | None,
        cameras: Sequence[str],
        episodes: int = 10,
        seed: int = 0,
        keep: str = "all",
        speeds: TeleopSpeeds | None = None,
        gamepad: Any = None,
        report: Callable[[str], None] | None = None,
    ) -> None:
        require_windows()
        self.env = env
        self.base = env.unwrapped
        self.writer = writer
        self.cameras = tuple(check_choice("camera", c, constants.CAMERA_NAMES) for c in cameras)
        if not self.cameras:
            raise ValueError("cameras must name at least one camera to show; got none.")
        self.episodes = check_int("episodes", episodes, 1)
        self.seed = check_int("seed", seed, 0)
        self.keep = check_choice("keep", keep, KEEP_CHOICES)
        self.speeds = speeds or TeleopSpeeds(step_s=self.base.dt)
        self.gamepad = gamepad
        self._report = report or (lambda line: None)
        # The teleop's own ee_delta solver, in radians whatever the env's units.
        self._ee = make_control(EE_DELTA, self.base.physics, joint_units("radians"))
        self._keyboard = KeyboardInput()
        self._frame_period_s = 1.0 / float(self.base.metadata["render_fps"])
        self._gripper_step_rad = GRIPPER_SPEED_RAD_S * self.base.dt
        self.summary = TeleopSummary()
        self._attempt = -1
        self._obs: Any = None
        self._info: dict[str, Any] = {}
        self._started = False
        self._steps = 0
        self._gripper_goal = 0.0
        self._gripper_rad = 0.0
        self._pending_frame: dict[str, Any] | None = None
        self._next_step_at = 0.0
        self._quit = False
        self._canvas: np.ndarray | None = None
        self._window_created = False

    @property
    def recording(self) -> bool:
        return self.writer is not None

    # --- the loop ------------------------------------------------------------------------
    def run(self) -> TeleopSummary:
        """Open the window and drive until quit, the window closes, Ctrl-C or enough episodes.

        Episodes saved before the end stay saved; an unsaved one is dropped (its frames
        stay in the writer's buffer, which ``finalize`` drops).
        """
        import cv2

        try:
            self._new_episode()
            while not self._quit:
                self._show()
                for code in self._keys(self._wait_ms()):
                    self._command(self._keyboard.press(code, time.perf_counter()))
                gamepad_motion = np.zeros(5)
                if self.gamepad is not None:
                    gamepad_motion, commands = self.gamepad.read()
                    for command in commands:
                        self._command(command)
                if not self._window_visible():
                    self._report("window closed")
                    self._quit = True
                if self._quit:
                    break
                motion = self._keyboard.motion(time.perf_counter()) + gamepad_motion
                if not self._started and (np.any(motion != 0.0) or self._gripper_moving):
                    self._started = True
                    self._report(f"start episode {self._attempt}")
                if self._started:
                    self._step(np.clip(motion, -1.0, 1.0))
        except KeyboardInterrupt:
            self.summary.interrupted = True
            self._report("interrupted")
        finally:
            if self._window_created:
                try:
                    cv2.destroyWindow(WINDOW_TITLE)
                    cv2.waitKey(1)
                except cv2.error:
                    pass  # the user closed it already
        self._report(
            f"exit episodes {self.summary.episodes} frames {self.summary.frames} "
            f"attempts {self.summary.attempts} successes {self.summary.successes}"
        )
        return self.summary

    def _keys(self, wait_ms: int) -> list[int]:
        """The keys pressed while waiting ``wait_ms``, and any more already queued."""
        import cv2

        codes = []
        code = cv2.waitKeyEx(wait_ms)
        while code >= 0 and len(codes) < _MAX_KEYS_PER_STEP:
            codes.append(code)
            code = cv2.waitKeyEx(1)
        return codes

    def _wait_ms(self) -> int:
        if not self._started:
            return IDLE_WAIT_MS
        wait_s = self._next_step_at - time.perf_counter()
        return max(1, round(wait_s * 1000.0))

    def _command(self, command: str | None) -> None:
        if command == GRIPPER:
            opening = not self._gripper_open
            self._gripper_goal = GRIPPER_OPEN_RAD if opening else GRIPPER_CLOSED_RAD
            self._report(f"gripper {'opens' if opening else 'closes'}")
        elif command == SAVE:
            if self._steps == 0:
                self._report("nothing to save: move first")
            else:
                self._end_episode("saved by the user")
        elif command == DISCARD:
            self._discard("discarded")
        elif command == QUIT:
            self._report("quit")
            self._quit = True

    # --- episodes ------------------------------------------------------------------------
    def _new_episode(self) -> None:
        self._attempt += 1
        self.summary.attempts += 1
        self._obs, self._info = self.env.reset(seed=self.seed + self._attempt)
        self._started = False
        self._steps = 0
        self._pending_frame = None
        self._keyboard.clear()
        self._gripper_rad = self._gripper_goal = float(self.base.commanded_targets[-1])
        self._compose()
        self._report(
            f"reset episode {self._attempt} seed {self.seed + self._attempt} "
            f"{self._jaw_text()} task {self.base.task_description!r}"
        )

    @property
    def _gripper_open(self) -> bool:
        """Whether the gripper is (or is going) open rather than closed."""
        return self._gripper_goal > 0.5 * (GRIPPER_OPEN_RAD + GRIPPER_CLOSED_RAD)

    @property
    def _gripper_moving(self) -> bool:
        return self._gripper_rad != self._gripper_goal

    def _step(self, motion: np.ndarray) -> None:
        limit = self._gripper_step_rad
        change = min(max(self._gripper_goal - self._gripper_rad, -limit), limit)
        self._gripper_rad += change
        if abs(self._gripper_goal - self._gripper_rad) < 1e-12:
            self._gripper_rad = self._gripper_goal
        current = self.base.commanded_targets
        targets = self._ee.targets(self.speeds.ee_delta(motion, self._gripper_rad), current)
        action = self.base.control.action_for_targets(targets, current)
        frame = self._frame_before(action) if self.recording else None
        self._obs, reward, terminated, truncated, self._info = self.env.step(action)
        self._steps += 1
        self._next_step_at = max(self._next_step_at + self._frame_period_s, time.perf_counter())
        if self._info.get("physics_unstable"):
            self._discard("the simulation diverged; discarded")
            return
        if frame is not None:
            frame["next.reward"] = np.array([reward], np.float32)
            frame["next.success"] = np.array([bool(self._info["is_success"])])
            frame["next.done"] = np.array([bool(terminated or truncated)])
            self._flush_pending()
            self._pending_frame = frame
        self._compose()
        if terminated:
            self._end_episode("the task succeeded")
        elif truncated:
            self._end_episode("the step limit")

    def _frame_before(self, action: np.ndarray) -> dict[str, Any]:
        """The frame of the observation before a step and the action sent at it."""
        assert self.writer is not None
        frame: dict[str, Any] = {
            "observation.state": np.asarray(self._obs["agent_pos"], dtype=np.float32),
            "action": np.asarray(action, dtype=np.float32),
            "task": self.base.task_description,
        }
        for key in self.writer.features:
            if key.startswith("observation.images."):
                frame[key] = self._obs["pixels"][key.removeprefix("observation.images.")]
        if "observation.environment_state" in self.writer.features:
            state = self._obs["environment_state"]
            frame["observation.environment_state"] = np.asarray(state, dtype=np.float32)
        return frame

    def _flush_pending(self) -> None:
        if self._pending_frame is not None:
            assert self.writer is not None
            self.writer.add_frame(self._pending_frame)
            self._pending_frame = None

    def _end_episode(self, why: str) -> None:
        success = bool(self._info.get("is_success", False))
        self.summary.successes += success
        text = f"episode {self._attempt} frames {self._steps} success {_yes(success)} ({why})"
        if self.writer is None:
            self.summary.episodes += 1
            self._report(f"ended {text} {self._jaw_text()}")
        elif self.keep == "success" and not success:
            self._pending_frame = None
            self.writer.clear_episode_buffer()
            self._report(f"dropped {text} {self._jaw_text()}")
        else:
            if self._pending_frame is not None:
                self._pending_frame["next.done"] = np.array([True])
            self._flush_pending()
            index = self.writer.save_episode()
            self.summary.episodes += 1
            self.summary.frames += self._steps
            self._report(f"saved {text} as episode_index {index} {self._jaw_text()}")
            if self.summary.episodes >= self.episodes:
                self._report(f"recorded {self.summary.episodes} episodes")
                self._quit = True
                return
        self._new_episode()

    def _discard(self, what: str) -> None:
        self._pending_frame = None
        if self.writer is not None:
            self.writer.clear_episode_buffer()
        self._report(f"{what} episode {self._attempt} frames {self._steps} {self._jaw_text()}")
        self._new_episode()

    # --- the window ----------------------------------------------------------------------
    def _jaw(self) -> np.ndarray:
        """The measured jaws' ``[x, y, z, pitch, roll]`` (base frame, m and rad)."""
        return self._ee.pose(self.base.physics.joint_angles())

    def _jaw_text(self) -> str:
        x, y, z, pitch, roll = self._jaw()
        return f"jaw x={x:+.4f} y={y:+.4f} z={z:+.4f} pitch={pitch:+.3f} roll={roll:+.3f}"

    def _camera_images(self) -> list[np.ndarray]:
        pixels = self._obs.get("pixels") if isinstance(self._obs, dict) else None
        return [
            pixels[camera]
            if pixels is not None and camera in pixels
            else self.base.render_camera_image(camera)
            for camera in self.cameras
        ]

    def _compose(self) -> None:
        """Draw the cameras side by side over a status panel (BGR, kept for showing)."""
        images = np.concatenate(self._camera_images(), axis=1)
        height, width = images.shape[:2]
        canvas_width = max(width, MIN_PANEL_WIDTH)
        x, y, z, pitch, roll = self._jaw()
        success = bool(self._info.get("is_success", False))
        mode = "REC" if self.recording else "DRIVE (not recording)"
        saved = f" ({self.summary.episodes}/{self.episodes} saved)" if self.recording else ""
        state = f"step {self._steps}" if self._started else "press a key to start"
        lines = [
            (f"{mode} episode {self._attempt}{saved}  {state}", _RED if self.recording else _WHITE),
            (
                f"success {_yes(success)}   gripper {'open' if self._gripper_open else 'closed'}",
                _GREEN if success else _WHITE,
            ),
            (f"jaw x{x:+.3f} y{y:+.3f} z{z:+.3f} m  pitch{pitch:+.2f} roll{roll:+.2f} rad", _WHITE),
            (self.base.task_description, _GREY),
            *((line, _GREY) for line in _HELP_LINES),
        ]
        panel = np.zeros((len(lines) * 22 + 8, canvas_width, 3), dtype=np.uint8)
        panel_height = draw_text_block(panel, lines)
        canvas = np.zeros((height + panel_height, canvas_width, 3), dtype=np.uint8)
        left = (canvas_width - width) // 2
        canvas[:height, left : left + width] = images[:, :, ::-1]
        canvas[height:] = panel[:panel_height]
        self._canvas = canvas

    def _show(self) -> None:
        import cv2

        if not self._window_created:
            cv2.namedWindow(WINDOW_TITLE, cv2.WINDOW_AUTOSIZE | cv2.WINDOW_GUI_NORMAL)
            self._window_created = True
        cv2.imshow(WINDOW_TITLE, self._canvas)

    def _window_visible(self) -> bool:
        import cv2

        try:
            return cv2.getWindowProperty(WINDOW_TITLE, cv2.WND_PROP_VISIBLE) >= 1
        except cv2.error:
            return False  # Qt forgets its windows once the last one is closed


def _yes(value: bool) -> str:
    return "yes" if value else "no"
