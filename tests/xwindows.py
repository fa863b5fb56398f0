"""Talking to real X11 windows from tests: find, key presses, pixels and closing.

Keys go through ``xdotool`` (synthetic key events, as a person's keyboard would send);
pixels are read back with ``XGetImage`` and windows are closed with the same
``WM_DELETE_WINDOW`` message a window manager sends when its close button is clicked.
libX11 is reached through ctypes, so the tests need no extra Python package.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

REQUIRE_WINDOWS_ENV = "GYM_SOARM_REQUIRE_WINDOWS"
WAIT_S = 60.0  # generous: two CPU cores are shared with software rendering
_REGEX_SPECIAL = set(".[]()*+?{}|^$\\")


def skip_or_fail(reason: str) -> None:
    """Skip a window test, or fail it when the run must exercise windows (CI)."""
    if os.environ.get(REQUIRE_WINDOWS_ENV) == "1":
        pytest.fail(f"{REQUIRE_WINDOWS_ENV}=1 but window tests cannot run: {reason}")
    pytest.skip(reason)


def require_window_tools() -> None:
    """Skip/fail unless OpenCV can open windows here and xdotool and libX11 exist."""
    from gym_soarm.render.display import window_support_problem

    problem = window_support_problem()
    if problem is not None:
        skip_or_fail(problem)
    if shutil.which("xdotool") is None:
        skip_or_fail("xdotool is not installed (apt-get install xdotool)")
    if ctypes.util.find_library("X11") is None:
        skip_or_fail("libX11 is not installed (apt-get install libx11-6)")


def wait_for(condition: Callable[[], object], what: str, timeout_s: float = WAIT_S) -> object:
    """Poll ``condition`` until it returns neither None nor False; fail naming ``what``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value is not None and value is not False:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout_s:.0f} s waiting for {what}")
        time.sleep(0.05)


def find_windows(name: str) -> list[int]:
    """Ids of the X windows whose title is exactly ``name``."""
    pattern = "".join(f"\\{c}" if c in _REGEX_SPECIAL else c for c in name)
    result = subprocess.run(
        ["xdotool", "search", "--name", f"^{pattern}$"],
        capture_output=True,
        text=True,
        check=False,
    )
    return [int(line) for line in result.stdout.split()]


def wait_for_window(name: str) -> int:
    """The id of the window titled ``name``, once it exists and is mapped."""

    def mapped_window() -> int | None:
        for window in find_windows(name):
            if window_size(window) is not None:
                return window
        return None

    return int(wait_for(mapped_window, f"a window titled {name!r}"))


def press(window: int, key: str, window_may_close: bool = False) -> None:
    """Send a key press and release (an xdotool key name, e.g. '2', 'q', 'space').

    With ``window_may_close`` the key may close the window before its release is
    sent; xdotool then fails on the release, which is expected.
    """
    result = subprocess.run(
        ["xdotool", "key", "--window", str(window), key], capture_output=True, text=True
    )
    if result.returncode != 0 and not window_may_close:
        pytest.fail(f"xdotool could not send {key!r} to window {window}: {result.stderr}")


def click(window: int, x: int, y: int, button: int = 1) -> None:
    """Click mouse ``button`` at (x, y) inside ``window``."""
    subprocess.run(
        ["xdotool", "mousemove", "--window", str(window), str(x), str(y), "click", str(button)],
        check=True,
        capture_output=True,
    )


class _XImage(ctypes.Structure):
    _fields_ = [
        ("width", ctypes.c_int),
        ("height", ctypes.c_int),
        ("xoffset", ctypes.c_int),
        ("format", ctypes.c_int),
        ("data", ctypes.POINTER(ctypes.c_ubyte)),
        ("byte_order", ctypes.c_int),
        ("bitmap_unit", ctypes.c_int),
        ("bitmap_bit_order", ctypes.c_int),
        ("bitmap_pad", ctypes.c_int),
        ("depth", ctypes.c_int),
        ("bytes_per_line", ctypes.c_int),
        ("bits_per_pixel", ctypes.c_int),
        ("red_mask", ctypes.c_ulong),
        ("green_mask", ctypes.c_ulong),
        ("blue_mask", ctypes.c_ulong),
    ]


