"""What the imitation trainers' runs share: the curve's file and columns, the training
episodes' reset seeds and Ctrl-C handling (a run stops cleanly, keeping its checkpoint)."""

from __future__ import annotations

import csv
import json
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm import __version__
from gym_soarm.rl.curves import write_curve_png
from gym_soarm.validation import check_int, check_number

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


def dart_noise(labels: np.ndarray, std: float, rng: np.random.Generator) -> np.ndarray:
    """DART: the executed actions are the expert's ``labels`` plus Gaussian noise of
    standard deviation ``std``, clipped to [-1, 1] (the labels themselves when 0)."""
    if std <= 0:
        return labels
    noise = rng.normal(0.0, std, np.shape(labels)).astype(np.float32)
    return np.clip(labels + noise, -1.0, 1.0).astype(np.float32)


class Curve:
    """A run's curve: one row an evaluation, rewritten to ``curve.csv`` and
    ``curve.png`` in ``folder`` after each (the wall time counted from its making)."""

    def __init__(self, folder: Path, title: str) -> None:
        self.folder, self.title = Path(folder), title
        self.rows: list[dict[str, Any]] = []
        self.started = time.perf_counter()

    def add(
        self,
        round_: int,
        env_steps: int,
        samples: int,
        success_rate: float,
        result: dict[str, Any],
        episodes: int,
    ) -> None:
        """A row for round ``round_`` with ``score``'s ``result``; writes both files."""
        self.rows.append(
            {
                "round": round_,
                "env_steps": env_steps,
                "samples": samples,
                "wall_s": round(time.perf_counter() - self.started, 2),
                "success_rate": success_rate,
                "mean_return": round(result["mean_return"], 4),
                "episodes": episodes,
            }
        )
        with open(self.folder / CURVE_CSV, "w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=CURVE_FIELDS)
            writer.writeheader()
            writer.writerows(self.rows)
        write_curve_png(self.rows, self.folder / CURVE_PNG, self.title)


def write_run_settings(path: Path, fields: dict[str, Any]) -> None:
    """Write a run's ``settings.json``: ``fields``, then how its training episodes were
    seeded and the package's version."""
    settings = {
        **fields,
        "training_seeds": f"{SEED_STRIDE} * (seed + 1) + {ROUND_STRIDE} * round + k",
        "gym_soarm_version": __version__,
    }
    path.write_text(json.dumps(settings, indent=2) + "\n")


def check_run_numbers(
    algo: str, settings: dict[str, Any], max_rounds: int = MAX_ROUNDS
) -> dict[str, Any]:
    """Check (and normalise) the numbers every bc/dagger recipe has, state or pixels:
    environments, threads, episodes, the regression and DAgger's rounds; ValueError
    naming the key."""
    params = settings["algo"]
    settings["n_envs"] = check_int("n_envs", settings["n_envs"], 1)
    settings["torch_threads"] = check_int("torch_threads", settings["torch_threads"], 1)
    settings["eval_episodes"] = check_int("eval_episodes", settings["eval_episodes"], 1)
    params["demos"] = check_int("demos", params["demos"], 1, ROUND_STRIDE - 1)
    params["dart_std"] = check_number("dart_std", params["dart_std"], 0.0)
    params["epochs"] = check_int("epochs", params["epochs"], 1)
    params["batch_size"] = check_int("batch_size", params["batch_size"], 1)
    params["learning_rate"] = check_number("learning_rate", params["learning_rate"], 0.0)
    if params["learning_rate"] == 0:
        raise ValueError("learning_rate must be a finite number > 0; got 0.")
    if algo == "dagger":
        params["rounds"] = check_int("rounds", params["rounds"], 1, max_rounds)
        params["episodes_per_round"] = check_int(
            "episodes_per_round", params["episodes_per_round"], 1, ROUND_STRIDE - 1
        )
        params["round_epochs"] = check_int("round_epochs", params["round_epochs"], 1)
        for key in ("beta0", "beta_decay"):
            value = check_number(key, params[key], 0.0)
            if value > 1:
                raise ValueError(f"{key} must be a number from 0 to 1; got {value!r}.")
            params[key] = value
    return settings


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
