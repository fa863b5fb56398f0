"""Offscreen rendering of the scene's cameras straight through MuJoCo's renderer.

* Contexts are created on first use, inside the process that renders (never inherited
  through ``fork``), one per image size, and reused for every frame.
* Every frame is a fresh C-contiguous ``uint8`` array of shape (H, W, 3).
"""

from __future__ import annotations

import atexit
import logging
import os
import weakref

import mujoco
import numpy as np

from gym_soarm.render import backend
from gym_soarm.render.backend import RENDER_QUALITIES

logger = logging.getLogger(__name__)

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
    """After fork the child must not touch the parent's GL contexts: drop them."""
    for renderer in list(_live_renderers):
        renderer._abandon()
    backend.forget_inherited_backend()


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
        self._gl = backend.new_gl_context(self.width, self.height)
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
