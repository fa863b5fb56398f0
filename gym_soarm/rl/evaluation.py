"""Score a trained policy, or the scripted expert, on the benchmark's protocol.

Episode ``k`` resets with seed ``first_seed + k`` (default :data:`EVAL_SEED`, 1000, as
``lerobot-eval`` runs it) and no options; the policy acts deterministically. A policy
folder is what :func:`gym_soarm.rl.training.train` writes: the model, its environment
settings and, for recipes that normalise observations, their statistics.
"""

from __future__ import annotations

import json
import os
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gym_soarm.expert import make_expert, run_episode
from gym_soarm.rl.hyperparams import POLICY_CLASSES, TRAINERS
from gym_soarm.rl.rsl_policy import RSL_LIBRARY, RSL_MODEL_FILE
from gym_soarm.tasks import get_task
from gym_soarm.tasks.suites import EVAL_SEED

POLICY_FORMAT = "gym_soarm.policy/1"
"""The ``format`` of a policy folder's ``settings.json``."""
SETTINGS_FILE = "settings.json"
MODEL_FILE = "model.zip"
NORMALIZE_FILE = "vecnormalize.pkl"


def require_sb3() -> Any:
    """Stable-Baselines3, or an ImportError that says how to install it."""
    try:
        import stable_baselines3
    except ImportError as exc:
        raise ImportError(
            "training and loading policies need Stable-Baselines3 and PyTorch: "
            'pip install "gym-soarm[rl]" (for a CPU-only PyTorch, first: pip install torch '
            "--index-url https://download.pytorch.org/whl/cpu)."
        ) from exc
    return stable_baselines3


def make_env(task: str, env_kwargs: dict[str, Any]) -> gym.Env:
    """``gym.make`` of ``task``'s id with ``env_kwargs`` (Gymnasium's checker off: our
    own checks run in the environment)."""
    return gym.make(get_task(task).env_id, disable_env_checker=True, **env_kwargs)


def read_settings(folder: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``settings.json`` of a policy folder, checked.

    Raises:
        ValueError: the folder, its settings or its model is missing or not ours.
    """
    path = Path(folder)
    settings_path = path / SETTINGS_FILE
    if not path.is_dir():
        raise ValueError(
            f"--policy must be a folder written by python -m gym_soarm.train (or 'expert'); "
            f"{str(path)!r} is not a folder."
        )
    settings: Any = None
    if settings_path.is_file():
        try:
            settings = json.loads(settings_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{settings_path} is not valid JSON ({exc}).") from None
    model = model_file(settings)
    if not settings_path.is_file() or not (path / model).is_file():
        raise ValueError(
            f"{str(path)!r} is not a gym-soarm policy folder: it must hold {SETTINGS_FILE} "
            f"and {model}, as python -m gym_soarm.train writes them. Pass the --out "
            "folder of a training run."
        )
    if not isinstance(settings, dict) or settings.get("format") != POLICY_FORMAT:
        got = settings.get("format") if isinstance(settings, dict) else type(settings).__name__
        raise ValueError(
            f"{settings_path} is not a gym-soarm policy's settings: its format must be "
            f"{POLICY_FORMAT!r}; got {got!r}. Pass the --out folder of python -m gym_soarm.train."
        )
    for key, kind in (("algo", str), ("task", str), ("env", dict), ("observation_names", list)):
        if not isinstance(settings.get(key), kind):
            raise ValueError(
                f"{settings_path}: field {key!r} must be a {kind.__name__}; got "
                f"{settings.get(key)!r}. The file was edited or damaged; train again."
            )
    if settings["algo"] not in TRAINERS:
        raise ValueError(
            f"{settings_path}: algo must be one of {', '.join(TRAINERS)}; got {settings['algo']!r}."
        )
    get_task(settings["task"])  # a ValueError naming the registered tasks
    return settings


def model_file(settings: Any) -> str:
    """The model's file name in a policy folder of ``settings`` (a pixel student's own)."""
    from gym_soarm.rl.pixels import PIXEL_MODEL_FILE, PIXEL_POLICY

    if isinstance(settings, dict) and settings.get("policy") == PIXEL_POLICY:
        return PIXEL_MODEL_FILE
    if isinstance(settings, dict) and settings.get("library") == RSL_LIBRARY:
        return RSL_MODEL_FILE
    return MODEL_FILE


class TrainedPolicy:
    """A policy folder loaded for acting: ``policy(obs, info) -> action``.

    Args:
        folder: the ``--out`` folder of a training run.
        task: the task it is to act on (None: the one it was trained on); another task
            is refused.

    Raises:
        ValueError: not a policy folder, another task, or an observation layout that
            differs from this package's (trained on another version).
    """

    def __init__(self, folder: str | os.PathLike[str], task: str | None = None) -> None:
        settings = read_settings(folder)
        trained = get_task(settings["task"]).name
        if task is not None and get_task(task).name != trained:
            raise ValueError(
                f"the policy in {str(folder)!r} was trained for {trained}; got --task "
                f"{get_task(task).name}. Evaluate it on {trained}, or train one for "
                f"{get_task(task).name}."
            )
        env = make_env(trained, settings["env"])
        try:
            names = list(getattr(env.unwrapped, "observation_names", ()))
            obs_space = env.observation_space
            action_space = env.action_space
        finally:
            env.close()
        self._columns = _trained_columns(folder, settings, names, trained)
        if self._columns is not None:
            obs_space = spaces.Box(-np.inf, np.inf, (len(self._columns),), np.float32)
        self.settings = settings
        self.task = trained
        self._normalizer = None
        self._pixels = None
        self._actor = None
        if settings.get("library") == RSL_LIBRARY:
            self._actor = _rsl_actor(Path(folder), settings, obs_space.shape, action_space.shape)
            return
        if model_file(settings) != MODEL_FILE:
            from gym_soarm.rl.pixels import PixelPolicy

            self._pixels = PixelPolicy.load(folder)
            if self._pixels.net.head[-1].out_features != action_space.shape[0]:
                raise ValueError(
                    f"the pixel policy in {str(folder)!r} gives {self._pixels.net.head[-1].out_features} "
                    f"actions; {trained} with its saved settings takes {action_space.shape[0]}. "
                    "Retrain it."
                )
            return
        sb3 = require_sb3()
        algo_class = getattr(sb3, POLICY_CLASSES[settings["algo"]])
        path = Path(folder)
        self.model = algo_class.load(path / MODEL_FILE, device="cpu")
        if self.model.observation_space.shape != obs_space.shape or (
            self.model.action_space.shape != action_space.shape
        ):
            layout = "another observation layout: " if self._columns is not None else ""
            raise ValueError(
                f"{layout}the model in {str(path / MODEL_FILE)!r} takes observations of shape "
                f"{self.model.observation_space.shape} and actions of shape "
                f"{self.model.action_space.shape}; {trained} with its saved settings has "
                f"{obs_space.shape} and {action_space.shape}. Retrain it."
            )
        if (path / NORMALIZE_FILE).is_file():
            import pickle

            with open(path / NORMALIZE_FILE, "rb") as stream:
                self._normalizer = pickle.load(stream)
            self._normalizer.training = False

    def reset(self) -> None:
        """Call after each ``env.reset``: a pixel policy forgets the last step's joints."""
        if self._pixels is not None:
            self._pixels.reset()

    def __call__(self, obs: Any, info: dict[str, Any] | None = None) -> np.ndarray:
        if self._pixels is not None:
            return self._pixels(obs, info)
        if self._columns is not None:
            obs = np.asarray(obs)[..., self._columns]
        if self._actor is not None:
            return self._actor(obs)
        if self._normalizer is not None:
            obs = self._normalizer.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def _trained_columns(
    folder: Any, settings: dict[str, Any], names: list[str], trained: str
) -> list[int] | None:
    """Where the values a state policy was trained on lie in today's observation ``names``
    (None: the same layout). A policy trained before the observation gained values (a
    task's progress) reads its own by name; one whose values are not all there is
    refused."""
    trained_names = settings["observation_names"]
    if trained_names == names:
        return None
    missing = [name for name in trained_names if name not in names]
    if missing or model_file(settings) != MODEL_FILE:
        lacking = f"; without {missing[:4]}" if missing else ""
        raise ValueError(
            f"the policy in {str(folder)!r} was trained on another observation layout "
            f"({len(trained_names)} values) than {trained} has now ({len(names)}{lacking}); "
            "retrain it with this version of gym-soarm."
        )
    return [names.index(name) for name in trained_names]


