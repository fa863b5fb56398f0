"""Draw docs/variation.png: one task under none / light / heavy visual randomisation
(top row) and its RGB, depth and segmentation images side by side (bottom row).

    python scripts/make_variation_picture.py [--task SortCubes-v0] [--camera front_camera]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import gymnasium as gym
import numpy as np
from picture_tools import write_picture

import gym_soarm

OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "variation.png"
HEIGHT, WIDTH = 300, 400
CAPTION_H = 28


def _caption(image: np.ndarray, text: str) -> np.ndarray:
    band = np.full((CAPTION_H, image.shape[1], 3), 255, np.uint8)
    cv2.putText(band, text, (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([image, band], axis=0)


def _observe(task: str, camera: str, seed: int, **kwargs) -> dict:
    env = gym.make(
        gym_soarm.get_task(task).env_id,
        obs_type="pixels",
        camera_config=[camera],
        observation_height=HEIGHT,
        observation_width=WIDTH,
        **kwargs,
    )
    try:
        obs, _ = env.reset(seed=seed)
        return {"obs": obs, "ids": env.unwrapped.segmentation_ids}
    finally:
        env.close()


def _depth_image(depth: np.ndarray) -> np.ndarray:
    near = float(depth.min())
    far = near + 0.7  # the table and the arm; the floor beyond is dark
    scaled = np.clip((depth - near) / max(far - near, 1e-6), 0.0, 1.0)
    coloured = cv2.applyColorMap((255 * (1.0 - scaled)).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    return cv2.cvtColor(coloured, cv2.COLOR_BGR2RGB)


def _segmentation_image(segments: np.ndarray, count: int) -> np.ndarray:
    palette = np.random.default_rng(7).integers(40, 255, size=(count, 3), dtype=np.uint8)
    palette[0] = 0
    return palette[segments]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help=f"default: {OUTPUT}")
    parser.add_argument("--task", default="SortCubes-v0")
    parser.add_argument("--camera", default="front_camera")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args(argv)
    top = []
    for level in ("none", "light", "heavy"):
        seen = _observe(args.task, args.camera, args.seed, visual_randomization=level)
        top.append(_caption(seen["obs"][args.camera], f"visual_randomization={level!r}"))
    seen = _observe(
        args.task,
        args.camera,
        args.seed,
        image_modalities=("rgb", "depth", "segmentation"),
        distractors=2,
    )
    obs = seen["obs"]
    bottom = [
        _caption(obs["pixels"][args.camera], "rgb (distractors=2)"),
        _caption(_depth_image(obs["depth"][args.camera]), "depth (near: bright, 0.7 m on: dark)"),
        _caption(
            _segmentation_image(obs["segmentation"][args.camera], len(seen["ids"])),
            "segmentation (one colour per id)",
        ),
    ]
    sheet = np.concatenate([np.concatenate(top, axis=1), np.concatenate(bottom, axis=1)], axis=0)
    write_picture(args.output, sheet)


if __name__ == "__main__":
    main()
