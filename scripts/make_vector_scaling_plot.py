"""Draw the plot of vector env scaling in docs/performance.md: docs/vector_scaling.png.

    python -m gym_soarm.bench --configs "" --vector-scaling 1,2,4,8,16 \\
        --vector-obs state,front_wrist --json scaling.json
    python scripts/make_vector_scaling_plot.py scaling.json [more.json ...] [--out PATH]

Reads the ``vector_scaling`` reports of one or more benchmark JSON files and draws one
panel per observation type: the speedup of each vector env (native worker processes,
``AsyncVectorEnv``, ``SyncVectorEnv``) over one environment against ``num_envs`` (log
scale), with the one-env line, the ceiling measured in the same run (the environments
on one free-running process per CPU, no communication), the bare physics of
``mujoco.rollout`` on a thread per CPU where the report has it and, for state
observations, the target of 1.7.
Drawn with OpenCV, so it needs nothing beyond gym_soarm's dependencies.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from gym_soarm.bench.bench import VECTOR_SPEEDUP_TARGET

OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "vector_scaling.png"
PANEL = (420, 520)  # (height, width) of one panel
MARGIN = (50, 60, 60, 20)  # top, left, bottom, right of the plotting area
COLOURS = {  # BGR
    "batched": (40, 40, 200),
    "processes": (180, 100, 30),
    "native": (180, 100, 30),  # the processes env in reports of earlier versions
    "async": (30, 130, 230),
    "sync": (110, 110, 110),
    "ceiling": (90, 170, 90),
    "rollout": (160, 60, 160),
}
LABELS = {
    "batched": "batched (mujoco.batch)",
    "processes": "processes (worker processes)",
    "native": "processes (worker processes)",
    "async": "AsyncVectorEnv",
    "sync": "SyncVectorEnv",
    "ceiling": "ceiling (free-running)",
    "rollout": "mujoco.rollout",
}
STATE_TARGET = VECTOR_SPEEDUP_TARGET
FONT = cv2.FONT_HERSHEY_SIMPLEX
INK = (40, 40, 40)


def load_reports(paths: Sequence[Path]) -> list[dict[str, Any]]:
    """Every measured ``vector_scaling`` report of the benchmark JSON files, in order."""
    reports = []
    for path in paths:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        reports += [r for r in data.get("vector_scaling", []) if "rows" in r]
    if not reports:
        raise ValueError(f"no vector_scaling report in {', '.join(map(str, paths))}")
    return reports


def _text(image: np.ndarray, text: str, at: tuple[int, int], scale: float = 0.45) -> None:
    cv2.putText(image, text, at, FONT, scale, INK, 1, cv2.LINE_AA)


def panel(report: dict[str, Any]) -> np.ndarray:
    """One report's speedups against num_envs, on a white panel."""
    height, width = PANEL
    top, left, bottom, right = MARGIN
    image = np.full((height, width, 3), 255, np.uint8)
    counts = sorted({r["num_envs"] for r in report["rows"]})
    speedups = [r["speedup"] for r in report["rows"]]
    speedups += [r.get("ceiling_speedup", 0.0) for r in report["rows"]]
    speedups += [_rollout_speedup(r) for r in report["rows"]]
    y_max = max(2.0, math.ceil(max(speedups) * 5 + 1) / 5)
    x_lo, x_hi = math.log2(counts[0]), max(math.log2(counts[-1]), math.log2(counts[0]) + 1)

    def point(n: int, y: float) -> tuple[int, int]:
        fx = (math.log2(n) - x_lo) / (x_hi - x_lo)
        return (
            round(left + fx * (width - left - right)),
            round(height - bottom - y / y_max * (height - top - bottom)),
        )

    step = 0.5 if y_max <= 3 else 1.0 if y_max <= 10 else 5.0
    for tick in np.arange(0, y_max + 1e-9, step):
        y = point(counts[0], tick)[1]
        cv2.line(image, (left, y), (width - right, y), (230, 230, 230), 1)
        _text(image, f"{tick:.1f}", (left - 36, y + 5), 0.4)
    for n in counts:
        x = point(n, 0)[0]
        cv2.line(image, (x, height - bottom), (x, height - bottom + 5), INK, 1)
        _text(image, str(n), (x - 5 * len(str(n)), height - bottom + 20), 0.4)
    cv2.rectangle(image, (left, top), (width - right, height - bottom), INK, 1)
    _text(image, "num_envs", (width // 2 - 30, height - 20))
    _text(image, "speedup over one env", (8, top - 12), 0.4)
    guides = [(1.0, "one env", (150, 150, 150))]
    if report["obs"] == "state":
        guides.append((STATE_TARGET, "target 1.7x", (60, 60, 200)))
    for value, label, colour in guides:
        y = point(counts[0], value)[1]
        for x in range(left, width - right, 12):  # dashed
            cv2.line(image, (x, y), (min(x + 6, width - right), y), colour, 1, cv2.LINE_AA)
        cv2.putText(image, label, (width - right - 90, y - 5), FONT, 0.4, colour, 1, cv2.LINE_AA)
    first_mode = report["modes"][0]
    ceiling_rows = sorted(
        (r for r in report["rows"] if r["mode"] == first_mode and "ceiling_speedup" in r),
        key=lambda r: r["num_envs"],
    )
    lines = [("ceiling", [point(r["num_envs"], r["ceiling_speedup"]) for r in ceiling_rows])]
    if all("rollout_steps_per_s" in r for r in ceiling_rows):
        lines.append(("rollout", [point(r["num_envs"], _rollout_speedup(r)) for r in ceiling_rows]))
    for mode in report["modes"]:
        rows = sorted((r for r in report["rows"] if r["mode"] == mode), key=lambda r: r["num_envs"])
        lines.append((mode, [point(r["num_envs"], r["speedup"]) for r in rows]))
    for mode, points in lines:
        if not points:
            continue
        colour = COLOURS.get(mode, INK)
        thickness = 1 if mode in ("ceiling", "rollout") else 2
        cv2.polylines(image, [np.array(points, np.int32)], False, colour, thickness, cv2.LINE_AA)
        for p in points:
            small = mode in ("ceiling", "rollout")
            cv2.circle(image, p, 3 if small else 4, colour, -1, cv2.LINE_AA)
    obs = (
        report["obs"]
        if report["obs"] == "state"
        else f"{report['obs']} {report['size'][0]}x{report['size'][1]}"
    )
    one = f"{report.get('cpus', '?')} cores, one env {report['single_steps_per_s']:,.0f} steps/s"
    cv2.putText(image, f"{obs} ({one})", (left, 24), FONT, 0.5, INK, 1, cv2.LINE_AA)
    return image


def _rollout_speedup(row: dict[str, Any]) -> float:
    """``mujoco.rollout``'s steps/s over one env's, in the row's run (0 if not measured)."""
    return row.get("rollout_steps_per_s", 0.0) / row["single_steps_per_s"]


def legend(modes: Sequence[str], width: int) -> np.ndarray:
    """A strip naming each mode's colour."""
    image = np.full((30, width, 3), 255, np.uint8)
    x = 60
    for mode in modes:
        cv2.line(image, (x, 15), (x + 24, 15), COLOURS.get(mode, INK), 2, cv2.LINE_AA)
        _text(image, LABELS.get(mode, mode), (x + 30, 20))
        x += 200
    return image


def draw(reports: Sequence[dict[str, Any]]) -> np.ndarray:
    """Panels side by side above a legend."""
    row = np.hstack([panel(r) for r in reports])
    modes = list(dict.fromkeys(m for r in reports for m in r["modes"]))
    if any("ceiling_speedup" in row for r in reports for row in r["rows"]):
        modes.append("ceiling")
    if any("rollout_steps_per_s" in row for r in reports for row in r["rows"]):
        modes.append("rollout")
    return np.vstack([row, legend(modes, row.shape[1])])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("json", nargs="+", type=Path, help="benchmark JSON files")
    parser.add_argument("--out", type=Path, default=OUTPUT, help="default: %(default)s")
    args = parser.parse_args(argv)
    try:
        image = draw(load_reports(args.json))
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), image, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        parser.error(f"could not write {args.out}")
    print(f"wrote {args.out} ({args.out.stat().st_size // 1024} KB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
