"""Recording in worker processes: the same dataset as one process, whatever happens."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from dataset_files import decode_video
from interrupt import interrupt_when

from gym_soarm.cli.record import build_parser
from gym_soarm.data.format import SCRATCH_DIR
from gym_soarm.record.record import record

PIXELS = {"camera_config": "front_wrist", "size": (48, 64)}


def assert_same_dataset(a: Path, b: Path) -> None:
    """Same parquet tables, same metadata, same decoded video frames."""
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert files_a == files_b
    for rel in files_a:
        if rel.suffix == ".parquet":
            assert pq.read_table(a / rel).equals(pq.read_table(b / rel)), rel
        elif rel.suffix == ".json":
            assert json.loads((a / rel).read_text()) == json.loads((b / rel).read_text()), rel
        elif rel.suffix == ".mp4":
            frames_a, frames_b = decode_video(a / rel), decode_video(b / rel)
            assert frames_a.shape == frames_b.shape and np.array_equal(frames_a, frames_b), rel
        else:
            assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel


@pytest.fixture(scope="module")
def one_worker(tmp_path_factory):
    root = tmp_path_factory.mktemp("w1") / "ds"
    return root, record(root, task="LiftCube-v0", episodes=3, seed=4, **PIXELS)


def test_two_workers_give_the_same_dataset(one_worker, tmp_path):
    reference, summary_1 = one_worker
    root = tmp_path / "ds"
    summary_2 = record(root, task="LiftCube-v0", episodes=3, seed=4, workers=2, **PIXELS)
    assert (summary_2.episodes, summary_2.frames) == (summary_1.episodes, summary_1.frames)
    assert (summary_2.attempts, summary_2.successes) == (summary_1.attempts, summary_1.successes)
    assert not (root / SCRATCH_DIR).exists()
    assert_same_dataset(reference, root)


def test_keep_success_keeps_the_first_successes_in_attempt_order(tmp_path):
    # Strong DART noise: many attempts fail, and which ones must not depend on timing.
    # Enough state-only episodes that the recorder starts its worker (it does when the
    # attempts left outlast the worker's start-up).
    args = {"task": "LiftCube-v0", "episodes": 16, "seed": 100, "camera_config": "none"}
    one = record(tmp_path / "w1", dart_noise=0.1, **args)
    two = record(tmp_path / "w2", dart_noise=0.1, workers=2, **args)
    assert one.attempts > one.episodes  # some attempts failed and were dropped
    assert (two.attempts, two.successes, two.episodes) == (
        one.attempts,
        one.successes,
        one.episodes,
    )
    assert_same_dataset(tmp_path / "w1", tmp_path / "w2")


def test_cli_takes_workers():
    args = build_parser().parse_args(["--workers", "3"])
    assert args.workers == 3
    with pytest.raises(ValueError, match="workers"):
        record("/nonexistent/never-written", workers=0)


def _worker_dirs(root: Path) -> list[Path]:
    return sorted((root / SCRATCH_DIR / "shards").glob("worker-*"))


@pytest.mark.subprocess
def test_a_worker_killed_mid_episode_costs_a_retry(one_worker, tmp_path):
    reference, _ = one_worker
    root = tmp_path / "ds"
    command = [
        *(sys.executable, "-m", "gym_soarm.record", "--task", "LiftCube-v0"),
        *("--episodes", "3", "--seed", "4", "--root", str(root), "--no-progress"),
        *("--camera-config", "front_wrist", "--size", "48x64", "--workers", "2"),
    ]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    try:
        deadline = time.monotonic() + 240
        while killed is None and time.monotonic() < deadline and proc.poll() is None:
            # A worker is mid-episode while its scratch folder holds an open video segment
            # (the recorder's own process plays attempts too: not that one).
            for folder in _worker_dirs(root):
                if folder.name == f"worker-{proc.pid}":
                    continue
                if list((folder / SCRATCH_DIR).glob("*-segment.mp4")):
                    killed = int(folder.name.split("-")[1])
                    os.kill(killed, signal.SIGKILL)
                    break
            time.sleep(0.05)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert killed is not None, "no worker was seen mid-episode"
    assert proc.returncode == 0, err
    assert "3 episodes" in out
    assert_same_dataset(reference, root)


@pytest.mark.subprocess
def test_ctrl_c_keeps_every_finished_episode(tmp_path):
    root = tmp_path / "ds"
    command = [
        *(sys.executable, "-m", "gym_soarm.record", "--task", "LiftCube-v0"),
        *("--episodes", "50", "--seed", "0", "--root", str(root), "--no-progress"),
        *("--camera-config", "none", "--workers", "2"),
    ]
    info = root / "meta" / "info.json"
    done = interrupt_when(
        command,
        lambda _: info.exists() and json.loads(info.read_text())["total_episodes"] >= 2,
        within_s=240,
        answer_s=120,
        what="two saved episodes",
    )
    assert done.returncode == 130, done.stderr
    saved = json.loads(info.read_text())
    assert saved["total_episodes"] >= 2 and f"{saved['total_episodes']} episodes" in done.stdout
    episodes = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    assert episodes.column("episode_index").to_pylist() == list(range(saved["total_episodes"]))
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    assert data.num_rows == saved["total_frames"]
    assert not (root / SCRATCH_DIR).exists()


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _listening(port: int) -> bool:
    import socket

    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


@pytest.mark.subprocess
def test_ray_tasks_on_a_local_head_give_the_same_dataset(one_worker, tmp_path):
    pytest.importorskip("ray")
    reference, _ = one_worker
    port = _free_port()
    ray_dir = tempfile.mkdtemp(prefix="ray-", dir="/tmp")  # Unix socket paths must be short
    # An explicit address never sends Ray's authentication token: run without it.
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "disabled"}
    head = subprocess.Popen(
        [
            *(sys.executable, "-m", "ray.scripts.scripts", "start", "--head", "--block"),
            *("--port", str(port), "--num-cpus", "2", "--include-dashboard", "false"),
            *("--temp-dir", ray_dir),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
        start_new_session=True,  # the head and its processes are ended together below
    )
    root = tmp_path / "ds"
    try:
        command = [
            *(sys.executable, "-m", "gym_soarm.record", "--task", "LiftCube-v0"),
            *("--episodes", "3", "--seed", "4", "--root", str(root), "--no-progress"),
            *("--camera-config", "front_wrist", "--size", "48x64"),
            *("--ray", f"127.0.0.1:{port}", "--workers", "2"),
        ]
        deadline = time.monotonic() + 120
        while not _listening(port):  # the head takes a while to start
            assert head.poll() is None and time.monotonic() < deadline, "the Ray head did not start"
            time.sleep(0.5)
        time.sleep(5)  # its raylet starts after the GCS server listens
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        assert "3 episodes" in done.stdout
        assert_same_dataset(reference, root)
    finally:
        head.terminate()
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            head.kill()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(head.pid, signal.SIGKILL)
        shutil.rmtree(ray_dir, ignore_errors=True)


def test_workers_write_the_same_variation_lines(tmp_path):
    args = {"task": "LiftCube-v0", "episodes": 2, "seed": 9, "camera_config": "none"}
    variation = {"object_placement": "uniform", "distractors": 2}
    record(tmp_path / "w1", variation=variation, **args)
    record(tmp_path / "w2", variation=variation, workers=2, **args)
    lines = (tmp_path / "w2" / "meta" / "variation.jsonl").read_text().splitlines()
    assert [json.loads(line)["seed"] for line in lines] == [9, 10]
    assert_same_dataset(tmp_path / "w1", tmp_path / "w2")


def test_a_multi_task_recording_is_the_same_with_workers_and_ray(tmp_path):
    """Two tasks into one dataset: one process, two workers and a local Ray cluster (started
    once for both tasks) write the same files."""
    args = {"task": "ReachTarget-v0,PushCube-v0", "episodes": 2, "seed": 2, **PIXELS}
    record(tmp_path / "one", **args)
    record(tmp_path / "two", workers=2, **args)
    assert_same_dataset(tmp_path / "one", tmp_path / "two")
    pytest.importorskip("ray")
    summary = record(tmp_path / "ray", ray_address="local", workers=2, **args)
    assert summary.tasks == ("ReachTarget-v0", "PushCube-v0") and summary.episodes == 4
    assert_same_dataset(tmp_path / "one", tmp_path / "ray")


@pytest.mark.subprocess
def test_workers_that_cannot_start_end_the_recording_with_the_fix(tmp_path):
    # A script fed on stdin: the workers cannot import its main module again and die
    # while starting; the recorder gives up after a few, naming the fix.
    script = (
        "from gym_soarm.record.record import record\n"
        f"record({str(tmp_path / 'ds')!r}, task='LiftCube-v0', episodes=60, seed=0,\n"
        "       camera_config='none', workers=2, progress=False)\n"
    )
    done = subprocess.run(
        [sys.executable, "-"], input=script, capture_output=True, text=True, timeout=300
    )
    assert done.returncode != 0
    assert "recording workers died 3 times while starting" in done.stderr
    assert 'if __name__ == "__main__":' in done.stderr
