"""Render the picture of the two render qualities in docs/performance.md: docs/quality_fast_vs_high.png.

    python scripts/make_quality_comparison.py

Runs the scripted expert until the open jaws are over the cube (the same state in both
qualities: the physics does not depend on them), then renders the arm through the
front camera (a crop of a 640x480 frame) and the wrist camera in ``fast`` (top row),
with the ``fast`` settings but the ``high`` meshes (middle row: what the mesh
simplification alone changes) and in ``high`` (bottom row). Rerun it after a change
to the scene or to the meshes.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
from picture_tools import parse_picture_args, run_to_approach, write_picture

from gym_soarm.render.camera import CameraRenderer

OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "quality_fast_vs_high.png"
FRONT_SIZE = (480, 640)  # rendered (height, width); the arm is cropped out of it
FRONT_CROP = (slice(40, 280), slice(160, 480))  # 240 x 320 around the arm
WRIST_SIZE = (240, 320)
LABEL_WIDTH = 150
GAP = 4
LABELS = {
    "fast": ("fast", "simplified meshes", "no shadows", "no reflections", "no multisampling"),
    "high meshes": ("fast settings", "with the high", "meshes"),
    "high": ("high", "full-detail meshes", "shadows", "reflections", "4x multisampling"),
}


def views(
    quality: str, seed: int, grid_cell: int, steps: int, settings: str | None = None
) -> list[np.ndarray]:
    """Front-camera crop and wrist-camera image after ``steps`` expert steps.

    ``quality`` picks the meshes (and the renderer settings unless ``settings`` names
    other ones).
    """
    env = gym.make(
        "SoArm-v0",
        obs_type="pixels",
        camera_config=["wrist_camera"],
        observation_height=WRIST_SIZE[0],
        observation_width=WRIST_SIZE[1],
        render_quality=quality,
    )
    try:
        obs = run_to_approach(env, seed, grid_cell, steps)
        if settings is None:
            front = env.unwrapped.render_camera_image("front_camera", *FRONT_SIZE)
            return [front[FRONT_CROP], obs["wrist_camera"]]
        physics = env.unwrapped.physics
        images = []
        for camera, (height, width) in (("front_camera", FRONT_SIZE), ("wrist_camera", WRIST_SIZE)):
            renderer = CameraRenderer(physics.model.ptr, width, height, settings)
            try:
                images.append(
                    renderer.render(physics.data.ptr, physics.model.name2id(camera, "camera"))
                )
            finally:
                renderer.close()
        return [images[0][FRONT_CROP], images[1]]
    finally:
        env.close()


def compose(rows: dict[str, list[np.ndarray]]) -> np.ndarray:
    """One row per variant, a label on the left of each."""
    import cv2

    height = rows["fast"][0].shape[0]
    width = LABEL_WIDTH + sum(image.shape[1] + GAP for image in rows["fast"])
    sheet = np.full((len(rows) * (height + GAP) - GAP, width, 3), 255, dtype=np.uint8)
    for r, (quality, images) in enumerate(rows.items()):
        y = r * (height + GAP)
        x = LABEL_WIDTH
        for image in images:
            sheet[y : y + height, x : x + image.shape[1]] = image
            x += image.shape[1] + GAP
        for i, text in enumerate(LABELS[quality]):
            cv2.putText(
                sheet,
                text,
                (8, y + 30 + 24 * i),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.7 if i == 0 else 0.45,
                (30, 30, 30),
                2 if i == 0 else 1,
                cv2.LINE_AA,
            )
    return sheet


def main(argv: list[str] | None = None) -> None:
    args = parse_picture_args(__doc__.splitlines()[0], OUTPUT, argv)
    rows = {
        "fast": views("fast", args.seed, args.grid_cell, args.steps),
        "high meshes": views("high", args.seed, args.grid_cell, args.steps, settings="fast"),
        "high": views("high", args.seed, args.grid_cell, args.steps),
    }
    write_picture(args.output, compose(rows))


if __name__ == "__main__":
    main()
