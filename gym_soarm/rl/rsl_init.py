"""PPO on RSL-RL from a Stable-Baselines3 policy folder: ``--init DIR`` where ``DIR`` holds a
BC, DAgger or PPO policy of the package (``model.zip``, ``vecnormalize.pkl``).

The folder's actor becomes RSL-RL's, so that PPO's first rollouts act as the folder's
policy does:

* SB3's ``MlpPolicy`` actor (its policy MLP, then the action layer) is copied layer for
  layer into the RSL-RL actor's MLP; the run's ``hidden_dims`` and ``activation`` are the
  folder's (``settings.json`` records them, so that :func:`gym_soarm.rl.rsl_policy.load_actor`
  rebuilds the same network);
* the folder's observation statistics become the actor's observation normaliser, frozen
  for the whole run (RSL-RL's normaliser divides by ``std + 0.01``, SB3's by
  ``sqrt(var + 1e-8)``: the stored standard deviation is shifted so that both give the same
  inputs; SB3 also clips them to +-10, which the demonstrations' states never reach);
* the critic starts from scratch, its normaliser from the same statistics (updated as
  RSL-RL updates it), and learns alone for ``critic_warmup`` iterations (the actor's
  parameters frozen) before the actor moves: a fresh critic's advantages would otherwise
  pull a good actor anywhere;
* the Gaussian's standard deviation starts at ``noise_std`` (normalised action units),
  low, so that the first rollouts are the policy's own;
* each PPO update is followed by gradient steps of behaviour cloning on the folder's
  demonstrations, with a weight that decays (:mod:`gym_soarm.rl.rsl_bc`): plain PPO
  unlearns the pretrained actor.

The recipe's ``init`` keys (:data:`gym_soarm.rl.hyperparams.RSL_HYPERPARAMS`) give
``noise_std``, ``critic_warmup``, ``bc_coef``, ``bc_decay`` and ``bc_batch_size``.
"""

from __future__ import annotations

import dataclasses
import logging
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.rl.evaluation import MODEL_FILE, NORMALIZE_FILE

logger = logging.getLogger(__name__)

_ACTIVATIONS = {"Tanh": "tanh", "ReLU": "relu"}
"""RSL-RL's names of the activations an SB3 ``MlpPolicy`` of the package may have."""
RSL_NORMALIZER_EPS = 1e-2
"""What RSL-RL's ``EmpiricalNormalization`` adds to the standard deviation it divides by."""


@dataclasses.dataclass
class Sb3Actor:
    """The deterministic actor of an SB3 policy folder, as plain arrays."""

    hidden_dims: list[int]
    activation: str
    layers: list[tuple[np.ndarray, np.ndarray]]  # (weight, bias) of each Linear, in order
    obs_mean: np.ndarray
    obs_var: np.ndarray
    obs_epsilon: float
    obs_count: float


def read_sb3_actor(folder: str | Path) -> Sb3Actor:
    """The actor and observation statistics of the SB3 policy folder ``folder``.

    Raises:
        ValueError: the folder's policy is not an MLP the RSL-RL actor can take, or it
            has no observation statistics.
    """
    from stable_baselines3 import PPO

    path = Path(folder)
    if not (path / NORMALIZE_FILE).is_file():
        raise ValueError(
            f"--init {str(path)!r} has no {NORMALIZE_FILE}: PPO on RSL-RL normalises "
            "observations and starts from the folder's statistics. Train the folder with "
            "the package's recipe (normalize: True)."
        )
    policy = PPO.load(path / MODEL_FILE, device="cpu").policy
    activation = policy.activation_fn.__name__
    if activation not in _ACTIVATIONS:
        raise ValueError(
            f"--init {str(path)!r}: its hidden layers use {activation}; RSL-RL's actor "
            f"takes {', '.join(_ACTIVATIONS)} here. Retrain it with one of them."
        )
    linears = [
        module
        for module in (*policy.mlp_extractor.policy_net, policy.action_net)
        if type(module).__name__ == "Linear"
    ]
    with open(path / NORMALIZE_FILE, "rb") as stream:
        normalizer = pickle.load(stream)
    return Sb3Actor(
        hidden_dims=[int(layer.out_features) for layer in linears[:-1]],
        activation=_ACTIVATIONS[activation],
        layers=[
            (layer.weight.detach().numpy().copy(), layer.bias.detach().numpy().copy())
            for layer in linears
        ],
        obs_mean=np.asarray(normalizer.obs_rms.mean, np.float64),
        obs_var=np.asarray(normalizer.obs_rms.var, np.float64),
        obs_epsilon=float(normalizer.epsilon),
        obs_count=float(normalizer.obs_rms.count),
    )


