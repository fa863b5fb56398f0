"""Offscreen rendering of the scene's cameras straight through MuJoCo's renderer.

* Contexts are created on first use, inside the process that renders (never inherited
  through ``fork``), one per image size, and reused for every frame.
* Every frame is a fresh C-contiguous ``uint8`` array of shape (H, W, 3).
* :meth:`CameraRenderer.render_images` also gives depth (float32 metres, read from the
  depth buffer of the colour render) and segmentation (int32 segment ids, from a second
  render with MuJoCo's segmentation and id-colour flags); only what is asked is drawn.
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

# Geoms a scene can hold; segmentation codes (index + 1) then fit in 16 bits.
_MAX_SCENE_GEOMS = 500
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
        self._depth_buffer: np.ndarray | None = None
        self._segment_buffer: np.ndarray | None = None
        self._segment_lookup = np.zeros(0, dtype=np.int32)
        self.render_count = 0
        """How many times the scene was drawn (one per colour/depth frame, one more per
        segmentation frame); tests read it to check that nothing extra is rendered."""
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
        # Depth is read as OpenGL keeps it (reversed z: 1 at the near plane, 0 at the far
        # one), which _linear_depth inverts; colour images are not affected.
        self._mjr.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._scene = mujoco.MjvScene(model, maxgeom=_MAX_SCENE_GEOMS)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = high
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = high
        _close_all_at_exit()

    def _update_scene(self, data: mujoco.MjData, camera_id: int) -> None:
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

    def render(self, data: mujoco.MjData, camera_id: int) -> np.ndarray:
        """Render camera ``camera_id`` into a new (H, W, 3) uint8 array."""
        self._update_scene(data, camera_id)
        mujoco.mjr_render(self._viewport, self._scene, self._mjr)
        self.render_count += 1
        mujoco.mjr_readPixels(self._buffer, None, self._viewport, self._mjr)
        return np.ascontiguousarray(self._buffer[::-1])

    def render_images(
        self,
        data: mujoco.MjData,
        camera_id: int,
        rgb: bool = True,
        depth: bool = False,
        segment_of_geom: np.ndarray | None = None,
    ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """Render the asked images of camera ``camera_id``, each a fresh array.

        Colour and depth come from one render; segmentation takes a second one.

        Args:
            data: the simulation state to draw.
            camera_id: a fixed camera of the model.
            rgb: return the colour image, uint8 (H, W, 3).
            depth: return the depth image, float32 (H, W): the distance in metres along
                the camera's axis, up to the far clipping plane (:attr:`far_m`).
            segment_of_geom: int32 array with one segment id per model geom; when given,
                return the segmentation image, int32 (H, W), holding the segment id of
                the geom seen at each pixel and 0 where no geom is (the sky).

        Returns:
            (rgb, depth, segmentation), None for each image not asked for.
        """
        self._update_scene(data, camera_id)
        colour = distance = segments = None
        if rgb or depth:
            mujoco.mjr_render(self._viewport, self._scene, self._mjr)
            self.render_count += 1
            if depth and self._depth_buffer is None:
                self._depth_buffer = np.empty((self.height, self.width), dtype=np.float32)
            mujoco.mjr_readPixels(
                self._buffer if rgb else None,
                self._depth_buffer if depth else None,
                self._viewport,
                self._mjr,
            )
            if rgb:
                colour = np.ascontiguousarray(self._buffer[::-1])
            if depth:
                distance = self._linear_depth()
        if segment_of_geom is not None:
            segments = self._render_segments(segment_of_geom)
        return colour, distance, segments

    @property
    def far_m(self) -> float:
        """The far clipping plane (m): the largest depth, where nothing was drawn."""
        return float(np.float32(self._model.vis.map.zfar * self._model.stat.extent))

    def _linear_depth(self) -> np.ndarray:
        """The depth buffer (non-linear, reversed z: 1 near, 0 far) in metres."""
        assert self._depth_buffer is not None and self._scene is not None
        extent = self._model.stat.extent
        # As OpenGL's projection matrix: float32 clipping planes, float64 arithmetic.
        near = float(np.float32(self._model.vis.map.znear * extent))
        far = float(np.float32(self._model.vis.map.zfar * extent))
        z = self._depth_buffer[::-1].astype(np.float64)
        if self._scene.camera[0].orthographic:
            metres = far - z * (far - near)
        else:
            # MuJoCo renders with reversed z: the buffer holds near * (far / z - 1) /
            # (far - near) for a point at distance z; this inverts it.
            c = 0.5 * (far + near) / (far - near) - 0.5
            d = far * near / (far - near)
            metres = d / (z + c)
        out = metres.astype(np.float32)
        return np.clip(out, 0.0, np.float32(far), out=out)

    def _render_segments(self, segment_of_geom: np.ndarray) -> np.ndarray:
        """Draw every geom in a colour encoding its scene index and map it to segments."""
        scene = self._scene
        assert scene is not None
        flags = scene.flags
        saved = flags.copy()
        rnd = mujoco.mjtRndFlag
        flags[rnd.mjRND_SEGMENT] = True
        flags[rnd.mjRND_IDCOLOR] = True
        # A shadow or a reflection on the floor would paint it with another geom's id.
        flags[rnd.mjRND_SHADOW] = False
        flags[rnd.mjRND_REFLECTION] = False
        try:
            mujoco.mjr_render(self._viewport, scene, self._mjr)
            self.render_count += 1
        finally:
            np.copyto(flags, saved)
        if self._segment_buffer is None:
            self._segment_buffer = np.empty((self.height, self.width, 3), dtype=np.uint8)
            self._segment_lookup = np.zeros(1 << 16, dtype=np.int32)
        mujoco.mjr_readPixels(self._segment_buffer, None, self._viewport, self._mjr)
        # Pixel colour (r, g, b) = scene geom index + 1 in little-endian bytes, 0 where
        # nothing was drawn. A scene holds at most _MAX_SCENE_GEOMS geoms, so blue is
        # always 0: red and green, read as one little-endian uint16 straight from the
        # buffer, index a table of every 16-bit code (a blended edge under multisampling
        # may give a code of no geom, which stays 0).
        ngeom = scene.ngeom
        lookup = self._segment_lookup
        lookup[: ngeom + 1] = 0
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for geom in scene.geoms[:ngeom]:
            if geom.objtype == geom_type and geom.segid >= 0:
                lookup[geom.segid + 1] = segment_of_geom[geom.objid]
        codes = np.ndarray(
            (self.height, self.width),
            dtype="<u2",
            buffer=self._segment_buffer,
            strides=(3 * self.width, 3),
        )
        return lookup[codes[::-1]]

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
