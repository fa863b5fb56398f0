"""Summarise RL runs (``python -m gym_soarm.train`` folders) over their training seeds.

    python scripts/summarize_rl.py runs --json docs/rl_baselines.json --plot docs/rl_curves.png

Groups the folders by (algorithm, task, variant), the variant being what a folder's name
adds to the algorithm, the task and the seed (``dagger_PickColoredCube-v0_wide_s0``:
``wide``; none for ``<task>/seed<k>``); per group: the protocol success of each seed
(``protocol.json`` from ``python -m gym_soarm.evaluate``, else the curve's last row),
their mean, min and max, the environment steps and wall time of each run, and the first
wall time at which a run's curve reached 95 %. The plot draws each group's mean success
against environment steps and wall time, with the seeds' spread as a band.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import statistics
from collections import defaultdict
from pathlib import Path


def _curve(folder: Path) -> list[dict[str, float]]:
    with open(folder / "curve.csv") as stream:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(stream)]


def _variant(folder: Path, algo: str, task: str) -> str:
    """What the folder's name adds to the algorithm, the task and the seed."""
    stem = re.sub(r"_?(?:s|seed)\d+$", "", folder.name) or folder.parent.name
    return stem.replace(task, "").replace(f"{algo}_", "", 1).strip("_")


def summarize(root: Path) -> dict[str, dict]:
    groups: dict[tuple[str, str, str], list[Path]] = defaultdict(list)
    for settings_path in sorted(root.rglob("settings.json")):
        settings = json.loads(settings_path.read_text())
        folder = settings_path.parent
        if (folder / "curve.csv").is_file():
            algo, task = settings["algo"], settings["task"]
            groups[(algo, task, _variant(folder, algo, task))].append(folder)
    summary = {}
    for (algo, task, variant), folders in sorted(groups.items()):
        seeds = []
        for folder in folders:
            settings = json.loads((folder / "settings.json").read_text())
            curve = _curve(folder)
            protocol = folder / "protocol.json"
            if protocol.is_file():
                result = json.loads(protocol.read_text())
                rate, episodes = result["success_rate"], result["episodes"]
            else:
                rate, episodes = curve[-1]["success_rate"], int(curve[-1]["episodes"])
            reached = next((row["wall_s"] for row in curve if row["success_rate"] >= 0.95), None)
            seeds.append(
                {
                    "seed": settings["seed"],
                    "folder": folder.relative_to(root).as_posix(),
                    "success_rate": rate,
                    "episodes": episodes,
                    "env_steps": int(curve[-1]["env_steps"]),
                    "wall_s": curve[-1]["wall_s"],
                    "wall_s_to_95": reached,
                }
            )
        rates = [s["success_rate"] for s in seeds]
        summary[f"{algo}/{task}" + (f"/{variant}" if variant else "")] = {
            "algo": algo,
            "task": task,
            "variant": variant,
            "seeds": seeds,
            "success_mean": statistics.fmean(rates),
            "success_min": min(rates),
            "success_max": max(rates),
            "wall_s_mean": statistics.fmean(s["wall_s"] for s in seeds),
            "env_steps": max(s["env_steps"] for s in seeds),
        }
    return summary


def plot(root: Path, summary: dict[str, dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for group in summary.values():
        curves = [_curve(root / s["folder"]) for s in group["seeds"]]
        n = min(len(c) for c in curves)
        rates = np.array([[100 * row["success_rate"] for row in c[:n]] for c in curves])
        steps = np.array([row["env_steps"] for row in curves[0][:n]])
        minutes = np.mean([[row["wall_s"] / 60 for row in c[:n]] for c in curves], axis=0)
        variant = f" {group['variant']}" if group.get("variant") else ""
        label = f"{group['algo'].upper()} {group['task']}{variant} ({len(curves)} seeds)"
        for axis, x in ((left, steps), (right, minutes)):
            # Markers, so that a one-row curve (a BC run: one evaluation) shows too.
            (line,) = axis.plot(x, rates.mean(axis=0), marker="o", markersize=4, label=label)
            axis.fill_between(x, rates.min(axis=0), rates.max(axis=0), alpha=0.2,
                              color=line.get_color())  # fmt: skip
            if n == 1:  # the seeds' spread of a single evaluation
                axis.vlines(x, rates.min(axis=0), rates.max(axis=0), color=line.get_color())
    left.set_xlabel("environment steps")
    right.set_xlabel("wall time, training and evaluation (min, 2 CPU cores)")
    for axis in (left, right):
        axis.set_ylabel("success on the protocol (%)")
        axis.set_ylim(-3, 103)
        axis.grid(alpha=0.3)
    left.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="folder holding the runs' folders")
    parser.add_argument("--json", type=Path, default=None, help="write the summary here")
    parser.add_argument("--plot", type=Path, default=None, help="draw the curves here")
    args = parser.parse_args()
    summary = summarize(args.root)
    for key, group in summary.items():
        per_seed = ", ".join(f"{100 * s['success_rate']:.0f} %" for s in group["seeds"])
        print(
            f"{key}: {100 * group['success_mean']:.0f} % mean ({per_seed}); "
            f"{group['env_steps']} steps, {group['wall_s_mean'] / 60:.1f} min per run"
        )
    if args.json is not None:
        args.json.write_text(json.dumps(summary, indent=2) + "\n")
    if args.plot is not None:
        plot(args.root, summary, args.plot)


if __name__ == "__main__":
    main()
