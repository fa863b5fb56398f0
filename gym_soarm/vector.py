"""A native vector environment: N SO-101 simulations stepped by a pool of threads.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")`` builds a
:class:`SoArmVectorEnv`. MuJoCo releases the GIL inside ``mj_step`` and while rendering,
so threads in one process run the simulations in parallel without the pipes and
pickling of ``AsyncVectorEnv``.

* Environment ``i`` belongs to worker thread ``i % num_threads`` for its whole life: it
  is stepped, rendered and closed there, so its GL contexts are only ever current on
  that thread (each renderer makes its context current before every frame).
* ``reset(seed=s)`` resets environment ``i`` with ``s + i``, as Gymnasium's vector
  environments do, and the episodes are those of N single ``gym.make`` environments,
  bit for bit (the time limit is that of Gymnasium's ``TimeLimit``).
* Observations and infos are batched as ``SyncVectorEnv`` batches them: a batched
  observation space, and an ``info`` dict of arrays with a ``_key`` mask per key.
* ``autoreset_mode`` is ``NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED``.
"""

from __future__ import annotations

import os
import queue
import threading
import weakref
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from gym_soarm.env import SoArmEnv

_Leaf = tuple[tuple[str, ...], tuple[int, ...], np.dtype]
_live_vector_envs: weakref.WeakSet[SoArmVectorEnv] = weakref.WeakSet()


TIME_LIMIT_ATTRIBUTE = "_max_episode_steps"
"""What Gymnasium's ``TimeLimit`` calls the step limit; the vector env answers it."""


def _close_live_vector_envs() -> None:
    """At interpreter exit: close every open vector env on its own threads.

    This runs when ``threading`` shuts down, before the ``atexit`` handlers that tear
    the GL displays down, so each GL context is freed on the thread it is current on.
    """
    for vector_env in list(_live_vector_envs):
        vector_env.close()


_register_thread_exit = getattr(threading, "_register_atexit", None)
if _register_thread_exit is not None:
    _register_thread_exit(_close_live_vector_envs)


class _WorkerThread(threading.Thread):
    """A thread that runs the jobs posted to its inbox, one at a time, in order."""

    def __init__(self, index: int, done: queue.SimpleQueue) -> None:
        super().__init__(name=f"gym_soarm-vector-{index}", daemon=True)
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._done = done

    def run(self) -> None:
        while True:
            job = self.inbox.get()
            if job is None:
                return
            function, argument = job
            try:
                function(argument)
            except BaseException as exc:  # handed to the calling thread, which re-raises
                self._done.put(exc)
            else:
                self._done.put(None)


def _parse_autoreset_mode(mode: AutoresetMode | str) -> AutoresetMode:
    if isinstance(mode, AutoresetMode):
        return mode
    names = [m.value for m in AutoresetMode]
    if isinstance(mode, str) and mode in names:
        return AutoresetMode(mode)
    raise ValueError(
        f"autoreset_mode must be a gymnasium.vector.AutoresetMode or one of {names}; got {mode!r}."
    )


def _leaves(space: spaces.Space, path: tuple[str, ...] = ()) -> list[_Leaf]:
    """The (key path, shape, dtype) of every array of an observation space, in order."""
    if isinstance(space, spaces.Dict):
        out: list[_Leaf] = []
        for key, sub in space.spaces.items():
            out.extend(_leaves(sub, (*path, key)))
        return out
    if isinstance(space, spaces.Box):
        return [(path, space.shape, space.dtype)]
    raise TypeError(
        f"SoArmVectorEnv batches Dict and Box observation spaces; got {type(space).__name__}."
    )


def _nest(flat: dict[tuple[str, ...], Any]) -> Any:
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


def _get(tree: Any, path: tuple[str, ...]) -> Any:
    for key in path:
        tree = tree[key]
    return tree


def _is_number(value: Any) -> bool:
    return type(value) in (int, float, bool) or isinstance(value, np.number)


