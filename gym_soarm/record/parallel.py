"""Recording in worker processes: attempts run in parallel, episodes merge in order.

:func:`record_in_workers` starts N - 1 local worker processes (``forkserver`` or
``spawn``) and plays attempts in this process too, so N processes record. Each builds
its own environment and expert, plays attempts and exports each episode to a shard (its
numbers and one encoded H.264 segment per camera, see
:meth:`~gym_soarm.data.writer.LeRobotDatasetWriter.export_episode`); the merge moves the
segments into the dataset without decoding them. This process merges the shards
strictly in attempt order and keeps the first ``episodes`` kept attempts, so the
dataset is the same, frame for frame, whatever the number of workers and however they
are scheduled.

* A worker is sent attempts only once it has built its environment and said so; until
  then, and whenever no worker is free, this process plays the next attempt itself.
  A state-only recording starts its workers only if, after one attempt played here,
  the attempts left take longer than starting them (:data:`WORKER_START_S`). So a
  short recording is never slower than in one process.

* A worker that dies (e.g. SIGKILL) is replaced, and its attempt runs again, from its
  seed, in the new worker: no episode is lost or duplicated.
* Ctrl-C stops the workers; every episode already finished is merged and kept.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import threading
import time
import traceback
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from gym_soarm.data.format import SCRATCH_DIR
from gym_soarm.data.writer import LeRobotDatasetWriter
from gym_soarm.record.attempt import AttemptPlan, record_attempt, write_variation
from gym_soarm.vector.workers import end_process, worker_context

# How many times one attempt may take its worker down before the recording gives up.
MAX_DEATHS_PER_ATTEMPT = 3

WORKER_START_S = 1.0
"""About what starting the workers costs on two cores (the fork server imports the
recorder, each worker builds its environment). A recording with cameras starts them at
once; a state-only one, whose attempts take a fraction of a second, first plays one
attempt here and starts them only if the attempts left take longer than this."""


class _Player:
    """An environment, its expert and a scratch dataset: plays attempts into shards."""

    def __init__(self, plan: AttemptPlan, shard_root: Path) -> None:
        import gymnasium as gym

        from gym_soarm.expert import make_expert
        from gym_soarm.tasks import register_task, task_names

        self.plan = plan
        self.shard_root = shard_root
        self.scratch = shard_root / f"worker-{os.getpid()}"
        self.env = self.writer = None
        try:
            if plan.spec.name not in task_names():
                register_task(plan.spec)  # a task registered by the parent's own code
            self.env = gym.make(plan.spec.env_id, **plan.env_kwargs)
            self.expert = make_expert(self.env)
        except BaseException:
            self.close()
            raise

    def _record(
        self, writer: LeRobotDatasetWriter, attempt: int
    ) -> tuple[bool, bool, dict[str, Any] | None]:
        """Play ``attempt`` into ``writer``'s buffer: whether to keep it (else the buffer
        is cleared), whether it succeeded, its draw."""
        try:
            success, drawn = record_attempt(self.env, self.expert, writer, self.plan, attempt)
        except BaseException:
            writer.clear_episode_buffer()
            raise
        keep = success or self.plan.keep == "all"
        if not keep:
            writer.clear_episode_buffer()
        return keep, success, drawn

    def play(self, attempt: int) -> tuple[bool, str | None, dict[str, Any] | None]:
        """Play ``attempt``: whether it succeeded, its shard (None: not kept), its draw."""
        if self.writer is None:  # made at the first attempt: an unused worker writes nothing
            self.writer = LeRobotDatasetWriter.create(
                self.scratch, self.plan.fps, self.plan.features, robot_type=self.plan.robot_type,
                overwrite=True,
            )  # fmt: skip
        keep, success, drawn = self._record(self.writer, attempt)
        shard = None
        if keep:
            shard = str(self.shard_root / f"attempt-{attempt:07d}")
            self.writer.export_episode(shard)
        return success, shard, drawn

    def play_into(
        self, writer: LeRobotDatasetWriter, attempt: int
    ) -> tuple[bool, int | None, dict[str, Any] | None]:
        """Play ``attempt`` straight into ``writer`` (no shard): whether it succeeded,
        its episode index (None: not kept), its draw."""
        keep, success, drawn = self._record(writer, attempt)
        return success, writer.save_episode() if keep else None, drawn

    def close(self) -> None:
        if self.env is not None:
            self.env.close()
        if self.writer is not None:
            self.writer.finalize()
            shutil.rmtree(self.scratch, ignore_errors=True)


def _worker_main(conn: Connection, plan: AttemptPlan, shard_root: str) -> None:
    """A worker process: play the attempts received on ``conn`` and export their shards.

    Says ``("ready",)`` once its environment is built, then replies ``("done", attempt,
    success, shard or None, drawn variation)`` per attempt, or ``("error", text)`` once
    if something raised (the worker then exits).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    player = None
    try:
        player = _Player(plan, Path(shard_root))
        conn.send(("ready",))
        while True:
            attempt = conn.recv()
            if attempt is None:
                break
            conn.send(("done", attempt, *player.play(attempt)))
    except EOFError:
        pass  # the parent went away
    except BaseException:
        with contextlib.suppress(OSError):
            conn.send(("error", traceback.format_exc()))
    finally:
        if player is not None:
            player.close()


