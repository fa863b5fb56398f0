"""A native vector environment: N SO-101 simulations stepped in worker processes.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")`` builds a
:class:`SoArmVectorEnv`.

* The environments are split into contiguous blocks over ``num_processes`` processes
  (default: one per CPU, at most ``num_envs``): this process steps one block itself
  and each worker process another, at the same time. One message wakes a worker per
  step; it steps its whole block and writes observations, rewards, terminations,
  truncations and the numbers of its infos (:mod:`gym_soarm.envs.infos`) straight into
  shared memory, so only the values of the infos that are not numbers travel through
  its pipe. The actions travel the other way through shared memory too.
* ``num_processes=1`` keeps every environment in this process (no worker at all).
* Workers start with ``forkserver`` (or ``spawn``, see :mod:`gym_soarm.vector.workers`), so
  each owns its OpenGL contexts; a script that makes the vector env runs it under
  ``if __name__ == "__main__":``.
* ``reset(seed=s)`` resets environment ``i`` with ``s + i``, as Gymnasium's vector
  environments do, and the episodes are those of N single ``gym.make`` environments,
  bit for bit (the time limit is that of Gymnasium's ``TimeLimit``).
* Observations and infos are batched as ``SyncVectorEnv`` batches them: a batched
  observation space, and an ``info`` dict of arrays with a ``_key`` mask per key.
* ``autoreset_mode`` is ``NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED``.
* A worker that dies raises :class:`WorkerDiedError` in the caller and closes the
  vector env; ``close()`` ends every worker process.
"""

from __future__ import annotations

import contextlib
import ctypes
import pickle
import signal
import traceback
import weakref
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.envs.infos import InfoReader, merge
from gym_soarm.validation import check_choice, check_int
from gym_soarm.vector.base import SoArmVectorBase, StepReturn
from gym_soarm.vector.blocks import Block, Field, block_size, layout, views
from gym_soarm.vector.common import Leaf
from gym_soarm.vector.workers import START_METHODS, cpu_count, end_process, worker_context

CLOSE_TIMEOUT_S = 10.0
"""How long ``close()`` waits for a worker to close its environments before ending it."""


class WorkerDiedError(RuntimeError):
    """A worker process of :class:`SoArmVectorEnv` ended while the caller waited on it."""


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a RuntimeError with its text."""
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:  # any failure to pickle: send the text instead
        return RuntimeError(f"{type(exc).__name__}: {exc}")
    return exc


def _make_envs(count: int, env_kwargs: dict[str, Any]) -> list[SoArmEnv]:
    envs: list[SoArmEnv] = []
    try:
        for _ in range(count):
            envs.append(SoArmEnv(**env_kwargs))
    except BaseException:
        for env in envs:
            env.close()
        raise
    return envs


def _worker_main(
    conn: Connection,
    block: Any,
    fields: list[Field],
    leaves: list[Leaf],
    first: int,
    count: int,
    spec: Any,
    env_kwargs: dict[str, Any],
    autoreset_mode: AutoresetMode,
) -> None:
    """A worker process: build ``count`` environments, then serve the caller's commands.

    Each command ``(name, args)`` is a method of :class:`~gym_soarm.vector.blocks.Block`; the reply is
    ``("ok", result)`` or ``("error", exception, traceback text)``. ``"close"`` closes
    the environments, replies and ends the process.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the caller's to handle
    from gym_soarm.tasks import register_task, task_names

    try:
        if spec.name not in task_names():
            register_task(spec)  # a task registered by the caller's own code
        runner = Block(
            _make_envs(count, env_kwargs),
            first,
            views(block, fields),
            leaves,
            autoreset_mode,
        )
    except Exception as exc:  # handed to the caller, which raises it
        conn.send(("error", _portable(exc), traceback.format_exc()))
        return
    conn.send(("ok", None))
    try:
        while True:
            try:
                name, args = conn.recv()
            except EOFError:
                return  # the caller went away
            if name == "close":
                break
            try:
                reply: tuple[Any, ...] = ("ok", getattr(runner, name)(*args))
            except Exception as exc:  # handed to the caller, which raises it
                reply = ("error", _portable(exc), traceback.format_exc())
            try:
                conn.send(reply)
            except (pickle.PicklingError, TypeError, AttributeError) as exc:
                # Nothing was written: a result that does not pickle is an error instead.
                problem = TypeError(
                    f"the result of {name}() cannot travel back from a worker process "
                    f"({exc}); ask for a value that pickles."
                )
                conn.send(("error", problem, traceback.format_exc()))
    finally:
        runner.close()
    conn.send(("ok", None))


