"""Datasets: a torch-free LeRobotDataset v3.0 writer and the expert's recorder.

:mod:`~gym_soarm.data.format` (paths and feature declarations),
:mod:`~gym_soarm.data.stats` (per-feature statistics),
:mod:`~gym_soarm.data.video_files` (H.264 episodes), :mod:`~gym_soarm.data.writer`
(:class:`LeRobotDatasetWriter`) and :mod:`~gym_soarm.record.record` (the recorder).
"""

from __future__ import annotations

from gym_soarm.data.format import (
    AUTO_FEATURES,
    CODEBASE_VERSION,
    NUMERIC_DTYPES,
    QUANTILES,
    STAT_NAMES,
    Feature,
    load_info,
)
from gym_soarm.data.stats import histogram_image_stats, numeric_stats
from gym_soarm.data.writer import LeRobotDatasetWriter

__all__ = [
    "AUTO_FEATURES",
    "CODEBASE_VERSION",
    "NUMERIC_DTYPES",
    "QUANTILES",
    "STAT_NAMES",
    "Feature",
    "LeRobotDatasetWriter",
    "histogram_image_stats",
    "load_info",
    "numeric_stats",
]
