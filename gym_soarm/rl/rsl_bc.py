"""RSL-RL's PPO with a behaviour-cloning term, for runs started from a BC or DAgger folder
(``--init DIR``, :mod:`gym_soarm.rl.rsl_init`). Imports torch and RSL-RL: import it lazily.

Plain PPO from a pretrained actor unlearns it: on Lift, seed 0, the BC actor scored 100 %
before the first update and 10 % after 1 M steps of PPO, its deterministic return falling
from 194 to 51. As :class:`gym_soarm.rl.bc_ppo.BCRegularizedPPO` does for
Stable-Baselines3, each PPO update here is followed by as many gradient steps (epochs
times minibatches) on ``bc_coef * MSE(actor mean(obs), expert action)`` over minibatches
of the folder's demonstrations (``demos.npz``); ``bc_coef`` is then multiplied by
``bc_decay``. The demonstrations are raw observations: the actor's own, frozen
normaliser reads them, as it reads the environment's.
"""

from __future__ import annotations

import numpy as np
import torch
from rsl_rl.algorithms import PPO
from tensordict import TensorDict

from gym_soarm.rl.cloning import clone_steps
from gym_soarm.rl.rsl_policy import OBS_GROUP


class BCRegularizedPPO(PPO):
    """RSL-RL's ``PPO`` and the behaviour-cloning term of the module's documentation
    (off until :meth:`set_demonstrations`)."""

    demo_obs: torch.Tensor | None = None
    demo_actions: torch.Tensor | None = None
    bc_coef: float = 0.0
    bc_decay: float = 1.0
    bc_batch_size: int = 256

    def set_demonstrations(
        self, obs: np.ndarray, actions: np.ndarray, coef: float, decay: float, batch_size: int
    ) -> None:
        self.demo_obs = torch.as_tensor(np.asarray(obs, np.float32), device=self.device)
        self.demo_actions = torch.as_tensor(np.asarray(actions, np.float32), device=self.device)
        self.bc_coef, self.bc_decay, self.bc_batch_size = float(coef), float(decay), int(batch_size)

    def update(self) -> dict[str, float]:
        losses = super().update()
        actor_learns = any(p.requires_grad for p in self.actor.parameters())
        if self.demo_obs is not None and self.bc_coef > 0 and actor_learns:
            losses["bc"] = self._clone(self.num_learning_epochs * self.num_mini_batches)
            losses["bc_coef"] = self.bc_coef
            self.bc_coef *= self.bc_decay
        return losses

    def _clone(self, steps: int) -> float:
        """``steps`` gradient steps of the BC term; their mean loss."""
        losses = clone_steps(
            lambda obs: self.actor(TensorDict({OBS_GROUP: obs}, batch_size=[len(obs)])),
            self.actor.parameters, self.optimizer, self.demo_obs, self.demo_actions,
            self.bc_coef, self.bc_batch_size, steps, self.max_grad_norm,
        )  # fmt: skip
        return sum(losses) / steps


__all__ = ["BCRegularizedPPO"]
