"""Draw docs/architecture.png: the layers of gym_soarm and how a step flows through them.

python scripts/make_architecture_picture.py [OUT]
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

BOXES = {
    # name: (x, y, w, h, title, lines, colour)
    "programs": (
        0.02,
        0.86,
        0.96,
        0.11,
        "programs  cli/",
        "train · evaluate · record · replay · sysid · teleop · expert · bench",
        "#e8e8e8",
    ),
    "users": (
        0.02,
        0.70,
        0.30,
        0.13,
        "learning  rl/",
        "PPO/SAC · BC/DAgger · pixel students",
        "#dbe9f6",
    ),
    "record": (
        0.35,
        0.70,
        0.30,
        0.13,
        "record/  data/",
        "recording loops · LeRobot dataset",
        "#dbe9f6",
    ),
    "lerobot": (
        0.68,
        0.70,
        0.30,
        0.13,
        "lerobot/  real/  teleop/",
        "suites · units · calibration · replay",
        "#dbe9f6",
    ),
    "single": (
        0.02,
        0.50,
        0.45,
        0.15,
        "envs.env.SoArmEnv",
        "one simulation; checks, resets,\ncameras (render/), snapshots",
        "#fdebd0",
    ),
    "vector": (
        0.53,
        0.50,
        0.45,
        0.15,
        "vector/",
        "batched (one mujoco.batch) ·\nprocesses (workers, pixels)",
        "#fdebd0",
    ),
    "core": (
        0.02,
        0.28,
        0.96,
        0.17,
        "envs.core.StepCore  —  the step, written once",
        "servo chain → backend.step → divergence → task.evaluate → reward terms,\nsuccess, reward → state observation, info values",
        "#f9d5d3",
    ),
    "tasks": (
        0.02,
        0.06,
        0.30,
        0.17,
        "tasks/  expert/",
        "placement · array code over\nSimArrays · experts",
        "#d5f5e3",
    ),
    "backends": (
        0.35,
        0.06,
        0.30,
        0.17,
        "sim.backends",
        "MjDataBackend (one MjData)\nBatchBackend (mujoco.batch)",
        "#d5f5e3",
    ),
    "sim": (
        0.68,
        0.06,
        0.30,
        0.17,
        "sim/",
        "scene · physics · arrays ·\nkinematics · randomisation",
        "#d5f5e3",
    ),
}
ARROWS = [
    ("programs", "users"),
    ("programs", "record"),
    ("programs", "lerobot"),
    ("users", "single"),
    ("users", "vector"),
    ("record", "single"),
    ("record", "vector"),
    ("lerobot", "vector"),
    ("single", "core"),
    ("vector", "core"),
    ("core", "tasks"),
    ("core", "backends"),
    ("backends", "sim"),
]


def main(out: str = "docs/architecture.png") -> None:
    fig, ax = plt.subplots(figsize=(10, 7.2), dpi=110)
    ax.set_axis_off()
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    centre = {}
    for name, (x, y, w, h, title, lines, colour) in BOXES.items():
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.005", fc=colour, ec="#555"))
        ax.text(
            x + w / 2, y + h - 0.03, title, ha="center", va="center", fontsize=10, weight="bold"
        )
        ax.text(x + w / 2, y + (h - 0.04) / 2, lines, ha="center", va="center", fontsize=8.5)
        centre[name] = (x + w / 2, y, y + h)
    for a, b in ARROWS:
        (xa, ya, ta), (xb, yb_low, yb) = centre[a], centre[b]
        if ya == yb_low:  # side by side: from a's right edge to b's left edge
            start = (BOXES[a][0] + BOXES[a][2], (ya + ta) / 2)
            end = (BOXES[b][0], (ya + ta) / 2)
        else:
            start, end = (xa, ya), (xb, yb)
        ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=12, color="#444"))
    ax.set_title(
        "gym_soarm: layers, and a step from an environment down to the physics", fontsize=11
    )
    fig.savefig(out, bbox_inches="tight")


if __name__ == "__main__":
    main(*sys.argv[1:])
