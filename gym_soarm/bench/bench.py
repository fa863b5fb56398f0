"""Speed benchmark of the SO-101 environments: ``python -m gym_soarm.bench``.

For each configuration it measures, in a fresh process of its own (so that peak memory
and GL contexts of one configuration never touch another):

* env steps per second through ``gym.make`` (median, min and max of the repeats), with
  random actions from a seeded generator; resets are not counted;
* milliseconds per step, split into rendering (time inside the camera renderer) and
  everything else (physics, reward, observation: reported as ``physics``);
* ``make`` time (the first ``gym.make`` in the process), ``reset`` time (median of warm
  resets) and the first reset (which creates the GL context for pixel observations);
* peak resident memory of the process.

In the same run it measures the ceiling each configuration is compared with, in another
fresh process that does not import gym_soarm (the program :mod:`gym_soarm.bench.ceiling`,
run by its path): bare ``mujoco.mj_step`` with the same
number of substeps for state observations, and a bare ``mujoco.Renderer`` on the same
compiled model, cameras, image size and quality settings (shadows, reflections,
multisampling) for pixel observations. The repeats of a configuration and of its
ceiling alternate, so both see the same machine load; the ratio to the ceiling (the
median of the per-repeat ratios) shows how much the environment costs on top of what
MuJoCo itself needs.

``--control-mode`` measures another control mode (:mod:`gym_soarm.envs.control`) with its
own random actions, uniform in its action space; the floors of ``TARGETS`` are those of
the default ``joint_pos`` and are checked only there.

``--processes N`` adds the aggregate throughput of ``N`` environments stepped together
by ``gymnasium.vector.AsyncVectorEnv``. The cold ``make`` time (an empty model cache:
rebuild the meshes and compile) is measured once per visual variant.

``--vector-scaling 1,2,4,8,16`` adds the scaling of vector environments
(:mod:`gym_soarm.bench.bench_vector`): aggregate steps/s of the batched vector env (one
``mujoco.batch``), the processes vector env (worker processes), ``AsyncVectorEnv`` and ``SyncVectorEnv`` at each ``num_envs``, and the speedup
of each over one environment measured in the same rounds, beside the ceiling of free-running
processes; state observations, and the camera configs of ``--vector-obs`` at
``--image-size``. Its targets (the processes env's best speedup at ``num_envs`` >= 8: at
least 1.7 with state observations, 1.8 with cameras; the batched env's at 64 environments,
or the most measured, at least 1.8 with state observations) join the checked targets.

``--recording N`` adds recording throughput (:mod:`gym_soarm.bench.bench_record`):
episodes per minute of ``LiftCube-v0``'s scripted expert recorded by one process and by
``N`` worker processes (and as Ray tasks on a local cluster with ``--recording-ray``),
without cameras and with the ``--recording-cameras`` at ``--image-size``. Each recording
runs in a fresh process and its dataset is read back to count what it holds.

Timings on a shared machine are noisy: read the medians and the ratios.

The modules, one a measurement: :mod:`~gym_soarm.bench.config` (the configurations and
defaults), :mod:`~gym_soarm.bench.single` (one environment against its ceiling, and its
table), :mod:`~gym_soarm.bench.ceiling` (the ceiling's program and the processes' line
protocol), :mod:`~gym_soarm.bench.jobs` (what a worker process runs: ``--processes``,
the cold make), :mod:`~gym_soarm.bench.bench_vector`, :mod:`~gym_soarm.bench.bench_record`,
:mod:`~gym_soarm.bench.targets` (the floors) and :mod:`~gym_soarm.bench.child` (the
processes). This module runs them all (:func:`run`) and keeps every name importable
from here.
"""

from __future__ import annotations

import math
import os
import platform
import subprocess
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from gym_soarm.bench import bench_record, bench_vector
from gym_soarm.bench.bench_record import format_recording, measure_recording
from gym_soarm.bench.bench_vector import measure_vector_scaling
from gym_soarm.bench.child import one_shot
from gym_soarm.bench.config import (
    ACTION_SEED,
    DEFAULT_CONFIGS,
    DEFAULT_CONTROL_MODE,
    DEFAULT_IMAGE_SIZE,
    DEFAULT_JSON,
    DEFAULT_REPEATS,
    DEFAULT_SECONDS,
    N_ACTIONS,
    PIXEL_RESETS,
    SLICES_PER_REPEAT,
    STATE_RESETS,
    BenchConfig,
)
from gym_soarm.bench.jobs import serve_worker
from gym_soarm.bench.single import format_table, measure_config
from gym_soarm.bench.targets import (
    BATCHED_SPEEDUP_TARGET,
    BATCHED_TARGET_MIN_ENVS,
    RATIO_TARGET,
    TARGETS,
    VECTOR_CAMERA_SPEEDUP_TARGET,
    VECTOR_SPEEDUP_TARGET,
    VECTOR_TARGET_MIN_ENVS,
    check_scaling_target,
    check_targets,
)
from gym_soarm.tasks import DEFAULT_TASK, get_task

