"""Render the picture of the three cameras in docs/environments.md: docs/camera_views.png.

    python scripts/make_camera_views.py

Resets SoArm-v0 (cube in the centre cell), lets the scripted expert bring the open
jaws over the cube, renders the overview, front and wrist cameras in high quality and
writes them side by side with their names. Rerun it after a change to the scene.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
from picture_tools import parse_picture_args, run_to_approach, write_picture

from gym_soarm import constants

OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "camera_views.png"
TILE_HEIGHT, TILE_WIDTH = 240, 320
LABEL_HEIGHT = 26
GAP = 4


def camera_views(seed: int, grid_cell: int, steps: int) -> dict[str, np.ndarray]:
    """The three camera images after ``steps`` expert steps."""
    env = gym.make(
        "SoArm-v0",
        obs_type="pixels",
        camera_config="all",
        observation_height=TILE_HEIGHT,
        observation_width=TILE_WIDTH,
        render_quality="high",
    )
    try:
        obs = run_to_approach(env, seed, grid_cell, steps)
        return {name: obs[name] for name in constants.CAMERA_NAMES}
    finally:
        env.close()


def compose(views: dict[str, np.ndarray]) -> np.ndarray:
    """Tiles side by side on a white sheet, each with its camera name above it."""
    import cv2

    width = len(views) * TILE_WIDTH + (len(views) - 1) * GAP
    sheet = np.full((LABEL_HEIGHT + TILE_HEIGHT, width, 3), 255, dtype=np.uint8)
    for i, (name, image) in enumerate(views.items()):
        x = i * (TILE_WIDTH + GAP)
        sheet[LABEL_HEIGHT:, x : x + TILE_WIDTH] = image
        cv2.putText(
            sheet,
            name,
            (x + 6, LABEL_HEIGHT - 8),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.55,
            (30, 30, 30),
            1,
            cv2.LINE_AA,
        )
    return sheet


def main(argv: list[str] | None = None) -> None:
    args = parse_picture_args(__doc__.splitlines()[0], OUTPUT, argv)
    write_picture(args.output, compose(camera_views(args.seed, args.grid_cell, args.steps)))


if __name__ == "__main__":
    main()
