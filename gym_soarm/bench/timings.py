"""How the benchmarks summarise the repeats of one measurement, and write a figure."""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from typing import Any


def spread(values: Sequence[float]) -> dict[str, Any]:
    """The median, min and max of ``values``, and the values themselves (``repeats``)."""
    return {
        "median": statistics.median(values),
        "min": min(values),
        "max": max(values),
        "repeats": list(values),
    }


def format_number(x: float) -> str:
    """A rate for a table: no decimals from 100, one from 10, two below."""
    if x >= 100:
        return f"{x:,.0f}"
    return f"{x:.1f}" if x >= 10 else f"{x:.2f}"
