"""Reading MP4 files back for tests, with imageio's ffmpeg plugin."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def read_video(path: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """All frames of a video as uint8 (N, H, W, 3) and its metadata (codec, pix_fmt, fps)."""
    import imageio.v2 as imageio

    with imageio.get_reader(path, format="FFMPEG") as reader:
        meta = dict(reader.get_meta_data())
        # list(reader) would ask for len(), which is inf for this plugin.
        frames = np.stack([np.asarray(frame) for frame in reader])
    return frames, meta
