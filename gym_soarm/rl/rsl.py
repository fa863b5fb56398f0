"""PPO on RSL-RL over the package's own vector envs (``--vector-env batched|warp``).

:class:`RslVecEnv` shows a native vector env (:func:`gym_soarm.vector.batched.make_vector_env`:
the batched ``mujoco.batch`` env on the CPU, or the MuJoCo Warp env on a device) through
RSL-RL's ``VecEnv`` interface: the observations as a ``TensorDict`` of one group
(``"policy"``, read by the actor and the critic), rewards and dones as torch tensors on the
env's device, an ended episode reset inside ``step`` (Gymnasium's ``SAME_STEP`` autoreset:
the returned observation is the next episode's first) and ``extras["time_outs"]`` marking
the episodes cut by the time limit, so that PPO bootstraps their value.

:func:`train_rsl` runs RSL-RL's ``OnPolicyRunner`` in chunks of iterations, evaluating the
deterministic actor on the protocol between chunks, in a :class:`RunFolder
<gym_soarm.rl.runs.RunFolder>` like every trainer of the package:

* ``model.pt``: RSL-RL's checkpoint (actor with its observation normaliser, critic,
  optimiser; ``runner.load`` reads it, :func:`load_actor` the actor alone, which is what
  :class:`gym_soarm.rl.evaluation.TrainedPolicy` acts with);
* ``settings.json`` (format ``gym_soarm.policy/1``, ``"library": "rsl_rl"``), ``curve.csv``
  and ``curve.png``.

Needs the ``rl`` extra (``rsl-rl-lib`` 5.x and its ``tensordict``).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.rl.cloning import frozen
from gym_soarm.rl.curves import CURVE_FIELDS, TrainResult
from gym_soarm.rl.evaluation import POLICY_FORMAT, SETTINGS_FILE, score
from gym_soarm.rl.rsl_init import freeze_normalizer, start_from_sb3
from gym_soarm.rl.rsl_policy import (
    OBS_GROUP,
    RSL_LIBRARY,
    RSL_MODEL_FILE,
    acting,
    require_rsl,
    runner_config,
)
from gym_soarm.rl.runs import RunFolder
from gym_soarm.tasks.suites import EVAL_SEED

logger = logging.getLogger(__name__)

RSL_VECTOR_ENVS: tuple[str, ...] = ("batched", "warp")
"""The vector envs PPO trains on with RSL-RL (the others keep Stable-Baselines3)."""


def _vec_env_base() -> type:
    require_rsl()
    from rsl_rl.env import VecEnv

    return VecEnv


class RslVecEnv:
    """``num_envs`` environments of ``task`` in a native vector env, as RSL-RL's ``VecEnv``.

    Built by :func:`make_rsl_env` (which makes it a subclass of ``rsl_rl.env.VecEnv``
    without importing RSL-RL with this module).

    Args:
        task: a registered task's name.
        env_kwargs: ``gym.make``'s keywords for each environment (state observations).
        num_envs: environments stepped together.
        vector_env: ``"batched"`` (the CPU) or ``"warp"`` (MuJoCo Warp on ``device``).
        device: where the tensors live: ``"cpu"`` for the batched env; the Warp env's
            device for ``"warp"``.
        seed: environment ``i`` is first reset with ``seed + i``.
    """

    def __init__(
        self,
        task: str,
        env_kwargs: dict[str, Any],
        num_envs: int,
        vector_env: str = "batched",
        device: str = "cpu",
        seed: int = 0,
    ) -> None:
        import torch
        from gymnasium.vector import AutoresetMode

        from gym_soarm.tasks import get_task
        from gym_soarm.vector.batched import make_vector_env

        spec = get_task(task)
        extra = {"device": device} if vector_env == "warp" else {}
        self.vector = make_vector_env(
            num_envs,
            vector_env=vector_env,
            max_episode_steps=spec.max_episode_steps,
            autoreset_mode=AutoresetMode.SAME_STEP,
            task=spec.name,
            **env_kwargs,
            **extra,
        )
        self.num_envs = num_envs
        self.num_actions = int(self.vector.single_action_space.shape[0])
        self.max_episode_length = spec.max_episode_steps
        self.device = torch.device(device)
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        self.cfg = {"task": spec.name, "env": dict(env_kwargs), "vector_env": vector_env}
        obs, _ = self.vector.reset(seed=[seed + i for i in range(num_envs)])
        self._obs = self._tensor(obs)

    def _tensor(self, array: Any, dtype: Any = None) -> Any:
        """``array`` as a torch tensor on the env's device (no copy where it already is)."""
        import torch

        tensor = torch.as_tensor(array, device=self.device)
        return tensor.to(dtype or torch.float32)

    def get_observations(self) -> Any:
        from tensordict import TensorDict

        return TensorDict({OBS_GROUP: self._obs}, batch_size=[self.num_envs], device=self.device)

    def step(self, actions: Any) -> tuple[Any, Any, Any, dict[str, Any]]:
        """Step every environment with ``actions`` (``(num_envs, num_actions)``); an ended
        episode is reset here. ``extras`` holds ``time_outs`` and ``log["/success"]`` (the
        share of the episodes ended in this step that succeeded, where any ended)."""
        import torch

        chosen = actions.detach().to("cpu").numpy() if torch.is_tensor(actions) else actions
        obs, rewards, terminated, truncated, info = self.vector.step(np.asarray(chosen))
        terminated, truncated = np.asarray(terminated), np.asarray(truncated)
        ended = terminated | truncated
        self._obs = self._tensor(obs)
        dones = self._tensor(ended, torch.long)
        self.episode_length_buf += 1
        self.episode_length_buf[dones.bool()] = 0
        extras: dict[str, Any] = {
            "time_outs": self._tensor(truncated & ~terminated),
            "log": {},
        }
        final = info.get("final_info", {})
        if ended.any() and "is_success" in final:
            extras["log"]["/success"] = float(np.mean(np.asarray(final["is_success"])[ended]))
        return self.get_observations(), self._tensor(rewards), dones, extras

    def close(self) -> None:
        self.vector.close()