class _XWindowAttributes(ctypes.Structure):
    _fields_ = [
        ("x", ctypes.c_int),
        ("y", ctypes.c_int),
        ("width", ctypes.c_int),
        ("height", ctypes.c_int),
        ("border_width", ctypes.c_int),
        ("depth", ctypes.c_int),
        ("visual", ctypes.c_void_p),
        ("root", ctypes.c_ulong),
        ("class_", ctypes.c_int),
        ("bit_gravity", ctypes.c_int),
        ("win_gravity", ctypes.c_int),
        ("backing_store", ctypes.c_int),
        ("backing_planes", ctypes.c_ulong),
        ("backing_pixel", ctypes.c_ulong),
        ("save_under", ctypes.c_int),
        ("colormap", ctypes.c_ulong),
        ("map_installed", ctypes.c_int),
        ("map_state", ctypes.c_int),
        ("all_event_masks", ctypes.c_long),
        ("your_event_mask", ctypes.c_long),
        ("do_not_propagate_mask", ctypes.c_long),
        ("override_redirect", ctypes.c_int),
        ("screen", ctypes.c_void_p),
    ]


class _XClientMessageEvent(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_int),
        ("serial", ctypes.c_ulong),
        ("send_event", ctypes.c_int),
        ("display", ctypes.c_void_p),
        ("window", ctypes.c_ulong),
        ("message_type", ctypes.c_ulong),
        ("format", ctypes.c_int),
        ("data", ctypes.c_long * 5),
    ]


class _XEvent(ctypes.Union):
    _fields_ = [("client", _XClientMessageEvent), ("pad", ctypes.c_long * 24)]


_ZPIXMAP = 2
_ALL_PLANES = ctypes.c_ulong(-1 & 0xFFFFFFFFFFFFFFFF)
_IS_VIEWABLE = 2
_CLIENT_MESSAGE = 33
_NO_EVENT_MASK = 0


def _xlib() -> ctypes.CDLL:
    lib = ctypes.CDLL(ctypes.util.find_library("X11"))
    lib.XOpenDisplay.restype = ctypes.c_void_p
    lib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    lib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    lib.XGetImage.restype = ctypes.POINTER(_XImage)
    lib.XGetImage.argtypes = [
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.c_int,
        ctypes.c_int,
        ctypes.c_uint,
        ctypes.c_uint,
        ctypes.c_ulong,
        ctypes.c_int,
    ]
    lib.XDestroyImage.argtypes = [ctypes.POINTER(_XImage)]
    lib.XGetWindowAttributes.argtypes = [
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.POINTER(_XWindowAttributes),
    ]
    lib.XInternAtom.restype = ctypes.c_ulong
    lib.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    lib.XSendEvent.argtypes = [
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.c_int,
        ctypes.c_long,
        ctypes.POINTER(_XEvent),
    ]
    lib.XFlush.argtypes = [ctypes.c_void_p]
    lib.XSetErrorHandler.restype = ctypes.c_void_p
    lib.XSetErrorHandler.argtypes = [ctypes.c_void_p]
    return lib


_ERROR_HANDLER_TYPE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


@_ERROR_HANDLER_TYPE
def _ignore_x_error(_display: int, _event: int) -> int:
    # A window that closes between two calls gives BadWindow; the callers see None.
    return 0


class _Display:
    """A short-lived connection to the X server named by $DISPLAY."""

    def __enter__(self) -> tuple[ctypes.CDLL, int]:
        self.lib = _xlib()
        self.lib.XSetErrorHandler(ctypes.cast(_ignore_x_error, ctypes.c_void_p))
        self.display = self.lib.XOpenDisplay(None)
        if not self.display:
            pytest.fail(f"cannot open the X display {os.environ.get('DISPLAY')!r}")
        return self.lib, self.display

    def __exit__(self, *exc: object) -> None:
        self.lib.XCloseDisplay(self.display)


