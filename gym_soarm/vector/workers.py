"""How gym_soarm starts worker processes: one multiprocessing context for all of them.

The vector env (:mod:`gym_soarm.vector.processes`) and the recorder (:mod:`gym_soarm.record.parallel`)
run their environments in worker processes. Both start them with ``forkserver`` where
the platform has it, else ``spawn``: never ``fork``, because a forked child would share
the parent's OpenGL contexts and threads. The fork server imports the modules it is
told to preload once and forks every worker from there, so a worker starts in tens of
milliseconds instead of importing MuJoCo again.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Sequence
from multiprocessing.connection import Connection
from multiprocessing.context import BaseContext
from typing import Any

from gym_soarm.validation import check_choice

START_METHODS: tuple[str, ...] = ("forkserver", "spawn")
"""The start methods gym_soarm's worker processes accept."""


def default_start_method() -> str:
    """``"forkserver"`` where the platform has it, else ``"spawn"``."""
    return "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"


def worker_context(start_method: str | None, preload: Sequence[str] = ()) -> BaseContext:
    """The multiprocessing context that starts workers with ``start_method``.

    Args:
        start_method: ``"forkserver"``, ``"spawn"`` or None (the default of the platform,
            :func:`default_start_method`).
        preload: modules the fork server imports before it forks any worker (only
            before the fork server first starts; later calls add nothing).

    Raises:
        ValueError: a start method other than those of :data:`START_METHODS`.
    """
    if start_method is None:
        start_method = default_start_method()
    check_choice("start_method", start_method, START_METHODS)
    context = multiprocessing.get_context(start_method)
    if start_method == "forkserver" and preload:
        context.set_forkserver_preload(list(preload))
    return context


def end_process(process: Any, conn: Connection, timeout: float) -> None:
    """Wait up to ``timeout`` s for a worker told to stop, kill it if it has not, and
    close its pipe: no process is left behind."""
    process.join(timeout)
    if process.is_alive():
        process.kill()
        process.join()
    conn.close()


def cpu_count() -> int:
    """The CPUs this process may run on (its affinity where the platform reports it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


__all__ = ["START_METHODS", "cpu_count", "default_start_method", "end_process", "worker_context"]
