"""PPO from a pretrained policy with a behaviour-cloning term: :class:`BCRegularizedPPO`,
the model of ``python -m gym_soarm.train --algo ppo --init DIR`` (see
:mod:`gym_soarm.rl.training`). Imports Stable-Baselines3 and torch: import it lazily."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3 import PPO

from gym_soarm.rl.cloning import clone_steps, frozen
from gym_soarm.rl.imitation import actor_mean, actor_parameters


class BCRegularizedPPO(PPO):
    """PPO with a behaviour-cloning term on the actor.

    After each PPO update (:meth:`train`), as many gradient steps as the update took
    (``n_epochs`` passes of minibatches), each on ``bc_coef * MSE(actor mean(obs), expert
    action)`` over a minibatch of ``bc_batch_size`` demonstrations; ``bc_coef`` is then
    multiplied by ``bc_decay``. The demonstrations' raw observations are normalised with
    the environment's current statistics (a ``VecNormalize``) at each update. Its
    ``model.zip`` loads with SB3's ``PPO.load``.
    """

    demo_obs: np.ndarray | None = None
    demo_actions: np.ndarray | None = None
    bc_coef: float = 0.0
    bc_decay: float = 1.0
    bc_batch_size: int = 256
    critic_warmup: int = 0
    """PPO updates left in which only the value branch learns (the actor's parameters
    frozen): a pretrained actor with an untrained critic would otherwise be pushed by the
    critic's noise."""

    def actor_parameters(self) -> list[Any]:
        """The parameters of the actor (its branch, action head and log std)."""
        return [*actor_parameters(self.policy), self.policy.log_std]

    def set_demonstrations(
        self,
        obs: np.ndarray,
        actions: np.ndarray,
        bc_coef: float,
        bc_decay: float,
        bc_batch_size: int,
    ) -> None:
        self.demo_obs = np.asarray(obs, np.float32)
        self.demo_actions = np.asarray(actions, np.float32)
        self.bc_coef = float(bc_coef)
        self.bc_decay = float(bc_decay)
        self.bc_batch_size = int(bc_batch_size)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "demo_obs", "demo_actions"]

    def train(self) -> None:
        if self.critic_warmup > 0:
            self._train_critic_alone()
            return
        super().train()
        if self.demo_obs is None or not len(self.demo_obs) or self.bc_coef <= 0:
            return
        losses = self._clone(self._bc_steps())
        self.logger.record("train/bc_loss", float(np.mean(losses)))
        self.logger.record("train/bc_coef", self.bc_coef)
        self.bc_coef *= self.bc_decay

    def _train_critic_alone(self) -> None:
        with frozen(self.actor_parameters()):
            super().train()
        self.critic_warmup -= 1
        self.logger.record("train/critic_warmup_left", self.critic_warmup)

    def _bc_steps(self) -> int:
        """As many gradient steps as the PPO update took."""
        buffer = self.rollout_buffer
        return self.n_epochs * max(1, buffer.buffer_size * buffer.n_envs // self.batch_size)

    def _clone(self, steps: int) -> list[float]:
        """``steps`` gradient steps of the BC term; their losses."""
        normalizer = self.get_vec_normalize_env()
        obs = self.demo_obs if normalizer is None else normalizer.normalize_obs(self.demo_obs)
        x = torch.as_tensor(np.asarray(obs, np.float32), device=self.device)
        y = torch.as_tensor(self.demo_actions, device=self.device)
        self.policy.set_training_mode(True)
        try:
            return clone_steps(
                lambda batch: actor_mean(self.policy, batch), self.policy.parameters,
                self.policy.optimizer, x, y, self.bc_coef, self.bc_batch_size, steps,
                self.max_grad_norm,
            )  # fmt: skip
        finally:
            self.policy.set_training_mode(False)


__all__ = ["BCRegularizedPPO"]
