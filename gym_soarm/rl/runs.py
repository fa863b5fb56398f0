"""What the imitation trainers' runs share: the curve's file and columns, the training
episodes' reset seeds, the recipe's numbers, the fit's weights and learning rates, and
Ctrl-C handling (a run stops cleanly, keeping its checkpoint)."""

from __future__ import annotations

import csv
import json
import math
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm import __version__
from gym_soarm.rl.curves import TrainResult, write_curve_png
from gym_soarm.validation import ArgumentTypeError, check_int, check_number

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
VALIDATION_SEED = 50_000
"""The imitation trainers score each round on episodes ``VALIDATION_SEED + k``: neither
training seeds nor the protocol's (``EVAL_SEED + k``), so that the round a run keeps is
chosen on other episodes than those it is reported on."""


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


def episode_weights(episodes: np.ndarray, params: dict[str, Any]) -> np.ndarray:
    """Each stored step's weight in the loss: 1 for all, or with ``episode_weighting``
    (the recipe's, where it has it) the mean episode length over its episode's length, so
    that every episode counts alike and a long failed one (a student hovering to the time
    limit) does not outweigh the short successful ones. The weights average 1."""
    if not params.get("episode_weighting", False) or len(episodes) == 0:
        return np.ones(len(episodes), np.float32)
    _, inverse, counts = np.unique(episodes, return_inverse=True, return_counts=True)
    weights = counts.mean() / counts[inverse]
    return (weights / weights.mean()).astype(np.float32)


def learning_rates(
    params: dict[str, Any], epochs: int, steps_per_epoch: int, first: bool = True
) -> Any:
    """The learning rate of each optimiser step of a fit, ``rate(epoch, step)``: the
    recipe's ``learning_rate`` throughout (``round_learning_rate`` in the DAgger rounds'
    fits after the ``first``, where the recipe has one), or with ``lr_schedule="cosine"``
    annealed along a half cosine to a hundredth of it by the fit's last step (each fit,
    each DAgger round, starts again from its full rate)."""
    base, schedule = params["learning_rate"], params.get("lr_schedule", "constant")
    if not first and params.get("round_learning_rate") is not None:
        base = params["round_learning_rate"]
    if schedule == "constant":
        return lambda epoch, step: base
    if schedule != "cosine":
        raise ValueError(
            f"lr_schedule is 'constant' or 'cosine'; got {schedule!r}. Pass --hyperparams "
            "lr_schedule=\"'constant'\" or lr_schedule=\"'cosine'\"."
        )
    total = max(epochs * steps_per_epoch - 1, 1)

    def rate(epoch: int, step: int) -> float:
        done = (epoch * steps_per_epoch + step) / total
        return base * (0.01 + 0.99 * 0.5 * (1.0 + math.cos(math.pi * done)))

    return rate


class RunFolder:
    """A training run's folder, as every trainer of the package keeps it: made (the files
    of an earlier run there removed), its ``settings.json``, its curve (``curve.csv`` and
    ``curve.png``, rewritten after each evaluation) and Ctrl-C (use it as a context
    manager: :meth:`stop` turns true and the trainer ends cleanly, keeping its checkpoint
    and curve).

    Args:
        path: the folder.
        title: the curve's title (``"PPO on LiftCube-v0, seed 0"``).
        fields: the curve's columns (``wall_s`` is filled in by :meth:`add_row`).
    """

    def __init__(
        self, path: str | Path, title: str, fields: tuple[str, ...] = CURVE_FIELDS
    ) -> None:
        self.path, self.title, self.fields = Path(path), title, fields
        self.rows: list[dict[str, Any]] = []
        self.stop = StopOnInterrupt()
        self.started = time.perf_counter()

    def prepare(self, stale: tuple[str, ...] = ()) -> RunFolder:
        """Make the folder and remove an earlier run's ``stale`` files and curve."""
        self.path.mkdir(parents=True, exist_ok=True)
        for name in (*stale, CURVE_CSV, CURVE_PNG):
            (self.path / name).unlink(missing_ok=True)
        return self

    def __enter__(self) -> RunFolder:
        self.stop.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.__exit__(*exc)

    def wall_s(self) -> float:
        """Seconds since the folder was made."""
        return time.perf_counter() - self.started

    def write_settings(self, name: str, fields: dict[str, Any]) -> None:
        """Write ``fields`` and the package's version as the JSON file ``name``."""
        settings = {**fields, "gym_soarm_version": __version__}
        (self.path / name).write_text(json.dumps(settings, indent=2) + "\n")

    def add_row(self, row: dict[str, Any]) -> None:
        """Append an evaluation's row (its ``wall_s`` now) and rewrite the curve."""
        self.rows.append({**row, "wall_s": round(self.wall_s(), 2)})
        self.write_curve()

    def write_curve(self) -> None:
        with open(self.path / CURVE_CSV, "w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=self.fields)
            writer.writeheader()
            writer.writerows(self.rows)
        if self.rows:
            write_curve_png(self.rows, self.path / CURVE_PNG, self.title)

    def result(self, env_steps: int, success_rate: float | None) -> TrainResult:
        """The run's :class:`TrainResult` now."""
        return TrainResult(
            out=self.path,
            env_steps=int(env_steps),
            wall_s=self.wall_s(),
            success_rate=success_rate,
            interrupted=self.stop.interrupted,
        )


TRAINING_SEEDS = f"{SEED_STRIDE} * (seed + 1) + {ROUND_STRIDE} * round + k"
"""How an imitation run's training episodes are seeded, as its ``settings.json`` says."""


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
        if "patience" in params:
            params["patience"] = check_int(
                "patience", params["patience"], 1,
                fix="Pass e.g. --hyperparams patience=3 (as many as the rounds: never early).",
            )  # fmt: skip
        if params.get("round_learning_rate") is not None:
            rate = check_number("round_learning_rate", params["round_learning_rate"], 0.0)
            if rate == 0:
                raise ValueError(
                    "round_learning_rate must be a finite number > 0, or None for the "
                    "learning_rate; got 0. Pass e.g. --hyperparams round_learning_rate=3e-4."
                )
            params["round_learning_rate"] = rate
    weighting = params.get("episode_weighting", False)
    if not isinstance(weighting, bool):
        raise ArgumentTypeError(
            "episode_weighting must be true or false (every episode's steps weighted to count "
            f"alike); got {weighting!r}. Pass --hyperparams episode_weighting=True (or False)."
        )
    learning_rates(params, 1, 1)  # an unknown schedule is refused here
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