class _Slot:
    """One worker process, its pipe and the attempt it is playing (or None)."""

    def __init__(self, context: Any, plan: AttemptPlan, shard_root: Path) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(
            target=_worker_main, args=(child, plan, str(shard_root)), daemon=True
        )
        self.process.start()
        child.close()
        self.attempt: int | None = None
        self.ready = False  # the worker has built its environment

    def stop(self, timeout: float) -> None:
        """Ask the worker to finish, then end it if it does not."""
        if self.process.is_alive():
            with contextlib.suppress(OSError):
                self.conn.send(None)
        end_process(self.process, self.conn, timeout)


class _Starter:
    """Starts the worker processes in a background thread, so this process records
    meanwhile (starting the first worker waits for the fork server to import the
    recorder, about a second)."""

    def __init__(self, context: Any, plan: AttemptPlan, shard_root: Path, count: int) -> None:
        self._lock = threading.Lock()
        self._started: list[_Slot] = []
        self._stopped = False
        self.error: BaseException | None = None
        self._thread = threading.Thread(
            target=self._run,
            args=(context, plan, shard_root, count),
            name="gym_soarm-recorder-starter",
            daemon=True,
        )
        self._thread.start()

    def _run(self, context: Any, plan: AttemptPlan, shard_root: Path, count: int) -> None:
        for _ in range(count):
            try:
                slot = _Slot(context, plan, shard_root)
            except Exception as exc:  # handed to the recording loop, which raises it
                self.error = exc
                return
            with self._lock:
                if self._stopped:
                    slot.stop(0)
                    return
                self._started.append(slot)

    def new_slots(self) -> list[_Slot]:
        """The workers started since the last call."""
        with self._lock:
            started, self._started = self._started, []
        return started

    def stop(self) -> list[_Slot]:
        """Start no more workers; the ones started and not yet taken."""
        with self._lock:
            self._stopped = True
            started, self._started = self._started, []
        return started


class OrderedMerger:
    """Merges finished attempts into a dataset strictly in attempt order.

    Attempt ``k``'s result may arrive at any time; it is saved once every attempt before
    it is merged, and only while fewer than ``episodes`` episodes are kept, so the
    dataset never depends on which attempt finished first.

    Args:
        writer: the dataset.
        seed: the recording's seed (attempt ``k`` is seeded ``seed + k``).
        episodes: episodes to keep.
        max_attempts: attempts to make at most.
        bar: a tqdm progress bar to update, or None.
        label: the progress bar's note on where attempts run (e.g. ``"2 workers"``).
        task: the task's name, for ``meta/variation.jsonl``.
    """

    def __init__(
        self,
        writer: LeRobotDatasetWriter,
        seed: int,
        episodes: int,
        max_attempts: int,
        bar: Any = None,
        label: str = "",
        task: str = "",
    ) -> None:
        self.writer = writer
        self.task = task
        self.seed = seed
        self.episodes = episodes
        self.max_attempts = max_attempts
        self.bar = bar
        self.label = label
        self.results: dict[int, tuple[bool, Path | None, dict[str, Any] | None]] = {}
        self.next_attempt = self.merged = self.kept = self.successes = 0

    @property
    def finished(self) -> bool:
        """Enough episodes are kept, or every allowed attempt was merged."""
        return self.kept >= self.episodes or self.merged >= self.max_attempts

    def take_attempt(self) -> int | None:
        """The next attempt to start, or None while the ones started may be enough.

        Attempts started and not merged never outnumber the episodes still needed, so
        no attempt after the last kept one is ever played.
        """
        unmerged = self.next_attempt - self.merged
        if self.next_attempt >= self.max_attempts or unmerged >= self.episodes - self.kept:
            return None
        self.next_attempt += 1
        return self.next_attempt - 1

    def add(
        self, attempt: int, success: bool, shard: Path | None, drawn: dict[str, Any] | None
    ) -> None:
        """Note attempt ``attempt``'s outcome: its shard (None if it is not kept) and the
        variation its reset drew (or None)."""
        self.results[attempt] = (bool(success), shard, drawn)

    def add_saved(
        self, attempt: int, success: bool, index: int | None, drawn: dict[str, Any] | None
    ) -> None:
        """Note attempt ``attempt``, the next to merge, saved straight into the dataset
        as episode ``index`` (None: not kept)."""
        if attempt != self.merged or self.results:
            raise RuntimeError(
                f"attempt {attempt} was saved out of order (next to merge: {self.merged}); "
                "this is a bug in gym_soarm."
            )
        self.merged += 1
        self.successes += success
        if index is not None:
            write_variation(self.writer.root, index, self.seed + attempt, drawn, self.task)
            self.kept += 1
        self._progress(index is not None)

    def _progress(self, kept: bool) -> None:
        if self.bar is None:
            return
        if kept:
            self.bar.update(1)
        self.bar.set_postfix(
            success=f"{self.successes}/{self.merged}", frames=self.writer.num_frames, on=self.label
        )

    def merge_ready(self) -> None:
        """Merge every result whose predecessors are all merged."""
        while self.merged in self.results and self.kept < self.episodes:
            self._merge(self.merged)

    def merge_finished(self) -> None:
        """After an interruption: merge every finished attempt, in attempt order."""
        for attempt in sorted(self.results):
            if self.kept >= self.episodes:
                break
            self._merge(attempt)

    def _merge(self, attempt: int) -> None:
        success, shard, drawn = self.results.pop(attempt)
        self.merged += 1
        self.successes += success
        if shard is not None:
            index = self.writer.import_episode(shard)
            write_variation(self.writer.root, index, self.seed + attempt, drawn, self.task)
            shutil.rmtree(shard, ignore_errors=True)
            self.kept += 1
        self._progress(shard is not None)


