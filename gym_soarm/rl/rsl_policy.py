"""What acting with an RSL-RL folder needs (:mod:`gym_soarm.rl.rsl` trains them): the
folder's names, RSL-RL's runner configuration from the package's recipe, and the actor
loaded from the checkpoint. Needs the ``rl`` extra (``rsl-rl-lib`` 5.x)."""

from __future__ import annotations

import copy
import os
from typing import Any

RSL_LIBRARY = "rsl_rl"
"""``settings.json``'s ``library`` of a folder trained by RSL-RL."""

RSL_MODEL_FILE = "model.pt"
"""RSL-RL's checkpoint in a run folder."""

OBS_GROUP = "policy"
"""The one observation group the adapter gives (the actor's and the critic's input)."""


def require_rsl() -> Any:
    """Import RSL-RL, or an ImportError naming the extra that installs it."""
    try:
        import rsl_rl.runners
        import tensordict  # noqa: F401
    except ImportError as exc:  # pragma: no cover - the rl extra is installed in CI
        raise ImportError(
            "PPO on --vector-env batched or warp trains with RSL-RL: "
            'pip install "gym-soarm[rl]" (rsl-rl-lib 5.x).'
        ) from exc
    import rsl_rl

    return rsl_rl


def runner_config(params: dict[str, Any]) -> dict[str, Any]:
    """RSL-RL's ``OnPolicyRunner`` configuration from a recipe's ``algo`` keys."""
    params = copy.deepcopy(params)
    model = {
        "hidden_dims": params.pop("hidden_dims"),
        "activation": params.pop("activation"),
        "obs_normalization": params.pop("obs_normalization"),
    }
    init_std = params.pop("init_noise_std")
    return {
        "num_steps_per_env": params.pop("num_steps_per_env"),
        "save_interval": 10**9,
        "obs_groups": {"actor": [OBS_GROUP], "critic": [OBS_GROUP]},
        "actor": {
            "class_name": "rsl_rl.models.MLPModel",
            **model,
            "distribution_cfg": {
                "class_name": "rsl_rl.modules.GaussianDistribution",
                "init_std": init_std,
                "std_type": "scalar",
            },
        },
        "critic": {"class_name": "rsl_rl.models.MLPModel", **model},
        "algorithm": {"class_name": "rsl_rl.algorithms.PPO", "rnd_cfg": None, **params},
    }


def load_actor(
    path: str | os.PathLike[str], recipe: dict[str, Any], obs_dim: int, act_dim: int
) -> Any:
    """The actor (its observation normaliser included) of the RSL-RL checkpoint ``path``,
    built as ``recipe`` (a folder's ``settings["recipe"]``) says, in evaluation mode:
    ``actor(TensorDict({"policy": obs}))`` gives the deterministic action.

    Raises:
        ValueError: the checkpoint's actor does not fit ``obs_dim`` and ``act_dim``.
    """
    import torch
    from tensordict import TensorDict

    require_rsl()
    from rsl_rl.models import MLPModel

    config = runner_config(recipe["algo"])["actor"]
    config.pop("class_name")
    obs = TensorDict({OBS_GROUP: torch.zeros(1, obs_dim)}, batch_size=[1])
    actor = MLPModel(obs, {"actor": [OBS_GROUP]}, "actor", act_dim, **config)
    weights = torch.load(path, map_location="cpu", weights_only=False)["actor_state_dict"]
    try:
        actor.load_state_dict(weights)
    except RuntimeError as exc:
        raise ValueError(
            f"the actor in {str(path)!r} does not fit observations of {obs_dim} values and "
            f"actions of {act_dim}: {exc}. Retrain it."
        ) from exc
    return actor.eval()


def acting(actor: Any, device: Any = "cpu") -> Any:
    """An RSL-RL ``actor`` as ``act(obs) -> action``: one observation (a NumPy vector) in,
    the deterministic action (NumPy) out."""
    import numpy as np
    import torch
    from tensordict import TensorDict

    def act(obs: Any) -> Any:
        batch = torch.as_tensor(np.asarray(obs, np.float32), device=device)[None]
        with torch.inference_mode():
            return (
                actor(TensorDict({OBS_GROUP: batch}, batch_size=[1], device=device))[0]
                .cpu()
                .numpy()
            )

    return act


__all__ = [
    "OBS_GROUP",
    "RSL_LIBRARY",
    "RSL_MODEL_FILE",
    "acting",
    "load_actor",
    "require_rsl",
    "runner_config",
]