class SoArmVectorEnv(VectorEnv):
    """``num_envs`` :class:`~gym_soarm.env.SoArmEnv` simulations stepped by worker threads.

    Made by ``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")``;
    every keyword that ``gym.make`` takes for the id is passed to each environment.

    Args:
        num_envs: number of environments (at least 1).
        max_episode_steps: truncate an episode after this many steps, as Gymnasium's
            ``TimeLimit`` does (``make_vec`` passes the id's limit); None for no limit.
        autoreset_mode: ``"NextStep"`` (default), ``"SameStep"`` or ``"Disabled"``, or a
            :class:`gymnasium.vector.AutoresetMode`.
        num_threads: worker threads (default: the number of CPUs, at most ``num_envs``).
            Environment ``i`` always runs on thread ``i % num_threads``.
        copy: return fresh observation arrays on every call (default). With False the
            same arrays are filled again by the next call.
        **env_kwargs: the arguments of :class:`~gym_soarm.env.SoArmEnv` (``task``,
            ``obs_type``, ``observation_height`` ...).

    Raises:
        ValueError: a bad ``num_envs``, ``num_threads``, ``autoreset_mode`` or
            environment argument.
    """

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        num_threads: int | None = None,
        copy: bool = True,
        **env_kwargs: Any,
    ) -> None:
        if (
            isinstance(num_envs, bool)
            or not isinstance(num_envs, (int, np.integer))
            or num_envs < 1
        ):
            raise ValueError(f"num_envs must be an int >= 1; got {num_envs!r}.")
        if num_threads is None:
            num_threads = min(int(num_envs), os.cpu_count() or 1)
        if (
            isinstance(num_threads, bool)
            or not isinstance(num_threads, (int, np.integer))
            or num_threads < 1
        ):
            raise ValueError(f"num_threads must be an int >= 1 or None; got {num_threads!r}.")
        if max_episode_steps is not None and (
            isinstance(max_episode_steps, bool)
            or not isinstance(max_episode_steps, (int, np.integer))
            or max_episode_steps < 1
        ):
            raise ValueError(
                f"max_episode_steps must be an int >= 1 or None; got {max_episode_steps!r}."
            )
        self.autoreset_mode = _parse_autoreset_mode(autoreset_mode)
        self.num_envs = int(num_envs)
        self.copy = bool(copy)
        self.max_episode_steps = max_episode_steps
        self.closed = False
        self.envs: list[SoArmEnv] = []
        self._threads: list[_WorkerThread] = []
        try:
            for _ in range(self.num_envs):
                self.envs.append(SoArmEnv(**env_kwargs))
        except BaseException:
            for env in self.envs:
                env.close()
            raise
        first = self.envs[0]
        self.metadata = dict(SoArmEnv.metadata)
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.render_mode = first.render_mode
        self.single_action_space = first.action_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = first.observation_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

        self._leaves = _leaves(self.single_observation_space)
        self._buffers = self._new_buffers()
        self._rewards = np.zeros(self.num_envs, dtype=np.float64)
        self._terminations = np.zeros(self.num_envs, dtype=np.bool_)
        self._truncations = np.zeros(self.num_envs, dtype=np.bool_)
        self._autoreset_envs = np.zeros(self.num_envs, dtype=np.bool_)
        self._elapsed = [0] * self.num_envs
        self._all_true = np.ones(self.num_envs, dtype=np.bool_)
        self._infos: list[dict[str, Any] | None] = [None] * self.num_envs
        self._final: list[tuple[Any, dict[str, Any]] | None] = [None] * self.num_envs
        self._actions: np.ndarray | None = None
        self._seeds: list[int | None] = [None] * self.num_envs
        self._options: dict[str, Any] | None = None
        self._reset_mask: np.ndarray | None = None
        self._started = False

        # Environment i always runs on partition i % T. Without cameras nothing is bound
        # to a thread, so the calling thread steps partition 0 itself (no hand-off);
        # with cameras every partition has a worker thread of its own, which holds the
        # GL contexts of its environments.
        num_threads = min(int(num_threads), self.num_envs)
        partitions = [list(range(t, self.num_envs, num_threads)) for t in range(num_threads)]
        renders = bool(first.cameras) or self.render_mode is not None
        self._caller_partition: list[int] = [] if renders else partitions.pop(0)
        self._partitions = partitions
        self._done: queue.SimpleQueue = queue.SimpleQueue()
        self._threads = [_WorkerThread(t, self._done) for t in range(len(partitions))]
        for thread in self._threads:
            thread.start()
        _live_vector_envs.add(self)

    @property
    def num_threads(self) -> int:
        """The number of threads that step environments (the calling one included)."""
        return len(self._threads) + bool(self._caller_partition)

    # --- batching ----------------------------------------------------------------------
    def _new_buffers(self) -> list[np.ndarray]:
        return [np.empty((self.num_envs, *shape), dtype) for _, shape, dtype in self._leaves]

    def _write_obs(self, i: int, obs: Any) -> None:
        for (path, _, _), buffer in zip(self._leaves, self._buffers, strict=True):
            buffer[i] = _get(obs, path)

    def _batched_obs(self) -> Any:
        buffers = self._buffers
        if self.copy:
            self._buffers = self._new_buffers()
            for new, old in zip(self._buffers, buffers, strict=True):
                new[...] = old
        return _nest({path: b for (path, _, _), b in zip(self._leaves, buffers, strict=True)})

    def _merge_infos(self, infos: Sequence[dict[str, Any] | None]) -> dict[str, Any]:
        """Batch per-environment infos exactly as ``SyncVectorEnv`` does (``_key`` masks)."""
        present = [i for i, info in enumerate(infos) if info is not None]
        if len(present) == self.num_envs:
            fast = self._merge_same_keys(infos)  # type: ignore[arg-type]
            if fast is not None:
                return fast
        merged: dict[str, Any] = {}
        for i in present:
            merged = self._add_info(merged, infos[i], i)  # type: ignore[arg-type]
        return merged

    def _merge_same_keys(self, infos: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
        """The batched infos when every env has the same keys and value types, else None.

        Gives what ``SyncVectorEnv``'s per-environment ``_add_info`` gives, with one
        numpy call per key instead of one assignment per key and environment.
        """
        first_info = infos[0]
        keys = list(first_info)
        if "final_obs" in first_info:
            return None  # kept unbatched, as _add_info keeps it
        for info in infos:
            if list(info) != keys:
                return None
        merged: dict[str, Any] = {}
        n = self.num_envs
        ones = self._all_true
        for key in keys:
            values = [info[key] for info in infos]
            first = values[0]
            kind = type(first)
            for value in values:
                if type(value) is not kind:
                    return None
            if kind is dict:
                array: Any = self._merge_same_keys(values)
                if array is None:
                    return None
            elif kind in (bool, int, float) or issubclass(kind, np.number):
                array = np.array(values, dtype=kind)
            elif kind is np.ndarray:
                try:
                    array = np.array(values, dtype=first.dtype)
                except ValueError:
                    return None  # shapes differ
                if array.shape != (n, *first.shape):
                    return None
            elif kind is str:
                array = np.empty(n, dtype=object)
                array[:] = values
            else:
                return None
            merged[key] = array
            merged[f"_{key}"] = ones.copy()
        return merged

    # --- running jobs on the worker threads --------------------------------------------
    def _run(self, job: Callable[[list[int]], None]) -> None:
        """Run ``job(partition)`` on every worker thread and wait; re-raise the first error."""
        if self.closed:
            raise RuntimeError(
                "this vector environment was closed; create a new one with gym.make_vec(...)."
            )
        for thread, partition in zip(self._threads, self._partitions, strict=True):
            thread.inbox.put((job, partition))
        error: BaseException | None = None
        if self._caller_partition:
            try:
                job(self._caller_partition)
            except BaseException as exc:  # wait for the workers before raising
                error = exc
        for _ in self._threads:
            result = self._done.get()
            if result is not None and error is None:
                error = result
        if error is not None:
            raise error

    def _reset_job(self, partition: list[int]) -> None:
        mask = self._reset_mask
        for i in partition:
            if mask is not None and not mask[i]:
                continue
            obs, info = self.envs[i].reset(seed=self._seeds[i], options=self._options)
            self._elapsed[i] = 0
            self._write_obs(i, obs)
            self._infos[i] = info

    def _step_job(self, partition: list[int]) -> None:
        envs, actions, elapsed, limit = (
            self.envs,
            self._actions,
            self._elapsed,
            self.max_episode_steps,
        )
        rewards, terms, truncs = self._rewards, self._terminations, self._truncations
        mode = self.autoreset_mode
        for i in partition:
            env = envs[i]
            if mode is AutoresetMode.NEXT_STEP and self._autoreset_envs[i]:
                obs, info = env.reset()
                elapsed[i] = 0
                rewards[i] = 0.0
                terms[i] = truncs[i] = False
            else:
                obs, reward, terminated, truncated, info = env.step(actions[i])  # type: ignore[index]
                elapsed[i] += 1
                if limit is not None and elapsed[i] >= limit:
                    truncated = True
                rewards[i] = reward
                terms[i] = terminated
                truncs[i] = truncated
                if mode is AutoresetMode.SAME_STEP and (terminated or truncated):
                    self._final[i] = (obs, info)
                    obs, info = env.reset()
                    elapsed[i] = 0
            self._write_obs(i, obs)
            self._infos[i] = info

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
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(
                    f"seed must be None, an int or a list of num_envs={self.num_envs} seeds; "
                    f"got a list of length {len(seeds)}."
                )
        options = dict(options) if options is not None else None
        mask = None
        if options is not None and "reset_mask" in options:
            mask = np.asarray(options.pop("reset_mask"))
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({self.num_envs},) "
                    f"with at least one True; got {mask!r}."
                )
        self._seeds, self._options, self._reset_mask = seeds, options, mask
        self._infos = [None] * self.num_envs
        self._run(self._reset_job)
        reset = np.ones(self.num_envs, np.bool_) if mask is None else mask
        self._terminations[reset] = False
        self._truncations[reset] = False
        self._autoreset_envs[reset] = False
        self._started = True
        return self._batched_obs(), self._merge_infos(self._infos)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every environment with its row of ``actions`` (shape ``(num_envs, 6)``).

        Returns:
            Batched observations, rewards (float64), terminations, truncations and infos.
            With ``NEXT_STEP`` an environment whose episode ended on the previous step is
            reset instead (reward 0, not terminated or truncated, its reset info). With
            ``SAME_STEP`` it is reset at once and ``info["final_obs"]`` and
            ``info["final_info"]`` hold the last observation and info of the episode.
        """
        if not self._started:
            raise RuntimeError("call reset() before step() on the vector environment.")
        array = np.asarray(actions)
        expected = self.action_space.shape
        if array.shape != expected:
            raise ValueError(
                f"actions must have shape {expected} (one row of joint targets per "
                f"environment); got shape {array.shape}."
            )
        if self.autoreset_mode is AutoresetMode.DISABLED and self._autoreset_envs.any():
            done = np.flatnonzero(self._autoreset_envs).tolist()
            raise RuntimeError(
                f"environments {done} ended their episodes and autoreset_mode is DISABLED: "
                "reset them first with reset(options={'reset_mask': mask})."
            )
        self._actions = array
        self._final = [None] * self.num_envs
        self._run(self._step_job)
        infos = self._merge_infos(self._infos)
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            for i, final in enumerate(self._final):
                if final is not None:
                    infos = self._add_info(
                        infos, {"final_obs": final[0], "final_info": final[1]}, i
                    )
        self._autoreset_envs = np.logical_or(self._terminations, self._truncations)
        return (
            self._batched_obs(),
            np.copy(self._rewards),
            np.copy(self._terminations),
            np.copy(self._truncations),
            infos,
        )

    def render(self) -> tuple[Any, ...] | None:
        """Each environment's ``render()``, rendered on its own worker thread."""
        if self.render_mode is None:
            return None
        return tuple(self.call("render"))

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call ``name`` (a method, or read an attribute) of every environment on its thread.

        ``_max_episode_steps`` answers the step limit, as a ``TimeLimit``-wrapped env
        made by ``gym.make`` does (LeRobot's evaluation reads it this way).

        Returns:
            One result per environment, in order.
        """
        if name == TIME_LIMIT_ATTRIBUTE:
            return self.get_attr(name)
        results: list[Any] = [None] * self.num_envs

        def job(partition: list[int]) -> None:
            for i in partition:
                attribute = getattr(self.envs[i], name)
                results[i] = attribute(*args, **kwargs) if callable(attribute) else attribute

        self._run(job)
        return tuple(results)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """The attribute ``name`` of every environment, in order."""
        if name == TIME_LIMIT_ATTRIBUTE:
            return (self.max_episode_steps,) * self.num_envs
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set ``name`` on every environment: one value each, or the same value for all."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(
                f"values must hold one value per environment (num_envs={self.num_envs}); "
                f"got {len(values)}."
            )
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    def close_extras(self, **kwargs: Any) -> None:
        """Close every environment on its own worker thread, then stop the threads."""
        if self._threads or self._caller_partition:

            def job(partition: list[int]) -> None:
                for i in partition:
                    self.envs[i].close()

            try:
                self._run(job)
            finally:
                for thread in self._threads:
                    thread.inbox.put(None)
                for thread in self._threads:
                    if thread is not threading.current_thread():
                        thread.join()
                self._threads = []
        else:
            for env in self.envs:
                env.close()
        _live_vector_envs.discard(self)

    def close(self, **kwargs: Any) -> None:
        """Close all environments (their GL contexts on their own threads); idempotent."""
        if self.closed:
            return
        self.close_extras(**kwargs)
        self.closed = True


__all__ = ["SoArmVectorEnv"]
