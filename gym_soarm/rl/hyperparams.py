"""The RL recipes: environment settings and Stable-Baselines3 arguments per (algorithm, task).

One table, as rl-baselines3-zoo keeps one file of hyperparameters per algorithm: the
``"default"`` row of an algorithm applies to every task, and a task's own row overrides
its keys (``env`` and ``algo`` are merged key by key). Every recipe learns from
``obs_type="state"`` with ``normalize_actions=True`` (see :class:`gym_soarm.envs.env.SoArmEnv`).

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
  ``eval_episodes``: episodes of each (seeds 1000 + k; the imitation trainers score
  validation episodes instead, seeds 50000 + k).
* ``algo``: keyword arguments of the SB3 algorithm (``policy_kwargs`` included).
* ``init`` (PPO only): how ``--init DIR`` starts PPO from a BC/DAgger policy:
  ``log_std`` (the log standard deviation of the exploration noise at the start, low so
  that the pretrained policy is not wrecked), ``bc_coef`` (weight of the
  behaviour-cloning term on the actor, against the demonstrations saved in ``DIR``),
  ``bc_decay`` (``bc_coef`` is multiplied by it after each PPO update), ``bc_batch_size``,
  ``critic_warmup`` (the first PPO updates in which only the value branch learns, the
  actor frozen: the critic starts untrained).

The imitation trainers (:mod:`gym_soarm.rl.imitation`, ``--algo bc`` and ``--algo
dagger``) keep the same ``env``, ``n_envs`` (environments stepped together in one
process, their actions computed in one batch), ``torch_threads``, ``normalize``
(observations normalised with the statistics of the first demonstrations, saved as
``vecnormalize.pkl``) and ``eval_episodes`` keys; their ``algo`` holds:

* ``demos``: expert episodes of the demonstrations (BC; round 0 of DAgger);
* ``dart_std``: DART noise: the executed action is the expert's plus Gaussian noise of
  this standard deviation (in the normalised action space, clipped to [-1, 1]); the
  recorded label is the clean expert action;
* ``epochs``, ``batch_size``, ``learning_rate``: the supervised regression (Adam, mean
  squared error of the actor's mean action); ``policy_kwargs``: the SB3 ``MlpPolicy``'s;
  ``lr_schedule`` and ``episode_weighting``: as the pixel students' (below);
* DAgger only: ``rounds`` (R), ``episodes_per_round``, ``round_epochs`` (epochs over all
  the aggregated data after each round, warm-started), ``beta0`` and ``beta_decay``: in
  round r (1 .. R) each step executes the expert's action with probability
  ``beta0 * beta_decay ** r``, else the learner's; the expert labels every step;
  ``patience``: the rounds stop once this many in a row failed to beat the best
  validation.
"""

from __future__ import annotations

import copy
from typing import Any

from gym_soarm.sim.randomization import LEVELS
from gym_soarm.tasks import lift_cube, push_cube, reach_target, sort_cubes, stack_cube
from gym_soarm.validation import check_choice

ALGORITHMS: tuple[str, ...] = ("ppo", "sac")
"""The reinforcement-learning algorithms of :func:`gym_soarm.rl.training.train`."""

IMITATION: tuple[str, ...] = ("bc", "dagger")
"""The imitation trainers of :mod:`gym_soarm.rl.imitation`."""

TRAINERS: tuple[str, ...] = ALGORITHMS + IMITATION
"""Every ``--algo`` of ``python -m gym_soarm.train``."""

POLICY_CLASSES: dict[str, str] = {"ppo": "PPO", "sac": "SAC", "bc": "PPO", "dagger": "PPO"}
"""The Stable-Baselines3 class that loads each trainer's ``model.zip`` (BC and DAgger
store their policy as a PPO model, so that ``--algo ppo --init`` continues from it)."""

VEC_ENVS: tuple[str, ...] = ("native", "dummy", "subproc")
"""How a recipe's ``n_envs`` environments are stepped (the ``vec_env`` key)."""

REACH = reach_target.SPEC.name
LIFT = lift_cube.SPEC.name
STACK = stack_cube.SPEC.name
PUSH = push_cube.SPEC.name
SORT = sort_cubes.SPEC.name