_PROCESS_ERRORS = (RuntimeError, subprocess.TimeoutExpired, OSError)


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _load_average() -> tuple[float, float, float] | None:
    return os.getloadavg() if hasattr(os, "getloadavg") else None


def _check_cameras(name: str, values: Sequence[str], extra: str) -> None:
    """Each of ``values`` is ``extra`` or a camera config (checked now, not in a worker
    after other sections ran)."""
    from gym_soarm import constants
    from gym_soarm.validation import resolve_camera_config

    for value in values:
        if value != extra:
            try:
                resolve_camera_config(value)
            except ValueError:
                raise ValueError(
                    f"{name} must be {extra!r} or a camera config "
                    f"({', '.join(constants.CAMERA_CONFIGS)}); got {value!r}"
                ) from None


def _check_vector(
    counts: Sequence[int], modes: Sequence[str], obs: Sequence[str], size: tuple[int, int]
) -> None:
    """The vector scaling's options (ValueError)."""
    if counts and min(counts) < 1:
        raise ValueError(f"vector scaling counts must be at least 1; got {list(counts)}")
    unknown = [m for m in modes if m not in bench_vector.VECTOR_MODES]
    if unknown:
        raise ValueError(
            f"vector modes must be among {', '.join(bench_vector.VECTOR_MODES)}; got {unknown}"
        )
    if not obs:
        raise ValueError("vector obs must name 'state' or a camera config")
    if min(size) < 2 or any(v % 2 for v in size):
        raise ValueError(f"image size must be even and positive; got {size!r}")
    _check_cameras("vector obs", obs, "state")


def _check_recording(workers: int, episodes: int, cameras: Sequence[str]) -> None:
    """The recording throughput's options (ValueError)."""
    if workers < 0:
        raise ValueError(f"recording workers must be >= 0 (0: no recording); got {workers!r}")
    if episodes < 1:
        raise ValueError(f"recording episodes must be at least 1; got {episodes!r}")
    _check_cameras("recording cameras", cameras, "none")


def _check_run(measures: bool, seconds: float, repeats: int, processes: int) -> None:
    """Something to measure, and the timing's options (ValueError)."""
    if not measures:
        raise ValueError("configs must name at least one configuration")
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number; got {seconds!r}")
    if repeats < 1:
        raise ValueError(f"repeats must be at least 1; got {repeats!r}")
    if processes < 1:
        raise ValueError(f"processes must be at least 1; got {processes!r}")


