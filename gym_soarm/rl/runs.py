"""What the imitation trainers' runs share: the curve's file and columns, the training
episodes' reset seeds and Ctrl-C handling (a run stops cleanly, keeping its checkpoint)."""

from __future__ import annotations

import json
import signal
import threading
from pathlib import Path
from typing import Any

from gym_soarm import __version__
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
