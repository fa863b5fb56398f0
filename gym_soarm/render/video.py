"""Writing camera frames to MP4 files that play in a browser."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def save_frames_to_mp4(
    frames: Sequence[np.ndarray], path: str | os.PathLike[str], fps: int = 50
) -> Path:
    """Encode RGB frames as an H.264 (yuv420p) MP4 file and return its path.

    The file plays in web browsers. yuv420p needs even sizes, so an odd height or
    width is padded by one edge pixel (never rescaled).

    Example::

        frames = [env.render() for _ in range(100)]  # render_mode="rgb_array"
        gym_soarm.save_frames_to_mp4(frames, "videos/run.mp4", fps=50)

    Args:
        frames: a non-empty sequence of uint8 arrays of one shape (H, W, 3).
        path: the file to write; missing parent folders are created.
        fps: frames per second of the video (the environment runs at 50).

    Raises:
        ValueError: no frames, frames of different sizes, a frame that is not a
            uint8 (H, W, 3) array, or a non-positive ``fps``. Nothing is written then.
    """
    import imageio.v2 as imageio

    frames = list(frames)
    if not frames:
        raise ValueError("frames is empty; pass at least one (H, W, 3) uint8 frame.")
    if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or fps <= 0:
        raise ValueError(f"fps must be a positive int (e.g. 50); got {fps!r}.")
    first = np.asarray(frames[0])
    for i, frame in enumerate(frames):
        array = np.asarray(frame)
        if array.dtype != np.uint8:
            raise ValueError(
                f"frame {i} has dtype {array.dtype}; expected uint8 RGB. Convert it with "
                "np.clip(frame, 0, 255).astype(np.uint8)."
            )
        if array.ndim != 3 or array.shape[2] != 3:
            raise ValueError(f"frame {i} has shape {array.shape}; expected (H, W, 3).")
        if array.shape != first.shape:
            raise ValueError(
                f"frame {i} has shape {array.shape} but frame 0 has {first.shape}; "
                "all frames of one video must have the same size."
            )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    height, width = first.shape[:2]
    # yuv420p needs even sizes; pad by one pixel rather than rescale.
    pad = ((0, height % 2), (0, width % 2), (0, 0))
    with imageio.get_writer(
        path,
        fps=fps,
        codec="libx264",
        pixelformat="yuv420p",
        macro_block_size=1,
        ffmpeg_params=["-movflags", "+faststart"],
        ffmpeg_log_level="error",
    ) as writer:
        for frame in frames:
            array = np.asarray(frame)
            writer.append_data(np.pad(array, pad, mode="edge") if any(p[1] for p in pad) else array)
    return path
