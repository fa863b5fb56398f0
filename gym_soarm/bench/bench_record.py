"""Recording throughput: episodes of the scripted expert per minute, 1 and N workers.

``python -m gym_soarm.bench --recording N [--recording-ray]`` reports it (see
:mod:`gym_soarm.bench.bench`). Each recording is one call of
:func:`gym_soarm.record.record.record` into a fresh temporary folder, in a fresh process
(:func:`measure_recording`); its time is the
whole call, start-up of the worker processes or of the local Ray cluster included, so
a handful of episodes shows what a short recording costs and a longer one (more
``episodes``) the steady rate. The dataset written is read back to count its episodes
and frames.
"""

from __future__ import annotations

import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from gym_soarm.bench.child import one_shot
from gym_soarm.bench.timings import format_number, spread

RECORD_TASK = "LiftCube-v0"
DEFAULT_EPISODES = 6
DEFAULT_CAMERAS: tuple[str, ...] = ("none", "front_wrist")


def variants(workers: int, ray: bool) -> list[dict[str, Any]]:
    """The recorders compared: one process, ``workers`` processes, and Ray if asked."""
    out = [{"name": "1 process", "workers": 1, "ray_address": None}]
    if workers > 1:
        out.append({"name": f"{workers} workers", "workers": workers, "ray_address": None})
    if ray:
        out.append({"name": f"Ray local ({workers})", "workers": workers, "ray_address": "local"})
    return out


def record_once(
    camera_config: str,
    size: tuple[int, int],
    episodes: int,
    workers: int,
    ray_address: str | None,
    task: str = RECORD_TASK,
) -> dict[str, Any]:
    """Record ``episodes`` episodes into a temporary folder; its time and what it wrote."""
    from gym_soarm.data.format import load_info
    from gym_soarm.record.record import record

    with tempfile.TemporaryDirectory(prefix="gym_soarm_bench_record_") as folder:
        root = Path(folder) / "dataset"
        started = time.perf_counter()
        summary = record(
            root,
            task=task,
            episodes=episodes,
            camera_config=camera_config,
            size=size,
            workers=workers,
            ray_address=ray_address,
            progress=False,
        )
        seconds = time.perf_counter() - started
        info = load_info(root)
    return {
        "seconds": seconds,
        "episodes": summary.episodes,
        "frames": summary.frames,
        "attempts": summary.attempts,
        "dataset_episodes": info["total_episodes"],
        "dataset_frames": info["total_frames"],
        "bytes_on_disk": summary.bytes_on_disk,
        "episodes_per_min": summary.episodes * 60.0 / seconds,
    }


def _recording_row(
    camera_config: str, variant: dict[str, Any], got: list[dict], base: list[dict]
) -> dict[str, Any]:
    """One recorder's row: its medians over the repeats and its speedup over ``base``."""
    rates = [r["episodes_per_min"] for r in got]
    row: dict[str, Any] = {
        "camera_config": camera_config,
        "recorder": variant["name"],
        "workers": variant["workers"],
        "ray": variant["ray_address"] is not None,
        "episodes_per_min": spread(rates),
        "seconds": spread([r["seconds"] for r in got]),
        "episodes": [r["episodes"] for r in got],
        "dataset_episodes": [r["dataset_episodes"] for r in got],
        "frames": [r["frames"] for r in got],
        "dataset_frames": [r["dataset_frames"] for r in got],
        "bytes_on_disk": statistics.median(r["bytes_on_disk"] for r in got),
    }
    if len(base) == len(got):
        row["speedup"] = statistics.median(
            r["episodes_per_min"] / b["episodes_per_min"] for r, b in zip(got, base, strict=True)
        )
    return row


def _record_repeats(
    camera_config: str,
    recorders: list[dict[str, Any]],
    job: dict[str, Any],
    repeats: int,
    say: Callable[[str], None],
) -> tuple[dict[str, list[dict]], dict[str, str]]:
    """Every recorder's runs in turn, ``repeats`` times, and the error of those that failed."""
    runs: dict[str, list[dict]] = {v["name"]: [] for v in recorders}
    errors: dict[str, str] = {}
    for repeat in range(repeats):
        for variant in recorders:
            if variant["name"] in errors:
                continue
            say(
                f"recording {job['episodes']} episodes ({camera_config}, {variant['name']}, "
                f"repeat {repeat + 1}/{repeats}) ..."
            )
            run = {
                **job,
                "camera_config": camera_config,
                "workers": variant["workers"],
                "ray_address": variant["ray_address"],
            }
            try:
                runs[variant["name"]].append(one_shot(run, 600 + 60 * job["episodes"]))
            except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
                errors[variant["name"]] = str(exc)
    return runs, errors


def measure_recording(
    workers: int,
    ray: bool,
    episodes: int,
    cameras: Sequence[str],
    size: tuple[int, int],
    repeats: int,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Episodes per minute of 1 and ``workers`` recorders (and Ray), each in a fresh process.

    The repeats take every recorder in turn, so they see the same machine load; the
    median episodes per minute is reported with the speedup over one process (the
    median of the per-repeat ratios).
    """
    recorders = variants(workers, ray)
    job = {"kind": "recording", "size": list(size), "episodes": episodes}
    rows = []
    for camera_config in cameras:
        runs, errors = _record_repeats(
            camera_config, recorders, job, repeats, progress or (lambda _message: None)
        )
        base = runs[recorders[0]["name"]]
        for variant in recorders:
            if variant["name"] in errors:
                rows.append(
                    {
                        "camera_config": camera_config,
                        "recorder": variant["name"],
                        "workers": variant["workers"],
                        "ray": variant["ray_address"] is not None,
                        "error": errors[variant["name"]],
                    }
                )
            else:
                rows.append(_recording_row(camera_config, variant, runs[variant["name"]], base))
    return {
        "task": RECORD_TASK,
        "episodes": episodes,
        "size": list(size),
        "workers": workers,
        "ray": ray,
        "repeats": repeats,
        "rows": rows,
    }


def format_recording(report: dict[str, Any]) -> str:
    """The recording throughput as a Markdown table."""
    header = ["cameras", "recorder", "episodes/min median (min-max)", "speedup", "s per run"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in report["rows"]:
        cameras = r["camera_config"]
        if cameras != "none":
            cameras = f"{cameras} {report['size'][0]}x{report['size'][1]}"
        if "error" in r:
            lines.append(f"| {cameras} | {r['recorder']} | failed: {r['error']} | - | - |")
            continue
        median, low, high = (
            format_number(r["episodes_per_min"][k]) for k in ("median", "min", "max")
        )
        speedup = f"{r['speedup']:.2f}x" if "speedup" in r else "-"
        lines.append(
            f"| {cameras} | {r['recorder']} | {median} ({low}-{high}) | {speedup} | "
            f"{r['seconds']['median']:.1f} |"
        )
    return "\n".join(lines)
