"""Stable-Baselines3's view of gym_soarm's native vector env.

``python -m gym_soarm.train`` steps its environments through :class:`NativeVecEnv` when a
recipe says ``vec_env="native"`` (the default): for state observations the
:class:`gym_soarm.vector.batched.BatchedVectorEnv` (every simulation in one ``mujoco.batch``
call, the task scored as arrays), for pixels the worker processes of
:class:`gym_soarm.vector.SoArmVectorEnv`, seen through SB3's ``VecEnv`` interface. It gives what SB3's ``DummyVecEnv`` over the same ``gym.make``
environments gives, bit for bit: the same seeds (environment ``i`` gets ``seed + i``),
observations, float32 rewards, dones, ``terminal_observation`` and
``TimeLimit.truncated``; of the task's own info only ``is_success`` is passed on (what
SB3 reads), which keeps the step free of per-environment dicts.

Needs the ``rl`` extra (``pip install "gym-soarm[rl]"``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from gym_soarm.tasks import get_task
from gym_soarm.vector.batched import make_vector_env


def _one(info: dict[str, Any], i: int) -> dict[str, Any]:
    """Environment ``i``'s own info from a batched one (the keys its ``_key`` mask marks)."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        if key.startswith("_") or not info.get(f"_{key}", np.zeros(i + 1, bool))[i]:
            continue
        out[key] = _one(value, i) if isinstance(value, dict) else value[i]
    return out


class NativeVecEnv(VecEnv):
    """``n_envs`` environments of ``task`` in gym_soarm's native vector env.

    Args:
        task: a registered task's name.
        env_kwargs: the keywords of ``gym.make`` for each environment.
        n_envs: environments stepped together.
        num_processes: worker processes that step them (``vector_env="processes"``;
            default: one per CPU).
        vector_env: ``"auto"`` (default: batched for state observations), ``"batched"``
            or ``"processes"`` (see :func:`gym_soarm.vector.batched.make_vector_env`).
    """

    def __init__(
        self,
        task: str,
        env_kwargs: dict[str, Any],
        n_envs: int,
        num_processes: int | None = None,
        vector_env: str = "auto",
    ) -> None:
        spec = get_task(task)
        self.vector = make_vector_env(
            n_envs,
            vector_env=vector_env,
            max_episode_steps=spec.max_episode_steps,
            autoreset_mode=AutoresetMode.SAME_STEP,
            num_processes=num_processes,
            task=spec.name,
            **env_kwargs,
        )
        super().__init__(
            n_envs, self.vector.single_observation_space, self.vector.single_action_space
        )
        self.metadata = self.vector.metadata
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        """Reset every environment with the seeds given to :meth:`seed` (once), else fresh.

        Raises:
            ValueError: environments were given different reset options (the native
                vector env resets all with the same).
        """
        options = [o or None for o in self._options] or [None]
        if any(o != options[0] for o in options):
            raise ValueError(
                "NativeVecEnv resets every environment with the same options; got different "
                f"options per environment: {options}. Use vec_env='dummy' for that."
            )
        obs, info = self.vector.reset(seed=list(self._seeds), options=options[0])
        self.reset_infos = [_one(info, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        obs, rewards, terminated, truncated, info = self.vector.step(self._actions)
        dones = terminated | truncated
        success = info.get("is_success")
        infos: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            entry: dict[str, Any] = {
                "TimeLimit.truncated": bool(truncated[i] and not terminated[i])
            }
            if dones[i]:
                final_info = info["final_info"]
                entry["terminal_observation"] = info["final_obs"][i]
                if "is_success" in final_info:
                    entry["is_success"] = bool(final_info["is_success"][i])
            elif success is not None:
                entry["is_success"] = bool(success[i])
            infos.append(entry)
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.vector.close()

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        return list(self._get_indices(indices))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        wanted = self._indices(indices)
        if wanted == list(range(self.num_envs)):
            return list(self.vector.get_attr(attr_name))
        values = self.vector.call_some(wanted, "__getattribute__", attr_name)
        return [values[i] for i in wanted]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        wanted = self._indices(indices)
        if wanted == list(range(self.num_envs)):
            self.vector.set_attr(attr_name, value)
        else:
            self.vector.call_some(wanted, "__setattr__", attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        wanted = self._indices(indices)
        if wanted == list(range(self.num_envs)):
            return list(self.vector.call(method_name, *method_args, **method_kwargs))
        results = self.vector.call_some(wanted, method_name, *method_args, **method_kwargs)
        return [results[i] for i in wanted]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return list(self.vector.call("render"))


__all__ = ["NativeVecEnv"]
