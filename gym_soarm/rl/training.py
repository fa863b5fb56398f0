"""Train a state policy with Stable-Baselines3: checkpoints and a learning curve on disk.

:func:`train` runs one recipe of :mod:`gym_soarm.rl.hyperparams` (PPO or SAC on one
task, one seed) and writes into its output folder:

* ``model.zip``: the latest checkpoint (SB3's own format), saved at every evaluation,
  at the end and when the run is interrupted (Ctrl-C);
* ``vecnormalize.pkl``: the observation statistics, for recipes that normalise;
* ``settings.json``: what the policy needs to act again (format ``gym_soarm.policy/1``:
  algorithm, task, seed, ``gym.make`` keywords, the observation's names) and the recipe;
* ``curve.csv``: one row per evaluation: ``env_steps``, ``wall_s``, ``success_rate``
  (on the protocol: seeds 1000 + k), ``mean_return``, ``episodes``;
* ``curve.png``: the success rate against environment steps and wall time.

``init`` (``--algo ppo --init DIR``) starts PPO from the policy in ``DIR`` (a BC or
DAgger folder of :mod:`gym_soarm.rl.imitation`, or another PPO run) on the same task and
observation layout: its weights, its observation statistics, a low exploration noise
and a behaviour-cloning term on the actor against ``DIR``'s ``demos.npz``
(:class:`gym_soarm.rl.bc_ppo.BCRegularizedPPO`; the recipe's ``init`` keys).
"""

from __future__ import annotations

import importlib.util
import logging
import os
import pickle
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.envs.settings import merge_keywords
from gym_soarm.rl.curves import (
    CURVE_FIELDS,
    TrainResult,
    pyplot,
)
from gym_soarm.rl.evaluation import (
    MODEL_FILE,
    NORMALIZE_FILE,
    POLICY_FORMAT,
    SETTINGS_FILE,
    make_env,
    read_settings,
    require_sb3,
    score,
)
from gym_soarm.rl.hyperparams import (
    ALGORITHMS,
    IMITATION,
    POLICY_CLASSES,
    VEC_ENVS,
    VECTOR_ENVS,
    override,
    recipe,
    rsl_recipe,
)
from gym_soarm.rl.rsl import RSL_VECTOR_ENVS
from gym_soarm.rl.rsl_policy import RSL_LIBRARY, RSL_MODEL_FILE
from gym_soarm.rl.runs import RunFolder
from gym_soarm.tasks import get_task
from gym_soarm.tasks.suites import EVAL_SEED
from gym_soarm.validation import check_choice, check_int

logger = logging.getLogger(__name__)