_STATE_ENV: dict[str, Any] = {
    "obs_type": "state",
    "normalize_actions": True,
    "control_mode": "joint_delta",
}

_STATE_IMITATION_RUN: dict[str, Any] = {
    "env": _STATE_ENV,
    "n_envs": 4,
    "torch_threads": 1,
    "normalize": True,
    "eval_episodes": 20,
}
"""The run settings the state BC and DAgger recipes share."""

_TWICE_THE_DEMOS: dict[str, Any] = {"algo": {"demos": 400}}
"""Stack's BC and DAgger gather twice the demonstrations (and push's: :data:`_PUSH`).
Stack holds two grasps and a placement on a cube: with 200 its BC scored 82, 66, 86 % on
three seeds, with 400 100, 92, 100 %. Push: 92, 82, 86 % with 200, 92, 92, 92 % with 400
(90, 94, 90 % with 600; ``docs/learning.md``)."""

_PUSH: dict[str, Any] = {"algo": {"demos": 400, "lr_schedule": "cosine"}}
"""Push's BC and DAgger also anneal each fit's learning rate (a half cosine, as the pixel
recipes do): 100 % on the protocol on three seeds with either, where the constant rate
left BC at 92 % and DAgger at 92-96 % (``docs/learning.md``)."""

_SORT: dict[str, Any] = {"algo": {"demos": 400, "lr_schedule": "cosine", "epochs": 100}}
"""Sort's BC: 400 demonstrations, the learning rate annealed, 100 passes (as many
optimiser steps as 200 passes over 200). Its student reads the task's progress (which
cubes are sorted, the cube worked on now: ``SortCubesTask.progress_fields``); without
it, 400 demonstrations with the annealed rate scored 56 % and 60 % (``docs/learning.md``)."""

_STATE_STUDENT: dict[str, Any] = {
    "dart_std": 0.05,
    "epochs": 200,
    "batch_size": 256,
    "learning_rate": 1e-3,
    "lr_schedule": "constant",
    "episode_weighting": False,
    "policy_kwargs": {"net_arch": [256, 256]},
}
"""The state BC and DAgger students' shared network and fit."""

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
            "init": {
                "log_std": -3.0,
                "bc_coef": 1.0,
                "bc_decay": 0.995,
                "bc_batch_size": 256,
                "critic_warmup": 10,
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
    "bc": {
        "default": {
            **_STATE_IMITATION_RUN,
            "algo": {"demos": 200, **_STATE_STUDENT},
        },
        REACH: {"algo": {"dart_std": 0.15}},
        STACK: _TWICE_THE_DEMOS,
        PUSH: _PUSH,
        SORT: _SORT,
    },
    "dagger": {
        "default": {
            **_STATE_IMITATION_RUN,
            "eval_episodes": 50,
            "algo": {
                "demos": 200,
                **_STATE_STUDENT,
                "rounds": 5,
                "episodes_per_round": 40,
                "round_epochs": 50,
                "beta0": 0.5,
                "beta_decay": 0.5,
                "patience": 5,
            },
        },
        REACH: {"algo": {"dart_std": 0.15}},
        STACK: _TWICE_THE_DEMOS,
        PUSH: _PUSH,
    },
}


DRAWN_LOOKS = "drawn looks"
"""The row of a pixel recipe used where ``visual_randomization`` draws the looks (lights,
colours, cameras) at every reset: merged over the default and under the task's row. DAgger
doubles its demonstrations there: each look is seen less, and 150 demonstrations left Lift
at 62 % under light where 300 reached 95 % (``docs/learning.md``). On a task whose 300
episodes and rounds would pass ``max_memory_gb`` the run gathers as many as fit, never
fewer than without the row (:func:`gym_soarm.rl.pixels.demos_within_store`: 170 on a
400-step task)."""

_PIXEL_ENV: dict[str, Any] = {
    "obs_type": "pixels_agent_pos",
    "camera_config": "front_wrist",
    "observation_height": 96,
    "observation_width": 128,
    "normalize_actions": True,
    "control_mode": "joint_pos",
}

