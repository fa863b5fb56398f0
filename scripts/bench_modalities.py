"""Render cost of depth and segmentation per camera (ms, median of repeats).

python scripts/bench_modalities.py --size 480x640 --repeats 30
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym

import gym_soarm  # noqa: F401  (registers the environments)
from gym_soarm.validation import parse_size

COMBINATIONS = (
    ("rgb",),
    ("rgb", "depth"),
    ("rgb", "segmentation"),
    ("rgb", "depth", "segmentation"),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="480x640", help="HEIGHTxWIDTH")
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--camera", default="front_camera")
    args = parser.parse_args()
    height, width = parse_size(args.size)
    envs = {
        modalities: gym.make(
            "gym_soarm/PickAndPlaceCube-v0",
            obs_type="pixels",
            camera_config=[args.camera],
            observation_height=height,
            observation_width=width,
            image_modalities=modalities,
        )
        for modalities in COMBINATIONS
    }
    times: dict[tuple[str, ...], list[float]] = {m: [] for m in COMBINATIONS}
    for env in envs.values():
        env.reset(seed=0)
    # Round robin, so that every combination sees the same machine load.
    for _ in range(args.repeats):
        for modalities, env in envs.items():
            start = time.perf_counter()
            env.unwrapped.observation()
            times[modalities].append((time.perf_counter() - start) * 1e3)
    for modalities, env in envs.items():
        env.close()
        median = statistics.median(times[modalities])
        print(f"{'+'.join(modalities):24s} {median:7.2f} ms per camera")


if __name__ == "__main__":
    main()
