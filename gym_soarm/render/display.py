"""Can this process open an OpenCV window? Checked before any window is created.

gym_soarm depends on ``opencv-python-headless`` (the build LeRobot and most training
stacks install), which has no GUI backend. Windows need the GUI build of OpenCV and
a display; without either we raise :class:`DisplayUnavailableError` up front instead
of letting Qt abort the process or a call hang.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib.metadata
import os
import sys


class DisplayUnavailableError(RuntimeError):
    """A window was asked for, but OpenCV has no GUI backend or there is no display."""


DISPLAY_FIX = (
    "run on a desktop session, or on a server start a virtual display: "
    "xvfb-run -a python your_script.py (apt-get install xvfb)"
)

# xcb_connection_has_error() codes, from xcb.h.
_XCB_ERRORS = {
    1: "the connection failed (no X server listens there, or it refused us)",
    2: "the X server lacks a required extension",
    3: "out of memory",
    4: "request too long",
    5: "the DISPLAY value could not be parsed",
    6: "the X server has no such screen",
    7: "file descriptor passing failed",
}


def opencv_gui_backend() -> str | None:
    """Name of OpenCV's GUI backend (e.g. 'GTK3', 'QT5'), or None for a headless build."""
    import cv2

    info = cv2.getBuildInformation()
    _, found, rest = info.partition("GUI:")
    backend = rest.splitlines()[0].strip() if found and rest else ""
    return None if backend.upper() in {"", "NONE", "NO"} else backend


def gui_opencv_fix() -> str:
    """The command that puts the GUI build of OpenCV in place of the headless one.

    The same version is installed over the headless wheel's files, so packages that
    depend on ``opencv-python-headless`` stay satisfied.
    """
    try:
        version = importlib.metadata.version("opencv-python-headless")
    except importlib.metadata.PackageNotFoundError:
        import cv2

        version = f"{cv2.__version__}.*"
    return (
        "install the GUI build of OpenCV in place of the headless one: "
        f'pip install --force-reinstall --no-deps "opencv-python=={version}"'
    )


def _x_display_error(name: str) -> str | None:
    """Why the X display ``name`` cannot be reached, or None when a connection works.

    Connects with libxcb (what Qt's X11 backend uses) and disconnects at once, so an
    unreachable display is reported here instead of aborting inside Qt.
    """
    library = ctypes.util.find_library("xcb")
    if library is None:
        return "libxcb is not installed (apt-get install libxcb1)"
    xcb = ctypes.CDLL(library)
    xcb.xcb_connect.restype = ctypes.c_void_p
    xcb.xcb_connect.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
    xcb.xcb_connection_has_error.restype = ctypes.c_int
    xcb.xcb_connection_has_error.argtypes = [ctypes.c_void_p]
    xcb.xcb_disconnect.argtypes = [ctypes.c_void_p]
    connection = xcb.xcb_connect(name.encode(), None)
    try:
        code = xcb.xcb_connection_has_error(connection) if connection else 1
    finally:
        if connection:
            xcb.xcb_disconnect(connection)
    if code == 0:
        return None
    return _XCB_ERRORS.get(code, f"xcb error {code}")


def display_problem(gui_backend: str | None = None) -> str | None:
    """Why no display can be used here, with the fix; None when one is reachable.

    Args:
        gui_backend: OpenCV's GUI backend; Qt builds (the ``opencv-python`` wheels)
            need an X display, other backends may also use Wayland.
    """
    if not sys.platform.startswith("linux"):
        return None  # macOS and Windows always have their window system
    x_display = os.environ.get("DISPLAY")
    if x_display:
        error = _x_display_error(x_display)
        if error is None:
            return None
        return f"the X display DISPLAY={x_display!r} cannot be reached ({error}); {DISPLAY_FIX}"
    is_qt = (gui_backend or "").upper().startswith("QT")
    if os.environ.get("WAYLAND_DISPLAY"):
        if not is_qt:
            return None
        return (
            "only a Wayland display is available (WAYLAND_DISPLAY is set, DISPLAY is not) and "
            "OpenCV's Qt windows need X11; enable XWayland so that DISPLAY is set, or "
            + DISPLAY_FIX
        )
    return f"no display is available (DISPLAY is not set); {DISPLAY_FIX}"


def has_display() -> bool:
    """True when a window system is reachable (always on macOS and Windows)."""
    return display_problem(opencv_gui_backend()) is None


def window_support_problem() -> str | None:
    """Why no window can be opened here, with the fix; None when windows work."""
    backend = opencv_gui_backend()
    problems = []
    if backend is None:
        problems.append(
            f"the installed OpenCV is a headless build (no GUI backend); {gui_opencv_fix()}"
        )
    no_display = display_problem(backend)
    if no_display is not None:
        problems.append(no_display)
    if not problems:
        return None
    return "Cannot open a window: " + ". Also, ".join(problems) + "."


def require_windows() -> None:
    """Raise :class:`DisplayUnavailableError` unless OpenCV windows can be opened."""
    problem = window_support_problem()
    if problem is not None:
        raise DisplayUnavailableError(problem)