_PIXEL_STUDENT: dict[str, Any] = {
    "dart_std": 0.003,
    "batch_size": 64,
    "learning_rate": 1e-3,
    "shift_px": 4,
    "downsample": 2,
    "channels": [16, 32, 32, 32],
    "hidden": [256, 256],
    "max_memory_gb": 8.0,
    "aux_weight": 1.0,
    "aux_input": True,
    "lr_schedule": "cosine",
}
"""What the BC and DAgger pixel recipes share: the network, its inputs and its fit."""

PIXEL_HYPERPARAMS: dict[str, dict[str, dict[str, Any]]] = {
    "bc": {
        "default": {
            "env": _PIXEL_ENV,
            "n_envs": 4,
            "torch_threads": 2,
            "eval_episodes": 20,
            "algo": {
                **_PIXEL_STUDENT,
                "demos": 100,
                "epochs": 60,
                "episode_weighting": False,
            },
        },
        REACH: {"algo": {"dart_std": 0.01, "demos": 60}},
    },
    "dagger": {
        "default": {
            "env": _PIXEL_ENV,
            "n_envs": 4,
            "torch_threads": 2,
            "eval_episodes": 30,
            "algo": {
                **_PIXEL_STUDENT,
                "demos": 150,
                "epochs": 30,
                "episode_weighting": True,
                "round_learning_rate": None,
                "rounds": 6,
                "patience": 3,
                "episodes_per_round": 20,
                "round_epochs": 20,
                "beta0": 0.5,
                "beta_decay": 0.5,
            },
        },
        REACH: {"algo": {"dart_std": 0.01, "demos": 60}},
        DRAWN_LOOKS: {"algo": {"demos": 300}},
    },
}
"""The pixel students' recipes (:mod:`gym_soarm.rl.pixels`): the same keys as the state
imitation recipes, the network given by ``channels`` (the four convolutions of each
camera's encoder) and ``hidden`` (the MLP), ``downsample`` (an average pooling of the
images by this factor before the encoder: cheaper convolutions), ``shift_px`` (random-shift
augmentation, in pixels of the stored image), ``max_memory_gb`` (the bound on the
stored frames), ``aux_weight`` (the weight of the auxiliary targets' loss: what the state
expert reads, predicted from the images; 0 turns them off), ``aux_input`` (their estimate
also feeds the action's MLP), ``lr_schedule`` (``"constant"`` or ``"cosine"``: each fit
anneals the rate to a hundredth of ``learning_rate``), ``episode_weighting`` (each
step's loss weighted so that every episode counts alike) and, for DAgger,
``round_learning_rate`` (the rounds' fits start from this rate instead of
``learning_rate``; None: the same) and ``patience`` (the rounds stop once this many in a
row fail to beat the best evaluation)."""


def pixel_recipe(algo: str, task: str, visual_randomization: str = "none") -> dict[str, Any]:
    """The settings of a pixel student of ``algo`` (``"bc"`` or ``"dagger"``) on ``task``;
    with ``visual_randomization`` other than ``"none"``, the recipe's :data:`DRAWN_LOOKS`
    row is merged under the task's.

    Raises:
        ValueError: ``algo`` is not one of :data:`IMITATION`.
    """
    refusal = f"a pixel student trains with {', '.join(IMITATION)}; got {algo!r}. Pass --algo bc."
    check_choice("visual_randomization", visual_randomization, LEVELS)
    rows = (DRAWN_LOOKS,) if visual_randomization != "none" else ()
    return _merged(_algo_table(PIXEL_HYPERPARAMS, algo, refusal), task, rows)


def _algo_table(
    tables: dict[str, dict[str, dict[str, Any]]], algo: str, refusal: str
) -> dict[str, dict[str, Any]]:
    """``algo``'s table of recipes; a ValueError saying ``refusal`` when there is none."""
    if algo not in tables:
        raise ValueError(refusal)
    return tables[algo]


def _merged(
    table: dict[str, dict[str, Any]], task: str, rows: tuple[str, ...] = ()
) -> dict[str, Any]:
    """The table's default with ``rows`` and then the task's row merged over it."""
    merged = copy.deepcopy(table["default"])
    for row in (*rows, task):
        for key, value in copy.deepcopy(table.get(row, {})).items():
            if key in ("env", "algo", "init"):
                merged[key] = {**merged[key], **value}
            else:
                merged[key] = value
    return merged