class _Run:
    """The bookkeeping of one SB3 run in its :class:`RunFolder`: evaluations, curve rows
    and checkpoints."""

    def __init__(
        self, folder: RunFolder, task: str, env_kwargs: dict, episodes: int, model: Any
    ) -> None:
        self.folder = folder
        self.task = task
        self.env_kwargs = env_kwargs
        self.episodes = episodes
        self.model = model
        self.last_rate: float | None = None

    def normalizer(self) -> Any:
        from stable_baselines3.common.vec_env import VecNormalize

        env = self.model.get_env()
        return env if isinstance(env, VecNormalize) else None

    def save(self) -> None:
        self.model.save(self.folder.path / MODEL_FILE)
        normalizer = self.normalizer()
        if normalizer is not None:
            # The statistics alone (the environments are not pickled).
            venv, normalizer.venv = normalizer.venv, None
            try:
                with open(self.folder.path / NORMALIZE_FILE, "wb") as stream:
                    pickle.dump(normalizer, stream)
            finally:
                normalizer.venv = venv

    def evaluate(self, env_steps: int) -> float:
        wall = self.folder.wall_s()
        normalizer = self.normalizer()
        model = self.model

        def act(obs: np.ndarray, info: dict) -> np.ndarray:
            if normalizer is not None:
                obs = normalizer.normalize_obs(obs)
            return model.predict(obs, deterministic=True)[0]

        result = score(self.task, self.env_kwargs, act, self.episodes, EVAL_SEED)
        self.folder.rows.append(
            {
                "env_steps": env_steps,
                "wall_s": round(wall, 2),
                "success_rate": result["success_rate"],
                "mean_return": round(result["mean_return"], 4),
                "episodes": self.episodes,
            }
        )
        self.folder.write_curve()
        self.save()
        logger.info(
            "%s: %d steps, %.0f s, success %.0f %%",
            self.folder.title,
            env_steps,
            wall,
            100 * result["success_rate"],
        )
        self.last_rate = result["success_rate"]
        return self.last_rate

    def learn(self, steps: int, eval_every: int, progress_bar: bool) -> None:
        """``model.learn`` for ``steps``, evaluating every ``eval_every`` steps and at the
        end; Ctrl-C stops it after the current step, keeping the checkpoint and curve."""
        from stable_baselines3.common.callbacks import BaseCallback

        run, stop = self, self.folder.stop

        class _Callback(BaseCallback):
            def __init__(self) -> None:
                super().__init__()
                self.next_eval = eval_every

            def _on_step(self) -> bool:
                if self.num_timesteps >= self.next_eval:
                    self.next_eval += eval_every
                    run.evaluate(self.num_timesteps)
                return not stop.interrupted

        model = self.model
        model.learn(total_timesteps=steps, callback=_Callback(), progress_bar=progress_bar)
        rows = self.folder.rows
        if stop.interrupted:
            logger.warning(
                "%s: interrupted; the checkpoint and the curve are kept", self.folder.title
            )
            self.save()
            self.folder.write_curve()
        elif not rows or rows[-1]["env_steps"] != model.num_timesteps:
            self.evaluate(model.num_timesteps)


def _check_init(
    init: str | os.PathLike[str],
    task: str,
    env_kwargs: dict[str, Any],
    observation_names: list[str],
    normalize: bool,
) -> dict[str, Any]:
    """The settings of the ``init`` folder, checked against the run's task and
    environment; ValueError naming both sides of a difference."""
    from gym_soarm.rl.imitation import DEMOS_FILE

    settings = read_settings(init)  # ValueError: not a policy folder
    folder = str(init)
    if POLICY_CLASSES[settings["algo"]] != "PPO":
        raise ValueError(
            f"--init needs a PPO-class policy (bc, dagger or ppo); {folder!r} holds a "
            f"{settings['algo']} policy."
        )
    trained = get_task(settings["task"]).name
    if trained != task:
        raise ValueError(
            f"--init {folder!r} holds a policy for {trained}; got --task {task}. Start "
            f"from a {task} policy (python -m gym_soarm.train --algo bc --task {task})."
        )
    if settings["observation_names"] != observation_names:
        raise ValueError(
            f"--init {folder!r} was trained on another observation layout "
            f"({len(settings['observation_names'])} values) than {task} has now "
            f"({len(observation_names)}); retrain it with this version of gym-soarm."
        )
    if settings["env"] != env_kwargs:
        raise ValueError(
            f"--init {folder!r} was trained with the environment settings "
            f"{settings['env']}; the ppo recipe of {task} uses {env_kwargs}."
        )
    path = Path(init)
    if (path / NORMALIZE_FILE).is_file() != bool(normalize):
        raise ValueError(
            f"--init {folder!r} {'has' if not normalize else 'has no'} {NORMALIZE_FILE} "
            f"(observation statistics), but the ppo recipe of {task} "
            f"{'normalises' if normalize else 'does not normalise'} observations; train "
            "the two with matching normalisation."
        )
    settings["_demos"] = path / DEMOS_FILE if (path / DEMOS_FILE).is_file() else None
    settings["_normalizer"] = path / NORMALIZE_FILE if (path / NORMALIZE_FILE).is_file() else None
    settings["_folder"] = path
    return settings


