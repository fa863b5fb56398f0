"""Scaling of the native vector env: aggregate steps/s for several ``num_envs``.

Run ``python -m gym_soarm.tools.bench_vector --num-envs 1,2,4,8,16``. Each round
measures one ``gym.make`` environment (the baseline) and then the native vector env
(``vectorization_mode="vector_entry_point"``) at every ``num_envs``, with random actions
from a seeded generator; rounds alternate so that every figure sees the same machine
load, and the medians over rounds are reported. ``speedup`` is the vector env's
aggregate steps/s over the single environment's, from the same rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import gym_soarm  # noqa: F401  (registers the environments)

DEFAULT_ENV_ID = "gym_soarm/LiftCube-v0"


def _env_kwargs(obs: str, size: tuple[int, int]) -> dict[str, Any]:
    if obs == "state":
        return {"obs_type": "environment_state_agent_pos"}
    return {
        "obs_type": "pixels_agent_pos",
        "camera_config": obs,
        "observation_height": size[0],
        "observation_width": size[1],
    }


def single_rate(env: gym.Env, actions: np.ndarray, seconds: float) -> float:
    """Steps/s of one environment stepped for about ``seconds``."""
    steps = 0
    started = time.perf_counter()
    while time.perf_counter() - started < seconds:
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        steps += len(actions)
    return steps / (time.perf_counter() - started)


def vector_rate(envs: gym.vector.VectorEnv, actions: np.ndarray, seconds: float) -> float:
    """Aggregate steps/s of a vector env (its autoreset starts new episodes)."""
    steps = 0
    started = time.perf_counter()
    while time.perf_counter() - started < seconds:
        for batch in actions:
            envs.step(batch)
        steps += len(actions) * envs.num_envs
    return steps / (time.perf_counter() - started)


def measure(
    env_id: str,
    num_envs: Sequence[int],
    obs: str = "state",
    size: tuple[int, int] = (48, 64),
    seconds: float = 1.0,
    rounds: int = 3,
    num_threads: int | None = None,
) -> dict[str, Any]:
    """Median steps/s of one env and of the vector env at each ``num_envs``.

    Raises:
        ValueError: an empty ``num_envs`` or a count below 1.
    """
    if not num_envs or min(num_envs) < 1:
        raise ValueError(f"num_envs must list counts >= 1; got {list(num_envs)!r}.")
    kwargs = _env_kwargs(obs, size)
    single = gym.make(env_id, **kwargs)
    single.reset(seed=0)
    rng = np.random.default_rng(0)
    low, high = single.action_space.low, single.action_space.high
    single_actions = rng.uniform(low, high, (50, 6)).astype(np.float32)
    vectors = {}
    for n in num_envs:
        envs = gym.make_vec(
            env_id,
            num_envs=n,
            vectorization_mode="vector_entry_point",
            num_threads=num_threads,
            **kwargs,
        )
        envs.reset(seed=0)
        vectors[n] = (envs, rng.uniform(low, high, (max(1, 200 // n), n, 6)).astype(np.float32))
    rates: dict[str, list[float]] = {"single": []} | {str(n): [] for n in num_envs}
    try:
        for _ in range(rounds):
            rates["single"].append(single_rate(single, single_actions, seconds))
            for n, (envs, actions) in vectors.items():
                rates[str(n)].append(vector_rate(envs, actions, seconds))
    finally:
        single.close()
        for envs, _ in vectors.values():
            envs.close()
    base = statistics.median(rates["single"])
    rows = []
    for n in num_envs:
        median = statistics.median(rates[str(n)])
        rows.append(
            {
                "num_envs": n,
                "steps_per_s": median,
                "min": min(rates[str(n)]),
                "max": max(rates[str(n)]),
                "speedup": median / base,
            }
        )
    return {
        "env_id": env_id,
        "obs": obs,
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "single_steps_per_s": base,
        "vector": rows,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; prints a table (and writes JSON with ``--json``)."""
    parser = argparse.ArgumentParser(prog="python -m gym_soarm.tools.bench_vector")
    parser.add_argument("--env-id", default=DEFAULT_ENV_ID)
    parser.add_argument("--num-envs", default="1,2,4,8,16", help="counts, comma-separated")
    parser.add_argument("--obs", default="state", help="'state' or a camera config")
    parser.add_argument("--size", default="48x64", help="image HEIGHTxWIDTH for pixels")
    parser.add_argument("--seconds", type=float, default=1.0, help="seconds per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (medians)")
    parser.add_argument("--threads", type=int, default=None, help="worker threads")
    parser.add_argument("--json", default=None, help="write the figures to this file")
    args = parser.parse_args(argv)
    try:
        counts = [int(c) for c in args.num_envs.split(",") if c.strip()]
        height, width = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(
            f"--num-envs must be comma-separated ints and --size HEIGHTxWIDTH; got "
            f"{args.num_envs!r} and {args.size!r}"
        )
    report = measure(
        args.env_id, counts, args.obs, (height, width), args.seconds, args.rounds, args.threads
    )
    lines = [f"single env: {report['single_steps_per_s']:,.0f} steps/s ({report['obs']})"]
    lines.append("num_envs | steps/s median (min-max) | speedup")
    for row in report["vector"]:
        lines.append(
            f"{row['num_envs']:>8} | {row['steps_per_s']:,.0f} ({row['min']:,.0f}-"
            f"{row['max']:,.0f}) | {row['speedup']:.2f}x"
        )
    sys.stdout.write("\n".join(lines) + "\n")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as file:
            json.dump(report, file, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