def override(settings: dict[str, Any], hyperparams: dict[str, Any] | None, algo: str) -> None:
    """Replace values of ``settings["algo"]`` by ``hyperparams`` (copied); a ValueError
    naming the valid keys when one is not a key of the recipe (nothing changed then)."""
    if not hyperparams:
        return
    unknown = sorted(set(hyperparams) - set(settings["algo"]))
    if unknown:
        raise ValueError(
            f"hyperparams {unknown} are not keys of the {algo} recipe; valid: "
            f"{', '.join(sorted(settings['algo']))}."
        )
    settings["algo"].update(copy.deepcopy(hyperparams))


def recipe(algo: str, task: str) -> dict[str, Any]:
    """The settings of ``algo`` on ``task``: the algorithm's default merged with the task's row.

    Args:
        algo: one of :data:`TRAINERS`.
        task: a registered task name (``"ReachTarget-v0"``).

    Returns:
        A new dict (free to modify).

    Raises:
        ValueError: ``algo`` is not one of :data:`TRAINERS`.
    """
    refusal = f"algo must be one of {', '.join(TRAINERS)}; got {algo!r}. Pass e.g. --algo ppo."
    return _merged(_algo_table(HYPERPARAMS, algo, refusal), task)


VECTOR_ENVS: tuple[str, ...] = ("batched", "processes", "warp")
"""The package's vector envs (``--vector-env``): PPO trains with RSL-RL on ``batched`` and
``warp`` (:mod:`gym_soarm.rl.rsl`), with Stable-Baselines3 on ``processes``."""

RSL_HYPERPARAMS: dict[str, dict[str, Any]] = {
    "default": {
        "env": _STATE_ENV,
        "num_envs": 64,
        "num_envs_cuda": 4096,
        "torch_threads": 1,
        "steps": 2_000_000,
        "eval_every": 100_000,
        "eval_episodes": 20,
        "algo": {
            "num_steps_per_env": 24,
            "learning_rate": 1e-3,
            "schedule": "adaptive",
            "desired_kl": 0.01,
            "num_learning_epochs": 5,
            "num_mini_batches": 4,
            "clip_param": 0.2,
            "gamma": 0.99,
            "lam": 0.95,
            "entropy_coef": 0.005,
            "value_loss_coef": 1.0,
            "max_grad_norm": 1.0,
            "hidden_dims": [256, 128, 64],
            "activation": "elu",
            "obs_normalization": True,
            "init_noise_std": 1.0,
        },
        "init": {
            "noise_std": 0.05,
            "critic_warmup": 10,
            "bc_coef": 1.0,
            "bc_decay": 0.999,
            "bc_batch_size": 256,
        },
    },
    REACH: {"steps": 2_400_000, "eval_every": 50_000},
    LIFT: {"steps": 6_000_000, "eval_every": 250_000},
}
"""PPO on RSL-RL (``--vector-env batched|warp``): ``num_envs`` environments on the CPU
(``num_envs_cuda`` on a GPU), ``torch_threads``, ``steps``, ``eval_every``,
``eval_episodes`` and the ``algo`` keys: RSL-RL's PPO arguments (``num_steps_per_env``
steps of every environment per iteration, ``schedule="adaptive"`` scales the learning
rate to keep the policy's KL near ``desired_kl``) and the actor's and critic's MLP
(``hidden_dims``, ``activation``, ``obs_normalization``, ``init_noise_std``: the Gaussian's
first standard deviation, in normalised action units). The ``init`` keys apply to ``--init``
with a BC, DAgger or SB3 PPO folder (:mod:`gym_soarm.rl.rsl_init`): ``noise_std`` (the
Gaussian's first standard deviation), ``critic_warmup`` (iterations in which only the
critic learns) and the behaviour-cloning term on the folder's demonstrations after each
update (:mod:`gym_soarm.rl.rsl_bc`: ``bc_coef``, multiplied by ``bc_decay`` per update,
minibatches of ``bc_batch_size``)."""


def rsl_recipe(task: str) -> dict[str, Any]:
    """The settings of PPO on RSL-RL for ``task`` (a new dict, free to modify)."""
    return _merged(RSL_HYPERPARAMS, task)