class _Worker:
    """One worker process, its pipe and the rows of the environments it holds."""

    def __init__(self, index: int, rows: range, process: Any, conn: Connection) -> None:
        self.index = index
        self.rows = rows
        self.process = process
        self.conn = conn

    def describe(self) -> str:
        first, last = self.rows[0], self.rows[-1]
        envs = f"environment {first}" if first == last else f"environments {first}-{last}"
        return f"worker process {self.index} (pid {self.process.pid}, {envs})"


def _stop_workers(workers: list[_Worker], timeout: float) -> None:
    """Ask every worker to close its environments, wait up to ``timeout``, then kill."""
    for worker in workers:
        if worker.process.is_alive():
            with contextlib.suppress(OSError, ValueError):
                worker.conn.send(("close", ()))
    for worker in workers:
        with contextlib.suppress(OSError, EOFError, ValueError):
            if worker.process.is_alive() and worker.conn.poll(timeout):
                worker.conn.recv()
        end_process(worker.process, worker.conn, timeout)


def _exit_text(exitcode: int | None) -> str:
    if exitcode is None:
        return "an unknown status"
    if exitcode < 0:
        with contextlib.suppress(ValueError):
            return f"signal {signal.Signals(-exitcode).name}"
        return f"signal {-exitcode}"
    return f"exit code {exitcode}"


