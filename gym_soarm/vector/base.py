"""The base of the package's vector envs: the Gymnasium ``VectorEnv`` shell, written once.

:class:`SoArmVectorBase` holds what does not depend on how the simulations are stepped:
the checks of the constructor's common arguments, the spaces and metadata taken from the
first environment, the seed, reset-mask and action checks, the time limit and the
autoreset (an :class:`EpisodeClock`: the steps of each episode, which episodes ended, which
environments reset instead of stepping and which reach the limit, per
:class:`gymnasium.vector.AutoresetMode`), the final observations and infos of
``SAME_STEP``, the time limit's attribute, and
``call``/``call_some``/``get_attr``/``set_attr``/``render``/``close``. A subclass is the
transport: :class:`~gym_soarm.vector.batched.BatchedVectorEnv` (one batch of simulations
in this process) and :class:`~gym_soarm.vector.processes.SoArmVectorEnv` (worker
processes) implement ``_reset``, ``_step``, ``_call``, ``_get_attr``, ``_set_attr`` and
``close_extras``; their ``_step`` applies the clock's plan and keeps no count of its own.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.validation import check_int
from gym_soarm.vector.common import (
    TIME_LIMIT_ATTRIBUTE,
    batched_obs,
    check_actions,
    observation_leaves,
    parse_autoreset_mode,
    parse_seeds,
    pop_reset_mask,
    values_per_env,
)

StepReturn = tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]


class EpisodeClock:
    """The time limit and the autoreset of a vector env's episodes, kept once.

    Holds the steps of each environment's episode (:attr:`elapsed`, as Gymnasium's
    ``TimeLimit`` counts them) and which episodes ended and wait for a reset
    (:attr:`ended`). Before a step, :meth:`plan` says which environments reset instead
    of stepping (``NEXT_STEP``) and which reach the time limit with this step; after
    it, :meth:`advance` counts the step and notes the ends.
    """

    def __init__(self, num_envs: int, mode: AutoresetMode) -> None:
        self.mode = mode
        self.elapsed = np.zeros(num_envs, dtype=np.int64)
        self.ended = np.zeros(num_envs, dtype=np.bool_)

    def plan(self, limit: int | None) -> tuple[np.ndarray, np.ndarray]:
        """``(restart, time_up)``: the environments that reset instead of stepping, and
        those whose step reaches the time limit ``limit`` (truncated, whatever else
        happens; None: no limit)."""
        restart = np.zeros_like(self.ended)
        if self.mode is AutoresetMode.NEXT_STEP:
            restart = self.ended.copy()
        time_up = np.zeros_like(self.ended)
        if limit is not None:
            time_up = ~restart & (self.elapsed + 1 >= limit)
        return restart, time_up

    def reset(self, mask: np.ndarray | None) -> None:
        """The environments of ``mask`` (None: all) start new episodes."""
        where = slice(None) if mask is None else mask
        self.elapsed[where] = 0
        self.ended[where] = False

    def advance(
        self,
        restart: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
        done: np.ndarray | None = None,
    ) -> None:
        """Count a step of the plan ``restart`` that ended these episodes (``SAME_STEP``
        reset them already). ``done``: the environments that took their step (None:
        all; a step that raised part-way leaves the others as they were)."""
        took = np.ones_like(restart) if done is None else np.asarray(done, dtype=np.bool_)
        stepping = ~restart & took
        self.elapsed[stepping] += 1
        self.elapsed[restart & took] = 0
        ended = (terminated | truncated) & stepping
        if self.mode is AutoresetMode.SAME_STEP:
            self.elapsed[ended] = 0
            self.ended[took] = False
        else:
            self.ended[took] = ended[took]


class SoArmVectorBase(VectorEnv):
    """``num_envs`` :class:`~gym_soarm.envs.env.SoArmEnv` simulations behind Gymnasium's
    ``VectorEnv`` API; the subclass moves actions, observations and calls to them.

    Attributes:
        num_envs: number of environments.
        max_episode_steps: the time limit's step count, or None.
        autoreset_mode: the :class:`gymnasium.vector.AutoresetMode`.
        copy: whether every call returns fresh observation arrays.
        settings: every environment's settings (set by :meth:`_take_spaces`).
    """

    closed = True  # until the subclass has built its environments

    # --- construction ------------------------------------------------------------------
    def _check_arguments(
        self,
        num_envs: int,
        max_episode_steps: int | None,
        autoreset_mode: AutoresetMode | str,
        copy: bool,
    ) -> int:
        """Check and keep the arguments every vector env takes; ``num_envs`` checked.

        Raises:
            ValueError: a bad ``num_envs``, ``max_episode_steps`` or ``autoreset_mode``.
        """
        num_envs = check_int("num_envs", num_envs, 1)
        if max_episode_steps is not None:
            max_episode_steps = check_int("max_episode_steps", max_episode_steps, 1)
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        self.num_envs = num_envs
        self.copy = bool(copy)
        self.max_episode_steps = max_episode_steps
        return num_envs

    def _take_spaces(self, first: SoArmEnv) -> None:
        """The settings, metadata, render mode and spaces of ``first``, batched."""
        self.settings = first.settings
        """Every environment's settings (:class:`gym_soarm.envs.settings.EnvSettings`)."""
        self.metadata = dict(first.metadata)  # render_fps: the control rate
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.render_mode = first.render_mode
        self.single_action_space = first.action_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = first.observation_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._leaves = observation_leaves(self.single_observation_space)
        self._obs_arrays: list[np.ndarray] = []  # one array per leaf, filled by the subclass
        self._clock = EpisodeClock(self.num_envs, self.autoreset_mode)
        self._host_ends: tuple[np.ndarray, np.ndarray] | None = None
        self._started = False

    # --- what the subclass implements --------------------------------------------------
    def _reset(
        self, seeds: list[int | None], options: dict[str, Any] | None, mask: np.ndarray | None
    ) -> dict[str, Any]:
        """Reset the environments of ``mask`` (None: all) and write their observations;
        their infos, batched."""
        raise NotImplementedError

    def _step(self, actions: np.ndarray, restart: np.ndarray, time_up: np.ndarray) -> StepReturn:
        """Step with checked ``actions``: the environments of ``restart`` reset instead
        (reward 0, not ended, their reset's info), those of ``time_up`` are truncated, and
        in ``SAME_STEP`` an ended episode resets at once (:meth:`_add_finals`)."""
        raise NotImplementedError

    def _call(self, indices: list[int], name: str, args: tuple, kwargs: dict) -> list[Any]:
        """Call ``name`` (or read it) on the environments of ``indices`` (sorted)."""
        raise NotImplementedError

    def _get_attr(self, name: str) -> list[Any]:
        """The attribute ``name`` of every environment, in order."""
        raise NotImplementedError

    def _set_attr(self, name: str, values: list[Any]) -> None:
        """Set ``name`` on every environment, one value each."""
        raise NotImplementedError

    def _batched_obs(self) -> Any:
        """The observation from the leaf arrays ``_obs_arrays`` (copies if :attr:`copy`)."""
        return batched_obs(self._leaves, self._obs_arrays, self.copy)

    # --- Gymnasium API -------------------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every environment (or those of ``options["reset_mask"]``).

        Args:
            seed: None (fresh entropy), an int ``s`` (environment ``i`` gets ``s + i``) or
                one seed (or None) per environment.
            options: the reset options of every environment; ``"reset_mask"`` (a bool
                array of shape ``(num_envs,)``) resets only the marked environments.

        Returns:
            The batched observations and infos of the environments that were reset.
        """
        self._check_open()
        seeds = parse_seeds(seed, self.num_envs)
        options = dict(options) if options is not None else None
        mask = pop_reset_mask(options, self.num_envs)
        infos = self._reset(seeds, options, mask)
        self._clock.reset(mask)
        self._started = True
        return self._batched_obs(), infos

    def step(self, actions: Any) -> StepReturn:
        """Step every environment with its row of ``actions`` (shape ``(num_envs, 6)``).

        Returns:
            Batched observations, rewards (float64), terminations, truncations and infos.
            With ``NEXT_STEP`` an environment whose episode ended on the previous step is
            reset instead (reward 0, not terminated or truncated, its reset info). With
            ``SAME_STEP`` it is reset at once and ``info["final_obs"]`` and
            ``info["final_info"]`` hold the last observation and info of the episode.

        Raises:
            ValueError: actions of another shape, or not finite numbers (nothing is
                stepped).
            RuntimeError: before the first reset, or (``DISABLED``) an ended episode not
                reset yet.
        """
        self._check_open()
        if not self._started:
            raise RuntimeError("call reset() before step() on the vector environment.")
        array = check_actions(
            actions, self.action_space.shape, self.autoreset_mode, self._clock.ended
        )
        restart, time_up = self._clock.plan(self.max_episode_steps)
        obs, rewards, terminated, truncated, infos = self._step(array, restart, time_up)
        self._note_ends(restart, terminated, truncated)
        return obs, rewards, terminated, truncated, infos

    def _note_ends(self, restart: np.ndarray, terminated: Any, truncated: Any) -> None:
        """The clock counts the step of the plan ``restart`` and notes which episodes
        ended. A transport that returns the ends as tensors on a device leaves their
        host copies in ``_host_ends``, read instead."""
        if self._host_ends is not None:
            terminated, truncated = self._host_ends
        self._clock.advance(restart, np.asarray(terminated), np.asarray(truncated))

    def _add_finals(
        self, infos: dict[str, Any], finals: dict[int, tuple[Any, dict[str, Any]]]
    ) -> dict[str, Any]:
        """``SAME_STEP``: the ended episodes' last observations and infos
        (``final_obs``, ``final_info``), environment index -> (obs, info), into ``infos``."""
        for i in sorted(finals):
            final_obs, final_info = finals[i]
            infos = self._add_info(infos, {"final_obs": final_obs, "final_info": final_info}, i)
        return infos

    def render(self) -> tuple[Any, ...] | None:
        """Each environment's ``render()``."""
        if self.render_mode is None:
            return None
        return tuple(self.call("render"))

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call ``name`` (a method, or read an attribute) of every environment.

        ``_max_episode_steps`` answers the step limit, as a ``TimeLimit``-wrapped env
        made by ``gym.make`` does (LeRobot's evaluation reads it this way).

        Returns:
            One result per environment, in order.
        """
        if name == TIME_LIMIT_ATTRIBUTE:
            return self.get_attr(name)
        self._check_open()
        return tuple(self._call(list(range(self.num_envs)), name, args, kwargs))

    def call_some(
        self, indices: Sequence[int], name: str, *args: Any, **kwargs: Any
    ) -> dict[int, Any]:
        """:meth:`call` on the environments of ``indices`` only; their results by index.

        Raises:
            ValueError: an index outside ``0 .. num_envs - 1``.
        """
        self._check_open()
        wanted = sorted({check_int("index", i, 0, self.num_envs - 1) for i in indices})
        return dict(zip(wanted, self._call(wanted, name, args, kwargs), strict=True))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """The attribute ``name`` of every environment, in order."""
        if name == TIME_LIMIT_ATTRIBUTE:
            return (self.max_episode_steps,) * self.num_envs
        self._check_open()
        return tuple(self._get_attr(name))

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set ``name`` on every environment: one value each, or the same value for all."""
        self._check_open()
        self._set_attr(name, values_per_env(values, self.num_envs))

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError(
                "this vector environment was closed; create a new one with gym.make_vec(...)."
            )

    def close(self, **kwargs: Any) -> None:
        """Close all environments; idempotent."""
        if self.closed:
            return
        self.closed = True
        self.close_extras(**kwargs)


__all__ = ["SoArmVectorBase"]
