"""The torch-free LeRobotDataset v3.0 writer: files written, read back and decoded."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from dataset_files import decode_video, frame_times, psnr, read_dataset
from paths import TESTS

from gym_soarm.data import (
    AUTO_FEATURES,
    QUANTILES,
    STAT_NAMES,
    LeRobotDatasetWriter,
    histogram_image_stats,
    numeric_stats,
)
from gym_soarm.real import units

FPS = 50
HEIGHT, WIDTH = 48, 64
CAMERAS = ("front_camera", "wrist_camera")
LENGTHS = (20, 13)
TASKS = ("Pick up the blue cube and lift it 5 cm above the table.", "Another sentence.")
NAMES = list(units.FEATURE_NAMES)


def _features(cameras=CAMERAS) -> dict:
    features = {
        "action": {"dtype": "float32", "shape": (6,), "names": NAMES},
        "observation.state": {"dtype": "float32", "shape": (6,), "names": NAMES},
        "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
        "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    }
    for camera in cameras:
        features[f"observation.images.{camera}"] = {
            "dtype": "video",
            "shape": (HEIGHT, WIDTH, 3),
            "names": ["height", "width", "channels"],
        }
    return features


def _frames(lengths=LENGTHS, seed: int = 0) -> list[list[dict]]:
    """Real rendered frames of the arm following a fixed joint trajectory."""
    env = gym.make(
        "gym_soarm/LiftCube-v0",
        camera_config="front_wrist",
        observation_height=HEIGHT,
        observation_width=WIDTH,
        units="lerobot",
    )
    low, high = env.action_space.low, env.action_space.high
    episodes = []
    try:
        for e, length in enumerate(lengths):
            obs, info = env.reset(seed=seed + e)
            frames = []
            for t in range(length):
                phase = 2 * np.pi * t / 40 + np.arange(6) + 1.7 * e
                action = (low + (high - low) * (0.5 + 0.3 * np.sin(phase))).astype(np.float32)
                frame = {
                    "observation.state": obs["agent_pos"].astype(np.float32),
                    "action": action,
                    "task": TASKS[e % 2],
                }
                for camera in CAMERAS:
                    frame[f"observation.images.{camera}"] = obs["pixels"][camera]
                obs, reward, _, _, info = env.step(action)
                frame["next.reward"] = np.array([reward], np.float32)
                frame["next.success"] = np.array([info["is_success"]])
                frames.append(frame)
            episodes.append(frames)
    finally:
        env.close()
    return episodes


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds") / "soarm"
    episodes = _frames()
    writer = LeRobotDatasetWriter.create(root, FPS, _features(), robot_type="so101_follower")
    for frames in episodes:
        for frame in frames:
            writer.add_frame(frame)
        writer.save_episode()
    writer.finalize()
    return root, episodes, read_dataset(root)


def _all(episodes, key) -> np.ndarray:
    return np.stack([f[key] for frames in episodes for f in frames])


def test_files_and_info(recorded):
    root, _, ds = recorded
    total = sum(LENGTHS)
    for path in (
        "meta/info.json",
        "meta/stats.json",
        "meta/tasks.parquet",
        "meta/episodes/chunk-000/file-000.parquet",
        "data/chunk-000/file-000.parquet",
        *(f"videos/observation.images.{c}/chunk-000/file-000.mp4" for c in CAMERAS),
    ):
        assert (root / path).is_file(), path
    assert sorted(p.name for p in root.iterdir()) == ["data", "meta", "videos"]  # no scratch
    info = ds.info
    assert info["codebase_version"] == "v3.0"
    assert info["fps"] == FPS and info["robot_type"] == "so101_follower"
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (2, total, 2)
    assert info["splits"] == {"train": "0:2"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["video_path"] == (
        "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    )
    assert info["features"]["action"] == {"dtype": "float32", "shape": [6], "names": NAMES}
    for key, dtype in AUTO_FEATURES.items():
        assert info["features"][key] == {"dtype": dtype, "shape": [1], "names": None}
    video = info["features"]["observation.images.front_camera"]
    assert video["dtype"] == "video" and video["shape"] == [HEIGHT, WIDTH, 3]
    assert video["info"]["video.codec"] == "h264" and video["info"]["video.fps"] == FPS
    assert video["info"]["video.pix_fmt"] == "yuv420p"


def test_rows_indices_timestamps_and_values(recorded):
    _, episodes, ds = recorded
    total = sum(LENGTHS)
    assert len(ds.data["index"]) == total
    np.testing.assert_array_equal(ds.data["index"], np.arange(total))
    expected_frame = np.concatenate([np.arange(n) for n in LENGTHS])
    np.testing.assert_array_equal(ds.data["frame_index"], expected_frame)
    np.testing.assert_array_equal(ds.data["episode_index"], np.repeat([0, 1], LENGTHS))
    np.testing.assert_array_equal(ds.data["task_index"], np.repeat([0, 1], LENGTHS))
    assert ds.data["timestamp"].dtype == np.float64  # pylist of float32 values
    np.testing.assert_array_equal(
        ds.data["timestamp"].astype(np.float32), (expected_frame / FPS).astype(np.float32)
    )
    for key in ("action", "observation.state"):
        np.testing.assert_array_equal(ds.data[key].astype(np.float32), _all(episodes, key))
    np.testing.assert_array_equal(ds.data["next.success"], _all(episodes, "next.success")[:, 0])
    assert ds.tasks == [{"task_index": 0, "task": TASKS[0]}, {"task_index": 1, "task": TASKS[1]}]
    assert ds.tasks_pandas_metadata["index_columns"] == ["task"]


def test_episode_boundaries(recorded):
    _, _, ds = recorded
    starts = np.cumsum((0, *LENGTHS))
    for e, row in enumerate(ds.episodes):
        assert row["episode_index"] == e and row["length"] == LENGTHS[e]
        assert row["tasks"] == [TASKS[e]]
        assert (row["dataset_from_index"], row["dataset_to_index"]) == (starts[e], starts[e + 1])
        assert (row["data/chunk_index"], row["data/file_index"]) == (0, 0)
        for camera in CAMERAS:
            key = f"videos/observation.images.{camera}"
            assert row[f"{key}/from_timestamp"] == pytest.approx(starts[e] / FPS, abs=1e-9)
            assert row[f"{key}/to_timestamp"] == pytest.approx(starts[e + 1] / FPS, abs=1e-9)


def test_videos_decode_to_the_recorded_frames_at_exact_times(recorded):
    _, episodes, ds = recorded
    for camera in CAMERAS:
        key = f"observation.images.{camera}"
        path = ds.video_path(key, 0)
        decoded = decode_video(path)
        original = _all(episodes, key)
        assert decoded.shape == original.shape
        for i in range(len(original)):
            own = psnr(decoded[i], original[i])
            assert own > 25, (camera, i)
            # No frame is shifted or swapped: a decoded frame is closer to its own recorded
            # frame than to any recorded frame that clearly differs from it.
            distinct = [j for j in range(len(original)) if psnr(original[i], original[j]) < 30]
            assert len(distinct) >= len(original) // 2, (camera, i)
            closest_other = max(psnr(decoded[i], original[j]) for j in distinct)
            assert own > closest_other, (camera, i)
        np.testing.assert_allclose(
            frame_times(path), np.arange(sum(LENGTHS)) / FPS, rtol=0, atol=1e-4
        )


def test_stats_with_quantiles(recorded):
    _, episodes, ds = recorded
    every = (*_features(), *AUTO_FEATURES)
    assert set(ds.stats) == set(every)
    for key in every:
        assert set(ds.stats[key]) == set(STAT_NAMES), key
    actions = _all(episodes, "action").astype(np.float64)
    stats = ds.stats["action"]
    np.testing.assert_allclose(stats["mean"], actions.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats["std"], actions.std(axis=0), rtol=1e-12)
    for name, q in QUANTILES.items():
        np.testing.assert_allclose(stats[name], np.quantile(actions, q, axis=0), rtol=1e-12)
    assert stats["count"] == [sum(LENGTHS)]
    np.testing.assert_allclose(ds.stats["timestamp"]["max"], [(max(LENGTHS) - 1) / FPS], rtol=1e-6)
    # Images: per channel, (3, 1, 1), in [0, 1], the mean of the recorded pixels.
    for camera in CAMERAS:
        key = f"observation.images.{camera}"
        image = ds.stats[key]
        assert np.array(image["mean"]).shape == (3, 1, 1)
        for name in ("min", "max", "mean", "std", *QUANTILES):
            values = np.array(image[name])
            assert ((values >= 0) & (values <= 1)).all(), (key, name)
        pixels = _all(episodes, key).reshape(-1, 3) / 255.0
        np.testing.assert_allclose(np.array(image["mean"]).ravel(), pixels.mean(axis=0), atol=0.02)
        q = np.array([image[name] for name in QUANTILES]).reshape(len(QUANTILES), 3)
        assert (np.diff(q, axis=0) >= 0).all()
    # Per-episode stats in the episodes table are the stats of that episode alone.
    second = _all(episodes[1:], "observation.state").astype(np.float64)
    np.testing.assert_allclose(
        ds.episodes[1]["stats/observation.state/q50"], np.median(second, axis=0), rtol=1e-12
    )
    assert ds.episodes[1]["stats/observation.state/count"] == [LENGTHS[1]]


def test_histogram_stats_equal_numpy_on_the_same_pixels():
    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, size=(5000, 3), dtype=np.uint8)
    pixels[:, 2] //= 7  # a skewed channel
    histogram = np.stack([np.bincount(pixels[:, c], minlength=256) for c in range(3)])
    stats = histogram_image_stats(histogram, frames=1)
    reference = numeric_stats(pixels / 255.0)
    for name in ("min", "max", "mean", "std", *QUANTILES):
        np.testing.assert_allclose(np.ravel(stats[name]), reference[name], atol=1e-12)


# --- bad input -------------------------------------------------------------------------------
def _state_features() -> dict:
    return _features(cameras=("front_camera",))


def _good_frame() -> dict:
    return {
        "action": np.zeros(6, np.float32),
        "observation.state": np.ones(6, np.float32),
        "next.reward": np.array([0.25], np.float32),
        "next.success": np.array([False]),
        "observation.images.front_camera": np.full((HEIGHT, WIDTH, 3), 100, np.uint8),
        "task": "Lift the cube.",
    }


BAD_FRAMES = {
    "missing feature": (lambda f: f.pop("action"), r"missing \['action'\]"),
    "missing task": (lambda f: f.pop("task"), r"missing \['task'\]"),
    "unknown key": (lambda f: f.update(extra=np.zeros(1)), r"unknown \['extra'\]"),
    "auto feature": (lambda f: f.update(timestamp=np.zeros(1)), r"unknown \['timestamp'\]"),
    "wrong dtype": (
        lambda f: f.update(action=np.zeros(6, np.float64)),
        r"action must be a numpy array of dtype float32 and shape \(6,\); got dtype float64",
    ),
    "wrong shape": (
        lambda f: f.update(action=np.zeros(5, np.float32)),
        r"got dtype float32 and shape \(5,\)",
    ),
    "a list": (lambda f: f.update(action=[0.0] * 6), r"got list"),
    "nan": (lambda f: f["observation.state"].__setitem__(2, np.nan), r"must be finite"),
    "float image": (
        lambda f: f.update({"observation.images.front_camera": np.zeros((HEIGHT, WIDTH, 3))}),
        r"uint8 array of shape \(48, 64, 3\)",
    ),
    "channel-first image": (
        lambda f: f.update(
            {"observation.images.front_camera": np.zeros((3, HEIGHT, WIDTH), np.uint8)}
        ),
        r"channel-first",
    ),
    "empty task": (lambda f: f.update(task=" "), r"non-empty sentence"),
}


@pytest.mark.parametrize("case", list(BAD_FRAMES))
def test_bad_frames_are_clear_errors_and_record_nothing(tmp_path, case):
    change, message = BAD_FRAMES[case]
    writer = LeRobotDatasetWriter.create(tmp_path / "ds", FPS, _state_features())
    writer.add_frame(_good_frame())
    writer.save_episode()
    writer.add_frame(_good_frame())
    bad = _good_frame()
    change(bad)
    with pytest.raises(ValueError, match=message):
        writer.add_frame(bad)
    assert writer.episode_buffer_size == 1
    writer.add_frame(_good_frame())
    writer.save_episode()
    writer.finalize()
    ds = read_dataset(tmp_path / "ds")
    assert ds.info["total_frames"] == 3 and len(ds.data["index"]) == 3
    np.testing.assert_array_equal(ds.data["episode_index"], [0, 1, 1])
    assert len(decode_video(ds.video_path("observation.images.front_camera", 1))) == 3


def test_finished_dataset_and_empty_episode_are_errors(tmp_path):
    writer = LeRobotDatasetWriter.create(tmp_path / "ds", FPS, _state_features())
    with pytest.raises(ValueError, match="no frames were added"):
        writer.save_episode()
    writer.add_frame(_good_frame())
    writer.save_episode()
    writer.finalize()
    writer.finalize()  # safe twice
    with pytest.raises(RuntimeError, match="was finalized"):
        writer.add_frame(_good_frame())
    with pytest.raises(RuntimeError, match="was finalized"):
        writer.save_episode()
    assert read_dataset(tmp_path / "ds").info["total_frames"] == 1


def test_existing_folders(tmp_path):
    root = tmp_path / "ds"
    root.mkdir()
    LeRobotDatasetWriter.create(root, FPS, _state_features()).finalize()  # empty folder: fine
    with pytest.raises(FileExistsError, match="overwrite=True"):
        LeRobotDatasetWriter.create(root, FPS, _state_features())
    writer = LeRobotDatasetWriter.create(root, FPS, _state_features(), overwrite=True)
    writer.add_frame(_good_frame())
    writer.save_episode()
    writer.finalize()
    assert read_dataset(root).info["total_episodes"] == 1
    # A folder that is not a dataset is never deleted.
    other = tmp_path / "notes"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="does not look like a dataset"):
        LeRobotDatasetWriter.create(other, FPS, _state_features(), overwrite=True)
    assert (other / "keep.txt").read_text() == "mine"


@pytest.mark.parametrize(
    ("features", "message"),
    [
        ({"a": {"dtype": "float16", "shape": (2,)}}, "dtype 'float16'"),
        ({"a": {"dtype": "float32", "shape": (2, 2)}}, "1-D shape"),
        ({"a": {"dtype": "float32", "shape": (2,), "names": ["x"]}}, "1 names for shape"),
        ({"cam": {"dtype": "video", "shape": (47, 64, 3)}}, "even height and width"),
        ({"cam": {"dtype": "video", "shape": (48, 64)}}, r"\(height, width, 3\)"),
        ({"index": {"dtype": "int64", "shape": (1,)}}, "written by the writer"),
        ({}, "non-empty dict"),
    ],
)
def test_bad_feature_declarations(tmp_path, features, message):
    with pytest.raises(ValueError, match=message):
        LeRobotDatasetWriter.create(tmp_path / "ds", FPS, features)
    assert not (tmp_path / "ds").exists()


def test_context_manager_drops_the_unsaved_episode(tmp_path):
    root = tmp_path / "ds"
    with (
        pytest.warns(RuntimeWarning, match="dropped 1 frames"),
        pytest.raises(KeyboardInterrupt),
        LeRobotDatasetWriter.create(root, FPS, _state_features()) as writer,
    ):
        for _ in range(4):
            writer.add_frame(_good_frame())
        writer.save_episode()
        writer.add_frame(_good_frame())
        raise KeyboardInterrupt
    ds = read_dataset(root)
    assert ds.info["total_frames"] == 4 and len(ds.data["index"]) == 4


INTERRUPTED = textwrap.dedent(
    """
    import os, sys
    import numpy as np
    from gym_soarm.data import LeRobotDatasetWriter
    sys.path[:0] = [{here!r}, {tests!r}]  # this module and the tests' helpers
    from test_dataset import _good_frame, _state_features
    writer = LeRobotDatasetWriter.create({root!r}, 50, _state_features())
    for length in (5, 7):
        for t in range(length):
            frame = _good_frame()
            frame["action"][:] = t
            writer.add_frame(frame)
        writer.save_episode()
    for t in range(3):
        writer.add_frame(_good_frame())
    os._exit(3)  # the process dies mid-episode: no finalize, no cleanup
    """
)


@pytest.mark.subprocess
def test_an_interrupted_recording_keeps_its_finished_episodes(tmp_path):
    root = tmp_path / "ds"
    script = INTERRUPTED.format(here=str(Path(__file__).parent), tests=str(TESTS), root=str(root))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 3, result.stderr
    ds = read_dataset(root)
    assert ds.info["total_episodes"] == 2 and ds.info["total_frames"] == 12
    np.testing.assert_array_equal(ds.data["frame_index"], [*range(5), *range(7)])
    np.testing.assert_array_equal(ds.data["action"][:, 0], [*range(5), *range(7)])
    assert [row["length"] for row in ds.episodes] == [5, 7]
    video = ds.video_path("observation.images.front_camera", 1)
    assert len(decode_video(video)) == 12
    np.testing.assert_allclose(frame_times(video), np.arange(12) / FPS, atol=1e-4)


def test_full_files_roll_over_to_new_ones(tmp_path):
    """Past the size limits, each episode starts new data and video files."""
    root = tmp_path / "ds"
    writer = LeRobotDatasetWriter.create(
        root, FPS, _state_features(), data_files_size_in_mb=1e-6, video_files_size_in_mb=1e-6
    )
    for e, length in enumerate((3, 4, 5)):
        for t in range(length):
            frame = _good_frame()
            frame["action"][:] = 10 * e + t
            frame["observation.images.front_camera"][:] = 40 * e
            writer.add_frame(frame)
        writer.save_episode()
    writer.finalize()
    ds = read_dataset(root)
    assert len(list(root.glob("data/chunk-000/*.parquet"))) == 3
    assert ds.info["total_frames"] == 12
    np.testing.assert_array_equal(ds.data["index"], np.arange(12))
    np.testing.assert_array_equal(
        ds.data["action"][:, 0], [0, 1, 2, 10, 11, 12, 13, 20, 21, 22, 23, 24]
    )
    key = "observation.images.front_camera"
    for e, row in enumerate(ds.episodes):
        assert row["data/file_index"] == row[f"videos/{key}/file_index"] == e
        assert row[f"videos/{key}/from_timestamp"] == 0.0
        frames = decode_video(ds.video_path(key, e))
        assert len(frames) == row["length"]
        assert abs(frames.mean() - 40 * e) < 3
    with pytest.raises(ValueError, match="video_files_size_in_mb must be a positive"):
        LeRobotDatasetWriter.create(
            tmp_path / "bad", FPS, _state_features(), video_files_size_in_mb=0
        )
