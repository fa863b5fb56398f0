"""What every vector env of the package shares: seeds, reset masks, action checks, the
autoreset mode, ``set_attr``'s values and observations kept as one array per leaf.

:class:`~gym_soarm.vector.processes.SoArmVectorEnv` and
:class:`~gym_soarm.vector.batched.BatchedVectorEnv` both build on these.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from gym_soarm.validation import check_int

Leaf = tuple[tuple[str, ...], tuple[int, ...], np.dtype]

TIME_LIMIT_ATTRIBUTE = "_max_episode_steps"
"""What Gymnasium's ``TimeLimit`` calls the step limit; the vector env answers it."""


def parse_autoreset_mode(mode: AutoresetMode | str) -> AutoresetMode:
    if isinstance(mode, AutoresetMode):
        return mode
    names = [m.value for m in AutoresetMode]
    if isinstance(mode, str) and mode in names:
        return AutoresetMode(mode)
    raise ValueError(
        f"autoreset_mode must be a gymnasium.vector.AutoresetMode or one of {names}; got {mode!r}."
    )


def parse_seeds(seed: Any, num_envs: int) -> list[int | None]:
    """One seed per environment: None (fresh entropy), an int ``s`` (environment ``i``
    gets ``s + i``) or a sequence of ``num_envs`` seeds (or Nones).

    Raises:
        ValueError: anything else, or a negative seed.
    """
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        seeds: list[Any] = [int(seed) + i for i in range(num_envs)]
    elif isinstance(seed, (Sequence, np.ndarray)) and not isinstance(seed, str):
        seeds = list(seed)
        if len(seeds) != num_envs:
            raise ValueError(
                f"seed must be None, an int or a list of num_envs={num_envs} seeds; "
                f"got a list of length {len(seeds)}."
            )
    else:
        raise ValueError(
            f"seed must be None, an int >= 0 or a list of num_envs={num_envs} seeds; got {seed!r}."
        )
    return [None if s is None else check_int("seed", s, 0) for s in seeds]


def values_per_env(values: Any, num_envs: int) -> list[Any]:
    """``set_attr``'s values: one per environment, or one value for all.

    Raises:
        ValueError: a list or tuple of another length.
    """
    if not isinstance(values, (list, tuple)):
        return [values] * num_envs
    if len(values) != num_envs:
        raise ValueError(
            f"values must hold one value per environment (num_envs={num_envs}); got {len(values)}."
        )
    return list(values)


def batched_obs(leaves: list[Leaf], arrays: list[Any], copy: bool) -> Any:
    """The observation of a vector env from its leaf arrays, NumPy arrays or torch
    tensors (fresh copies if ``copy``)."""
    if copy:
        arrays = [a.clone() if hasattr(a, "clone") else a.copy() for a in arrays]
    return nest({path: a for (path, _, _), a in zip(leaves, arrays, strict=True)})


def pop_reset_mask(options: dict[str, Any] | None, num_envs: int) -> np.ndarray | None:
    """``options["reset_mask"]``, taken out of ``options`` and checked (None if absent).

    Raises:
        ValueError: not a bool array of shape ``(num_envs,)`` with at least one True.
    """
    if options is None or "reset_mask" not in options:
        return None
    mask = np.asarray(options.pop("reset_mask"))
    if mask.shape != (num_envs,) or mask.dtype != np.bool_ or not mask.any():
        raise ValueError(
            f"options['reset_mask'] must be a bool array of shape ({num_envs},) "
            f"with at least one True; got {mask!r}."
        )
    return mask


def check_actions(
    actions: Any, shape: tuple[int, ...], mode: AutoresetMode, ended: np.ndarray
) -> np.ndarray:
    """A vector step's ``actions`` as an array, checked before anything steps.

    Args:
        actions: one row per environment (a torch tensor is copied to the host: the
            control modes convert actions in NumPy).
        shape: the batched action space's shape.
        mode: the autoreset mode (rows of environments that reset instead may be anything).
        ended: which environments ended their episodes on the previous step.

    Raises:
        ValueError: another shape, not real numbers, or NaN/inf in a row that steps.
        RuntimeError: ``DISABLED`` and an ended episode not reset yet.
    """
    if hasattr(actions, "detach") and hasattr(actions, "cpu"):  # torch, on any device
        actions = actions.detach().cpu().numpy()
    array = np.asarray(actions)
    if array.shape != shape:
        raise ValueError(
            f"actions must have shape {shape} (one row of joint targets per "
            f"environment); got shape {array.shape}."
        )
    if array.dtype.kind not in "iuf":
        raise ValueError(
            f"actions must be real numbers (ints or floats) of shape {shape}; got dtype "
            f"{array.dtype}."
        )
    if mode is AutoresetMode.DISABLED and ended.any():
        done = np.flatnonzero(ended).tolist()
        raise RuntimeError(
            f"environments {done} ended their episodes and autoreset_mode is DISABLED: "
            "reset them first with reset(options={'reset_mask': mask})."
        )
    rows = ~ended if mode is AutoresetMode.NEXT_STEP else np.ones(len(ended), np.bool_)
    finite = np.isfinite(array.reshape(len(ended), -1)).all(axis=1)
    if not finite[rows].all():
        bad = np.flatnonzero(rows & ~finite).tolist()
        raise ValueError(
            f"actions must be finite; the rows of environments {bad} hold NaN or inf. "
            "Nothing was stepped; check the policy's output before stepping."
        )
    return array


def observation_leaves(space: spaces.Space, path: tuple[str, ...] = ()) -> list[Leaf]:
    """The (key path, shape, dtype) of every array of an observation space, in order."""
    if isinstance(space, spaces.Dict):
        out: list[Leaf] = []
        for key, sub in space.spaces.items():
            out.extend(observation_leaves(sub, (*path, key)))
        return out
    if isinstance(space, spaces.Box):
        return [(path, space.shape, space.dtype)]
    raise TypeError(
        f"SoArmVectorEnv batches Dict and Box observation spaces; got {type(space).__name__}."
    )


def nest(flat: dict[tuple[str, ...], Any]) -> Any:
    """Rebuild the nested dicts of an observation from its leaves keyed by path."""
    if list(flat) == [()]:
        return flat[()]
    root: dict[str, Any] = {}
    for path, value in flat.items():
        node = root
        for key in path[:-1]:
            node = node.setdefault(key, {})
        node[path[-1]] = value
    return root


def leaf_value(tree: Any, path: tuple[str, ...]) -> Any:
    """The value at ``path`` (a key path of :func:`observation_leaves`) of an observation."""
    for key in path:
        tree = tree[key]
    return tree


__all__ = [
    "TIME_LIMIT_ATTRIBUTE",
    "Leaf",
    "batched_obs",
    "check_actions",
    "leaf_value",
    "nest",
    "observation_leaves",
    "parse_autoreset_mode",
    "parse_seeds",
    "pop_reset_mask",
    "values_per_env",
]
