"""What every trainer writes beside its model: the curve (``curve.csv``, ``curve.png``)
and the result of a run."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

CURVE_CSV = "curve.csv"
CURVE_PNG = "curve.png"
CURVE_FIELDS = ("env_steps", "wall_s", "success_rate", "mean_return", "episodes")


@dataclasses.dataclass
class TrainResult:
    """What a run did: its folder, steps, wall time, last success rate and whether Ctrl-C
    stopped it."""

    out: Path
    env_steps: int
    wall_s: float
    success_rate: float | None
    """The success rate of the policy the folder holds (for BC and DAgger its best round),
    None before the first evaluation."""
    interrupted: bool


def pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_curve_png(rows: list[dict[str, float]], path: Path, title: str) -> None:
    plt = pyplot()

    steps = [r["env_steps"] for r in rows]
    rates = [100 * r["success_rate"] for r in rows]
    minutes = [r["wall_s"] / 60 for r in rows]
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.4))
    left.plot(steps, rates, marker="o")
    left.set_xlabel("environment steps")
    right.plot(minutes, rates, marker="o")
    right.set_xlabel("wall time (min)")
    for axis in (left, right):
        axis.set_ylabel("success on the protocol (%)")
        axis.set_ylim(-3, 103)
        axis.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
