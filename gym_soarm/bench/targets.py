"""The benchmark's performance floors and the check of a report against them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

# The performance floors: (what is compared, configuration, bound, "min" or "max").
TARGETS: tuple[tuple[str, str, float, str], ...] = (
    ("steps_per_s", "state", 4000.0, "min"),
    ("steps_per_s", "front_only_640x480", 20.0, "min"),
    ("steps_per_s", "front_wrist_640x480", 10.0, "min"),
    ("steps_per_s", "front_wrist_224x224", 40.0, "min"),
    ("reset_ms", "state", 5.0, "max"),
    ("make_s", "state", 1.0, "max"),
)
RATIO_TARGET = 0.8  # every pixel configuration against its raw-renderer ceiling
VECTOR_SPEEDUP_TARGET = 1.7  # the processes vector env over one env, state observations
BATCHED_SPEEDUP_TARGET = 1.8  # the batched vector env over one env, state observations
BATCHED_TARGET_MIN_ENVS = 64  # ... at this many environments (or the most measured)
VECTOR_CAMERA_SPEEDUP_TARGET = 1.8  # the same with cameras
VECTOR_TARGET_MIN_ENVS = 8  # the targets hold from this many environments


def check_targets(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The performance floors, each with the measured value and whether it is met."""
    by_name = {r["name"]: r for r in results if "error" not in r}
    checks = []
    for field, name, bound, kind in TARGETS:
        if name not in by_name:
            continue
        value = by_name[name][field]
        if isinstance(value, dict):
            value = value["median"]
        met = value >= bound if kind == "min" else value < bound
        checks.append({"config": name, "figure": field, "bound": bound, "kind": kind,
                       "value": value, "met": met})  # fmt: skip
    for name, r in by_name.items():
        if r.get("camera_config"):
            ratio = r["ratio_to_ceiling"]
            checks.append({"config": name, "figure": "ratio_to_ceiling", "bound": RATIO_TARGET,
                           "kind": "min", "value": ratio, "met": ratio >= RATIO_TARGET})  # fmt: skip
    return checks


def check_scaling_target(scaling: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The scaling targets: the processes vector env's best speedup over one env at
    ``num_envs`` >= 8 (or the largest count measured, if smaller), with state
    observations and with cameras."""
    checks = []
    for report in scaling:
        # "native": the processes env's name in reports of earlier versions
        processes = [r for r in report.get("rows", []) if r["mode"] in ("processes", "native")]
        if not processes:
            continue
        least = min(VECTOR_TARGET_MIN_ENVS, max(r["num_envs"] for r in processes))
        rows = [r for r in processes if r["num_envs"] >= least]
        if not rows:
            continue
        state = report.get("obs") == "state"
        bound = VECTOR_SPEEDUP_TARGET if state else VECTOR_CAMERA_SPEEDUP_TARGET
        best = max(rows, key=lambda r: r["speedup"])
        name = f"processes_vector_{report.get('obs')}_{best['num_envs']}"
        checks.append({"config": name, "figure": "speedup", "bound": bound, "kind": "min",
                       "value": best["speedup"], "met": best["speedup"] >= bound})  # fmt: skip
    for report in scaling:
        batched = [r for r in report.get("rows", []) if r["mode"] == "batched"]
        if not batched or report.get("obs") != "state":
            continue
        least = min(BATCHED_TARGET_MIN_ENVS, max(r["num_envs"] for r in batched))
        best = max((r for r in batched if r["num_envs"] >= least), key=lambda r: r["speedup"])
        bound = BATCHED_SPEEDUP_TARGET
        name = f"batched_vector_state_{best['num_envs']}"
        checks.append({"config": name, "figure": "speedup", "bound": bound, "kind": "min",
                       "value": best["speedup"], "met": best["speedup"] >= bound})  # fmt: skip
    return checks