def record_in_workers(
    writer: LeRobotDatasetWriter,
    plan: AttemptPlan,
    episodes: int,
    max_attempts: int,
    workers: int,
    start_method: str | None = None,
    bar: Any = None,
) -> tuple[int, int, bool]:
    """Record attempts ``0, 1, ...`` in ``workers`` processes into ``writer``, in order.

    This process is one of them: it starts ``workers - 1`` worker processes and plays
    an attempt itself whenever none of them is ready and free.

    Args:
        writer: the dataset being written (its scratch folder holds the shards).
        plan: the recording's settings, sent to every worker.
        episodes: episodes to keep.
        max_attempts: attempts to make at most.
        workers: processes that record, this one included (at least 2).
        start_method: ``"forkserver"`` (default where available) or ``"spawn"``.
        bar: a tqdm progress bar to update, or None.

    Returns:
        (attempts, successes, interrupted): the attempts merged (exactly those a single
        process would have made) and their successes, and whether Ctrl-C stopped it.

    Raises:
        RuntimeError: a worker raised (the message holds its traceback), or one attempt
            took its worker down :data:`MAX_DEATHS_PER_ATTEMPT` times.
    """
    # The fork server imports the recorder (MuJoCo, gymnasium, the tasks) once and forks
    # every worker from there. It never renders, so the workers may.
    context = worker_context(start_method, preload=[__name__])
    shard_root = writer.root / SCRATCH_DIR / "shards"
    shard_root.mkdir(parents=True, exist_ok=True)
    merger = OrderedMerger(
        writer, plan.seed, episodes, max_attempts, bar, f"{workers} processes", plan.spec.name
    )
    pool = _Pool(context, plan, shard_root, merger, workers)
    interrupted = False
    try:
        pool.run()
    except KeyboardInterrupt:
        interrupted = True
        merger.merge_finished()  # every finished episode is kept, in attempt order
    finally:
        pool.close(interrupted)
    return merger.merged, merger.successes, interrupted


