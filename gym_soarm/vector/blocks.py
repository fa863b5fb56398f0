"""The shared memory of the process vector env and the environments each process steps.

:func:`layout` places every array of a step in one block of shared memory (actions, the
caller's plan for the step, rewards, ends, the numbers of the infos, the observation
leaves); :func:`views` gives NumPy arrays over it in any process. A :class:`Block` is the
environments one process steps (in a worker, or in the caller's own): it reads its rows
of the actions and of the plan (:class:`gym_soarm.vector.base.EpisodeClock`) and writes
its rows of the results.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.envs.infos import INFO_NUMBERS, InfoWriter
from gym_soarm.vector.common import Leaf, leaf_value

Field = tuple[str, int, tuple[int, ...], str]
"""One array of the block: name, byte offset, shape, dtype."""

ALIGN = 64
"""Byte alignment of each array in the shared block."""


def layout(num_envs: int, action_shape: tuple[int, ...], leaves: list[Leaf]) -> list[Field]:
    """Where each shared array lies in the shared block: actions, results, observations."""
    fields: list[Field] = []
    offset = 0

    def add(name: str, shape: tuple[int, ...], dtype: np.dtype | str) -> None:
        nonlocal offset
        dtype = np.dtype(dtype)
        fields.append((name, offset, shape, dtype.str))
        size = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        offset += -(-size // ALIGN) * ALIGN

    add("actions", (num_envs, *action_shape), np.float64)  # what SoArmEnv.step converts to
    add("rewards", (num_envs,), np.float64)
    add("terminations", (num_envs,), np.bool_)
    add("truncations", (num_envs,), np.bool_)
    add("restart", (num_envs,), np.bool_)  # the caller's plan for the step
    add("time_up", (num_envs,), np.bool_)
    add("stepped", (num_envs,), np.bool_)  # the rows whose step is done (a block may raise)
    add("infos", (num_envs, INFO_NUMBERS), np.float64)
    for index, (_, shape, dtype) in enumerate(leaves):
        add(f"obs{index}", (num_envs, *shape), dtype)
    return fields


def block_size(fields: list[Field]) -> int:
    _, offset, shape, dtype = fields[-1]
    return max(ALIGN, offset + int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize)


def views(block: Any, fields: list[Field]) -> dict[str, np.ndarray]:
    """Numpy arrays over the shared block, one per field of :func:`layout`."""
    buffer = memoryview(block).cast("B")
    return {
        name: np.ndarray(shape, np.dtype(dtype), buffer=buffer, offset=offset)
        for name, offset, shape, dtype in fields
    }


class Block:
    """Environments ``first, first + 1, ...`` of a vector env, stepped in turn.

    Reads its actions from, and writes its results and observations into, the rows
    ``first .. first + len(envs) - 1`` of the shared arrays. It runs in a worker process
    (or in the caller's own); the batching happens in the caller.
    """

    def __init__(
        self,
        envs: list[SoArmEnv],
        first: int,
        arrays: dict[str, np.ndarray],
        leaves: list[Leaf],
        autoreset_mode: AutoresetMode,
    ) -> None:
        self.envs = envs
        self.rows = range(first, first + len(envs))
        self.arrays = arrays
        self.paths = [path for path, _, _ in leaves]
        self.obs = [arrays[f"obs{k}"] for k in range(len(leaves))]
        self.mode = autoreset_mode
        self.info_writer = InfoWriter(arrays["infos"], self.rows)

    def _write_obs(self, row: int, obs: Any) -> None:
        for path, array in zip(self.paths, self.obs, strict=True):
            array[row] = leaf_value(obs, path)

    def reset(
        self, seeds: list[int | None], options: dict[str, Any] | None, mask: list[bool] | None
    ) -> list[dict[str, Any] | None]:
        infos: list[dict[str, Any] | None] = [None] * len(self.envs)
        for k, row in enumerate(self.rows):
            if mask is not None and not mask[k]:
                continue
            obs, info = self.envs[k].reset(seed=seeds[k], options=options)
            self._write_obs(row, obs)
            infos[k] = info
        return infos

    def step(self) -> tuple[tuple[Any, ...], dict[int, tuple[Any, dict[str, Any]]]]:
        """Step every environment as the caller's plan says (its rows of ``restart``
        reset instead, of ``time_up`` are truncated); its infos (as
        :meth:`InfoWriter.write` sends them) and, in ``SAME_STEP``, the ended episodes'
        last observations and infos keyed by environment index."""
        actions, restart, time_up = (self.arrays[k] for k in ("actions", "restart", "time_up"))
        rewards = self.arrays["rewards"]
        terms = self.arrays["terminations"]
        truncs = self.arrays["truncations"]
        infos: list[dict[str, Any]] = []
        finals: dict[int, tuple[Any, dict[str, Any]]] = {}
        for k, row in enumerate(self.rows):
            env = self.envs[k]
            if restart[row]:
                obs, info = env.reset()
                rewards[row] = 0.0
                terms[row] = truncs[row] = False
            else:
                obs, reward, terminated, truncated, info = env.step(actions[row])
                rewards[row] = reward
                terms[row] = terminated
                truncs[row] = truncated = truncated or time_up[row]
                if (terminated or truncated) and self.mode is AutoresetMode.SAME_STEP:
                    finals[row] = (obs, info)
                    obs, info = env.reset()
            self._write_obs(row, obs)
            self.arrays["stepped"][row] = True
            infos.append(info)
        return self.info_writer.write(infos), finals

    def call(
        self,
        name: str,
        args: tuple[Any, ...],
        kwargs: dict[str, Any],
        mask: list[bool] | None = None,
    ) -> list[Any]:
        results = []
        for k, env in enumerate(self.envs):
            if mask is not None and not mask[k]:
                results.append(None)
                continue
            attribute = getattr(env, name)
            results.append(attribute(*args, **kwargs) if callable(attribute) else attribute)
        return results

    def get_attr(self, name: str) -> list[Any]:
        return [getattr(env, name) for env in self.envs]

    def set_attr(self, name: str, values: list[Any]) -> None:
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    def close(self) -> None:
        for env in self.envs:
            env.close()
