"""Recording throughput: episodes of the scripted expert per minute, 1 and N workers.

``python -m gym_soarm.bench --recording N [--recording-ray]`` reports it (see
:mod:`gym_soarm.bench.bench`). Each recording is one call of
:func:`gym_soarm.record.record.record` into a fresh temporary folder; its time is the
whole call, start-up of the worker processes or of the local Ray cluster included, so
a handful of episodes shows what a short recording costs and a longer one (more
``episodes``) the steady rate. The dataset written is read back to count its episodes
and frames.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

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
