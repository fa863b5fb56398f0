"""One environment of a configuration against its ceiling (:func:`measure_config`).

Two fresh processes: a worker that builds the environment through ``gym.make`` and
steps it with seeded random actions (:func:`serve_env`), and the ceiling's program
(:mod:`gym_soarm.bench.ceiling`) on the same compiled model and start state. The parent
alternates short slices of the two, :data:`~gym_soarm.bench.config.SLICES_PER_REPEAT` a
repeat, so that both see the same machine load and their ratio holds even on a busy
machine. Each step is split into rendering (the time inside the camera renderer) and
the rest (``physics``: physics, reward, observation).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gym_soarm.bench import ceiling
from gym_soarm.bench.child import Child, one_shot, worker_command
from gym_soarm.bench.config import (
    ACTION_SEED,
    N_ACTIONS,
    PIXEL_RESETS,
    SLICES_PER_REPEAT,
    STATE_RESETS,
    BenchConfig,
)
from gym_soarm.bench.timings import format_number, spread


def _peak_rss_mb() -> float | None:
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    # Linux reports kilobytes, macOS bytes.
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024


class _RenderClock:
    """Time spent inside the camera renderer, to split each step into physics and
    rendering (it wraps ``CameraRenderer.render`` in this worker process)."""

    def __init__(self) -> None:
        from gym_soarm.render import camera

        self.seconds = 0.0
        original = camera.CameraRenderer.render

        def timed_render(renderer: Any, *args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return original(renderer, *args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start

        camera.CameraRenderer.render = timed_render


class _EnvRunner:
    """One environment of ``config``, built and reset with its timings, then stepped in
    slices on request (:meth:`run_slice`)."""

    def __init__(self, config: BenchConfig) -> None:
        import gymnasium as gym
        import numpy as np

        self.clock = _RenderClock()
        t0 = time.perf_counter()
        self.env = gym.make(config.env_id, **config.env_kwargs())
        self.make_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        self.env.reset(seed=0)
        self.first_reset_ms = (time.perf_counter() - t0) * 1e3
        reset_times = []
        for _ in range(PIXEL_RESETS if config.renders else STATE_RESETS):
            t0 = time.perf_counter()
            self.env.reset()
            reset_times.append((time.perf_counter() - t0) * 1e3)
        self.reset_ms = statistics.median(reset_times)
        rng = np.random.default_rng(ACTION_SEED)
        low, high = self.env.action_space.low, self.env.action_space.high
        self.actions = rng.uniform(low, high, size=(N_ACTIONS, len(low))).astype(np.float32)
        self.env.reset(seed=1)
        for i in range(3):  # warm up
            self.env.step(self.actions[i])
        self.counter = 0

    def run_slice(self, seconds: float) -> dict:
        """Step for about ``seconds``: the steps, the seconds in them and in rendering."""
        stepped = 0.0
        self.clock.seconds = 0.0
        n = 0
        i = self.counter
        deadline = time.perf_counter() + seconds
        while True:
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = self.env.step(self.actions[i % N_ACTIONS])
            t1 = time.perf_counter()
            stepped += t1 - t0
            n += 1
            i += 1
            if terminated or truncated:
                self.env.reset()
            if t1 >= deadline:
                break
        self.counter = i
        return {"steps": n, "seconds": stepped, "render_seconds": self.clock.seconds}

    def finish(self) -> dict:
        self.env.close()
        return {"peak_rss_mb": _peak_rss_mb()}


def serve_env(config: BenchConfig, model_out: str) -> None:
    """Set one environment of ``config`` up, save its compiled model to ``model_out``
    (for the ceiling) and time its steps as the protocol asks."""
    import mujoco

    import gym_soarm
    from gym_soarm.render import backend
    from gym_soarm.sim import cache
    from gym_soarm.sim import scene as model

    spec = gym_soarm.get_task(config.task)
    cache_file = cache.cached_path(
        model.model_cache_name(spec.scene, config.render_quality, spec.name)
    )
    model_cache_hit = cache_file is not None and cache_file.is_file()
    runner = _EnvRunner(config)
    env = runner.env
    physics = env.unwrapped.physics
    mj_data = physics.data.ptr
    mujoco.mj_saveModel(physics.model.ptr, model_out, None)
    ready = {
        "make_s": runner.make_s,
        "model_cache_hit": model_cache_hit,
        "first_reset_ms": runner.first_reset_ms,
        "reset_ms": runner.reset_ms,
        "substeps": env.unwrapped.timing.substeps,
        "episode_steps": env.spec.max_episode_steps,
        "camera_ids": [physics.model.name2id(c, "camera") for c in env.unwrapped.cameras],
        "state": {
            "qpos": mj_data.qpos.tolist(),
            "qvel": mj_data.qvel.tolist(),
            "ctrl": mj_data.ctrl.tolist(),
        },
        "gl_backend": backend.gl_backend() if config.renders else None,
        "gym_soarm": gym_soarm.__version__,
        "mujoco": mujoco.__version__,
    }
    ceiling.serve(ready, runner.run_slice, runner.finish)


def _ceiling_child(config: BenchConfig, ready: dict, state: dict, model: Path, timeout: float):
    """The ceiling's process on the model and start state the env's worker reported."""
    job = {
        "model": str(model),
        "state": state,
        "substeps": ready["substeps"],
        "episode_steps": ready["episode_steps"],
        "seed": ACTION_SEED,
        "mode": "render" if config.renders else "step",
        "cameras": ready["camera_ids"],
        "width": config.width,
        "height": config.height,
        "quality": config.render_quality,
    }
    env = dict(os.environ, MUJOCO_GL=ready["gl_backend"] or "disable")
    return Child([sys.executable, str(ceiling.PATH), json.dumps(job)], env, timeout)


def _alternate(env_child: Child, ceiling_child: Child, seconds: float, repeats: int):
    """Each repeat's totals of the env and of the ceiling, their slices alternated."""
    env_runs, ceiling_runs = [], []
    for _ in range(repeats):
        env_run = {"steps": 0, "seconds": 0.0, "render_seconds": 0.0}
        ceiling_run = {"steps": 0, "seconds": 0.0}
        for _ in range(SLICES_PER_REPEAT):  # alternate, so both see the same load
            for totals, child in ((env_run, env_child), (ceiling_run, ceiling_child)):
                part = child.ask(f"run {seconds / SLICES_PER_REPEAT!r}", "SLICE")
                for key in totals:
                    totals[key] += part[key]
        env_runs.append(env_run)
        ceiling_runs.append(ceiling_run)
    return env_runs, ceiling_runs


