"""Draw docs/tasks.png: every registered task's scene, one tile per task.

    python scripts/make_task_gallery.py

Each tile shows the workspace after the task's reset with seed 0, from a free camera in
front of the table (closer than the scene's own cameras), in high render quality, with
the task's name and instruction written underneath.
"""

from __future__ import annotations

import argparse
import os
import textwrap
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported: render offscreen

import cv2
import gymnasium as gym
import mujoco
import numpy as np
from picture_tools import write_picture

import gym_soarm

OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "tasks.png"
COLUMNS = 4
TILE_W, TILE_H = 400, 300
CAPTION_H = 60
LOOK_AT_M = (0.0, 0.33, 0.03)
DISTANCE_M = 0.62
AZIMUTH_DEG = -120.0
ELEVATION_DEG = -42.0


def task_tile(name: str, seed: int) -> np.ndarray:
    """The tile of task ``name``: its scene after reset, and a caption."""
    env = gym.make(
        gym_soarm.get_task(name).env_id,
        obs_type="environment_state_agent_pos",
        render_quality="high",
    )
    try:
        _, info = env.reset(seed=seed)
        physics = env.unwrapped.physics
        camera = mujoco.MjvCamera()
        camera.lookat[:] = LOOK_AT_M
        camera.distance, camera.azimuth, camera.elevation = DISTANCE_M, AZIMUTH_DEG, ELEVATION_DEG
        with mujoco.Renderer(physics.model.ptr, TILE_H, TILE_W) as renderer:
            renderer.update_scene(physics.data.ptr, camera)
            image = renderer.render()
    finally:
        env.close()
    caption = np.full((CAPTION_H, TILE_W, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(caption, name, (8, 18), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for row, line in enumerate(textwrap.wrap(info["task"], 54)[:2]):
        y = 37 + 17 * row
        cv2.putText(caption, line, (8, y), font, 0.42, (60, 60, 60), 1, cv2.LINE_AA)
    return np.concatenate([image, caption], axis=0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help=f"default: {OUTPUT}")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    tiles = [task_tile(name, args.seed) for name in gym_soarm.task_names()]
    blank = np.full_like(tiles[0], 255)
    tiles += [blank] * (-len(tiles) % COLUMNS)
    rows = [np.concatenate(tiles[i : i + COLUMNS], axis=1) for i in range(0, len(tiles), COLUMNS)]
    write_picture(args.output, np.concatenate(rows, axis=0))


if __name__ == "__main__":
    main()
