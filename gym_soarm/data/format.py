"""The LeRobotDataset v3.0 format: paths, feature declarations and folder checks."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILES_SIZE_MB = 100
VIDEO_FILES_SIZE_MB = 200
QUANTILES: dict[str, float] = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
STAT_NAMES: tuple[str, ...] = ("min", "max", "mean", "std", "count", *QUANTILES)

INFO_PATH = "meta/info.json"
STATS_PATH = "meta/stats.json"
TASKS_PATH = "meta/tasks.parquet"
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
EPISODES_PATH = "meta/episodes/" + CHUNK_FILE + ".parquet"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"
SCRATCH_DIR = ".writer-scratch"

NUMERIC_DTYPES: tuple[str, ...] = ("float32", "float64", "int32", "int64", "bool")
VIDEO_DTYPE = "video"
AUTO_FEATURES: dict[str, str] = {
    "timestamp": "float32",
    "frame_index": "int64",
    "episode_index": "int64",
    "index": "int64",
    "task_index": "int64",
}
"""Columns every dataset has; the writer fills them, frames must not carry them."""

# Image statistics use every frame, subsampled in space to about this many pixels a side.


def require_pyarrow() -> Any:
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as exc:
        raise ImportError(
            "Writing LeRobot datasets needs pyarrow: pip install 'gym-soarm[dataset]'"
        ) from exc
    return pyarrow


@dataclass(frozen=True)
class Feature:
    """One declared feature of a dataset.

    Attributes:
        key: the column or video name, e.g. ``"observation.state"``.
        dtype: one of :data:`NUMERIC_DTYPES` or ``"video"``.
        shape: ``(n,)`` for numbers, ``(height, width, 3)`` for videos.
        names: names of the ``n`` values, or ``None``.
    """

    key: str
    dtype: str
    shape: tuple[int, ...]
    names: tuple[str, ...] | None

    @property
    def is_video(self) -> bool:
        return self.dtype == VIDEO_DTYPE

    @property
    def size(self) -> int:
        return self.shape[0]


def parse_features(features: Any) -> dict[str, Feature]:
    if not isinstance(features, Mapping) or not features:
        raise ValueError(
            "features must be a non-empty dict {key: {'dtype': ..., 'shape': ..., 'names': ...}}; "
            f"got {features!r}."
        )
    parsed: dict[str, Feature] = {}
    for key, spec in features.items():
        if not isinstance(key, str) or not key or "/" in key:
            raise ValueError(f"feature keys must be non-empty strings without '/'; got {key!r}.")
        if key in AUTO_FEATURES or key == "task":
            raise ValueError(
                f"feature {key!r} is written by the writer itself; remove it from features."
            )
        if not isinstance(spec, Mapping) or "dtype" not in spec or "shape" not in spec:
            raise ValueError(
                f"feature {key!r} must be a dict with 'dtype' and 'shape' (and optional 'names'); "
                f"got {spec!r}."
            )
        dtype, names = spec["dtype"], spec.get("names")
        try:
            shape = tuple(int(n) for n in spec["shape"])
        except (TypeError, ValueError):
            raise ValueError(
                f"feature {key!r} has shape {spec['shape']!r}; expected ints."
            ) from None
        if dtype == VIDEO_DTYPE:
            if len(shape) != 3 or shape[2] != 3 or min(shape) <= 0:
                raise ValueError(
                    f"video feature {key!r} must have shape (height, width, 3); got {shape}."
                )
            if shape[0] % 2 or shape[1] % 2:
                raise ValueError(
                    f"video feature {key!r} has shape {shape}; H.264 yuv420p needs an even "
                    "height and width."
                )
            names = ("height", "width", "channels")
        elif dtype in NUMERIC_DTYPES:
            if len(shape) != 1 or shape[0] <= 0:
                raise ValueError(
                    f"numeric feature {key!r} must have a 1-D shape (n,); got {shape}."
                )
            if names is not None:
                names = tuple(str(n) for n in names)
                if len(names) != shape[0]:
                    raise ValueError(
                        f"feature {key!r} has {len(names)} names for shape {shape}; give one "
                        "name per value or names=None."
                    )
        else:
            raise ValueError(
                f"feature {key!r} has dtype {dtype!r}; expected one of "
                f"{', '.join(repr(d) for d in (*NUMERIC_DTYPES, VIDEO_DTYPE))}."
            )
        parsed[key] = Feature(key, dtype, shape, names)
    return parsed


def check_root(root: Path, overwrite: bool) -> None:
    if root.exists() and not root.is_dir():
        raise FileExistsError(
            f"root {str(root)!r} exists and is not a folder; choose another root."
        )
    if root.is_dir() and any(root.iterdir()):
        if not overwrite:
            raise FileExistsError(
                f"root {str(root)!r} already exists and is not empty; choose a new folder or "
                "pass overwrite=True (--overwrite) to replace the dataset in it."
            )
        if not (root / INFO_PATH).is_file():
            raise ValueError(
                f"root {str(root)!r} is not empty and holds no {INFO_PATH}; it does not look like "
                "a dataset, so it is not deleted even with overwrite=True. Choose another root."
            )
        shutil.rmtree(root)


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Hold Ctrl-C back until the block ends, so files are never left half-committed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[Any] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            raise KeyboardInterrupt


def load_info(root: str | os.PathLike[str]) -> dict[str, Any]:
    """Read ``meta/info.json`` of a dataset folder."""
    return json.loads((Path(root) / INFO_PATH).read_text())
