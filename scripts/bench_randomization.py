"""Reset time and steps/s with and without randomisation (state observations).

python scripts/bench_randomization.py --rounds 5
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np

import gym_soarm  # noqa: F401  (registers the environments)

CONFIGS: dict[str, dict[str, str]] = {
    "none": {},
    "heavy": {"visual_randomization": "heavy", "physics_randomization": "heavy"},
    "heavy+sts3215": {
        "visual_randomization": "heavy",
        "physics_randomization": "heavy",
        "servo_model": "sts3215",
    },
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--resets", type=int, default=50)
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args()
    envs = {
        name: gym.make(
            "gym_soarm/PickAndPlaceCube-v0", obs_type="environment_state_agent_pos", **kwargs
        ).unwrapped
        for name, kwargs in CONFIGS.items()
    }
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, (args.steps, 6)).astype(np.float32)
    reset_ms: dict[str, list[float]] = {name: [] for name in envs}
    steps_s: dict[str, list[float]] = {name: [] for name in envs}
    # Round robin, so that every configuration sees the same machine load.
    for round_ in range(args.rounds):
        for name, env in envs.items():
            for i in range(args.resets):
                start = time.perf_counter()
                env.reset(seed=round_ * args.resets + i)
                reset_ms[name].append((time.perf_counter() - start) * 1e3)
            env.reset(seed=round_)
            start = time.perf_counter()
            for action in actions:
                env.step(action)
            steps_s[name].append(args.steps / (time.perf_counter() - start))
    base = statistics.median(steps_s["none"])
    for name, env in envs.items():
        rate = statistics.median(steps_s[name])
        print(
            f"{name:14s} reset {statistics.median(reset_ms[name]):6.3f} ms   "
            f"{rate:7.0f} steps/s ({100 * (rate / base - 1):+.1f} %)"
        )
        env.close()


if __name__ == "__main__":
    main()
