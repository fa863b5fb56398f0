"""What the imitation trainers' runs share: the curve's file and columns, the training
episodes' reset seeds and Ctrl-C handling (a run stops cleanly, keeping its checkpoint)."""

from __future__ import annotations

import signal
import threading
from typing import Any

CURVE_CSV = "curve.csv"
CURVE_PNG = "curve.png"
CURVE_FIELDS = (
    "round",
    "env_steps",
    "samples",
    "wall_s",
    "success_rate",
    "mean_return",
    "episodes",
)
SEED_STRIDE = 100_000
"""Reset seeds of training seed ``s`` start at ``SEED_STRIDE * (s + 1)``."""
ROUND_STRIDE = 1_000
"""Reset seeds of round ``r`` start ``ROUND_STRIDE * r`` further on."""
MAX_ROUNDS = SEED_STRIDE // ROUND_STRIDE - 1


def training_seeds(seed: int, round_: int, episodes: int) -> list[int]:
    """The reset seeds of round ``round_``'s ``episodes`` training episodes."""
    base = SEED_STRIDE * (seed + 1) + ROUND_STRIDE * round_
    return [base + k for k in range(episodes)]


# --------------------------------------------------------------------------- Ctrl-C


class StopOnInterrupt:
    """Ctrl-C (SIGINT) sets a flag that the trainer polls; the run then stops cleanly
    and keeps its checkpoint and curve."""

    def __init__(self) -> None:
        self.interrupted = False
        self._previous: Any = None

    def __enter__(self) -> StopOnInterrupt:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._interrupt)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

    def _interrupt(self, signum: int, frame: Any) -> None:
        self.interrupted = True

    def __call__(self) -> bool:
        return self.interrupted
