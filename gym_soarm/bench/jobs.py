"""What a worker process of the benchmark runs: ``python -m gym_soarm.bench --worker JOB``
(:func:`serve_worker`), one job a process.

The jobs: ``env`` (one environment against its ceiling, :mod:`gym_soarm.bench.single`),
``vector`` (``--processes N``: the aggregate steps/s of ``N`` environments in an
``AsyncVectorEnv``, :func:`measure_async_vector`), ``cold_make`` (``gym.make`` with an
empty model cache, :func:`measure_cold_make`), ``vector_scaling``
(:func:`gym_soarm.bench.bench_vector.measure`) and ``recording``
(:func:`gym_soarm.bench.bench_record.record_once`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time

from gym_soarm.bench.ceiling import emit
from gym_soarm.bench.config import ACTION_SEED, N_ACTIONS, BenchConfig
from gym_soarm.bench.single import serve_env
from gym_soarm.bench.timings import spread
from gym_soarm.tasks import DEFAULT_TASK


def measure_async_vector(config: BenchConfig, seconds: float, repeats: int, processes: int) -> dict:
    """Aggregate steps/s of ``processes`` environments in an AsyncVectorEnv."""
    import gymnasium as gym
    import numpy as np

    import gym_soarm  # noqa: F401 - registers the environments

    t0 = time.perf_counter()
    envs = gym.make_vec(
        config.env_id, num_envs=processes, vectorization_mode="async", **config.env_kwargs()
    )
    make_s = time.perf_counter() - t0
    try:
        envs.reset(seed=0)
        rng = np.random.default_rng(ACTION_SEED)
        space = envs.single_action_space
        actions = rng.uniform(
            space.low, space.high, size=(N_ACTIONS, processes, space.shape[0])
        ).astype(np.float32)
        envs.step(actions[0])  # warm up
        rates = []
        i = 0
        for _ in range(repeats):
            n = 0
            t0 = time.perf_counter()
            deadline = t0 + seconds
            while time.perf_counter() < deadline or n == 0:
                envs.step(actions[i % N_ACTIONS])
                n += 1
                i += 1
            rates.append(n * processes / (time.perf_counter() - t0))
    finally:
        envs.close()
    return {"processes": processes, "make_s": make_s, "steps_per_s": spread(rates)}


def measure_cold_make(visual: str, task: str = DEFAULT_TASK) -> dict:
    """``gym.make`` with an empty model cache: rebuild the meshes and compile."""
    with tempfile.TemporaryDirectory(prefix="gym_soarm_cold_cache_") as folder:
        os.environ["GYM_SOARM_CACHE_DIR"] = folder
        import gymnasium as gym

        import gym_soarm

        t0 = time.perf_counter()
        env = gym.make(
            gym_soarm.get_task(task).env_id,
            obs_type="environment_state_agent_pos",
            render_quality=visual,
        )
        cold = time.perf_counter() - t0
        env.close()
    return {"visual": visual, "make_s": cold}


def serve_worker(job_text: str) -> None:
    """Run one measurement job (JSON from the parent) in this process and emit its result.

    The benchmark starts each job as ``python -m gym_soarm.bench --worker <json>``.
    """
    job = json.loads(job_text)
    kind = job["kind"]
    if kind == "env":
        serve_env(BenchConfig.from_job(job), job["model_out"])
        return
    if kind == "vector":
        config = BenchConfig.from_job(job)
        out = measure_async_vector(config, job["seconds"], job["repeats"], job["processes"])
    elif kind == "cold_make":
        out = measure_cold_make(job["visual"], job["task"])
    elif kind == "vector_scaling":
        from gym_soarm.bench import bench_vector

        out = bench_vector.measure(
            job["env_id"],
            job["counts"],
            job["obs"],
            tuple(job["size"]),
            job["seconds"],
            job["repeats"],
            modes=job["modes"],
        )
    elif kind == "recording":
        from gym_soarm.bench import bench_record

        out = bench_record.record_once(
            job["camera_config"],
            tuple(job["size"]),
            job["episodes"],
            job["workers"],
            job["ray_address"],
        )
    else:
        raise ValueError(f"unknown worker job {kind!r}")
    emit("RESULT", out)
