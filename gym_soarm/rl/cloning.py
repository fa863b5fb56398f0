"""What PPO started from a pretrained policy needs on either library (Stable-Baselines3's
:class:`gym_soarm.rl.bc_ppo.BCRegularizedPPO`, RSL-RL's :class:`gym_soarm.rl.rsl_bc.BCRegularizedPPO`):
the actor frozen while the critic warms up, and the gradient steps of the behaviour-cloning
term. Imports torch only when called."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator
from typing import Any


@contextlib.contextmanager
def frozen(parameters: Iterable[Any]) -> Iterator[None]:
    """``parameters`` take no gradient inside the block (an optimiser leaves them alone)."""
    parameters = list(parameters)
    for parameter in parameters:
        parameter.requires_grad_(False)
    try:
        yield
    finally:
        for parameter in parameters:
            parameter.requires_grad_(True)


def clone_steps(
    predict: Callable[[Any], Any],
    parameters: Callable[[], Iterable[Any]],
    optimizer: Any,
    obs: Any,
    actions: Any,
    coef: float,
    batch_size: int,
    steps: int,
    max_grad_norm: float,
) -> list[float]:
    """``steps`` gradient steps on ``coef * MSE(predict(obs), actions)``, each over a
    random minibatch of ``batch_size`` rows of the tensors ``obs`` and ``actions``, the
    gradient of ``parameters()`` clipped to ``max_grad_norm``; the unweighted losses."""
    import torch

    size = min(batch_size, len(obs))
    losses = []
    for _ in range(steps):
        index = torch.randint(len(obs), (size,), device=obs.device)
        loss = torch.nn.functional.mse_loss(predict(obs[index]), actions[index])
        optimizer.zero_grad()
        (coef * loss).backward()
        torch.nn.utils.clip_grad_norm_(parameters(), max_grad_norm)
        optimizer.step()
        losses.append(loss.item())
    return losses


__all__ = ["clone_steps", "frozen"]
