"""The RL recipes: environment settings and Stable-Baselines3 arguments per (algorithm, task).

One table, as rl-baselines3-zoo keeps one file of hyperparameters per algorithm: the
``"default"`` row of an algorithm applies to every task, and a task's own row overrides
its keys (``env`` and ``algo`` are merged key by key). Every recipe learns from
``obs_type="state"`` with ``normalize_actions=True`` (see :class:`gym_soarm.env.SoArmEnv`).

Keys of a recipe:

* ``env``: keywords of ``gym.make`` (obs type, control mode, ...).
* ``n_envs``: environments stepped together; ``vec_env``: ``"native"`` (gym_soarm's
  vector env, one process per CPU, :class:`gym_soarm.rl.native.NativeVecEnv`; the
  fastest measured), ``"dummy"`` (SB3's, in this process) or ``"subproc"`` (SB3's, one
  process per environment). The episodes are the same in all three.
* ``torch_threads``: PyTorch's threads (1: small networks gain nothing from more, and
  lose much when other processes share the cores).
* ``normalize``: running normalisation of observations and rewards (SB3's
  ``VecNormalize``), saved beside the model.
* ``steps``: environment steps of a run (``--steps`` overrides it).
* ``eval_every``: environment steps between two evaluations on the protocol;
  ``eval_episodes``: episodes of each (seeds 1000 + k).
* ``algo``: keyword arguments of the SB3 algorithm (``policy_kwargs`` included).
"""

from __future__ import annotations

import copy
from typing import Any

from gym_soarm.tasks import lift_cube, reach_target

ALGORITHMS: tuple[str, ...] = ("ppo", "sac")
"""The algorithms ``python -m gym_soarm.train`` knows."""

VEC_ENVS: tuple[str, ...] = ("native", "dummy", "subproc")
"""How a recipe's ``n_envs`` environments are stepped (the ``vec_env`` key)."""

REACH = reach_target.SPEC.name
LIFT = lift_cube.SPEC.name

_STATE_ENV: dict[str, Any] = {
    "obs_type": "state",
    "normalize_actions": True,
    "control_mode": "joint_delta",
}

HYPERPARAMS: dict[str, dict[str, dict[str, Any]]] = {
    "ppo": {
        "default": {
            "env": _STATE_ENV,
            "n_envs": 8,
            "vec_env": "native",
            "torch_threads": 1,
            "normalize": True,
            "steps": 2_000_000,
            "eval_every": 100_000,
            "eval_episodes": 20,
            "algo": {
                "learning_rate": 3e-4,
                "n_steps": 256,
                "batch_size": 512,
                "n_epochs": 5,
                "gamma": 0.99,
                "gae_lambda": 0.95,
                "clip_range": 0.2,
                "ent_coef": 0.0,
                "policy_kwargs": {"net_arch": [128, 128]},
            },
        },
        REACH: {"steps": 1_000_000, "eval_every": 50_000},
        LIFT: {
            "n_envs": 16,
            "steps": 6_000_000,
            "eval_every": 250_000,
            "algo": {"n_steps": 128, "batch_size": 1024, "n_epochs": 5, "ent_coef": 0.001},
        },
    },
    "sac": {
        "default": {
            "env": _STATE_ENV,
            "n_envs": 4,
            "vec_env": "native",
            "torch_threads": 1,
            "normalize": False,
            "steps": 300_000,
            "eval_every": 25_000,
            "eval_episodes": 20,
            "algo": {
                "learning_rate": 1e-3,
                "buffer_size": 300_000,
                "learning_starts": 2_000,
                "batch_size": 128,
                "gamma": 0.98,
                "tau": 0.02,
                "train_freq": 1,
                "gradient_steps": 1,
                "policy_kwargs": {"net_arch": [128, 128]},
            },
        },
        REACH: {"steps": 300_000, "eval_every": 25_000},
    },
}


def recipe(algo: str, task: str) -> dict[str, Any]:
    """The settings of ``algo`` on ``task``: the algorithm's default merged with the task's row.

    Args:
        algo: one of :data:`ALGORITHMS`.
        task: a registered task name (``"ReachTarget-v0"``).

    Returns:
        A new dict (free to modify).

    Raises:
        ValueError: ``algo`` is not one of :data:`ALGORITHMS`.
    """
    if algo not in HYPERPARAMS:
        raise ValueError(
            f"algo must be one of {', '.join(ALGORITHMS)}; got {algo!r}. Pass e.g. --algo ppo."
        )
    table = HYPERPARAMS[algo]
    merged = copy.deepcopy(table["default"])
    for key, value in copy.deepcopy(table.get(task, {})).items():
        if key in ("env", "algo"):
            merged[key] = {**merged[key], **value}
        else:
            merged[key] = value
    return merged
