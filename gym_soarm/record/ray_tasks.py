"""Recording on a Ray cluster: each attempt is a Ray task, merged here in attempt order.

``record(..., ray_address=ADDRESS)`` (``--ray [ADDRESS]``) connects to a running cluster
(``"auto"``, ``"ray://host:10001"``, ``"host:6379"``) or, with ``"local"``, starts a
local one. Every cluster node needs gym_soarm installed (``pip install
"gym-soarm[ray]"``). A task plays one attempt in a Ray worker process (which keeps its
environment and expert for the next tasks of the same recording) and returns the
episode's shard as bytes, so the nodes need no shared file system; this process merges
the shards exactly as :mod:`gym_soarm.record.parallel` does, so the dataset is the same
as with one process. Ray runs a task again when its worker dies.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import shutil
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from gym_soarm.data.format import SCRATCH_DIR
from gym_soarm.data.writer import LeRobotDatasetWriter
from gym_soarm.record.attempt import AttemptPlan, record_attempt
from gym_soarm.record.parallel import OrderedMerger

# Times Ray runs a task again when its worker process dies.
TASK_RETRIES = 3
_worker_state: dict[str, Any] = {}


def require_ray() -> Any:
    """The ``ray`` module, or ImportError with the install command."""
    try:
        import ray
    except ImportError:
        raise ImportError(
            'recording with --ray needs Ray: pip install "gym-soarm[ray]" (or pip install ray).'
        ) from None
    return ray


def _close_worker_state() -> None:
    if not _worker_state:
        return
    _worker_state["env"].close()
    _worker_state["writer"].finalize()
    shutil.rmtree(_worker_state["scratch"], ignore_errors=True)
    _worker_state.clear()


def play_attempt(
    token: str, plan: AttemptPlan, attempt: int
) -> tuple[int, bool, dict | None, dict | None]:
    """A Ray task: play ``attempt``; return (attempt, success, shard files or None, variation).

    The shard is ``{file name: bytes}`` of the folder that
    :meth:`~gym_soarm.data.writer.LeRobotDatasetWriter.export_episode` writes.
    """
    import gymnasium as gym

    from gym_soarm.expert import make_expert
    from gym_soarm.tasks import register_task, task_names

    if _worker_state.get("token") != token:
        if not _worker_state:
            atexit.register(_close_worker_state)
        _close_worker_state()
        if plan.spec.name not in task_names():
            register_task(plan.spec)
        scratch = Path(tempfile.mkdtemp(prefix="gym_soarm-ray-"))
        env = gym.make(plan.spec.env_id, **plan.env_kwargs)
        _worker_state.update(
            token=token,
            scratch=scratch,
            env=env,
            expert=make_expert(env),
            writer=LeRobotDatasetWriter.create(
                scratch / "writer", plan.fps, plan.features, robot_type=plan.robot_type
            ),
        )
    state = _worker_state
    writer = state["writer"]
    success, drawn = record_attempt(state["env"], state["expert"], writer, plan, attempt)
    if not (success or plan.keep == "all"):
        writer.clear_episode_buffer()
        return attempt, success, None, drawn
    shard = state["scratch"] / f"attempt-{attempt:07d}"
    writer.export_episode(shard)
    files = {path.name: path.read_bytes() for path in shard.iterdir()}
    shutil.rmtree(shard, ignore_errors=True)
    return attempt, success, files, drawn


def _connect(ray: Any, address: str) -> bool:
    """Connect to (or start) the Ray cluster unless connected; whether this call did."""
    if ray.is_initialized():
        return False
    ray.init(
        address=None if address == "local" else address,
        include_dashboard=False,
        log_to_driver=False,
        runtime_env={"env_vars": {"PYTHONPATH": os.environ.get("PYTHONPATH", "")}}
        if os.environ.get("PYTHONPATH")
        else None,
    )
    return True


@contextlib.contextmanager
def ray_session(address: str) -> Iterator[None]:
    """Stay connected to the Ray cluster at ``address`` (``"local"``: a new local one)
    across several recordings, so a multi-task recording starts Ray once."""
    ray = require_ray()
    started_here = _connect(ray, address)
    try:
        yield
    finally:
        if started_here:
            ray.shutdown()


def _collect(ray: Any, ref: Any, shard_root: Path, merger: OrderedMerger) -> None:
    """Hand a finished task's attempt to ``merger``, its shard written under ``shard_root``."""
    try:
        attempt, success, files, drawn = ray.get(ref)
    except Exception as exc:  # Ray wraps the task's error; ours names the attempt
        raise RuntimeError(f"a Ray recording task failed for good: {exc}") from exc
    shard = None
    if files is not None:
        shard = shard_root / f"attempt-{attempt:07d}"
        shutil.rmtree(shard, ignore_errors=True)
        shard.mkdir()
        for name, content in files.items():
            (shard / name).write_bytes(content)
    merger.add(attempt, success, shard, drawn)


def record_with_ray(
    writer: LeRobotDatasetWriter,
    plan: AttemptPlan,
    episodes: int,
    max_attempts: int,
    address: str,
    parallel: int | None = None,
    bar: Any = None,
) -> tuple[int, int, bool]:
    """Record attempts as Ray tasks into ``writer``, merged in attempt order.

    Args:
        writer: the dataset being written.
        plan: the recording's settings, sent with every task.
        episodes: episodes to keep.
        max_attempts: attempts to make at most.
        address: a Ray cluster address for ``ray.init`` (``"auto"``, ``"host:6379"``,
            ``"ray://host:10001"``), or ``"local"`` to start a local cluster.
        parallel: tasks in flight at most (default: the cluster's CPUs).
        bar: a tqdm progress bar to update, or None.

    Returns:
        (attempts, successes, interrupted), as :func:`~gym_soarm.record.parallel.record_in_workers`.

    Raises:
        ImportError: Ray is not installed.
        RuntimeError: a task failed for good (its error is chained).
    """
    ray = require_ray()
    started_here = _connect(ray, address)
    if parallel is None:
        parallel = max(1, int(ray.cluster_resources().get("CPU", 1)))
    task = ray.remote(num_cpus=1, max_retries=TASK_RETRIES)(play_attempt)
    token = uuid.uuid4().hex
    plan_ref = ray.put(plan)
    shard_root = writer.root / SCRATCH_DIR / "shards"
    shard_root.mkdir(parents=True, exist_ok=True)
    merger = OrderedMerger(
        writer, plan.seed, episodes, max_attempts, bar, f"ray x{parallel}", plan.spec.name
    )
    pending: list[Any] = []
    interrupted = False
    try:
        while True:
            merger.merge_ready()
            if merger.finished:
                break
            while len(pending) < parallel:
                attempt = merger.take_attempt()
                if attempt is None:
                    break
                pending.append(task.remote(token, plan_ref, attempt))
            if not pending:
                raise RuntimeError(
                    f"no Ray task is running and attempt {merger.merged} has no result; "
                    "expected a task to be playing it (this is a bug in gym_soarm)."
                )
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                _collect(ray, ref, shard_root, merger)
    except KeyboardInterrupt:
        interrupted = True
        merger.merge_finished()
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()
    return merger.merged, merger.successes, interrupted
