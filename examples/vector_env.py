"""Step many SO-101 simulations at once in gym_soarm's native vector env.

    python examples/vector_env.py --num-envs 64 --steps 200
    python examples/vector_env.py --num-envs 8 --vector-env processes

With state observations the environments are one batch by default: every simulation
stepped in one ``mujoco.batch`` call on a thread per CPU, the task scored as arrays over
the batch. ``--vector-env processes`` runs them in one process per CPU instead (this one
steps a block of them too), with observations, rewards and infos in shared memory. The
script steps them with random actions, counts the episodes that end (the vector env
starts new ones by itself) and prints the aggregate steps per second next to one plain
``gym.make`` environment.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

import gym_soarm  # registers the environments
from gym_soarm.cli.options import task_name


def rate_of_one(env_id: str, steps: int, seed: int) -> float:
    """Steps per second of one ``gym.make`` environment with random actions."""
    env = gym.make(env_id, obs_type="state")
    try:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        started = time.perf_counter()
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
        return steps / (time.perf_counter() - started)
    finally:
        env.close()


def build_parser() -> argparse.ArgumentParser:
    """The script's command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--task",
        type=task_name,
        default="LiftCube-v0",
        metavar="TASK",
        help="the task, by name, alias or gym id (default: LiftCube-v0)",
    )
    parser.add_argument("--num-envs", type=int, default=8, help="environments (default 8)")
    parser.add_argument("--steps", type=int, default=200, help="vector steps (default 200)")
    parser.add_argument("--seed", type=int, default=0, help="environment i is seeded seed + i")
    parser.add_argument(
        "--vector-env",
        default="auto",
        choices=("auto", "batched", "processes"),
        help="one mujoco.batch (batched; auto for state) or worker processes",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    env_id = gym_soarm.get_task(args.task).env_id
    if args.num_envs < 1 or args.steps < 1:
        parser.error(f"--num-envs and --steps must be >= 1; got {args.num_envs}, {args.steps}")

    envs = gym.make_vec(
        env_id,
        num_envs=args.num_envs,
        vectorization_mode="vector_entry_point",
        obs_type="state",
        vector_env=args.vector_env,
    )
    try:
        inner = envs.unwrapped
        if hasattr(inner, "worker_pids"):
            print(
                f"{args.num_envs} x {env_id} in {inner.num_processes} processes "
                f"(this one and workers {list(inner.worker_pids)})"
            )
        else:
            print(f"{args.num_envs} x {env_id} in one mujoco.batch on {inner.num_threads} threads")
        obs, _ = envs.reset(seed=args.seed)
        envs.action_space.seed(args.seed)
        ended = 0
        started = time.perf_counter()
        for _ in range(args.steps):
            obs, _, terminated, truncated, _ = envs.step(envs.action_space.sample())
            ended += int(np.count_nonzero(terminated | truncated))
        seconds = time.perf_counter() - started
    finally:
        envs.close()
    total = args.steps * args.num_envs
    one = rate_of_one(env_id, min(total, 2000), args.seed)
    print(f"observations {obs.shape}, {ended} episodes ended")
    print(f"vector env: {total / seconds:,.0f} steps/s; one env: {one:,.0f} steps/s")
    return 0


if __name__ == "__main__":  # worker processes import this file again: run nothing there
    sys.exit(main())