def load_sb3_actor(alg: Any, source: Sb3Actor, noise_std: float) -> None:
    """Write ``source`` into RSL-RL's PPO ``alg``: the actor's MLP and frozen normaliser,
    the critic's normaliser and the starting noise (see the module's documentation).

    Raises:
        ValueError: ``alg``'s actor is not the network ``source`` describes.
    """
    import torch

    actor = alg.actor
    linears = [m for m in actor.mlp if isinstance(m, torch.nn.Linear)]
    shapes = [tuple(layer.weight.shape) for layer in linears]
    wanted = [weight.shape for weight, _ in source.layers]
    if shapes != wanted:
        raise ValueError(
            f"the RSL-RL actor's layers are {shapes}; the --init folder's are {wanted}. "
            "Build the actor with the folder's hidden_dims."
        )
    with torch.no_grad():
        for layer, (weight, bias) in zip(linears, source.layers, strict=True):
            layer.weight.copy_(torch.as_tensor(weight))
            layer.bias.copy_(torch.as_tensor(bias))
        std = np.sqrt(source.obs_var + source.obs_epsilon)
        set_normalizer(actor.obs_normalizer, source.obs_mean, std - RSL_NORMALIZER_EPS, 0)
        set_normalizer(
            alg.critic.obs_normalizer, source.obs_mean, np.sqrt(source.obs_var), source.obs_count
        )
        actor.distribution.std_param.fill_(float(noise_std))
    freeze_normalizer(actor)


def start_from_sb3(alg: Any, folder: Path, init: dict[str, Any]) -> None:
    """Start RSL-RL's PPO ``alg`` (a :class:`gym_soarm.rl.rsl_bc.BCRegularizedPPO`) from the
    SB3 folder ``folder``: its actor (:func:`load_sb3_actor`) and, where the folder kept
    them, its demonstrations for the behaviour-cloning term (the recipe's ``init`` keys:
    ``noise_std``, ``bc_coef``, ``bc_decay``, ``bc_batch_size``)."""
    from gym_soarm.rl.imitation import DEMOS_FILE, Dataset

    load_sb3_actor(alg, read_sb3_actor(folder), init["noise_std"])
    if not (folder / DEMOS_FILE).is_file():
        logger.warning("--init %s has no demonstrations: PPO without the BC term", folder)
        return
    demos = Dataset.load(folder / DEMOS_FILE)
    alg.set_demonstrations(
        demos.obs, demos.actions, init["bc_coef"], init["bc_decay"], init["bc_batch_size"]
    )


def set_normalizer(normalizer: Any, mean: np.ndarray, std: np.ndarray, count: float) -> None:
    """Set an RSL-RL ``EmpiricalNormalization``'s statistics (``count``: how many samples
    they stand for against the ones it learns next)."""
    import torch

    device = normalizer._mean.device
    normalizer._mean.copy_(torch.as_tensor(mean, dtype=torch.float32, device=device)[None])
    normalizer._std.copy_(torch.as_tensor(std, dtype=torch.float32, device=device)[None])
    normalizer._var.copy_(normalizer._std**2)
    normalizer.count.fill_(int(count))


def freeze_normalizer(actor: Any) -> None:
    """Stop the actor's observation normaliser from learning (RSL-RL's ``until``)."""
    actor.obs_normalizer.until = 0


__all__ = [
    "Sb3Actor",
    "freeze_normalizer",
    "load_sb3_actor",
    "read_sb3_actor",
    "set_normalizer",
    "start_from_sb3",
]