def window_size(window: int) -> tuple[int, int] | None:
    """(width, height) of a mapped, viewable window; None if it is gone or unmapped."""
    with _Display() as (lib, display):
        attributes = _XWindowAttributes()
        if not lib.XGetWindowAttributes(display, window, ctypes.byref(attributes)):
            return None
        if attributes.map_state != _IS_VIEWABLE:
            return None
        return attributes.width, attributes.height


def grab(window: int) -> np.ndarray | None:
    """The pixels a window shows now, as uint8 RGB (H, W, 3); None if it is gone."""
    size = window_size(window)
    if size is None:
        return None
    width, height = size
    with _Display() as (lib, display):
        image_ptr = lib.XGetImage(display, window, 0, 0, width, height, _ALL_PLANES, _ZPIXMAP)
        if not image_ptr:
            return None
        try:
            image = image_ptr.contents
            if image.bits_per_pixel != 32:
                pytest.fail(f"expected a 32-bit X visual, got {image.bits_per_pixel} bits")
            raw = np.ctypeslib.as_array(image.data, shape=(image.height * image.bytes_per_line,))
            rows = raw.reshape(image.height, image.bytes_per_line)[:, : image.width * 4]
            bgrx = rows.reshape(image.height, image.width, 4)
            return np.ascontiguousarray(bgrx[:, :, 2::-1])  # little-endian BGRX to RGB
        finally:
            lib.XDestroyImage(image_ptr)


def close_window(window: int) -> None:
    """Ask a window to close, exactly as a window manager's close button does."""
    with _Display() as (lib, display):
        protocols = lib.XInternAtom(display, b"WM_PROTOCOLS", False)
        delete = lib.XInternAtom(display, b"WM_DELETE_WINDOW", False)
        event = _XEvent()
        event.client.type = _CLIENT_MESSAGE
        event.client.window = window
        event.client.message_type = protocols
        event.client.format = 32
        event.client.data[0] = delete
        event.client.data[1] = 0  # CurrentTime
        lib.XSendEvent(display, window, False, _NO_EVENT_MASK, ctypes.byref(event))
        lib.XFlush(display)


class EventProgram:
    """A window program run in its own process that prints one line per event.

    Subclasses start ``self.process`` with stdout and stderr going to ``self.stdout_path``
    and ``self.stderr_path``; ``name`` names the program in failure messages.
    """

    name = "the program"
    process: subprocess.Popen
    stdout_path: Path
    stderr_path: Path

    def start(self, command: list[str], tmp_path: Path, env: dict[str, str] | None = None) -> None:
        self.stdout_path = tmp_path / "stdout.txt"
        self.stderr_path = tmp_path / "stderr.txt"
        with open(self.stdout_path, "w") as out, open(self.stderr_path, "w") as err:
            self.process = subprocess.Popen(
                command, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env
            )

    def check_running(self, waiting_for: str) -> None:
        if self.process.poll() is not None:
            pytest.fail(
                f"{self.name} exited with {self.process.returncode} while waiting for "
                f"{waiting_for}: {self.stderr_path.read_text()[-2000:]}"
            )

    def lines(self, event: str) -> list[str]:
        text = self.stdout_path.read_text()
        return [line for line in text.splitlines() if line.split(" ", 1)[0] == event]

    def wait_for_event(self, event: str, count: int) -> str:
        """The ``count``-th line of ``event`` (1-based), once the program printed it."""

        def printed() -> str | None:
            exited = self.process.poll() is not None
            found = self.lines(event)  # read after poll(): an exited program has flushed
            if len(found) >= count:
                return found[count - 1]
            if exited:
                self.check_running(f"event {event!r} #{count}")
            return None

        return str(wait_for(printed, f"event {event!r} #{count}"))

    def wait_for_exit(self) -> int:
        try:
            return self.process.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            pytest.fail(f"{self.name} did not exit")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
