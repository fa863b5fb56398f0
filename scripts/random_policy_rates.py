"""Success of uniform random joint targets on every task (the figures in docs/tasks.md).

    python scripts/random_policy_rates.py [--episodes 100]

Episode k of a task resets with seed k; the actions come from a generator seeded with k.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import gym_soarm


def random_successes(task: str, episodes: int) -> int:
    """How many of ``episodes`` random-action episodes of ``task`` succeed."""
    env = gym.make(gym_soarm.get_task(task).env_id, obs_type="environment_state_agent_pos")
    low, high = env.action_space.low, env.action_space.high
    wins = 0
    try:
        for seed in range(episodes):
            rng = np.random.default_rng(seed)
            env.reset(seed=seed)
            while True:
                action = rng.uniform(low, high).astype(np.float32)
                _, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    break
            wins += info["is_success"]
    finally:
        env.close()
    return wins


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    for task in gym_soarm.task_names():
        wins = random_successes(task, args.episodes)
        print(f"{task}: {wins}/{args.episodes} random episodes succeeded", flush=True)


if __name__ == "__main__":
    main()
