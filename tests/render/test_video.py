"""save_frames_to_mp4: real H.264 files, read back with imageio."""

from __future__ import annotations

import numpy as np
import pytest
from mp4 import read_video

import gym_soarm
from gym_soarm import save_frames_to_mp4


def _frames(count: int, height: int = 48, width: int = 64) -> list[np.ndarray]:
    # A bright square that moves one block per frame: the frames differ visibly.
    frames = []
    for i in range(count):
        frame = np.full((height, width, 3), 30, dtype=np.uint8)
        x = (8 * i) % (width - 16)
        frame[16:32, x : x + 16] = (240, 200, 40)
        frames.append(frame)
    return frames


def test_writes_browser_playable_h264_that_reads_back(tmp_path):
    frames = _frames(12)
    target = tmp_path / "nested" / "folder" / "clip.mp4"
    path = save_frames_to_mp4(frames, target)
    assert path == target
    assert path.is_file()

    decoded, meta = read_video(path)
    assert meta["codec"] == "h264"
    assert meta["pix_fmt"].startswith("yuv420p")
    assert meta["fps"] == pytest.approx(50.0)
    assert decoded.shape == (12, 48, 64, 3)
    # Lossy, but each frame is close to what was written.
    error = np.abs(decoded.astype(int) - np.stack(frames).astype(int)).mean(axis=(1, 2, 3))
    assert error.max() < 6.0


def test_fps_and_odd_sizes(tmp_path):
    frames = _frames(5, height=47, width=63)
    decoded, meta = read_video(save_frames_to_mp4(frames, tmp_path / "odd.mp4", fps=25))
    assert meta["fps"] == pytest.approx(25.0)
    # yuv420p needs even sizes: one edge pixel is added, nothing is rescaled.
    assert decoded.shape == (5, 48, 64, 3)
    error = np.abs(decoded[:, :47, :63].astype(int) - np.stack(frames).astype(int)).mean()
    assert error < 6.0


def test_accepts_a_stacked_array_and_is_exported(tmp_path):
    assert gym_soarm.save_frames_to_mp4 is save_frames_to_mp4
    decoded, _ = read_video(save_frames_to_mp4(np.stack(_frames(3)), tmp_path / "a.mp4"))
    assert decoded.shape == (3, 48, 64, 3)


@pytest.mark.parametrize(
    ("frames", "message"),
    [
        ([], "frames is empty"),
        ([np.zeros((48, 64, 3), np.uint8), np.zeros((48, 66, 3), np.uint8)], "same size"),
        ([np.zeros((48, 64, 3), np.float32)], "dtype float32; expected uint8"),
        ([np.zeros((48, 64), np.uint8)], "expected (H, W, 3)"),
    ],
    ids=["empty", "mixed-sizes", "float", "grayscale"],
)
def test_bad_frames_raise_value_error_and_write_nothing(tmp_path, frames, message):
    target = tmp_path / "out" / "bad.mp4"
    with pytest.raises(ValueError, match=re_escape(message)):
        save_frames_to_mp4(frames, target)
    assert not target.parent.exists()


@pytest.mark.parametrize("fps", [0, -5, 2.5, True])
def test_bad_fps_raises(tmp_path, fps):
    with pytest.raises(ValueError, match="fps must be a positive int"):
        save_frames_to_mp4(_frames(2), tmp_path / "x.mp4", fps=fps)


def re_escape(text: str) -> str:
    import re

    return re.escape(text)
