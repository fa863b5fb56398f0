"""Record one episode of the SO-101 in the default scene to one MP4 per camera.

    python examples/example.py

writes videos/front_camera_YYYYmmdd_HHMMSS.mp4 and videos/wrist_camera_YYYYmmdd_HHMMSS.mp4.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gym_soarm
from gym_soarm.video import save_frames_to_mp4


def smooth_motion(step: int, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """A slow sweep of every joint around the home pose."""
    t = step / 50.0
    phase = np.array([0.0, 0.7, 1.4, 2.1, 2.8, 0.3])
    amplitude = 0.35 * np.minimum(np.abs(low), np.abs(high))
    return np.clip(amplitude * np.sin(0.8 * t + phase), low, high).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--steps", type=int, default=250)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output-dir", type=Path, default=Path("videos"))
    args = parser.parse_args()

    env = gym.make("SoArm-v0", camera_config="front_wrist", render_quality="high")
    obs, info = env.reset(seed=args.seed)
    frames: dict[str, list[np.ndarray]] = {name: [frame] for name, frame in obs["pixels"].items()}
    low, high = env.action_space.low, env.action_space.high
    for step in range(args.steps):
        obs, _reward, terminated, truncated, info = env.step(smooth_motion(step, low, high))
        for name, frame in obs["pixels"].items():
            frames[name].append(frame)
        if terminated or truncated:
            break
    env.close()

    stamp = time.strftime("%Y%m%d_%H%M%S")
    for name, camera_frames in frames.items():
        path = save_frames_to_mp4(camera_frames, args.output_dir / f"{name}_{stamp}.mp4", fps=50)
        print(f"wrote {path} ({len(camera_frames)} frames)")
    print(f"success: {info['is_success']}  (gym_soarm {gym_soarm.__version__})")


if __name__ == "__main__":
    main()