class SoArmVectorEnv(SoArmVectorBase):
    """``num_envs`` :class:`~gym_soarm.envs.env.SoArmEnv` simulations stepped in worker processes.

    Made by ``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")``;
    every keyword that ``gym.make`` takes for the id is passed to each environment.

    Args:
        num_envs: number of environments (at least 1).
        max_episode_steps: truncate an episode after this many steps, as Gymnasium's
            ``TimeLimit`` does (``make_vec`` passes the id's limit); None for no limit.
        autoreset_mode: ``"NextStep"`` (default), ``"SameStep"`` or ``"Disabled"``, or a
            :class:`gymnasium.vector.AutoresetMode`.
        num_processes: processes that step the environments, this one included
            (default: the CPUs this process may use; at most ``num_envs``). Each holds
            a contiguous block of environments, the sizes differing by one at most;
            this process takes a smallest block (it also batches the results), the
            worker processes the others. 1 steps every environment in this process.
        start_method: ``"forkserver"`` (default where available) or ``"spawn"``.
        copy: return fresh observation arrays on every call (default). With False the
            same (shared) arrays are filled again by the next call.
        **env_kwargs: the arguments of :class:`~gym_soarm.envs.env.SoArmEnv` (``task``,
            ``obs_type``, ``observation_height`` ...).

    Raises:
        ValueError: a bad ``num_envs``, ``num_processes``, ``autoreset_mode``,
            ``start_method`` or environment argument (checked in this process, before
            any worker starts).
    """

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        num_processes: int | None = None,
        start_method: str | None = None,
        copy: bool = True,
        **env_kwargs: Any,
    ) -> None:
        self.closed = True  # until every worker is up
        self._workers: list[_Worker] = []
        num_envs = self._check_arguments(num_envs, max_episode_steps, autoreset_mode, copy)
        if num_processes is None:
            num_processes = cpu_count()
        num_processes = min(check_int("num_processes", num_processes, 1), num_envs)
        if start_method is not None:
            check_choice("start_method", start_method, START_METHODS)

        # The first environment checks every argument here and gives the spaces.
        first = SoArmEnv(**env_kwargs)
        self._take_spaces(first)
        fields = layout(num_envs, self.single_action_space.shape, self._leaves)

        # Block sizes differ by one at most; this process takes a smallest one, as it
        # also batches the results.
        sizes = sorted(len(b) for b in np.array_split(np.arange(num_envs), num_processes))
        context = None
        if num_processes > 1:
            context = worker_context(start_method, preload=[__name__])
            self._block_memory: Any = context.RawArray(ctypes.c_uint8, block_size(fields))
        else:
            self._block_memory = bytearray(block_size(fields))
        self._arrays = views(self._block_memory, fields)
        try:
            envs = [first, *_make_envs(sizes[0] - 1, env_kwargs)]
        except BaseException:
            first.close()
            raise
        self._local = Block(envs, 0, self._arrays, self._leaves, self.autoreset_mode)
        self._rows = [self._local.rows]
        if context is not None:
            try:
                self._start_workers(context, sizes[1:], fields, first.task_spec, env_kwargs)
            except BaseException:
                self._local.close()
                raise
        self._finalizer = weakref.finalize(self, _stop_workers, self._workers, CLOSE_TIMEOUT_S)
        self._info_reader = InfoReader(self._arrays["infos"], self._rows)

        self._obs_arrays = [self._arrays[f"obs{k}"] for k in range(len(self._leaves))]
        self._all_true = np.ones(self.num_envs, dtype=np.bool_)
        self.closed = False

    def _start_workers(
        self,
        context: Any,
        sizes: list[int],
        fields: list[Field],
        spec: Any,
        env_kwargs: dict[str, Any],
    ) -> None:
        first = self._local.rows.stop
        try:
            for index, size in enumerate(sizes):
                conn, child = context.Pipe()
                process = context.Process(
                    target=_worker_main,
                    name=f"gym_soarm-vector-{index}",
                    args=(
                        child,
                        self._block_memory,
                        fields,
                        self._leaves,
                        first,
                        size,
                        spec,
                        env_kwargs,
                        self.autoreset_mode,
                    ),
                    daemon=True,
                )
                process.start()
                child.close()
                self._workers.append(_Worker(index + 1, range(first, first + size), process, conn))
                self._rows.append(range(first, first + size))
                first += size
            _, error = self._collect("start")
            if error is not None:
                raise error
        except BaseException:
            _stop_workers(self._workers, 1.0)
            self._workers.clear()
            raise

    @property
    def num_processes(self) -> int:
        """The processes that step environments: this one and the workers."""
        return 1 + len(self._workers)

    @property
    def worker_pids(self) -> tuple[int, ...]:
        """The process ids of the workers, in order (empty with ``num_processes=1``)."""
        return tuple(int(w.process.pid) for w in self._workers)

    # --- talking to the workers ---------------------------------------------------------
    def _ask(
        self,
        name: str,
        args: Sequence[tuple[Any, ...]],
        partial: Callable[[list[Any]], None] | None = None,
    ) -> list[Any]:
        """Run ``Block.<name>(*args[p])`` for every block (this process's is block 0) at
        once; the results in block order.

        Every worker answers before anything is raised, so the pipes stay in step; when a
        block raised, ``partial`` first sees the others' results (None for the failed).
        An interruption (Ctrl-C) in the middle closes the vector env: its workers may
        still be writing into the shared memory.
        """
        self._check_open()
        messages = []
        for worker_args in args[1:]:
            try:
                messages.append(ForkingPickler.dumps((name, worker_args)))
            except (pickle.PicklingError, TypeError, AttributeError) as exc:
                raise TypeError(
                    f"the arguments of {name}() cannot travel to the worker processes ({exc}); "
                    "pass values that pickle."
                ) from None
        try:
            for worker, message in zip(self._workers, messages, strict=True):
                with contextlib.suppress(OSError):  # it died: _collect names it
                    worker.conn.send_bytes(message)
            try:
                here = getattr(self._local, name)(*args[0])
            except Exception:
                replies, _ = self._collect(name)
                if partial is not None:
                    partial([None, *replies])
                raise
            replies, error = self._collect(name)
        except (Exception, WorkerDiedError):
            raise
        except BaseException:
            self.close()  # Ctrl-C between a request and its replies
            raise
        if error is not None:
            if partial is not None:
                partial([here, *replies])
            raise error
        return [here, *replies]

    def _collect(self, what: str) -> tuple[list[Any], BaseException | None]:
        """Every worker's reply, in order (None where it raised), and the first error.

        Raises:
            WorkerDiedError: a worker ended; the vector env is closed.
        """
        results: list[Any] = [None] * len(self._workers)
        error: BaseException | None = None
        dead: _Worker | None = None
        pending = list(enumerate(self._workers))
        while pending:
            watched = [w.conn for _, w in pending] + [w.process.sentinel for _, w in pending]
            ready = set(wait(watched))
            still = []
            for k, worker in pending:
                if worker.conn not in ready and worker.process.sentinel not in ready:
                    still.append((k, worker))
                    continue
                try:
                    reply = worker.conn.recv() if worker.conn.poll() else None
                except (EOFError, OSError):
                    reply = None
                if reply is None:
                    if worker.process.is_alive():
                        still.append((k, worker))  # the sentinel fired first; the reply follows
                        continue
                    dead = dead or worker
                elif reply[0] == "ok":
                    results[k] = reply[1]
                elif error is None:
                    error, text = reply[1], reply[2]
                    if hasattr(error, "add_note"):
                        error.add_note(f"raised in a vector env worker process:\n{text}")
            pending = still
            if dead is not None:
                break
        if dead is not None:
            dead.process.join(1.0)
            text = (
                f"{dead.describe()} died with {_exit_text(dead.process.exitcode)} during "
                f"{what}(); the vector environment is closed. Create a new one with "
                "gym.make_vec(...)."
            )
            if what == "start":
                text += (
                    " A worker imports the main module again: a script that makes the vector "
                    'env must do it under `if __name__ == "__main__":` (and not from stdin); '
                    "or pass num_processes=1."
                )
            self.close()
            raise WorkerDiedError(text)
        return results, error

    def _split(self, values: Sequence[Any]) -> list[list[Any]]:
        """``values`` (one per environment) cut into each block's share."""
        return [list(values[rows.start : rows.stop]) for rows in self._rows]

    # --- the transport under SoArmVectorBase -------------------------------------------
    def _reset(
        self, seeds: list[int | None], options: dict[str, Any] | None, mask: np.ndarray | None
    ) -> dict[str, Any]:
        shares = self._split(seeds)
        masks = self._split(mask.tolist()) if mask is not None else [None] * len(shares)
        args = [(share, options, part) for share, part in zip(shares, masks, strict=True)]
        infos = [info for part in self._ask("reset", args) for info in part]
        reset = self._all_true if mask is None else mask
        self._arrays["terminations"][reset] = False
        self._arrays["truncations"][reset] = False
        return merge(infos, self._all_true, self._add_info)

    def _step(self, actions: np.ndarray, restart: np.ndarray, time_up: np.ndarray) -> StepReturn:
        """One step of every block at once, each in its process (the blocks apply the
        clock's plan, read from the shared memory, to their environments).

        Raises:
            WorkerDiedError: a worker process ended; the vector env is closed.
        """
        self._arrays["actions"][...] = actions
        self._arrays["restart"][...] = restart
        self._arrays["time_up"][...] = time_up
        self._arrays["stepped"][...] = False
        messages = []
        finals: dict[int, tuple[Any, dict[str, Any]]] = {}
        parts = self._ask("step", [()] * self.num_processes, partial=self._after_failed_step)
        for message, part_finals in parts:
            messages.append(message)
            finals.update(part_finals)
        merged = self._add_finals(self._info_reader.read(messages, self._add_info), finals)
        return (
            self._batched_obs(),
            self._arrays["rewards"].copy(),
            self._arrays["terminations"].copy(),
            self._arrays["truncations"].copy(),
            merged,
        )

    def _after_failed_step(self, parts: list[Any]) -> None:
        """A block raised during a step: keep what the others sent (their new info
        layouts, their episodes' ends), so the next step reads them right. The clock
        counts the step of the environments that took it (their rows of ``stepped``); the
        others keep their count and their pending reset."""
        self._info_reader.note([None if part is None else part[0] for part in parts])
        arrays = self._arrays
        self._clock.advance(
            arrays["restart"].copy(),
            arrays["terminations"].copy(),
            arrays["truncations"].copy(),
            done=arrays["stepped"].copy(),
        )

    # --- calls and attributes (arguments and results travel between processes: they
    # must pickle) ---------------------------------------------------------------------------
    def _call(self, indices: list[int], name: str, args: tuple, kwargs: dict) -> list[Any]:
        if len(indices) == self.num_envs:
            shares: list[tuple[Any, ...]] = [(name, args, kwargs)] * self.num_processes
        else:
            wanted = set(indices)
            mask = [i in wanted for i in range(self.num_envs)]
            shares = [(name, args, kwargs, part) for part in self._split(mask)]
        results = [r for part in self._ask("call", shares) for r in part]
        return [results[i] for i in indices]

    def _get_attr(self, name: str) -> list[Any]:
        shares = [(name,)] * self.num_processes
        return [r for part in self._ask("get_attr", shares) for r in part]

    def _set_attr(self, name: str, values: list[Any]) -> None:
        self._ask("set_attr", [(name, share) for share in self._split(values)])

    def close_extras(self, **kwargs: Any) -> None:
        """Close every environment (each in its worker), then end the worker processes."""
        try:
            self._local.close()
        finally:
            self._finalizer()  # _stop_workers, once


__all__ = ["SoArmVectorEnv", "WorkerDiedError"]
