"""H.264 video files of a dataset: one encoder per episode and camera, joined by ffmpeg."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np


# --- video -----------------------------------------------------------------------------------
class SegmentEncoder:
    """Streams one episode of one camera into an H.264 mp4 through ffmpeg."""

    def __init__(self, path: Path, height: int, width: int, fps: int, crf: int, gop: int) -> None:
        import imageio_ffmpeg

        self.path = path
        self._writer = imageio_ffmpeg.write_frames(
            str(path),
            (width, height),
            fps=fps,
            codec="libx264",
            pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p",
            quality=None,
            macro_block_size=1,
            ffmpeg_log_level="error",
            output_params=["-crf", str(crf), "-g", str(gop), "-preset", "veryfast"],
        )
        self._writer.send(None)

    def add(self, frame: np.ndarray) -> None:
        self._writer.send(np.ascontiguousarray(frame))

    def close(self) -> None:
        self._writer.close()


def concatenate_videos(first: Path, second: Path, out: Path, scratch: Path) -> None:
    import imageio_ffmpeg

    listing = scratch / "concat.txt"
    listing.write_text(f"file '{first.resolve()}'\nfile '{second.resolve()}'\n")
    command = [
        imageio_ffmpeg.get_ffmpeg_exe(),
        "-y",
        "-loglevel",
        "error",
        "-f",
        "concat",
        "-safe",
        "0",
        "-i",
        str(listing),
        "-c",
        "copy",
        "-movflags",
        "+faststart",
        str(out),
    ]
    # A session of its own keeps a terminal's Ctrl-C away from ffmpeg; the writer decides.
    result = subprocess.run(
        command, capture_output=True, text=True, check=False, start_new_session=True
    )
    if result.returncode != 0:
        raise RuntimeError(f"ffmpeg could not join {first} and {second}: {result.stderr.strip()}")
