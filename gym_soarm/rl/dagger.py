"""One DAgger loop for every student the state expert teaches (state vectors or pixels).

:class:`ImitationTrainer` runs behaviour cloning and DAgger in a :class:`RunFolder
<gym_soarm.rl.runs.RunFolder>`:

1. **Round 0**: ``demos`` episodes of the expert with DART noise (the executed action is
   the expert's plus Gaussian noise of ``dart_std``, clipped to [-1, 1]; the stored label is
   the clean action), then ``epochs`` passes of regression; the student is evaluated on
   ``eval_episodes`` validation episodes.
2. **DAgger rounds** r = 1 .. ``rounds``: ``episodes_per_round`` episodes in which each
   step executes the expert's action with probability ``beta0 * beta_decay ** r`` and the
   student's otherwise; the expert labels every state; the student goes on from where it
   was (warm start) for ``round_epochs`` passes over everything gathered and is evaluated
   (on the validation episodes, seeds :data:`VALIDATION_SEED
   <gym_soarm.rl.runs.VALIDATION_SEED>` + k: the protocol's stay unseen for the report).
   The rounds stop early once ``patience`` rounds in a row failed to beat the best
   evaluation (the recipe's ``patience``, where it has one) or at 100 %.
3. The folder keeps the round that scored best (the latest among equals).

The episodes run side by side in a ``SyncVectorEnv`` of the recipe's environment, with
Gymnasium's autoreset disabled: each episode starts from its own training seed
(:func:`training_seeds <gym_soarm.rl.runs.training_seeds>`), and the task's state expert
(``make_expert(vector_env)``) labels the whole batch in one call. An environment with no
episode left to start goes on stepping (a vector env steps all of them) but stores nothing.
The validation episodes run on the same vector env, the student acting alone
(:meth:`ImitationTrainer.validate`).

A subclass says what the student is: how a step is stored (:meth:`record`), how the
student acts (:meth:`student_actions`), how it is built (:meth:`start_learning`), trained
(:meth:`fit`) and saved (:meth:`save`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm.expert import make_expert
from gym_soarm.rl.curves import TrainResult
from gym_soarm.rl.evaluation import POLICY_FORMAT, SETTINGS_FILE, make_env
from gym_soarm.rl.runs import (
    TRAINING_SEEDS,
    VALIDATION_SEED,
    RunFolder,
    dart_noise,
    learning_rates,
    training_seeds,
)

logger = logging.getLogger(__name__)


def env_info(infos: dict[str, Any], index: int) -> dict[str, Any]:
    """Environment ``index``'s info out of a vector env's (keys it has, ``_key`` masks)."""
    out: dict[str, Any] = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos.get(f"_{key}")
        if mask is not None and not mask[index]:
            continue
        out[key] = env_info(value, index) if isinstance(value, dict) else value[index]
    return out


class Gathering:
    """The episodes of one round on a vector env: which environment plays which episode,
    the observations and infos now, starting the next seed where an episode ended."""

    def __init__(self, venv: gym.vector.VectorEnv, seeds: list[int], first_episode: int) -> None:
        self.venv, self.pending = venv, list(seeds)
        n = venv.num_envs
        self.episode = np.full(n, -1, np.int64)
        self.next_episode = first_episode
        self.infos: list[dict[str, Any]] = [{} for _ in range(n)]
        self.obs: Any = None
        self.successes = self.finished = self.stepped = 0
        self.returns: list[float] = []
        self._return = np.zeros(n)
        self.start(np.ones(n, np.bool_))

    @property
    def live(self) -> np.ndarray:
        """The environments playing a stored episode."""
        return self.episode >= 0

    def start(self, mask: np.ndarray) -> None:
        """Reset the environments of ``mask``: the next pending seeds, then spare resets
        whose steps are not stored."""
        seeds: list[int | None] = [None] * len(mask)
        for i in np.flatnonzero(mask):
            if self.pending:
                seeds[i] = self.pending.pop(0)
                self.episode[i] = self.next_episode
                self.next_episode += 1
            else:
                self.episode[i] = -1
        self.obs, infos = self.venv.reset(seed=seeds, options={"reset_mask": mask.copy()})
        for i in np.flatnonzero(mask):
            self.infos[i] = env_info(infos, i)

    def step(self, actions: np.ndarray) -> np.ndarray:
        """Step every environment; returns the mask of those whose episode ended (each
        already reset: to the next seed, or a spare reset)."""
        live = self.live
        self.obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        self.stepped += len(live)
        self._return += np.where(live, rewards, 0.0)
        ended = np.logical_or(terminated, truncated)
        for i in range(len(ended)):
            self.infos[i] = env_info(infos, i)
            if ended[i] and live[i]:
                self.finished += 1
                self.successes += bool(self.infos[i].get("is_success", False))
                self.returns.append(float(self._return[i]))
        self._return[ended] = 0.0
        if ended.any():
            self.start(ended)
        return ended


class ImitationTrainer:
    """Behaviour cloning and DAgger of a student (a subclass) from the task's state expert.

    Args:
        algo: ``"bc"`` or ``"dagger"``.
        spec: the task's spec (with a state expert).
        folder: the run's folder (made, its Ctrl-C handling entered by the caller).
        seed: the training seed (the network, the noise, the training episodes' resets).
        settings: the checked recipe (``env``, ``n_envs``, ``algo`` ...).
        device: where the student trains.
    """

    rng_stream = 22
    """The second word of the noise generator's seed (``[seed, rng_stream]``)."""

    def __init__(
        self,
        algo: str,
        spec: Any,
        folder: RunFolder,
        seed: int,
        settings: dict[str, Any],
        device: str = "cpu",
    ) -> None:
        self.algo, self.spec, self.folder, self.seed = algo, spec, folder, seed
        self.settings, self.params, self.device = settings, settings["algo"], device
        self.env_kwargs = dict(settings["env"])
        self.rng = np.random.default_rng([seed, self.rng_stream])
        self.env_steps = self.episodes = self.fits = 0
        self.best = -1.0
        self.learning = False
        self.venv: gym.vector.VectorEnv | None = None
        self.title = f"{algo} on {spec.name}, seed {seed}"
        self.setup()
        folder.title = self.title

    def setup(self) -> None:
        """The student's own state (a subclass's), made at the end of ``__init__``."""

    @property
    def out_path(self) -> Path:
        return self.folder.path

    def stop(self) -> bool:
        return self.folder.stop()

    # ----------------------------------------------------------------------- the loop
    def run(self) -> TrainResult:
        """Train (see the module's documentation) and return the run's result."""
        self.venv = self.make_vector_env()
        try:
            self.expert = make_expert(self.venv)
            self.write_settings()
            self.gather(0, self.params["demos"], 1.0)
            if self.stored() and not self.stop():
                self.start_learning()
                self.learning = True
                self.train_round(0, self.params["epochs"])
                if self.algo == "dagger":
                    self.dagger_rounds()
            if self.stop():
                logger.warning("%s: interrupted; the checkpoint and the curve are kept", self.title)
                self.on_interrupt()
        finally:
            self.venv.close()
        # The folder holds the best round: its rate is the run's.
        return self.folder.result(self.env_steps, self.best if self.best >= 0 else None)

    def make_vector_env(self) -> gym.vector.VectorEnv:
        """``n_envs`` of the recipe's environment side by side, autoreset disabled."""
        name, kwargs = self.spec.name, self.env_kwargs
        venv = gym.vector.SyncVectorEnv(
            [lambda: make_env(name, kwargs) for _ in range(self.settings["n_envs"])],
            autoreset_mode=gym.vector.AutoresetMode.DISABLED,
        )
        self.observation_names = list(venv.envs[0].unwrapped.observation_names)
        return venv

    def dagger_rounds(self) -> None:
        params, since_best = self.params, 0
        patience = params.get("patience", params["rounds"])
        for round_ in range(1, params["rounds"] + 1):
            if self.stop() or self.best >= 1.0 or since_best >= patience:
                return
            best = self.best
            beta = params["beta0"] * params["beta_decay"] ** round_
            self.gather(round_, params["episodes_per_round"], beta)
            if self.stop():
                return
            self.train_round(round_, params["round_epochs"])
            since_best = 0 if self.best > best else since_best + 1

    def train_round(self, round_: int, epochs: int) -> None:
        loss = self.fit(epochs)
        if self.stop():
            return
        episodes = self.settings["eval_episodes"]
        rate, mean_return = self.validate(episodes)
        self.folder.add_row(
            {
                "round": round_,
                "env_steps": self.env_steps,
                "samples": self.stored(),
                "success_rate": rate,
                "mean_return": round(mean_return, 4),
                "episodes": episodes,
            }
        )
        if rate >= self.best:  # DAgger keeps its best round
            self.best = rate
            self.save()
        self.after_evaluation()
        self.write_settings()
        logger.info(
            "%s: round %d, %d samples, loss %.4f, %.0f s, success %.0f %%",
            self.title, round_, self.stored(), loss, self.folder.wall_s(), 100 * rate,
        )  # fmt: skip

    def validate(self, episodes: int) -> tuple[float, float]:
        """The student alone on ``episodes`` validation episodes (seeds
        :data:`VALIDATION_SEED <gym_soarm.rl.runs.VALIDATION_SEED>` + k), played side by
        side on the trainer's vector env with its actions computed in one batch; nothing
        is stored. Returns the success rate and the mean return."""
        run = Gathering(self.venv, [VALIDATION_SEED + k for k in range(episodes)], 0)
        everyone = np.ones(self.venv.num_envs, np.bool_)
        self.begin_episodes(run, everyone)  # the spare resets too: the student drives them
        while run.live.any():
            actions = self.student_actions(run, everyone)
            before = run.obs
            reset = run.step(actions)
            self.after_step(before, actions)
            if reset.any():
                self.begin_episodes(run, reset)
        return run.successes / run.finished, float(np.mean(run.returns))

    def fit_rates(self, epochs: int, samples: int) -> Callable[[int, int], float]:
        """The learning rate of each optimiser step of the next fit, ``epochs`` passes over
        ``samples`` in minibatches of the recipe's ``batch_size``
        (:func:`learning_rates <gym_soarm.rl.runs.learning_rates>`: the first fit is
        round 0's); counts the fit."""
        steps = -(-samples // self.params["batch_size"])
        rate = learning_rates(self.params, epochs, steps, first=self.fits == 0)
        self.fits += 1
        return rate

    # ----------------------------------------------------------------------- gathering
    def gather(self, round_: int, episodes: int, beta: float) -> None:
        """Play ``episodes`` training episodes of round ``round_``, storing every step with
        the expert's label; a share ``1 - beta`` of the steps executes the student's action."""
        began, steps_before = time.perf_counter(), self.env_steps
        run = Gathering(self.venv, training_seeds(self.seed, round_, episodes), self.episodes)
        self.begin_episodes(run, run.live)
        use_student = self.learning and beta < 1.0
        while run.live.any() and not self.stop():
            live = run.live
            labels = np.clip(np.asarray(self.expert(run.obs, None), np.float32), -1.0, 1.0)
            executed = dart_noise(labels, self.params["dart_std"], self.rng)
            if use_student:
                student = (self.rng.random(len(live)) >= beta) & live
                if student.any():
                    executed = executed.copy()
                    executed[student] = self.student_actions(run, student)
            self.record(run, live, labels, executed, round_)
            before = run.obs
            reset = run.step(executed)
            self.env_steps += int(live.sum())
            self.after_step(before, executed)
            if reset.any():
                self.begin_episodes(run, reset)
        self.episodes = run.next_episode
        seconds = time.perf_counter() - began
        stored = self.env_steps - steps_before
        logger.info(
            "%s: round %d gathered %d episodes (the expert acting with probability %.2f), "
            "%d of them successful; "
            "%d steps stored in %.0f s (%.0f a second, %d environment steps in all)",
            self.title, round_, run.finished, beta, run.successes, stored, seconds,
            stored / max(seconds, 1e-9), run.stepped,
        )  # fmt: skip

    def begin_episodes(self, run: Gathering, mask: np.ndarray) -> None:
        """Called when the environments of ``mask`` start an episode."""

    def after_step(self, before: Any, executed: np.ndarray) -> None:
        """Called after each step of the vector env (before the ended episodes'
        :meth:`begin_episodes`): ``before`` the observations the actions ``executed``
        were chosen on."""

    def after_evaluation(self) -> None:
        """Called after each evaluation (and the save of a best round)."""

    def on_interrupt(self) -> None:
        """Ctrl-C: keep what there is."""
        self.save()

    # ----------------------------------------------------------------------- the student
    def stored(self) -> int:
        """The number of steps stored."""
        raise NotImplementedError

    def record(
        self, run: Gathering, live: np.ndarray, labels: Any, executed: Any, round_: int
    ) -> None:
        """Store the steps of the environments of ``live`` (before they are stepped)."""
        raise NotImplementedError

    def student_actions(self, run: Gathering, mask: np.ndarray) -> np.ndarray:
        """The student's actions for the environments of ``mask``."""
        raise NotImplementedError

    def start_learning(self) -> None:
        """Build the student from the demonstrations (normalisation, network, optimiser)."""
        raise NotImplementedError

    def fit(self, epochs: int) -> float:
        """``epochs`` passes of regression over everything stored; the last pass's loss."""
        raise NotImplementedError

    def save(self) -> None:
        """Write the student's checkpoint into the folder."""
        raise NotImplementedError

    def extra_settings(self) -> dict[str, Any]:
        """What the student's ``settings.json`` holds beyond every imitation run's fields."""
        return {}

    def write_settings(self) -> None:
        """Write the folder's ``settings.json`` (format ``gym_soarm.policy/1``)."""
        self.folder.write_settings(
            SETTINGS_FILE,
            {
                "format": POLICY_FORMAT,
                "algo": self.algo,
                "task": self.spec.name,
                "seed": self.seed,
                "steps": self.env_steps,
                "env": self.env_kwargs,
                "observation_names": self.observation_names,
                "recipe": self.settings,
                "training_seeds": TRAINING_SEEDS,
                "validation_seed": VALIDATION_SEED,
                **self.extra_settings(),
            },
        )


__all__ = ["Gathering", "ImitationTrainer", "env_info"]