def _figures(config: BenchConfig, ready: dict, env_runs: list, ceiling_runs: list) -> dict:
    """Steps/s, ms per step (physics + render) and the ceiling's, from the repeats."""
    env_rates = [r["steps"] / r["seconds"] for r in env_runs]
    step_ms = [r["seconds"] / r["steps"] * 1e3 for r in env_runs]
    render_ms = [r["render_seconds"] / r["steps"] * 1e3 for r in env_runs]
    ceiling_rates = [r["steps"] / r["seconds"] for r in ceiling_runs]
    return {
        "steps_per_s": spread(env_rates),
        "ms_per_step": {
            "total": statistics.median(step_ms),
            "render": statistics.median(render_ms),
            "physics": statistics.median([s - r for s, r in zip(step_ms, render_ms, strict=True)]),
        },
        "ceiling": {
            "kind": (
                f"mujoco.Renderer, {len(ready['camera_ids'])} camera(s)"
                if config.renders
                else f"mujoco.mj_step x{ready['substeps']}"
            ),
            "steps_per_s": spread(ceiling_rates),
            "ms_per_step": 1e3 / statistics.median(ceiling_rates),
        },
        # Median of the ratios of repeats whose slices alternated.
        "ratio_to_ceiling": statistics.median(
            e / c for e, c in zip(env_rates, ceiling_rates, strict=True)
        ),
    }


def measure_config(
    config: BenchConfig, seconds: float, repeats: int, processes: int, workdir: Path
) -> dict[str, Any]:
    """Every figure of one configuration and of its ceiling (each in a fresh process)."""
    timeout = 180 + 3 * seconds * repeats
    model_path = workdir / f"{config.name}.mjb"
    result: dict[str, Any] = {"name": config.name, **config.env_kwargs()}
    job = {"kind": "env", **config.job(), "model_out": str(model_path)}
    env_child = Child(worker_command(job), dict(os.environ), timeout)
    ceiling_child = None
    try:
        ready = env_child.expect("READY")
        state = ready.pop("state")
        result.update(ready)
        ceiling_child = _ceiling_child(config, ready, state, model_path, timeout)
        ceiling_ready = ceiling_child.expect("READY")
        env_runs, ceiling_runs = _alternate(env_child, ceiling_child, seconds, repeats)
        result.update(env_child.ask("done", "RESULT"))
        ceiling_child.ask("done", "RESULT")
    finally:
        env_child.close()
        if ceiling_child is not None:
            ceiling_child.close()
    result.update(_figures(config, ready, env_runs, ceiling_runs))
    if "gl_renderer" in ceiling_ready:
        result["gl_renderer"] = ceiling_ready["gl_renderer"]
    if processes > 1:
        job = {"kind": "vector", **config.job(), "seconds": seconds, "repeats": repeats}
        result["vector"] = one_shot({**job, "processes": processes}, timeout + 120)
    return result


def format_table(results: Sequence[dict[str, Any]]) -> str:
    """The results as a Markdown table."""
    vector = any("vector" in r for r in results)
    header = [
        "config",
        "steps/s median (min-max)",
        "ms/step physics + render",
        "ceiling steps/s",
        "ratio",
        "make s",
        "reset ms",
        "peak RSS MB",
    ]
    if vector:
        header.append("vector steps/s")
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in results:
        if "error" in r:
            lines.append(f"| {r['name']} | failed: {r['error']} |" + " |" * (len(header) - 2))
            continue
        median, low, high = (format_number(r["steps_per_s"][k]) for k in ("median", "min", "max"))
        ms = r["ms_per_step"]
        rss = r.get("peak_rss_mb")
        row = [
            r["name"],
            f"{median} ({low}-{high})",
            f"{ms['physics']:.3f} + {ms['render']:.2f}",
            format_number(r["ceiling"]["steps_per_s"]["median"]),
            f"{r['ratio_to_ceiling']:.2f}",
            f"{r['make_s']:.2f}",
            f"{r['reset_ms']:.2f}",
            "-" if rss is None else f"{rss:.0f}",
        ]
        if vector:
            v = r.get("vector")
            rate = format_number(v["steps_per_s"]["median"]) if v else ""
            row.append(f"{rate} ({v['processes']} proc)" if v else "-")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)
