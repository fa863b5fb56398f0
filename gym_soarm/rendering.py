"""Offscreen rendering of the scene's cameras straight through MuJoCo's renderer.

* The OpenGL backend follows ``MUJOCO_GL`` when the user set it. When it is unset on
  Linux we use EGL (headless, Mesa's software rasteriser on machines without a GPU)
  and fall back to OSMesa. EGL is probed with plain ``ctypes`` before PyOpenGL is
  imported, because PyOpenGL binds to one platform for the life of the process.
* Contexts are created on first use, inside the process that renders (never inherited
  through ``fork``), one per image size, and reused for every frame. A child forked
  after its parent rendered with EGL renders through an EGL display of its own.
* Every frame is a fresh C-contiguous ``uint8`` array of shape (H, W, 3).
"""

from __future__ import annotations

import atexit
import ctypes
import ctypes.util
import logging
import os
import sys
import threading
import weakref

import mujoco
import numpy as np

from gym_soarm.display import has_display

logger = logging.getLogger(__name__)

RENDER_QUALITIES = ("fast", "high")
MIN_IMAGE_SIZE = 16
MAX_IMAGE_SIZE = 2048

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


def _new_gl_context(width: int, height: int):
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


_live_renderers: weakref.WeakSet[CameraRenderer] = weakref.WeakSet()
_exit_hook_pid: int | None = None


def _close_live_renderers() -> None:
    for renderer in list(_live_renderers):
        renderer.close()


def _close_all_at_exit() -> None:
    """Close every renderer at exit, before the GL backend tears its display down.

    ``atexit`` runs handlers last-in first-out; registering after the backend has
    registered its own teardown (on the first context) makes ours run first.
    """
    global _exit_hook_pid
    if _exit_hook_pid != os.getpid():
        _exit_hook_pid = os.getpid()
        atexit.register(_close_live_renderers)


def _forget_inherited_contexts() -> None:
    """After fork the child must not touch the parent's GL contexts: drop them.

    The child also notes which backends the parent rendered with, so that its first
    context opens a display of its own (see :func:`_prepare_after_fork`).
    """
    global _chosen_backend, _backend_pid
    for renderer in list(_live_renderers):
        renderer._abandon()
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


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_inherited_contexts)


class CameraRenderer:
    """Renders any fixed camera of one model at one image size.

    The GL context, MuJoCo rendering context and scene are created on the first
    :meth:`render` call and kept until :meth:`close`.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, quality: str = "fast"):
        if quality not in RENDER_QUALITIES:
            raise ValueError(f"render_quality must be one of {RENDER_QUALITIES}, got {quality!r}")
        self._model = model
        self.width = int(width)
        self.height = int(height)
        self.quality = quality
        self._gl = None
        self._mjr: mujoco.MjrContext | None = None
        self._scene: mujoco.MjvScene | None = None
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._option = mujoco.MjvOption()
        self._viewport = mujoco.MjrRect(0, 0, self.width, self.height)
        self._buffer = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._closed = False
        _live_renderers.add(self)

    def _open(self) -> None:
        model = self._model
        high = self.quality == "high"
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.height)
        model.vis.quality.offsamples = 4 if high else 0
        self._gl = _new_gl_context(self.width, self.height)
        self._gl.make_current()
        # "fast" draws no shadows, so it needs no shadow map (2048^2 depth texture: 16 MB
        # of RAM with a software rasteriser). The model's own setting is left as it was.
        shadowsize = model.vis.quality.shadowsize
        if not high:
            model.vis.quality.shadowsize = 0
        try:
            self._mjr = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        finally:
            model.vis.quality.shadowsize = shadowsize
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._mjr)
        self._scene = mujoco.MjvScene(model, maxgeom=500)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = high
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = high
        _close_all_at_exit()

    def render(self, data: mujoco.MjData, camera_id: int) -> np.ndarray:
        """Render camera ``camera_id`` into a new (H, W, 3) uint8 array."""
        if self._closed:
            raise RuntimeError("this renderer was closed; create the environment again to render")
        if self._gl is None:
            self._open()
        else:
            self._gl.make_current()
        self._camera.fixedcamid = camera_id
        mujoco.mjv_updateScene(
            self._model,
            data,
            self._option,
            None,
            self._camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self._scene,
        )
        mujoco.mjr_render(self._viewport, self._scene, self._mjr)
        mujoco.mjr_readPixels(self._buffer, None, self._viewport, self._mjr)
        return np.ascontiguousarray(self._buffer[::-1])

    def _abandon(self) -> None:
        # In a forked child: forget the parent's contexts without freeing them.
        self._gl = self._mjr = self._scene = None

    def close(self) -> None:
        """Free the GL and MuJoCo rendering contexts; safe to call more than once."""
        if self._closed:
            return
        self._closed = True
        if self._gl is not None:
            self._gl.make_current()
            if self._mjr is not None:
                self._mjr.free()
            self._gl.free()
        self._gl = self._mjr = self._scene = None
        _live_renderers.discard(self)
