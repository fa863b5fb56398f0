"""The ``render_mode='human'`` window: one camera at a time, in an OpenCV window.

Keys (with the window focused):

====  =====================================
1     ``overview_camera``
2     ``front_camera``
3     ``wrist_camera``
q     close the window (also Esc, or the window's close button)
====  =====================================

Closing the window only closes the viewer; the environment keeps stepping and
``render()`` keeps returning ``None``.
"""

from __future__ import annotations

import itertools
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from gym_soarm import constants
from gym_soarm.render.display import require_windows

if TYPE_CHECKING:
    from gym_soarm.envs.env import SoArmEnv

CAMERA_KEYS: dict[str, str] = {
    "1": "overview_camera",
    "2": "front_camera",
    "3": "wrist_camera",
}
CLOSE_KEYS: tuple[int, ...] = (ord("q"), ord("Q"), 27)  # q, Q, Esc
WINDOW_TITLE = "gym_soarm"

_OVERLAY_TEXT_BGR = (255, 255, 255)
_OVERLAY_SUCCESS_BGR = (80, 220, 80)
_OVERLAY_BACKGROUND_ALPHA = 0.55
_window_numbers = itertools.count(1)


def _shorten(camera: str) -> str:
    return camera.removesuffix("_camera")


def draw_text_block(image_bgr: np.ndarray, lines: list[tuple[str, tuple[int, int, int]]]) -> int:
    """Draw lines of text on a darkened band at the top of a BGR image, in place.

    Args:
        image_bgr: uint8 (H, W, 3) image to draw on.
        lines: (text, BGR colour) pairs, top to bottom.

    Returns:
        The height in pixels of the band that the text covers.
    """
    import cv2

    height, width = image_bgr.shape[:2]
    scale = max(0.3, min(0.6, width / 1100.0))
    thickness = 1
    (_, text_h), baseline = cv2.getTextSize("Ag", cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    line_h = text_h + baseline + 4
    band_h = min(height, line_h * len(lines) + 4)
    band = image_bgr[:band_h]
    band[:] = (band * (1.0 - _OVERLAY_BACKGROUND_ALPHA)).astype(np.uint8)
    for i, (text, colour) in enumerate(lines):
        y = 2 + line_h * i + text_h + 2
        cv2.putText(
            image_bgr,
            text,
            (4, y),
            cv2.FONT_HERSHEY_SIMPLEX,
            scale,
            colour,
            thickness,
            cv2.LINE_AA,
        )
    return band_h


class HumanViewer:
    """An OpenCV window that shows one camera of an environment after every step.

    The window opens on the first frame (the first ``reset``), shows the selected
    camera rendered at the observation size, and paces itself to the environment's
    frame rate. Key presses are read whenever a frame is shown.

    Args:
        env: the environment to show (``env.unwrapped``).
        camera: the camera shown first; defaults to ``env.render_camera``.

    Raises:
        DisplayUnavailableError: OpenCV is the headless build or no display is
            reachable. The message names which and how to fix it.
    """

    def __init__(self, env: SoArmEnv, camera: str | None = None) -> None:
        require_windows()
        camera = env.render_camera if camera is None else camera
        if camera not in constants.CAMERA_NAMES:
            raise ValueError(
                f"camera must be one of {', '.join(map(repr, constants.CAMERA_NAMES))}; "
                f"got {camera!r}."
            )
        self._env = env
        self.camera = camera
        number = next(_window_numbers)
        self.window_name = WINDOW_TITLE if number == 1 else f"{WINDOW_TITLE} ({number})"
        self.frame_period_s = 1.0 / float(env.metadata["render_fps"])
        self.last_frame: np.ndarray | None = None
        self._is_success = False
        self._window_created = False
        self._closed = False
        self._last_shown_at: float | None = None

    @property
    def is_open(self) -> bool:
        """True until the user or :meth:`close` closes the window."""
        return not self._closed

    def set_camera(self, camera: str) -> None:
        """Show ``camera`` from the next frame on."""
        if camera not in constants.CAMERA_NAMES:
            raise ValueError(
                f"camera must be one of {', '.join(map(repr, constants.CAMERA_NAMES))}; "
                f"got {camera!r}."
            )
        self.camera = camera

    def show(self, info: dict[str, Any] | None) -> None:
        """Render the current camera, draw the overlay, show it and handle keys.

        Args:
            info: the ``info`` of the reset or step just taken, or None to show the
                current state again (``render()``).
        """
        if self._closed:
            return
        import cv2

        if self._window_created and not self._window_visible():
            self._mark_closed()
            return
        if info is not None:
            self._is_success = bool(info.get("is_success", False))
        rgb = self._env.render_camera_image(self.camera)
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        draw_text_block(bgr, self._overlay_lines())
        if not self._window_created:
            cv2.namedWindow(self.window_name, cv2.WINDOW_AUTOSIZE | cv2.WINDOW_GUI_NORMAL)
            self._window_created = True
        cv2.imshow(self.window_name, bgr)
        self.last_frame = np.ascontiguousarray(bgr[:, :, ::-1])
        self._handle_key(cv2.waitKey(self._wait_ms()))
        if not self._closed and not self._window_visible():
            self._mark_closed()

    def close(self) -> None:
        """Close the window (safe to call twice, and after the user closed it)."""
        if self._closed:
            return
        self._closed = True
        if self._window_created:
            self._destroy_window()

    # --- internals -------------------------------------------------------------------
    def _overlay_lines(self) -> list[tuple[str, tuple[int, int, int]]]:
        physics = self._env.physics
        sim_time_s = float(physics.data.time)
        step = round(sim_time_s / self._env.dt)
        success = "yes" if self._is_success else "no"
        colour = _OVERLAY_SUCCESS_BGR if self._is_success else _OVERLAY_TEXT_BGR
        return [
            (f"{_shorten(self.camera)}  [1/2/3 camera, q close]", _OVERLAY_TEXT_BGR),
            (f"t {sim_time_s:6.2f} s  step {step}  success {success}", colour),
        ]

    def _wait_ms(self) -> int:
        """Milliseconds to wait for a key so that frames come at most at the frame rate."""
        now = time.perf_counter()
        wait_s = 0.0
        if self._last_shown_at is not None:
            wait_s = max(0.0, self._last_shown_at + self.frame_period_s - now)
        self._last_shown_at = now + wait_s
        return max(1, round(wait_s * 1000.0))

    def _handle_key(self, key: int) -> None:
        if key < 0:
            return
        key &= 0xFF
        if key in CLOSE_KEYS:
            self.close()
            return
        camera = CAMERA_KEYS.get(chr(key))
        if camera is not None:
            self.camera = camera

    def _window_visible(self) -> bool:
        import cv2

        try:
            return cv2.getWindowProperty(self.window_name, cv2.WND_PROP_VISIBLE) >= 1
        except cv2.error:
            # Qt drops its window registry once the last window is closed.
            return False

    def _mark_closed(self) -> None:
        self._closed = True
        self._destroy_window()

    def _destroy_window(self) -> None:
        import cv2

        try:
            cv2.destroyWindow(self.window_name)
            cv2.waitKey(1)  # let the GUI loop remove the window now
        except cv2.error:
            pass  # the window system already removed it (closed by the user)
