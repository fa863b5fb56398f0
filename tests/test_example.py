"""examples/example.py run as a user runs it: a subprocess that writes real MP4 files."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mp4 import read_video
from xwindows import find_windows, require_window_tools, wait_for, window_size

pytestmark = pytest.mark.gl

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "example.py"
SMALL = ["--height", "48", "--width", "64", "--quality", "fast"]
VIDEO_NAME = re.compile(r"^(overview|front|wrist)_camera_(\d{8}_\d{6})(_ep\d{2})?\.mp4$")
TAIL_STEPS = 25


def run_example(
    *args: str, env: dict[str, str] | None = None, cwd: Path | None = None
) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        env=env,
        cwd=cwd,
    )


def videos(folder: Path) -> dict[str, Path]:
    return {path.name: path for path in sorted(folder.glob("*.mp4"))}


def check_video(path: Path, frames: int, height: int = 48, width: int = 64) -> None:
    decoded, meta = read_video(path)
    assert decoded.shape == (frames, height, width, 3), path.name
    assert meta["codec"] == "h264"
    assert meta["pix_fmt"].startswith("yuv420p")
    assert meta["fps"] == pytest.approx(50.0)
    assert decoded.std() > 5.0  # a rendered scene, not a blank frame


@pytest.mark.subprocess
def test_random_policy_writes_both_videos_named_by_camera_and_time(tmp_path):
    before = time.strftime("%Y%m%d_%H%M%S")
    result = run_example(
        *SMALL, "--steps", "12", "--policy", "random", "--viewer", "off",
        "--output-dir", str(tmp_path / "out"),
    )  # fmt: skip
    after = time.strftime("%Y%m%d_%H%M%S")
    assert result.returncode == 0, result.stderr
    files = videos(tmp_path / "out")
    assert len(files) == 2, files
    matches = {name: VIDEO_NAME.match(name) for name in files}
    assert all(matches.values()), files
    assert {m.group(1) for m in matches.values()} == {"front", "wrist"}
    stamps = {m.group(2) for m in matches.values()}
    assert len(stamps) == 1 and before <= stamps.pop() <= after
    for name, path in files.items():
        check_video(path, frames=13)  # the reset frame and one per step
        assert f"wrote {path}" in result.stdout, name
    assert "episode 1: not successful" in result.stdout
    assert "random actions" in result.stdout
    assert "%" in result.stderr  # the progress bar


@pytest.mark.subprocess
def test_default_policy_is_the_expert_and_stops_after_success(tmp_path):
    result = run_example(
        *SMALL, "--camera-config", "front_only", "--grid-cell", "4", "--viewer", "off",
        "--output-dir", str(tmp_path),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "the scripted expert" in result.stdout
    found = re.search(r"episode 1: success at step (\d+)", result.stdout)
    assert found, result.stdout
    success_step = int(found.group(1))
    (path,) = videos(tmp_path).values()
    assert path.name.startswith("front_camera_")
    # The reset frame, every step up to success, then half a second more.
    check_video(path, frames=1 + success_step + TAIL_STEPS)
    assert "1/1 episodes succeeded" in result.stdout


@pytest.mark.subprocess
def test_episodes_and_camera_config_flags(tmp_path):
    result = run_example(
        *SMALL, "--episodes", "2", "--steps", "4", "--camera-config", "all", "--policy",
        "random", "--viewer", "off", "--seed", "3", "--output-dir", str(tmp_path),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    files = videos(tmp_path)
    assert len(files) == 6, files
    for episode in ("_ep01", "_ep02"):
        for camera in ("overview", "front", "wrist"):
            (name,) = [n for n in files if n.startswith(f"{camera}_camera_") and episode in n]
            assert VIDEO_NAME.match(name)
            check_video(files[name], frames=5)


@pytest.mark.subprocess
def test_bad_flags_are_refused():
    result = run_example("--grid-cell", "9")
    assert result.returncode == 2
    assert "--grid-cell" in result.stderr
    result = run_example("--steps", "0")
    assert result.returncode == 2
    assert "--steps must be at least 1" in result.stderr
    for flag, value in (("--height", "5"), ("--width", "4096"), ("--height", "abc")):
        result = run_example(flag, value)
        assert result.returncode == 2, (flag, value, result.stderr)
        assert flag in result.stderr and "Traceback" not in result.stderr
    result = run_example("--task", "NoSuchTask-v0")
    assert result.returncode == 2 and "--task" in result.stderr


@pytest.mark.subprocess
def test_the_default_run_is_the_fast_quality_and_any_task_can_be_chosen(tmp_path):
    result = run_example(
        "--height", "48", "--width", "64", "--steps", "3", "--policy", "random", "--viewer",
        "off", "--task", "LiftCube-v0", "--output-dir", str(tmp_path),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "gym_soarm/LiftCube-v0" in result.stdout and "fast quality" in result.stdout
    assert len(videos(tmp_path)) == 2


@pytest.mark.subprocess
def test_viewer_on_without_a_display_explains_and_writes_nothing(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = run_example(*SMALL, "--viewer", "on", "--output-dir", str(tmp_path), env=env)
    assert result.returncode == 1
    assert "DISPLAY is not set" in result.stderr
    assert videos(tmp_path) == {}


@pytest.mark.subprocess
def test_viewer_auto_runs_headless_without_a_display(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = run_example(
        *SMALL, "--steps", "3", "--policy", "random", "--output-dir", str(tmp_path), env=env
    )
    assert result.returncode == 0, result.stderr
    assert "window open" not in result.stdout
    assert len(videos(tmp_path)) == 2


@pytest.mark.subprocess
def test_viewer_on_shows_the_run_in_a_window(tmp_path):
    require_window_tools()
    out, err = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
    with open(out, "w") as stdout, open(err, "w") as stderr:
        process = subprocess.Popen(
            [sys.executable, str(SCRIPT), "--height", "120", "--width", "160", "--quality",
             "fast", "--steps", "150", "--policy", "random", "--viewer", "on",
             "--output-dir", str(tmp_path / "videos")],
            stdout=stdout,
            stderr=stderr,
        )  # fmt: skip
    try:

        def window_shown() -> bool:
            if process.poll() is not None:
                pytest.fail(f"example.py ended before its window was seen: {err.read_text()}")
            return any(window_size(w) == (160, 120) for w in find_windows("gym_soarm"))

        wait_for(window_shown, "the example's window")
        assert process.wait(timeout=600) == 0, err.read_text()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert "window open" in out.read_text()
    assert len(videos(tmp_path / "videos")) == 2