def _ppo_from(source: dict[str, Any], venv: Any, seed: int, settings: dict[str, Any]) -> Any:
    """A :class:`~gym_soarm.rl.bc_ppo.BCRegularizedPPO` with the weights, observation
    statistics and demonstrations of the ``--init`` folder."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from gym_soarm.rl.bc_ppo import BCRegularizedPPO
    from gym_soarm.rl.imitation import Dataset

    folder: Path = source["_folder"]
    pretrained = PPO.load(folder / MODEL_FILE, device="cpu")
    if isinstance(venv, VecNormalize):
        # The pretrained actor's inputs: the demonstrations' statistics, updated from
        # there on (their count weighs them against PPO's own observations).
        with open(source["_normalizer"], "rb") as stream:
            venv.obs_rms = pickle.load(stream).obs_rms.copy()
    algo_kwargs = dict(settings["algo"])
    algo_kwargs["policy_kwargs"] = dict(pretrained.policy_kwargs)
    model = BCRegularizedPPO("MlpPolicy", venv, seed=seed, device="cpu", **algo_kwargs)
    model.policy.load_state_dict(pretrained.policy.state_dict())
    init = settings["init"]
    with torch.no_grad():
        model.policy.log_std.fill_(float(init["log_std"]))
    model.critic_warmup = int(init["critic_warmup"])
    if source["_demos"] is not None:
        demos = Dataset.load(source["_demos"])
        model.set_demonstrations(
            demos.obs, demos.actions, init["bc_coef"], init["bc_decay"], init["bc_batch_size"]
        )
    else:
        logger.warning("--init %s has no demonstrations: PPO without the BC term", folder)
    return model


def train(
    algo: str,
    task: str,
    out: str | os.PathLike[str],
    seed: int = 0,
    steps: int | None = None,
    eval_every: int | None = None,
    eval_episodes: int | None = None,
    progress_bar: bool = False,
    hyperparams: dict[str, Any] | None = None,
    vec_env: str | None = None,
    init: str | os.PathLike[str] | None = None,
    env: Mapping[str, Any] | None = None,
    vector_env: str | None = None,
    device: str = "cpu",
) -> TrainResult:
    """Train ``algo`` on ``task`` with the package's recipe and write its folder.

    Every argument is checked before anything is built or written. The wall time on the
    curve counts training and evaluation alike.

    Args:
        algo: ``"ppo"`` or ``"sac"``.
        task: a registered task (its name, alias or id).
        out: the output folder (created; files of an earlier run there are replaced).
        seed: the training seed (the algorithm's and the environments' resets).
        steps: environment steps (default: the recipe's).
        eval_every: environment steps between evaluations (default: the recipe's).
        eval_episodes: protocol episodes per evaluation (default: the recipe's).
        progress_bar: show SB3's progress bar (needs ``rich``/``tqdm``).
        hyperparams: values that replace the recipe's algorithm arguments
            (``{"learning_starts": 100}``); only keys the recipe has.
        vec_env: how the environments are stepped: ``"native"``, ``"dummy"`` or
            ``"subproc"`` (default: the recipe's, see :mod:`gym_soarm.rl.hyperparams`);
            the episodes and so the run are the same in all three.
        init: PPO only: a policy folder to start from (see the module's documentation).
        env: ``gym.make`` keywords over the recipe's environment (e.g. ``{"dynamics":
            PATH}``); checked as :class:`gym_soarm.envs.settings.EnvSettings` checks them, and
            stored in the folder's ``settings.json`` (evaluation uses them).
        vector_env: one of the package's vector envs (:data:`VECTOR_ENVS
            <gym_soarm.rl.hyperparams.VECTOR_ENVS>`): PPO on ``"batched"`` or ``"warp"``
            trains with RSL-RL (:mod:`gym_soarm.rl.rsl`, its own recipe), on
            ``"processes"`` (and SAC on any but ``"warp"``) with Stable-Baselines3 over it.
            None (default): the recipe's ``vec_env``.
        device: where RSL-RL's tensors live: ``"cpu"`` (default) or, with ``vector_env=
            "warp"``, the Warp env's device (``"cuda"``, ``"cuda:N"``).

    Raises:
        ValueError: unknown algorithm or task, a non-positive count, ``out`` a file, an
            ``init`` folder of another task, observation layout or environment setting.
        ImportError: Stable-Baselines3 is not installed (names the extra).
    """
    spec = get_task(task)  # ValueError naming the registered tasks
    vector_env = _check_vector_env(algo, vector_env, vec_env, device)
    if algo == "ppo" and vector_env in RSL_VECTOR_ENVS:
        return _train_rsl(
            spec, out, seed, steps, eval_every, eval_episodes, hyperparams, init, env,
            vector_env, device,
        )  # fmt: skip
    settings = _checked_settings(algo, spec, env, hyperparams, vec_env, init)
    if vector_env is not None:
        settings["vec_env"], settings["vector_env"] = "native", vector_env
    seed = check_int("seed", seed, 0)
    # None takes the recipe's value.
    steps = check_int("steps", settings["steps"] if steps is None else steps, 1)
    every = settings["eval_every"] if eval_every is None else eval_every
    eval_every = check_int("eval_every", every, 1)
    episodes = settings["eval_episodes"] if eval_episodes is None else eval_episodes
    episodes = check_int("eval_episodes", episodes, 1)
    out_path = Path(out)
    if out_path.exists() and not out_path.is_dir():
        raise ValueError(f"out must be a folder; {str(out_path)!r} is a file. Pass a new folder.")
    require_sb3()
    pyplot()  # imported before training, never in the middle of it
    progress_bar = _progress_bar(progress_bar)
    import torch

    # Small networks: one thread is as fast, and several threads slow down badly
    # (spinning) whenever other processes share the cores.
    torch.set_num_threads(settings["torch_threads"])
    env_kwargs = dict(settings["env"])
    folder, source = _start_folder(out_path, algo, spec, seed, steps, settings, init)
    venv = _vector_env(spec.name, env_kwargs, settings, seed)
    try:
        model = _model(algo, venv, seed, settings, source)
        run = _Run(folder, spec.name, env_kwargs, episodes, model)
        with folder:
            run.learn(steps, eval_every, progress_bar)
    finally:
        venv.close()
    return folder.result(model.num_timesteps, run.last_rate)


def _check_vector_env(
    algo: str, vector_env: str | None, vec_env: str | None, device: str
) -> str | None:
    """``vector_env`` checked (None: neither it nor a device was given): PPO on batched or
    warp trains with RSL-RL, the rest with Stable-Baselines3."""
    if vector_env is not None and vec_env is not None:
        raise ValueError(
            f"pass vector_env ({vector_env!r}) or the older vec_env ({vec_env!r}), not both."
        )
    if vector_env is None and device == "cpu":
        return None
    vector_env = check_choice("vector_env", vector_env or "batched", VECTOR_ENVS)
    if algo == "ppo" and vector_env in RSL_VECTOR_ENVS:
        return vector_env
    if device != "cpu":
        raise ValueError(
            f"device {device!r} applies to PPO on vector_env 'batched' or 'warp' "
            f"(RSL-RL); got --algo {algo} on {vector_env!r}. Drop --device."
        )
    if vector_env == "warp":
        raise ValueError(
            f"vector_env 'warp' trains PPO (RSL-RL) only; got --algo {algo}. "
            "Pass --algo ppo, or --vector-env batched."
        )
    return vector_env


def _progress_bar(wanted: bool) -> bool:
    """Whether SB3's progress bar can show (a warning when it was wanted and cannot)."""
    if wanted and importlib.util.find_spec("rich") is None:
        warnings.warn(
            "the progress bar needs rich (pip install rich, or the rl extra); training without it.",
            UserWarning,
            stacklevel=3,
        )
        return False
    return wanted


def _start_folder(
    out_path: Path,
    algo: str,
    spec: Any,
    seed: int,
    steps: int,
    settings: dict[str, Any],
    init: Any,
) -> tuple[RunFolder, dict[str, Any] | None]:
    """The run's folder with its ``settings.json``, and the checked ``--init`` folder's
    settings (None without one)."""
    env_kwargs = dict(settings["env"])
    observation_names = _observation_names(spec.name, env_kwargs)
    source = (
        None
        if init is None
        else _check_init(init, spec.name, env_kwargs, observation_names, settings["normalize"])
    )
    folder = RunFolder(out_path, f"{algo.upper()} on {spec.name}, seed {seed}", CURVE_FIELDS)
    folder.prepare((MODEL_FILE, NORMALIZE_FILE))
    folder.write_settings(
        SETTINGS_FILE,
        {
            "format": POLICY_FORMAT,
            "algo": algo,
            "task": spec.name,
            "seed": seed,
            "steps": steps,
            "env": env_kwargs,
            "observation_names": observation_names,
            "recipe": settings,
            **({} if init is None else {"init": str(init)}),
        },
    )
    return folder, source


def _observation_names(task: str, env_kwargs: dict[str, Any]) -> list[str]:
    """The names of the observation's values of ``task`` made with ``env_kwargs``."""
    probe = make_env(task, env_kwargs)
    try:
        return list(probe.unwrapped.observation_names)
    finally:
        probe.close()


def _checked_settings(
    algo: str,
    spec: Any,
    env: Mapping[str, Any] | None,
    hyperparams: dict[str, Any] | None,
    vec_env: str | None,
    init: Any,
) -> dict[str, Any]:
    """The recipe of ``algo`` on ``spec`` with the caller's changes, checked."""
    if algo in IMITATION:
        raise ValueError(
            f"algo {algo!r} is an imitation trainer: gym_soarm.rl.imitation.train_imitation "
            f"(python -m gym_soarm.train --algo {algo}); train() runs {', '.join(ALGORITHMS)}."
        )
    settings = recipe(algo, spec.name)  # ValueError naming the algorithms
    settings["env"] = merge_keywords(settings["env"], spec.name, env)
    if init is not None and algo != "ppo":
        raise ValueError(f"init (--init) starts PPO only; got --algo {algo}. Pass --algo ppo.")
    if vec_env is not None:
        settings["vec_env"] = check_choice("vec_env", vec_env, VEC_ENVS)
    override(settings, hyperparams, algo)
    return settings


def _vector_env(task: str, env_kwargs: dict[str, Any], settings: dict[str, Any], seed: int) -> Any:
    """The recipe's SB3 vector env (native, dummy or subproc), normalised if it says so."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import (
        DummyVecEnv,
        SubprocVecEnv,
        VecMonitor,
        VecNormalize,
    )

    if settings["vec_env"] == "native":
        from gym_soarm.rl.native import NativeVecEnv

        vector_env = settings.get("vector_env", "auto")
        native = NativeVecEnv(task, env_kwargs, settings["n_envs"], vector_env=vector_env)
        venv = VecMonitor(native)
        venv.seed(seed)
    else:
        vec_class = SubprocVecEnv if settings["vec_env"] == "subproc" else DummyVecEnv
        venv = make_vec_env(
            lambda: make_env(task, env_kwargs),
            n_envs=settings["n_envs"],
            seed=seed,
            vec_env_cls=vec_class,
        )
    if settings["normalize"]:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=settings["algo"]["gamma"])
    return venv


def _model(
    algo: str, venv: Any, seed: int, settings: dict[str, Any], source: dict[str, Any] | None
) -> Any:
    """A new SB3 model of the recipe, or PPO from the ``--init`` folder ``source``."""
    if source is not None:
        return _ppo_from(source, venv, seed, settings)
    import stable_baselines3 as sb3

    algo_class = {"ppo": sb3.PPO, "sac": sb3.SAC}[algo]
    return algo_class("MlpPolicy", venv, seed=seed, device="cpu", **settings["algo"])


def _train_rsl(
    spec: Any,
    out: str | os.PathLike[str],
    seed: int,
    steps: int | None,
    eval_every: int | None,
    eval_episodes: int | None,
    hyperparams: dict[str, Any] | None,
    init: str | os.PathLike[str] | None,
    env: Mapping[str, Any] | None,
    vector_env: str,
    device: str,
) -> TrainResult:
    """PPO with RSL-RL (see :func:`train`): the recipe checked, then the run."""
    from gym_soarm.rl.rsl import train_rsl
    from gym_soarm.rl.rsl_policy import require_rsl

    settings = rsl_recipe(spec.name)
    settings["env"] = merge_keywords(settings["env"], spec.name, env)
    override(settings, hyperparams, "ppo (RSL-RL)")
    seed = check_int("seed", seed, 0)
    steps = check_int("steps", settings["steps"] if steps is None else steps, 1)
    every = check_int("eval_every", settings["eval_every"] if eval_every is None else eval_every, 1)
    episodes = settings["eval_episodes"] if eval_episodes is None else eval_episodes
    episodes = check_int("eval_episodes", episodes, 1)
    device = _check_rsl_device(device, vector_env)
    settings.update(vector_env=vector_env, device=device, library=RSL_LIBRARY)
    if device.startswith("cuda"):
        settings["num_envs"] = settings["num_envs_cuda"]
    if settings["env"].get("obs_type") != "state":
        raise ValueError(
            f"PPO on RSL-RL learns from state observations; got obs_type "
            f"{settings['env'].get('obs_type')!r}. Drop --obs-type."
        )
    out_path = Path(out)
    if out_path.exists() and not out_path.is_dir():
        raise ValueError(f"out must be a folder; {str(out_path)!r} is a file. Pass a new folder.")
    source = None if init is None else _check_rsl_init(Path(init), spec.name, settings)
    require_rsl()
    pyplot()
    return train_rsl(spec, out_path, seed, settings, steps, every, episodes, source)


def _check_rsl_device(device: str, vector_env: str) -> str:
    """``device`` checked against ``vector_env``: the batched env lives on the CPU."""
    if not isinstance(device, str) or not (
        device == "cpu" or device == "cuda" or device.startswith("cuda:")
    ):
        raise ValueError(f"device must be 'cpu', 'cuda' or 'cuda:N'; got {device!r}.")
    if vector_env == "batched" and device != "cpu":
        raise ValueError(
            f"vector_env 'batched' steps on the CPU; got device {device!r}. Pass --device cpu, "
            "or --vector-env warp for a GPU."
        )
    if device.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise ValueError(
                f"device {device!r}: torch sees no CUDA device here. Pass --device cpu."
            )
    return device


def _check_rsl_init(folder: Path, task: str, settings: dict[str, Any]) -> Path:
    """An ``--init`` folder for RSL-RL, checked against the run's task and settings: one
    it trained (the run continues it, with its network), or a BC, DAgger or PPO folder of
    Stable-Baselines3 (:mod:`gym_soarm.rl.rsl_init`: the run takes its actor's network and
    freezes its observation statistics). ``settings`` is updated to match."""
    from gym_soarm.rl.rsl_init import read_sb3_actor

    env_kwargs = settings["env"]
    source = read_settings(folder)  # ValueError: not a policy folder
    if source.get("library") != RSL_LIBRARY:
        _check_init(folder, task, env_kwargs, _observation_names(task, env_kwargs), normalize=True)
        actor = read_sb3_actor(folder)
        settings["algo"].update(hidden_dims=actor.hidden_dims, activation=actor.activation)
        settings["frozen_actor_normalizer"] = True
        return folder
    if not (folder / RSL_MODEL_FILE).is_file():
        raise ValueError(f"--init {str(folder)!r} has no {RSL_MODEL_FILE}; it did not finish.")
    if get_task(source["task"]).name != task or source["env"] != env_kwargs:
        raise ValueError(
            f"--init {str(folder)!r} was trained on {source['task']} with {source['env']}; "
            f"this run is {task} with {env_kwargs}. Start from a folder of the same task and settings."
        )
    for key in ("hidden_dims", "activation", "obs_normalization"):
        settings["algo"][key] = source["recipe"]["algo"][key]
    if source["recipe"].get("frozen_actor_normalizer"):
        settings["frozen_actor_normalizer"] = True
    return folder
