"""Which OpenGL backend renders, and its contexts, created inside the rendering process.

* The OpenGL backend follows ``MUJOCO_GL`` when the user set it. When it is unset on
  Linux we use EGL (headless, Mesa's software rasteriser on machines without a GPU)
  and fall back to OSMesa. EGL is probed with plain ``ctypes`` before PyOpenGL is
  imported, because PyOpenGL binds to one platform for the life of the process.
* A child forked after its parent rendered with EGL renders through an EGL display of
  its own.
"""

from __future__ import annotations

import atexit
import ctypes
import ctypes.util
import logging
import os
import sys
import threading

from gym_soarm.render.display import has_display

logger = logging.getLogger(__name__)

RENDER_QUALITIES = ("fast", "high")

# Debian/Ubuntu packages that provide each backend, for error messages.
BACKEND_APT_PACKAGES = {
    "egl": "libegl1 libgl1-mesa-dri",
    "osmesa": "libosmesa6",
    "glfw": "libglfw3 (and a display)",
}
_VALID_MUJOCO_GL = ("egl", "osmesa", "glfw")


class GLBackendError(RuntimeError):
    """No OpenGL backend could create a rendering context."""


_backend_lock = threading.Lock()
_chosen_backend: str | None = None
_backend_pid: int | None = None


def _egl_usable() -> tuple[bool, str]:
    """Whether an EGL device display can be initialised, checked without PyOpenGL."""
    name = ctypes.util.find_library("EGL") or "libEGL.so.1"
    try:
        lib = ctypes.CDLL(name)
    except OSError as exc:
        return False, f"cannot load libEGL ({exc})"
    get_proc = lib.eglGetProcAddress
    get_proc.restype = ctypes.c_void_p
    get_proc.argtypes = [ctypes.c_char_p]
    query_ptr = get_proc(b"eglQueryDevicesEXT")
    display_ptr = get_proc(b"eglGetPlatformDisplayEXT")
    if not query_ptr or not display_ptr:
        return False, "libEGL lacks the EGL_EXT_device_query / platform_device extensions"
    query_devices = ctypes.CFUNCTYPE(
        ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int)
    )(query_ptr)
    get_display = ctypes.CFUNCTYPE(
        ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p
    )(display_ptr)
    devices = (ctypes.c_void_p * 8)()
    count = ctypes.c_int(0)
    if not query_devices(8, devices, ctypes.byref(count)) or count.value == 0:
        return False, "EGL reports no rendering device"
    initialize = lib.eglInitialize
    initialize.restype = ctypes.c_uint
    initialize.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    egl_platform_device = 0x313F
    for i in range(count.value):
        display = get_display(egl_platform_device, devices[i], None)
        if display and initialize(display, None, None):
            return True, ""
    return False, "no EGL device display could be initialised"


def _backend_candidates() -> list[str]:
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested:
        if requested not in _VALID_MUJOCO_GL:
            raise GLBackendError(
                f"MUJOCO_GL={requested!r} cannot render offscreen for gym_soarm; expected one of "
                f"{_VALID_MUJOCO_GL}. Unset it to let gym_soarm choose (EGL, then OSMesa)."
            )
        return [requested]
    if sys.platform.startswith("linux"):
        return ["egl", "osmesa"]
    return ["glfw"]


def _import_context_class(backend: str):
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.glfw import GLContext
    return GLContext


def _select_backend() -> str:
    """Pick the OpenGL backend once per process (probing EGL before any GL import)."""
    global _chosen_backend, _backend_pid
    with _backend_lock:
        if _chosen_backend is not None and _backend_pid == os.getpid():
            return _chosen_backend
        tried: list[str] = []
        candidates = _backend_candidates()
        for backend in candidates:
            if backend == "egl" and len(candidates) > 1:
                ok, why = _egl_usable()
                if not ok:
                    tried.append(f"egl: {why}")
                    logger.info("EGL unavailable (%s); trying the next OpenGL backend", why)
                    continue
            if backend == "osmesa" and not ctypes.util.find_library("OSMesa"):
                tried.append("osmesa: libOSMesa not found")
                continue
            if backend == "glfw" and not has_display():
                tried.append("glfw: it opens a hidden window, but DISPLAY is not set")
                continue
            try:
                _import_context_class(backend)
            except (ImportError, OSError, RuntimeError, AttributeError) as exc:
                tried.append(f"{backend}: {_sentence(exc)}")
                continue
            _chosen_backend, _backend_pid = backend, os.getpid()
            return backend
        packages = " ".join(BACKEND_APT_PACKAGES[b] for b in candidates)
        raise GLBackendError(
            f"No OpenGL backend can render offscreen. Tried: {'; '.join(tried)}. "
            f"On Debian/Ubuntu install what they need with: sudo apt-get install {packages}; "
            f"or set MUJOCO_GL to a backend that works here (one of {', '.join(_VALID_MUJOCO_GL)})."
        )


