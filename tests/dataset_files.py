"""Reading a LeRobotDataset v3.0 folder back with pyarrow and ffmpeg, for the tests."""

from __future__ import annotations

import json
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import imageio_ffmpeg
import numpy as np
import pyarrow.parquet as pq


@dataclass
class DatasetFiles:
    root: Path
    info: dict[str, Any]
    stats: dict[str, dict[str, Any]]
    data: dict[str, np.ndarray]
    episodes: list[dict[str, Any]]
    tasks: list[dict[str, Any]]
    tasks_pandas_metadata: dict[str, Any]

    def column(self, key: str) -> np.ndarray:
        return self.data[key]

    def video_path(self, key: str, episode: int) -> Path:
        row = self.episodes[episode]
        return self.root / self.info["video_path"].format(
            video_key=key,
            chunk_index=row[f"videos/{key}/chunk_index"],
            file_index=row[f"videos/{key}/file_index"],
        )


def read_dataset(root: str | Path) -> DatasetFiles:
    root = Path(root)
    info = json.loads((root / "meta/info.json").read_text())
    stats = json.loads((root / "meta/stats.json").read_text())
    data_files = sorted(root.glob("data/*/*.parquet"))
    tables = [pq.read_table(p) for p in data_files]
    data: dict[str, np.ndarray] = {}
    for name in tables[0].column_names:
        data[name] = np.concatenate([np.array(t.column(name).to_pylist()) for t in tables], axis=0)
    episodes = []
    for path in sorted(root.glob("meta/episodes/*/*.parquet")):
        episodes += pq.read_table(path).to_pylist()
    tasks_table = pq.read_table(root / "meta/tasks.parquet")
    return DatasetFiles(
        root=root,
        info=info,
        stats=stats,
        data=data,
        episodes=episodes,
        tasks=tasks_table.to_pylist(),
        tasks_pandas_metadata=json.loads(tasks_table.schema.metadata[b"pandas"]),
    )


def decode_video(path: Path) -> np.ndarray:
    """Every frame of an mp4 as uint8 (N, H, W, 3)."""
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = reader.__next__()
    width, height = meta["size"]
    frames = [np.frombuffer(b, np.uint8).reshape(height, width, 3) for b in reader]
    return np.stack(frames)


def frame_times(path: Path) -> np.ndarray:
    """Presentation time (s) of every frame in an mp4, as ffmpeg reports it."""
    result = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-i", str(path), "-vf", "showinfo", "-f", "null", "-"],
        capture_output=True,
        text=True,
        check=True,
    )
    return np.array([float(t) for t in re.findall(r"pts_time:\s*([0-9.]+)", result.stderr)])


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)