def _rsl_actor(folder: Path, settings: dict[str, Any], obs_shape: Any, action_shape: Any) -> Any:
    """The actor of an RSL-RL folder (:mod:`gym_soarm.rl.rsl`) as ``obs -> action``."""
    from gym_soarm.rl.rsl_policy import RSL_MODEL_FILE, acting, load_actor

    return acting(
        load_actor(folder / RSL_MODEL_FILE, settings["recipe"], obs_shape[0], action_shape[0])
    )


def protocol_seeds(episodes: int, first_seed: int = EVAL_SEED) -> list[int]:
    """The seeds of ``episodes`` protocol episodes: ``first_seed + k``."""
    return [first_seed + k for k in range(episodes)]


def score(
    task: str,
    env_kwargs: dict[str, Any],
    policy: Callable[[Any, dict], np.ndarray] | None,
    episodes: int,
    first_seed: int = EVAL_SEED,
) -> dict[str, Any]:
    """Run ``policy`` (None: the task's scripted expert) on the protocol's episodes.

    Returns:
        ``success_rate`` (a fraction), ``episodes``, ``seeds``, ``successes`` (one bool
        per episode), ``mean_return`` and ``mean_steps``.
    """
    env = make_env(task, env_kwargs)
    try:
        actor = make_expert(env) if policy is None else policy
        seeds = protocol_seeds(episodes, first_seed)
        results = [run_episode(env, actor, seed, None) for seed in seeds]
    finally:
        env.close()
    successes = [result.success for result in results]
    return {
        "task": get_task(task).name,
        "success_rate": sum(successes) / len(successes),
        "episodes": episodes,
        "first_seed": first_seed,
        "seeds": seeds,
        "successes": successes,
        "mean_return": statistics.fmean(result.episode_return for result in results),
        "mean_steps": statistics.fmean(result.steps for result in results),
    }


__all__ = [
    "POLICY_FORMAT",
    "TrainedPolicy",
    "make_env",
    "protocol_seeds",
    "read_settings",
    "require_sb3",
    "score",
]