def make_rsl_env(*args: Any, **kwargs: Any) -> RslVecEnv:
    """A :class:`RslVecEnv` that is also an ``rsl_rl.env.VecEnv`` (see its arguments)."""
    base = _vec_env_base()
    cls = type("RslVecEnv", (RslVecEnv, base), {"__module__": __name__})
    return cls(*args, **kwargs)


class RslTrainer:
    """One PPO run of RSL-RL in ``folder`` (see :func:`train_rsl`)."""

    def __init__(
        self,
        spec: Any,
        folder: RunFolder,
        seed: int,
        settings: dict[str, Any],
        device: str,
        init: Path | None = None,
    ) -> None:
        import torch
        from rsl_rl.runners import OnPolicyRunner

        self.spec, self.folder, self.seed, self.settings = spec, folder, seed, settings
        self.init = init
        self.device = device
        self.env_kwargs = dict(settings["env"])
        torch.manual_seed(seed)
        self.env = make_rsl_env(
            spec.name, self.env_kwargs, settings["num_envs"], settings["vector_env"],
            device, seed,
        )  # fmt: skip
        config = runner_config(settings["algo"])
        from_sb3 = init is not None and not (init / RSL_MODEL_FILE).is_file()
        if from_sb3:  # a BC, DAgger or PPO folder of Stable-Baselines3
            from gym_soarm.rl.rsl_bc import BCRegularizedPPO

            config["algorithm"]["class_name"] = BCRegularizedPPO
        self.runner = OnPolicyRunner(self.env, config, log_dir=None, device=device)
        self.critic_warmup = 0  # iterations in which only the critic learns
        if init is not None and not from_sb3:
            self.runner.load(str(init / RSL_MODEL_FILE), map_location=device)
        elif from_sb3:
            start_from_sb3(self.runner.alg, init, settings["init"])
            self.critic_warmup = int(settings["init"]["critic_warmup"])
        if settings.get("frozen_actor_normalizer"):
            freeze_normalizer(self.runner.alg.actor)
        self.steps_per_iteration = settings["num_envs"] * config["num_steps_per_env"]
        self.env_steps = 0
        self.last_rate: float | None = None

    def policy(self) -> Any:
        """The deterministic actor as ``policy(obs, info) -> action`` for :func:`score`."""
        act = acting(self.runner.alg.get_policy(), self.device)
        return lambda obs, info: act(obs)

    def learn(self, steps: int, eval_every: int, episodes: int) -> None:
        """Train for ``steps`` environment steps, evaluating every ``eval_every`` (and once
        before the first update when the actor came from an ``--init`` folder)."""
        if self.critic_warmup:
            self.evaluate(episodes, save=False)  # RSL-RL saves only once it has learned
            self.warm_critic(self.critic_warmup)
        while self.env_steps < steps and not self.folder.stop():
            chunk = min(eval_every, steps - self.env_steps)
            self.iterate(-(-chunk // self.steps_per_iteration))  # whole iterations, rounded up
            self.evaluate(episodes)
        rows = self.folder.rows
        if self.env_steps and (not rows or rows[-1]["env_steps"] != self.env_steps):
            self.evaluate(episodes)  # a warm-up that ran past ``steps``
        self.save()

    def iterate(self, iterations: int) -> None:
        self.runner.learn(iterations)
        self.runner.current_learning_iteration += 1
        self.env_steps += iterations * self.steps_per_iteration

    def warm_critic(self, iterations: int) -> None:
        """``iterations`` of PPO in which the actor's parameters stay as they are; the
        learning rate then restarts from the recipe's (the adaptive schedule saw no KL)."""
        alg = self.runner.alg
        with frozen(alg.actor.parameters()):
            self.iterate(iterations)
        alg.learning_rate = float(self.settings["algo"]["learning_rate"])
        for group in alg.optimizer.param_groups:
            group["lr"] = alg.learning_rate
        logger.info("%s: the critic learned alone for %d iterations", self.folder.title, iterations)

    def evaluate(self, episodes: int, save: bool = True) -> None:
        self.runner.alg.eval_mode()
        result = score(self.spec.name, self.env_kwargs, self.policy(), episodes, EVAL_SEED)
        self.runner.alg.train_mode()
        self.last_rate = result["success_rate"]
        self.folder.add_row(
            {
                "env_steps": self.env_steps,
                "success_rate": self.last_rate,
                "mean_return": round(result["mean_return"], 4),
                "episodes": episodes,
            }
        )
        if save:
            self.save()
        logger.info(
            "%s: %d steps, %.0f s, success %.0f %%",
            self.folder.title, self.env_steps, self.folder.wall_s(), 100 * self.last_rate,
        )  # fmt: skip

    def save(self) -> None:
        path = self.folder.path
        self.runner.save(str(path / RSL_MODEL_FILE))
        self.folder.write_settings(
            SETTINGS_FILE,
            {
                "format": POLICY_FORMAT,
                "algo": "ppo",
                "library": RSL_LIBRARY,
                "task": self.spec.name,
                "seed": self.seed,
                "steps": self.env_steps,
                "env": self.env_kwargs,
                "observation_names": list(self.observation_names()),
                "recipe": self.settings,
                **({} if self.init is None else {"init": str(self.init)}),
            },
        )

    def observation_names(self) -> list[str]:
        envs = getattr(self.env.vector, "observation_names", None)
        if envs is not None:
            return list(envs)
        return list(self.env.vector.get_attr("observation_names")[0])

    def close(self) -> None:
        self.env.close()


def train_rsl(
    spec: Any,
    out: str | os.PathLike[str],
    seed: int,
    settings: dict[str, Any],
    steps: int,
    eval_every: int,
    episodes: int,
    init: Path | None = None,
) -> TrainResult:
    """Train PPO with RSL-RL on ``settings["vector_env"]`` (checked by the caller) and
    write the folder ``out`` (see the module's documentation)."""
    import torch

    require_rsl()
    torch.set_num_threads(settings["torch_threads"])
    folder = RunFolder(out, f"PPO (RSL-RL) on {spec.name}, seed {seed}", CURVE_FIELDS)
    folder.prepare((RSL_MODEL_FILE, SETTINGS_FILE))
    trainer = RslTrainer(spec, folder, seed, settings, settings["device"], init)
    try:
        with folder:
            trainer.learn(steps, eval_every, episodes)
    finally:
        trainer.close()
    return folder.result(trainer.env_steps, trainer.last_rate)


__all__ = ["RSL_VECTOR_ENVS", "RslVecEnv", "make_rsl_env", "train_rsl"]