def _sentence(exc: BaseException) -> str:
    """An exception's message without its final full stop, to embed in ours."""
    return str(exc).strip().rstrip(".")


def gl_backend() -> str:
    """Name of the OpenGL backend used in this process ('egl', 'osmesa' or 'glfw')."""
    return _select_backend()


# Mesa keeps its rasteriser threads with each EGL display and, for OSMesa, once per
# process. Threads do not survive fork(): a child that renders through a display its
# parent rendered on waits for them forever. So we remember what this process, or an
# ancestor it was forked from, has rendered with ("egl-device", "egl-surfaceless",
# "osmesa"), and a forked child renders through a display of its own.
_gl_used: set[str] = set()
_inherited_gl: set[str] = set()  # backends whose state came from the parent through fork
EGL_PLATFORM_SURFACELESS_MESA = 0x31DD
FORK_ADVICE = (
    "Mesa cannot render in a process forked from one that already rendered with it. "
    "Create vector environments before rendering in the parent, or start their workers "
    "with another start method: gym.make_vec(..., vectorization_mode='async', "
    "vector_kwargs={'context': 'forkserver'}) (or 'spawn')."
)


def _open_fresh_egl_display() -> None:
    """In a forked child, point MuJoCo's EGL contexts at a display the parent never used.

    The parent's device display is unusable here (its rasteriser threads stayed in the
    parent), and Mesa hands back that same display for every request on the same
    platform; the surfaceless platform gives a separate display with its own threads.
    """
    import mujoco.egl as mujoco_egl
    from mujoco.egl import egl_ext as EGL  # noqa: N812 - the EGL API's own spelling
    from OpenGL import error as gl_error

    if "egl-surfaceless" in _gl_used:
        raise GLBackendError(
            "This process was forked from one whose EGL displays (device and surfaceless) "
            f"were both already rendering. {FORK_ADVICE}"
        )
    try:
        display = EGL.eglGetPlatformDisplayEXT(
            EGL_PLATFORM_SURFACELESS_MESA, EGL.EGL_DEFAULT_DISPLAY, None
        )
        ok = display != EGL.EGL_NO_DISPLAY and EGL.eglInitialize(display, None, None)
    except gl_error.GLError as exc:
        ok, display = False, exc
    if not ok:
        raise GLBackendError(
            "This process was forked after its parent rendered with EGL, and no separate "
            f"EGL display (EGL_MESA_platform_surfaceless) could be opened here. {FORK_ADVICE}"
        )
    mujoco_egl.EGL_DISPLAY = display
    atexit.register(EGL.eglTerminate, display)
    _gl_used.add("egl-surfaceless")
    logger.info("forked after the parent rendered: using a separate EGL surfaceless display")


def _prepare_after_fork(backend: str) -> None:
    if backend not in _inherited_gl:
        return
    if backend == "osmesa":
        raise GLBackendError(
            f"This process was forked after its parent rendered with OSMesa. {FORK_ADVICE}"
        )
    if backend == "egl":
        _open_fresh_egl_display()
        _inherited_gl.discard("egl")


def new_gl_context(width: int, height: int):
    backend = _select_backend()
    context_class = _import_context_class(backend)
    _prepare_after_fork(backend)
    try:
        context = context_class(width, height)
    except Exception as exc:  # the backends raise assorted errors; report them as one
        others = ", ".join(b for b in _VALID_MUJOCO_GL if b != backend)
        raise GLBackendError(
            f"Could not create an OpenGL context with MUJOCO_GL={backend!r}: {_sentence(exc)}. "
            f"It needs: sudo apt-get install {BACKEND_APT_PACKAGES[backend]}; or set MUJOCO_GL "
            f"to another backend ({others}), or unset it to let gym_soarm choose."
        ) from exc
    if backend == "egl" and "egl-surfaceless" not in _gl_used:
        _gl_used.add("egl-device")  # mujoco.egl opens the device display on first use
    elif backend == "osmesa":
        _gl_used.add("osmesa")
    return context


def forget_inherited_backend() -> None:
    """In a child forked after its parent rendered: drop the parent's backend choice.

    The child notes which backends the parent rendered with, so that its first context
    opens a display of its own (see :func:`_prepare_after_fork`).
    """
    global _chosen_backend, _backend_pid
    _chosen_backend = _backend_pid = None
    egl_module = sys.modules.get("mujoco.egl")
    if egl_module is not None and getattr(egl_module, "EGL_DISPLAY", None) is not None:
        _inherited_gl.add("egl")
        # The parent's exit handler would terminate its display from here, which hangs
        # or crashes the child at exit; a display opened here registers its own.
        atexit.unregister(egl_module.EGL.eglTerminate)
        if not _gl_used & {"egl-device", "egl-surfaceless"}:
            _gl_used.add("egl-device")  # opened by other code through mujoco.egl
    if "osmesa" in _gl_used:
        _inherited_gl.add("osmesa")
