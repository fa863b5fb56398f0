"""A LeRobotDataset v3.0 writer that needs neither LeRobot nor torch.

:class:`LeRobotDatasetWriter` writes the folder layout that ``lerobot`` reads with
``LeRobotDataset(repo_id, root=...)``, using pyarrow for the parquet files (extra
``gym-soarm[dataset]``) and the ffmpeg binary of imageio-ffmpeg for H.264 videos::

    root/
      meta/info.json                          format version, fps, features, totals
      meta/stats.json                         min/max/mean/std/count and q01..q99 per feature
      meta/tasks.parquet                      task sentence <-> task_index
      meta/episodes/chunk-000/file-000.parquet  one row per episode: lengths, file
                                                pointers, video time spans, stats
      data/chunk-000/file-000.parquet         one row per frame, many episodes per file
      videos/<camera key>/chunk-000/file-000.mp4  one H.264 file per camera, episodes
                                                  one after another

Use it like LeRobot's own ``LeRobotDataset.create``::

    writer = LeRobotDatasetWriter.create(root, fps=50, features=features)
    for frame in frames:
        writer.add_frame({**frame, "task": "Lift the cube."})
    writer.save_episode()
    writer.finalize()

Every :meth:`~LeRobotDatasetWriter.save_episode` leaves a complete, readable dataset on
disk (files are replaced atomically), so an interrupted recording keeps every episode
saved before the interruption. :meth:`~LeRobotDatasetWriter.finalize` drops an unsaved
episode and removes the writer's scratch folder.

Frame timestamps are exactly ``frame_index / fps``; each episode's span in its video file
starts where the previous episode's frames end, on a frame boundary.
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.data.format import (
    AUTO_FEATURES,
    CHUNKS_SIZE,
    CODEBASE_VERSION,
    DATA_FILES_SIZE_MB,
    DATA_PATH,
    EPISODES_PATH,
    INFO_PATH,
    SCRATCH_DIR,
    STATS_PATH,
    TASKS_PATH,
    VIDEO_FILES_SIZE_MB,
    VIDEO_PATH,
    Feature,
    check_root,
    deferred_interrupt,
    parse_features,
    require_pyarrow,
)
from gym_soarm.data.stats import (
    histogram_image_stats,
    image_histogram,
    numeric_stats,
    stats_to_json,
)
from gym_soarm.data.tables import arrow_type, tasks_table
from gym_soarm.data.video_files import (
    SegmentEncoder,
    concatenate_videos,
)

_SHARD_FILE = "episode.pkl"


# --- the writer ------------------------------------------------------------------------------
@dataclass
class _FilePointer:
    chunk_index: int = 0
    file_index: int = 0
    frames: int = 0  # frames already in the current file

    def advance(self) -> None:
        self.frames = 0
        self.file_index += 1
        if self.file_index >= CHUNKS_SIZE:
            self.chunk_index, self.file_index = self.chunk_index + 1, 0


class LeRobotDatasetWriter:
    """Writes a LeRobotDataset v3.0 folder: create, add frames, save episodes, finalize.

    Args:
        root: the dataset folder; created, and must not hold anything unless ``overwrite``.
        fps: frames per second of the recording (the environments run at 50).
        features: ``{key: {"dtype": ..., "shape": ..., "names": ...}}`` in LeRobot's form:
            numbers as ``dtype`` ``float32``/``float64``/``int32``/``int64``/``bool`` with a
            1-D shape, camera frames as ``dtype`` ``"video"`` with shape ``(H, W, 3)``
            (even H and W). The keys ``timestamp``, ``frame_index``, ``episode_index``,
            ``index`` and ``task_index`` are added by the writer.
        robot_type: stored in ``info.json`` (LeRobot's SO-101 is ``"so101_follower"``).
        overwrite: replace an existing dataset in ``root`` (a folder holding
            ``meta/info.json``); any other non-empty folder is never deleted.
        video_crf: H.264 quality (lower is better and larger).
        video_gop: frames between key frames; short groups make random access cheap.
        data_files_size_in_mb: a data file that has reached this size is closed and the
            next episode starts a new one (LeRobot's default 100).
        video_files_size_in_mb: the same for each camera's video files (default 200).

    Raises:
        FileExistsError: ``root`` is not empty and ``overwrite`` is false.
        ValueError: a bad ``fps`` or feature declaration, or ``overwrite`` on a folder that
            is not a dataset.
        ImportError: pyarrow is missing (``pip install 'gym-soarm[dataset]'``).
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        fps: int,
        features: Mapping[str, Mapping[str, Any]],
        robot_type: str | None = None,
        overwrite: bool = False,
        video_crf: int = 23,
        video_gop: int = 2,
        data_files_size_in_mb: float = DATA_FILES_SIZE_MB,
        video_files_size_in_mb: float = VIDEO_FILES_SIZE_MB,
    ) -> None:
        self._pa = require_pyarrow()
        if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or fps <= 0:
            raise ValueError(f"fps must be a positive int (e.g. 50); got {fps!r}.")
        for name, value in (("video_crf", video_crf), ("video_gop", video_gop)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f"{name} must be a non-negative int; got {value!r}.")
        for name, value in (
            ("data_files_size_in_mb", data_files_size_in_mb),
            ("video_files_size_in_mb", video_files_size_in_mb),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name} must be a positive number of megabytes; got {value!r}.")
        if robot_type is not None and not isinstance(robot_type, str):
            raise ValueError(f"robot_type must be a string or None; got {robot_type!r}.")
        self.features = parse_features(features)
        self.root = Path(root)
        check_root(self.root, overwrite)

        self.fps = int(fps)
        self.robot_type = robot_type
        self._crf, self._gop = int(video_crf), int(video_gop)
        self._data_mb, self._video_mb = data_files_size_in_mb, video_files_size_in_mb
        self._video_keys = [k for k, f in self.features.items() if f.is_video]
        self._numeric_keys = [k for k, f in self.features.items() if not f.is_video]
        self._scratch = self.root / SCRATCH_DIR
        self._scratch.mkdir(parents=True)
        self._finalized = False

        self._tasks: dict[str, int] = {}
        self._episodes: list[dict[str, Any]] = []
        self._total_frames = 0
        self._data_file = _FilePointer()
        self._video_files = {key: _FilePointer() for key in self._video_keys}
        # Everything numeric ever saved (for exact dataset statistics) and image histograms.
        self._numeric_history: dict[str, list[np.ndarray]] = {
            key: [] for key in (*self._numeric_keys, *AUTO_FEATURES)
        }
        self._image_histograms = {key: np.zeros((3, 256), np.int64) for key in self._video_keys}
        self._image_frames = dict.fromkeys(self._video_keys, 0)
        self._reset_buffer()
        self._write_info()

    @classmethod
    def create(
        cls,
        root: str | os.PathLike[str],
        fps: int,
        features: Mapping[str, Mapping[str, Any]],
        robot_type: str | None = None,
        overwrite: bool = False,
        **kwargs: Any,
    ) -> LeRobotDatasetWriter:
        """Create an empty dataset in ``root`` (LeRobot's ``LeRobotDataset.create`` order)."""
        return cls(root, fps, features, robot_type=robot_type, overwrite=overwrite, **kwargs)

    # --- properties ----------------------------------------------------------------------
    @property
    def num_episodes(self) -> int:
        """Episodes saved so far."""
        return len(self._episodes)

    @property
    def num_frames(self) -> int:
        """Frames in saved episodes."""
        return self._total_frames

    @property
    def episode_buffer_size(self) -> int:
        """Frames added to the episode being recorded and not saved yet."""
        return len(self._buffer_tasks)

    @property
    def finalized(self) -> bool:
        return self._finalized

    # --- recording ---------------------------------------------------------------------
    def add_frame(self, frame: Mapping[str, Any]) -> None:
        """Add one frame to the current episode.

        ``frame`` holds every declared feature and ``"task"`` (the task sentence).
        Numbers are numpy arrays of exactly the declared dtype and shape; camera frames
        are uint8 ``(H, W, 3)`` arrays. A bad frame raises before anything is recorded.

        Raises:
            ValueError: a missing or unknown key, a wrong dtype or shape, a non-finite
                number or an empty task.
            RuntimeError: the dataset was finalized.
        """
        self._check_open()
        if not isinstance(frame, Mapping):
            raise ValueError(f"frame must be a dict of features; got {type(frame).__name__}.")
        expected = set(self.features) | {"task"}
        missing = sorted(expected - set(frame))
        unknown = sorted(set(frame) - expected)
        if missing or unknown:
            parts = []
            if missing:
                parts.append(f"missing {missing}")
            if unknown:
                parts.append(f"unknown {unknown}")
            raise ValueError(
                f"frame keys do not match the features: {'; '.join(parts)}. Expected exactly "
                f"{sorted(expected)}."
            )
        task = frame["task"]
        if not isinstance(task, str) or not task.strip():
            raise ValueError(f"frame['task'] must be a non-empty sentence; got {task!r}.")
        values = {key: self._check_value(self.features[key], frame[key]) for key in self.features}

        # Valid: record it.
        for key in self._numeric_keys:
            self._buffer[key].append(values[key])
        for key in self._video_keys:
            image = values[key]
            if key not in self._encoders:
                self._encoders[key] = self._open_encoder(key)
            self._encoders[key].add(image)
            self._buffer_histograms[key] += image_histogram(image)
        self._buffer_tasks.append(task)

    def _check_value(self, feature: Feature, value: Any) -> np.ndarray:
        if feature.is_video:
            if (
                not isinstance(value, np.ndarray)
                or value.dtype != np.uint8
                or value.shape != feature.shape
            ):
                got = (
                    f"{value.dtype} array of shape {value.shape}"
                    if isinstance(value, np.ndarray)
                    else type(value).__name__
                )
                hint = (
                    " (channel-first; use np.moveaxis(frame, 0, -1))"
                    if isinstance(value, np.ndarray) and value.shape[:1] == (3,)
                    else ""
                )
                raise ValueError(
                    f"{feature.key} must be a uint8 array of shape {feature.shape} (H, W, 3); "
                    f"got {got}{hint}."
                )
            return value
        if not isinstance(value, np.ndarray):
            raise ValueError(
                f"{feature.key} must be a numpy array of dtype {feature.dtype} and shape "
                f"{feature.shape}; got {type(value).__name__}. Use np.asarray(value, "
                f"dtype=np.{feature.dtype}).reshape({feature.size})."
            )
        if value.dtype != np.dtype(feature.dtype) or value.shape != feature.shape:
            raise ValueError(
                f"{feature.key} must be a numpy array of dtype {feature.dtype} and shape "
                f"{feature.shape}; got dtype {value.dtype} and shape {value.shape}."
            )
        if value.dtype.kind == "f" and not np.isfinite(value).all():
            raise ValueError(f"{feature.key} must be finite; got {value.tolist()!r}.")
        return value.copy()

    def clear_episode_buffer(self) -> None:
        """Drop the frames of the episode being recorded (nothing on disk changes)."""
        self._close_encoders()
        for path in self._scratch.glob("*-segment.mp4"):
            path.unlink()
        self._reset_buffer()

    def save_episode(self) -> int:
        """Write the current episode to disk and return its ``episode_index``.

        On return the folder is a complete dataset holding every saved episode. Ctrl-C
        during the final file replacement is held back until the files agree.

        Raises:
            ValueError: no frame was added since the last save.
            RuntimeError: the dataset was finalized.
        """
        self._check_open()
        length = self.episode_buffer_size
        if length == 0:
            raise ValueError("no frames were added to this episode; call add_frame() first.")
        self._close_encoders()
        episode_index = len(self._episodes)
        start = self._total_frames

        for task in self._buffer_tasks:
            self._tasks.setdefault(task, len(self._tasks))
        frame_index = np.arange(length, dtype=np.int64)
        columns: dict[str, np.ndarray] = {
            key: np.stack(self._buffer[key]) for key in self._numeric_keys
        }
        columns["timestamp"] = (frame_index / self.fps).astype(np.float32)
        columns["frame_index"] = frame_index
        columns["episode_index"] = np.full(length, episode_index, np.int64)
        columns["index"] = start + frame_index
        columns["task_index"] = np.array([self._tasks[t] for t in self._buffer_tasks], np.int64)

        stats: dict[str, dict[str, np.ndarray]] = {}
        for key in self.features:
            if self.features[key].is_video:
                stats[key] = histogram_image_stats(self._buffer_histograms[key], length)
            else:
                stats[key] = numeric_stats(columns[key].reshape(length, -1))
        for key in AUTO_FEATURES:
            stats[key] = numeric_stats(columns[key].reshape(length, 1))

        # Stage every new file in the scratch folder, then move them all into place.
        staged: list[tuple[Path, Path]] = []
        if self._data_file.frames and self._file_size_mb(self._data_path()) >= self._data_mb:
            self._data_file.advance()
        data_path = self._data_path()
        staged.append((self._stage_data(columns, data_path), data_path))
        row: dict[str, Any] = {
            "episode_index": episode_index,
            "tasks": list(dict.fromkeys(self._buffer_tasks)),
            "length": length,
            "data/chunk_index": self._data_file.chunk_index,
            "data/file_index": self._data_file.file_index,
            "dataset_from_index": start,
            "dataset_to_index": start + length,
        }
        for key in self._video_keys:
            pointer = self._video_files[key]
            if pointer.frames and self._file_size_mb(self._video_path(key)) >= self._video_mb:
                pointer.advance()
            video_path = self._video_path(key)
            segment = self._segment_path(key)
            if pointer.frames:
                joined = self._scratch / f"{_safe(key)}-joined.mp4"
                concatenate_videos(video_path, segment, joined, self._scratch)
                segment.unlink()
                staged.append((joined, video_path))
            else:
                staged.append((segment, video_path))
            row[f"videos/{key}/chunk_index"] = pointer.chunk_index
            row[f"videos/{key}/file_index"] = pointer.file_index
            row[f"videos/{key}/from_timestamp"] = pointer.frames / self.fps
            row[f"videos/{key}/to_timestamp"] = (pointer.frames + length) / self.fps
        for key, feature_stats in stats.items():
            for name, value in stats_to_json(feature_stats).items():
                row[f"stats/{key}/{name}"] = value
        row["meta/episodes/chunk_index"] = 0
        row["meta/episodes/file_index"] = 0

        with deferred_interrupt():
            for source, target in staged:
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(source, target)
            self._data_file.frames += length
            for key in self._video_keys:
                self._video_files[key].frames += length
                self._image_histograms[key] += self._buffer_histograms[key]
                self._image_frames[key] += length
            for key, history in self._numeric_history.items():
                history.append(columns[key].reshape(length, -1))
            self._episodes.append(row)
            self._total_frames += length
            self._write_metadata()
            self._reset_buffer()
        return episode_index

    def export_episode(self, folder: str | os.PathLike[str]) -> int:
        """Move the episode being recorded into ``folder`` (a shard) instead of the dataset.

        The shard holds the episode's numbers, task sentences, image histograms and one
        encoded H.264 segment per camera; :meth:`import_episode` of another writer with
        the same features saves it exactly as :meth:`save_episode` would have. The
        folder appears at once, complete (it is written next to it and renamed).

        Returns:
            The number of frames exported.

        Raises:
            ValueError: no frame was added since the last save.
            RuntimeError: the dataset was finalized.
        """
        self._check_open()
        length = self.episode_buffer_size
        if length == 0:
            raise ValueError("no frames were added to this episode; call add_frame() first.")
        self._close_encoders()
        folder = Path(folder)
        partial = folder.with_name(folder.name + ".partial")
        for stale in (partial, folder):
            shutil.rmtree(stale, ignore_errors=True)
        partial.mkdir(parents=True)
        content = {
            "features": sorted(self.features),
            "numeric": {key: np.stack(self._buffer[key]) for key in self._numeric_keys},
            "histograms": self._buffer_histograms,
            "tasks": list(self._buffer_tasks),
        }
        with open(partial / _SHARD_FILE, "wb") as file:
            pickle.dump(content, file, protocol=pickle.HIGHEST_PROTOCOL)
        for key in self._video_keys:
            os.replace(self._segment_path(key), partial / f"{_safe(key)}.mp4")
        os.replace(partial, folder)
        self._reset_buffer()
        return length

    def import_episode(self, folder: str | os.PathLike[str]) -> int:
        """Save the episode of a shard written by :meth:`export_episode`; return its index.

        The shard's video segments are moved into the dataset; the rest of the folder
        is left for the caller to delete.

        Raises:
            ValueError: the shard's features differ from this dataset's, or it is not a
                complete shard.
            RuntimeError: frames were added and not saved, or the dataset was finalized.
        """
        self._check_open()
        if self.episode_buffer_size:
            raise RuntimeError(
                f"import_episode() needs an empty episode buffer; {self.episode_buffer_size} "
                "frames were added and not saved. Call save_episode() or clear_episode_buffer()."
            )
        folder = Path(folder)
        path = folder / _SHARD_FILE
        if not path.is_file():
            raise ValueError(
                f"{str(folder)!r} is not an episode shard: expected {_SHARD_FILE} written by "
                "LeRobotDatasetWriter.export_episode()."
            )
        with open(path, "rb") as file:
            content = pickle.load(file)  # our own shard, written by export_episode
        if content["features"] != sorted(self.features):
            raise ValueError(
                f"the shard in {str(folder)!r} has features {content['features']}; this dataset "
                f"expects {sorted(self.features)}."
            )
        segments = {key: folder / f"{_safe(key)}.mp4" for key in self._video_keys}
        missing = [str(p) for p in segments.values() if not p.is_file()]
        if missing:
            raise ValueError(f"the shard in {str(folder)!r} lacks its videos {missing}.")
        self._reset_buffer()
        self._buffer = {key: list(content["numeric"][key]) for key in self._numeric_keys}
        self._buffer_tasks = list(content["tasks"])
        self._buffer_histograms = {
            key: np.asarray(content["histograms"][key], np.int64) for key in self._video_keys
        }
        for key, segment in segments.items():
            os.replace(segment, self._segment_path(key))
        return self.save_episode()

    def finalize(self) -> None:
        """Finish the dataset: drop an unsaved episode, remove scratch files. Safe twice."""
        if self._finalized:
            return
        if self.episode_buffer_size:
            warnings.warn(
                f"finalize() dropped {self.episode_buffer_size} frames of an episode that was "
                "never saved; call save_episode() first to keep them.",
                RuntimeWarning,
                stacklevel=2,
            )
        self.clear_episode_buffer()
        shutil.rmtree(self._scratch, ignore_errors=True)
        self._finalized = True

    def __enter__(self) -> LeRobotDatasetWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.finalize()

    # --- helpers -----------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._finalized:
            raise RuntimeError(
                f"the dataset in {str(self.root)!r} was finalized; create a new writer to record more."
            )

    def _reset_buffer(self) -> None:
        self._buffer: dict[str, list[np.ndarray]] = {key: [] for key in self._numeric_keys}
        self._buffer_tasks: list[str] = []
        self._buffer_histograms = {key: np.zeros((3, 256), np.int64) for key in self._video_keys}
        self._encoders: dict[str, SegmentEncoder] = {}

    def _close_encoders(self) -> None:
        for encoder in getattr(self, "_encoders", {}).values():
            encoder.close()
        self._encoders = {}

    def _open_encoder(self, key: str) -> SegmentEncoder:
        height, width, _ = self.features[key].shape
        return SegmentEncoder(
            self._segment_path(key), height, width, self.fps, self._crf, self._gop
        )

    def _segment_path(self, key: str) -> Path:
        return self._scratch / f"{_safe(key)}-segment.mp4"

    def _data_path(self) -> Path:
        pointer = self._data_file
        return self.root / DATA_PATH.format(
            chunk_index=pointer.chunk_index, file_index=pointer.file_index
        )

    def _video_path(self, key: str) -> Path:
        pointer = self._video_files[key]
        return self.root / VIDEO_PATH.format(
            video_key=key, chunk_index=pointer.chunk_index, file_index=pointer.file_index
        )

    @staticmethod
    def _file_size_mb(path: Path) -> float:
        return path.stat().st_size / 1024**2

    def _arrow_type(self, dtype: str, size: int) -> Any:
        pa = self._pa
        scalar = {
            "float32": pa.float32(),
            "float64": pa.float64(),
            "int32": pa.int32(),
            "int64": pa.int64(),
            "bool": pa.bool_(),
        }[dtype]
        return scalar if size == 1 else pa.list_(scalar, size)

    def _data_schema(self) -> Any:
        pa = self._pa
        fields = [
            pa.field(key, self._arrow_type(self.features[key].dtype, self.features[key].size))
            for key in self._numeric_keys
        ]
        fields += [
            pa.field(key, self._arrow_type(dtype, 1)) for key, dtype in AUTO_FEATURES.items()
        ]
        return pa.schema(fields)

    def _stage_data(self, columns: Mapping[str, np.ndarray], target: Path) -> Path:
        pa = self._pa
        import pyarrow.parquet as pq

        schema = self._data_schema()
        arrays = []
        for field in schema:
            values = columns[field.name]
            if pa.types.is_fixed_size_list(field.type):
                flat = pa.array(values.reshape(-1), type=field.type.value_type)
                arrays.append(pa.FixedSizeListArray.from_arrays(flat, field.type.list_size))
            else:
                arrays.append(pa.array(values.reshape(-1), type=field.type))
        table = pa.Table.from_arrays(arrays, schema=schema)
        if self._data_file.frames:
            table = pa.concat_tables([pq.read_table(target, schema=schema), table])
        staged = self._scratch / "data.parquet"
        pq.write_table(table, staged)
        return staged

    def _feature_info(self) -> dict[str, Any]:
        info: dict[str, Any] = {}
        for key, feature in self.features.items():
            entry: dict[str, Any] = {
                "dtype": feature.dtype,
                "shape": list(feature.shape),
                "names": list(feature.names) if feature.names is not None else None,
            }
            if feature.is_video:
                height, width, channels = feature.shape
                entry["info"] = {
                    "video.height": height,
                    "video.width": width,
                    "video.codec": "h264",
                    "video.pix_fmt": "yuv420p",
                    "video.fps": self.fps,
                    "video.channels": channels,
                    "video.g": self._gop,
                    "video.crf": self._crf,
                    "has_audio": False,
                    "is_depth_map": False,
                }
            info[key] = entry
        for key, dtype in AUTO_FEATURES.items():
            info[key] = {"dtype": dtype, "shape": [1], "names": None}
        return info

    def _write_info(self) -> None:
        info = {
            "codebase_version": CODEBASE_VERSION,
            "fps": self.fps,
            "features": self._feature_info(),
            "total_episodes": len(self._episodes),
            "total_frames": self._total_frames,
            "total_tasks": len(self._tasks),
            "chunks_size": CHUNKS_SIZE,
            "data_files_size_in_mb": self._data_mb,
            "video_files_size_in_mb": self._video_mb,
            "data_path": DATA_PATH,
            "video_path": VIDEO_PATH if self._video_keys else None,
            "robot_type": self.robot_type,
            "splits": {"train": f"0:{len(self._episodes)}"},
        }
        _write_json_atomically(self.root / INFO_PATH, info, self._scratch)

    def _dataset_stats(self) -> dict[str, dict[str, list]]:
        stats: dict[str, dict[str, list]] = {}
        for key in self.features:
            if self.features[key].is_video:
                feature_stats = histogram_image_stats(
                    self._image_histograms[key], self._image_frames[key]
                )
            else:
                feature_stats = numeric_stats(np.concatenate(self._numeric_history[key]))
            stats[key] = stats_to_json(feature_stats)
        for key in AUTO_FEATURES:
            stats[key] = stats_to_json(numeric_stats(np.concatenate(self._numeric_history[key])))
        return stats

    def _write_metadata(self) -> None:
        pa = self._pa
        import pyarrow.parquet as pq

        task_table = tasks_table(pa, self._tasks)
        # Explicit column types: pyarrow's type inference is slow (it tries optional imports).
        columns = list(self._episodes[0])
        episodes_table = pa.Table.from_arrays(
            [
                pa.array([row[c] for row in self._episodes], arrow_type(pa, self._episodes[0][c]))
                for c in columns
            ],
            names=columns,
        )
        staged = [
            (task_table, self.root / TASKS_PATH, "tasks.parquet"),
            (
                episodes_table,
                self.root / EPISODES_PATH.format(chunk_index=0, file_index=0),
                "episodes.parquet",
            ),
        ]
        for table, target, name in staged:
            path = self._scratch / name
            pq.write_table(table, path)
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(path, target)
        _write_json_atomically(self.root / STATS_PATH, self._dataset_stats(), self._scratch)
        self._write_info()


def _safe(key: str) -> str:
    return key.replace("/", "_")


def _write_json_atomically(path: Path, content: Any, scratch: Path) -> None:
    staged = scratch / (path.name + ".staged")
    staged.write_text(json.dumps(content, indent=4) + "\n")
    path.parent.mkdir(parents=True, exist_ok=True)
    os.replace(staged, path)
