"""Per-feature statistics of a LeRobotDataset: numbers exactly, images from histograms."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from gym_soarm.data.format import QUANTILES, STAT_NAMES

_STATS_IMAGE_SIDE = 150


# --- statistics ----------------------------------------------------------------------------
def numeric_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """Statistics of a (frames, n) array over frames: min, max, mean, std, count, q01..q99.

    Quantiles use numpy's default linear interpolation; ``std`` is the population value.
    """
    values = np.asarray(values, dtype=np.float64)
    stats = {
        "min": values.min(axis=0),
        "max": values.max(axis=0),
        "mean": values.mean(axis=0),
        "std": values.std(axis=0),
        "count": np.array([len(values)]),
    }
    quantiles = np.quantile(values, list(QUANTILES.values()), axis=0)
    stats.update(zip(QUANTILES, quantiles, strict=True))
    return stats


def _histogram_quantile(cumulative: np.ndarray, q: float) -> float:
    # The same value as np.quantile(values, q) for the values counted by the histogram.
    total = int(cumulative[-1])
    position = q * (total - 1)
    below = math.floor(position)
    above = min(below + 1, total - 1)
    low = int(np.searchsorted(cumulative, below, side="right"))
    high = int(np.searchsorted(cumulative, above, side="right"))
    return low + (position - below) * (high - low)


def histogram_image_stats(histogram: np.ndarray, frames: int) -> dict[str, np.ndarray]:
    """Image statistics in [0, 1] per channel, shape (3, 1, 1), from uint8 histograms.

    Args:
        histogram: (3, 256) pixel counts per channel and value.
        frames: the number of frames counted, reported as ``count``.
    """
    levels = np.arange(256, dtype=np.float64)
    stats: dict[str, list[float]] = {name: [] for name in STAT_NAMES if name != "count"}
    for counts in histogram:
        total = counts.sum()
        present = np.flatnonzero(counts)
        mean = float(counts @ levels) / total
        stats["min"].append(float(present[0]))
        stats["max"].append(float(present[-1]))
        stats["mean"].append(mean)
        stats["std"].append(math.sqrt(float(counts @ (levels - mean) ** 2) / total))
        cumulative = np.cumsum(counts)
        for name, q in QUANTILES.items():
            stats[name].append(_histogram_quantile(cumulative, q))
    result = {name: np.array(v).reshape(3, 1, 1) / 255.0 for name, v in stats.items()}
    result["count"] = np.array([frames])
    return result


def image_histogram(frame: np.ndarray) -> np.ndarray:
    stride = max(1, math.ceil(max(frame.shape[:2]) / _STATS_IMAGE_SIDE))
    sample = frame[::stride, ::stride].reshape(-1, 3)
    return np.stack([np.bincount(sample[:, c], minlength=256) for c in range(3)])


def stats_to_json(stats: Mapping[str, np.ndarray]) -> dict[str, list]:
    return {
        name: (
            np.asarray(value).astype(np.int64) if name == "count" else np.asarray(value, np.float64)
        ).tolist()
        for name, value in stats.items()
    }