class _Pool:
    """The recording loop of :func:`record_in_workers`: its worker processes, the
    attempts they play, the attempts to play again and this process's own player."""

    def __init__(
        self,
        context: Any,
        plan: AttemptPlan,
        shard_root: Path,
        merger: OrderedMerger,
        workers: int,
    ) -> None:
        self.context, self.plan, self.shard_root = context, plan, shard_root
        self.merger = merger
        self.workers = workers
        self.retry: list[int] = []  # attempts whose worker died, lowest first
        self.deaths: dict[int, int] = {}
        self.start_deaths = 0  # workers that died before they were ready
        self.slots: list[_Slot] = []
        self.player: _Player | None = None
        self.starter = None if plan.state_only else self._start_workers()

    def _start_workers(self) -> _Starter:
        return _Starter(self.context, self.plan, self.shard_root, self.workers - 1)

    def next_attempt(self) -> int | None:
        return self.retry.pop(0) if self.retry else self.merger.take_attempt()

    def run(self) -> None:
        """Hand out attempts and merge their results until the merger is finished."""
        merger = self.merger
        while True:
            merger.merge_ready()
            if merger.finished:
                break
            if self.starter is not None:
                self.slots.extend(self.starter.new_slots())
                if self.starter.error is not None:
                    raise RuntimeError(f"could not start a recording worker: {self.starter.error}")
            self._hand_out()
            watched = [s.conn for s in self.slots] + [s.process.sentinel for s in self.slots]
            ready = set(wait(watched, timeout=0))
            if not ready:
                attempt = self.next_attempt()
                if attempt is not None:  # nobody free: this process plays it
                    self._play_here(attempt)
                    continue
                if not any(slot.attempt is not None for slot in self.slots):
                    raise RuntimeError(
                        f"no attempt is running and attempt {merger.merged} has no result; "
                        "expected a worker to be playing it (this is a bug in gym_soarm)."
                    )
                ready = set(wait(watched))
            for index, slot in enumerate(self.slots):
                if slot.conn in ready or slot.process.sentinel in ready:
                    self._receive(index, slot, ready)

    def _hand_out(self) -> None:
        """Send the next attempts to the ready, free workers. Attempts not merged yet never
        exceed the episodes still needed: no attempt past the last kept one is ever played,
        whatever the timing."""
        for index, slot in enumerate(self.slots):
            if slot.attempt is not None or not slot.ready:
                continue
            attempt = self.next_attempt()
            if attempt is None:
                break
            try:
                slot.conn.send(attempt)
            except OSError:  # it died while idle: a new worker will take attempts
                slot.stop(0)
                self.slots[index] = _Slot(self.context, self.plan, self.shard_root)
                self.retry.append(attempt)
                self.retry.sort()
                continue
            slot.attempt = attempt

    def _play_here(self, attempt: int) -> None:
        """Play ``attempt`` in this process; start the workers if the attempts left take
        longer than starting them."""
        merger = self.merger
        if self.player is None:
            self.player = _Player(self.plan, self.shard_root)
        started = time.perf_counter()
        if attempt == merger.merged and not merger.results:
            # The next to merge: straight into the dataset, no shard.
            success, index, drawn = self.player.play_into(merger.writer, attempt)
            merger.add_saved(attempt, success, index, drawn)
        else:
            success, shard, drawn = self.player.play(attempt)
            merger.add(attempt, success, None if shard is None else Path(shard), drawn)
        left = merger.episodes - merger.kept - 1  # at the least
        if self.starter is None and left * (time.perf_counter() - started) > WORKER_START_S:
            self.starter = self._start_workers()

    def _receive(self, index: int, slot: _Slot, ready: set[Any]) -> None:
        """Take what worker ``index`` said (ready, a result, an error) or replace it if it
        died."""
        message = None
        if slot.conn in ready:
            try:
                message = slot.conn.recv()
            except (EOFError, OSError):
                message = None
        if message is not None and message[0] == "error":
            raise RuntimeError(f"a recording worker failed:\n{message[1]}")
        if message is not None and message[0] == "ready":
            slot.ready = True
        elif message is not None:
            _, attempt, success, shard, drawn = message
            self.merger.add(attempt, success, None if shard is None else Path(shard), drawn)
            slot.attempt = None
        else:
            self._replace_dead(index, slot)

    def _replace_dead(self, index: int, slot: _Slot) -> None:
        """A worker died (mid-attempt or starting): replace it and replay its attempt."""
        slot.process.join()
        lost = slot.attempt
        slot.stop(0)
        if lost is not None:
            self.deaths[lost] = self.deaths.get(lost, 0) + 1
            if self.deaths[lost] >= MAX_DEATHS_PER_ATTEMPT:
                raise RuntimeError(
                    f"attempt {lost} (seed {self.plan.seed + lost}) took its worker down "
                    f"{self.deaths[lost]} times (last exit code {slot.process.exitcode}); "
                    "expected a worker to finish it. A script that records with workers "
                    'must start them under `if __name__ == "__main__":` (spawn and '
                    "forkserver import the main module again); otherwise try the attempt "
                    "alone with workers=1."
                )
            self.retry.append(lost)
            self.retry.sort()
        elif not slot.ready:
            self.start_deaths += 1
            if self.start_deaths >= MAX_DEATHS_PER_ATTEMPT:
                raise RuntimeError(
                    f"recording workers died {self.start_deaths} times while starting (last "
                    f"exit code {slot.process.exitcode}). A script that records with "
                    'workers must start them under `if __name__ == "__main__":` (spawn '
                    "and forkserver import the main module again); otherwise record with "
                    "workers=1."
                )
        self.slots[index] = _Slot(self.context, self.plan, self.shard_root)

    def close(self, interrupted: bool) -> None:
        """Stop the workers (those playing an attempt get 5 s, unless interrupted) and this
        process's player."""
        if self.starter is not None:
            self.slots.extend(self.starter.stop())
        for slot in self.slots:
            slot.stop(0 if interrupted or slot.attempt is None else 5)
        if self.player is not None:
            self.player.close()