def _measure_configs(
    parsed: Sequence[BenchConfig],
    seconds: float,
    repeats: int,
    processes: int,
    say: Callable[[str], None],
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Each configuration against its ceiling, and a cold make per visual variant."""
    results: list[dict[str, Any]] = []
    cold: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="gym_soarm_bench_") as folder:
        for config in parsed:
            say(f"measuring {config.name} ...")
            try:
                results.append(measure_config(config, seconds, repeats, processes, Path(folder)))
            except (*_PROCESS_ERRORS, ValueError) as exc:
                results.append({"name": config.name, "error": str(exc)})
        for visual in sorted({c.render_quality for c in parsed}):
            say(f"measuring a cold make ({visual} meshes, empty model cache) ...")
            try:
                job = {"kind": "cold_make", "visual": visual, "task": parsed[0].task}
                cold.append(one_shot(job, 300))
            except _PROCESS_ERRORS as exc:
                cold.append({"visual": visual, "error": str(exc)})
    return results, cold


def _measure_scaling(
    counts: Sequence[int],
    observations: Sequence[str],
    size: tuple[int, int],
    seconds: float,
    repeats: int,
    task: str,
    modes: Sequence[str],
    say: Callable[[str], None],
) -> list[dict[str, Any]]:
    """The vector scaling of each of ``observations`` (none without ``counts``)."""
    if not counts:
        return []
    return [
        measure_vector_scaling(counts, obs, size, seconds, repeats, task, modes, progress=say)
        for obs in observations
    ]


def _versions(results: Sequence[dict[str, Any]]) -> dict[str, Any]:
    first = next((r for r in results if "error" not in r), {})
    return {"gym_soarm": first.get("gym_soarm"), "mujoco": first.get("mujoco")}


def _machine(results: Sequence[dict[str, Any]], load_start: Any) -> dict[str, Any]:
    return {
        "cpu": _cpu_name(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "gl_backend": next((r["gl_backend"] for r in results if r.get("gl_backend")), None),
        "gl_renderer": next((r["gl_renderer"] for r in results if r.get("gl_renderer")), None),
        "load_average_start": load_start,
        "load_average_end": _load_average(),
    }


def _targets(
    results: Sequence[dict[str, Any]], scaling: Sequence[dict[str, Any]], control_mode: str
) -> list[dict[str, Any]]:
    """The checked targets: those of the default control mode only."""
    if control_mode != DEFAULT_CONTROL_MODE:
        return []
    return check_targets(results) + check_scaling_target(scaling)


def run(
    configs: Sequence[str],
    seconds: float = DEFAULT_SECONDS,
    repeats: int = DEFAULT_REPEATS,
    processes: int = 1,
    progress: Callable[[str], None] | None = None,
    task: str = DEFAULT_TASK,
    control_mode: str = DEFAULT_CONTROL_MODE,
    vector_scaling: Sequence[int] = (),
    env: Mapping[str, Any] | None = None,
    vector_obs: Sequence[str] = ("state",),
    vector_modes: Sequence[str] | None = None,
    image_size: tuple[int, int] = DEFAULT_IMAGE_SIZE,
    recording: int = 0,
    recording_ray: bool = False,
    recording_episodes: int | None = None,
    recording_cameras: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Measure ``configs`` and return the whole report (what ``--json`` writes).

    Args:
        configs: configuration names (may be empty when ``vector_scaling`` or
            ``recording`` is asked for).
        vector_scaling: ``num_envs`` counts of the vector scaling (none: not measured).
        vector_obs: ``"state"`` or camera configs, each measured at every count.
        vector_modes: vector envs compared (default: batched, processes, async and sync;
            ``native``, the earlier name of processes, with a ``FutureWarning``).
        image_size: (height, width) of the camera configs of the scaling and recording.
        recording: worker count of the recording throughput (0: not measured).
        recording_ray: also record as Ray tasks on a local cluster.
        recording_episodes: episodes per recording.
        recording_cameras: ``"none"`` or camera configs, each recorded.
        env: further ``gym.make`` keywords of the measured configurations (``configs``
            only), e.g. ``{"dynamics": PATH}``.

    Raises:
        ValueError: a configuration name or the control mode is unknown, or
            seconds/repeats/processes or the scaling/recording options are out of range.
    """
    parsed = [BenchConfig.parse(name, task, control_mode, env) for name in configs]
    vector_modes = tuple(bench_vector.vector_modes(vector_modes or bench_vector.VECTOR_MODES))
    cameras = tuple(recording_cameras or bench_record.DEFAULT_CAMERAS)
    episodes = bench_record.DEFAULT_EPISODES if recording_episodes is None else recording_episodes
    _check_run(bool(parsed or vector_scaling or recording), seconds, repeats, processes)
    _check_vector(vector_scaling, vector_modes, vector_obs, image_size)
    _check_recording(recording, episodes, cameras)
    say = progress or (lambda _message: None)
    load_start = _load_average()
    started = time.time()
    results, cold = _measure_configs(parsed, seconds, repeats, processes, say)
    scaling = _measure_scaling(
        vector_scaling, vector_obs, image_size, seconds, repeats, task, vector_modes, say
    )
    recorded = None
    if recording:
        recorded = measure_recording(
            recording, recording_ray, episodes, cameras, image_size, repeats, say
        )
    return {
        "machine": _machine(results, load_start),
        "versions": _versions(results),
        "settings": {
            "task": get_task(task).name,
            "control_mode": control_mode,
            "env": dict(env or {}),
            "seconds": seconds,
            "repeats": repeats,
            "processes": processes,
            "vector_scaling": list(vector_scaling),
            "recording_workers": recording,
            "started_unix": started,
            "duration_s": time.time() - started,
        },
        "configs": results,
        "cold_make": cold,
        "vector_scaling": scaling,
        "recording": recorded,
        "targets": _targets(results, scaling, control_mode),
    }


__all__ = [
    "ACTION_SEED",
    "BATCHED_SPEEDUP_TARGET",
    "BATCHED_TARGET_MIN_ENVS",
    "DEFAULT_CONFIGS",
    "DEFAULT_CONTROL_MODE",
    "DEFAULT_IMAGE_SIZE",
    "DEFAULT_JSON",
    "DEFAULT_REPEATS",
    "DEFAULT_SECONDS",
    "N_ACTIONS",
    "PIXEL_RESETS",
    "RATIO_TARGET",
    "SLICES_PER_REPEAT",
    "STATE_RESETS",
    "TARGETS",
    "VECTOR_CAMERA_SPEEDUP_TARGET",
    "VECTOR_SPEEDUP_TARGET",
    "VECTOR_TARGET_MIN_ENVS",
    "BenchConfig",
    "check_scaling_target",
    "check_targets",
    "format_recording",
    "format_table",
    "measure_config",
    "measure_recording",
    "measure_vector_scaling",
    "run",
    "serve_worker",
]
