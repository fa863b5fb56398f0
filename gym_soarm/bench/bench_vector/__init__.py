"""Scaling of vector environments: aggregate steps/s for several ``num_envs``.

``python -m gym_soarm.bench --vector-scaling 1,2,4,8,16`` reports it (this module
measures it; ``python -m gym_soarm.bench.bench_vector`` runs it alone). For each
``num_envs`` the same environment is built as one ``gym.make`` environment (the
baseline) and as each vector env:

* ``batched``: ``gym.make_vec(..., vectorization_mode="vector_entry_point",
  vector_env="batched")``, :class:`gym_soarm.vector.batched.BatchedVectorEnv`: every simulation
  in one ``mujoco.batch`` call (a thread per CPU), the task scored as arrays;
* ``processes``: the same with ``vector_env="processes"``, the worker processes of
  :class:`gym_soarm.vector.SoArmVectorEnv` (one per CPU; ``native`` is its earlier name,
  still taken with a ``FutureWarning``; reports of earlier versions hold ``native`` rows);
* ``async``: ``gymnasium.vector.AsyncVectorEnv``, one process per environment
  (``forkserver`` context);
* ``sync``: ``gymnasium.vector.SyncVectorEnv``, every environment in turn in this thread.

They are stepped with random actions from a seeded generator in rounds that take each
of them in turn (so every figure sees the same machine load), and the medians over
rounds are reported. ``speedup`` is the median over rounds of a vector env's aggregate
steps/s over the single environment's in the same round.

Each round also measures the *ceiling* of that ``num_envs``: the same environments split
over one process per CPU as the processes env splits them, each process stepping its
share in turn flat out, with no communication at all. Its speedup over one env is what
this machine allows: cycling through several simulations in one process costs more
per step than stepping one (each has its own 5 MB model, so they no longer fit the
CPU caches), and two cores that share caches and memory, or a busy host, give less than
2x. ``ratio_to_ceiling`` puts each vector env's speedup against it.

Each round also measures the bare physics: ``batch_physics`` steps the same ``num_envs``
simulations with ``mujoco.batch`` alone (the same threads, the same substeps, no task,
no observation), the ceiling of the batched env (``ratio_to_physics``); at ``num_envs``
1 it is one simulation's bare physics, against which the single environment's rate is
put (``single_to_physics``). ``rollout`` steps them with ``mujoco.rollout`` on a thread per
CPU, twenty control steps a call (``ratio_to_rollout``): MuJoCo's fastest way from Python.
"""

from __future__ import annotations

import contextlib
import os
import signal
import statistics
import subprocess
import time
import warnings
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np

import gym_soarm  # noqa: F401  (registers the environments)
from gym_soarm.bench.child import one_shot
from gym_soarm.bench.timings import spread
from gym_soarm.tasks import DEFAULT_TASK, get_task
from gym_soarm.vector.workers import cpu_count, end_process, worker_context

DEFAULT_ENV_ID = "gym_soarm/LiftCube-v0"
VECTOR_MODES: tuple[str, ...] = ("batched", "processes", "async", "sync")
"""The vector envs measured: the package's own by the names ``gym.make_vec``'s ``vector_env``
gives them (``batched``, ``processes``) and Gymnasium's ``AsyncVectorEnv`` and
``SyncVectorEnv``."""
DEPRECATED_MODES: dict[str, str] = {"native": "processes"}
"""Earlier names of :data:`VECTOR_MODES`, still taken with a ``FutureWarning``."""
DEFAULT_SIZE = (96, 128)  # (height, width) of camera observations
N_ACTIONS = 64  # random actions (or batches) drawn up front and cycled


def env_kwargs(obs: str, size: tuple[int, int] = DEFAULT_SIZE) -> dict[str, Any]:
    """``gym.make`` keywords of ``obs``: ``"state"`` or a camera config at ``size`` (h, w)."""
    if obs == "state":
        return {"obs_type": "environment_state_agent_pos"}
    return {
        "obs_type": "pixels_agent_pos",
        "camera_config": obs,
        "observation_height": size[0],
        "observation_width": size[1],
    }


def vector_modes(modes: Sequence[str]) -> list[str]:
    """``modes`` with the deprecated names replaced (a ``FutureWarning`` for each)."""
    named = []
    for mode in modes:
        if mode in DEPRECATED_MODES:
            new = DEPRECATED_MODES[mode]
            warnings.warn(
                f"vector mode {mode!r} is deprecated; pass {new!r} (the name gym.make_vec's "
                "vector_env gives it).",
                FutureWarning,
                stacklevel=3,
            )
            mode = new
        named.append(mode)
    return named


def make_vector(
    env_id: str, num_envs: int, mode: str, kwargs: dict[str, Any], num_processes: int | None = None
) -> gym.vector.VectorEnv:
    """A vector env of ``mode`` (one of :data:`VECTOR_MODES`) over ``num_envs`` environments.

    Raises:
        ValueError: an unknown ``mode``.
    """
    if mode in ("batched", "processes"):
        # The batched env's workers are threads; the process env's, processes.
        workers = "num_threads" if mode == "batched" else "num_processes"
        return gym.make_vec(
            env_id,
            num_envs=num_envs,
            vectorization_mode="vector_entry_point",
            vector_env=mode,
            **{workers: num_processes},
            **kwargs,
        )
    if mode == "async":
        return gym.make_vec(
            env_id,
            num_envs=num_envs,
            vectorization_mode="async",
            vector_kwargs={"context": "forkserver"},
            **kwargs,
        )
    if mode == "sync":
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="sync", **kwargs)
    raise ValueError(f"mode must be one of {', '.join(VECTOR_MODES)}; got {mode!r}.")


def cycle_rate(envs: Sequence[gym.Env], actions: np.ndarray, seconds: float) -> float:
    """Steps/s of ``envs`` stepped in turn for about ``seconds`` (at least one round)."""
    steps = 0
    started = time.perf_counter()
    deadline = started + seconds
    while True:
        for env in envs:
            _, _, terminated, truncated, _ = env.step(actions[steps % len(actions)])
            steps += 1
            if terminated or truncated:
                env.reset()
        if time.perf_counter() >= deadline:
            break
    return steps / (time.perf_counter() - started)


def single_rate(env: gym.Env, actions: np.ndarray, seconds: float) -> float:
    """Steps/s of one environment stepped for about ``seconds`` (at least one step)."""
    return cycle_rate([env], actions, seconds)


def calls_per_second(call: Any, seconds: float) -> float:
    """How many times a second ``call(k)`` (``k``: 0, 1, ...) runs, called for about
    ``seconds`` (at least once)."""
    calls = 0
    started = time.perf_counter()
    deadline = started + seconds
    while True:
        call(calls)
        calls += 1
        if time.perf_counter() >= deadline:
            break
    return calls / (time.perf_counter() - started)


def vector_rate(envs: gym.vector.VectorEnv, actions: np.ndarray, seconds: float) -> float:
    """Aggregate steps/s of a vector env (its autoreset starts new episodes)."""
    return envs.num_envs * calls_per_second(lambda k: envs.step(actions[k % len(actions)]), seconds)


def _start(env_id: str, kwargs: dict[str, Any], spec: Any) -> tuple[Any, np.ndarray]:
    """The physics of ``env_id`` after ``reset(seed=0)`` and its state of ``spec``; the
    environment is closed, its physics kept."""
    import mujoco

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    physics = env.unwrapped.physics
    state = np.empty(mujoco.mj_stateSize(physics.model.ptr, spec))
    mujoco.mj_getState(physics.model.ptr, physics.data.ptr, state, spec)
    env.close()
    return physics, state


class BatchPhysics:
    """``num_envs`` simulations of ``env_id``'s scene stepped by ``mujoco.batch`` alone:
    the servo targets of random actions, the control step's substeps, nothing else."""

    def __init__(
        self, env_id: str, kwargs: dict[str, Any], num_envs: int, threads: int | None = None
    ) -> None:
        import mujoco
        import mujoco.batch

        from gym_soarm import constants

        physics, state = _start(env_id, kwargs, mujoco.mjtState.mjSTATE_INTEGRATION)
        model = physics.model.ptr
        self.batch = mujoco.batch.Batch(model, num_envs, min(num_envs, threads or cpu_count()))
        self.batch.state[:] = state
        low, high = physics.control_range()
        rng = np.random.default_rng(0)
        self.targets = rng.uniform(low, high, (N_ACTIONS, num_envs, len(low)))
        self.actuators = physics._actuator_ids
        self.ctrl = self.batch.bind("ctrl")
        self.substeps = constants.N_SUBSTEPS
        self.stage = int(mujoco.mjtStage.mjSTAGE_VEL)
        self.num_envs = num_envs

    def _step(self, k: int) -> None:
        self.ctrl[:, self.actuators] = self.targets[k % N_ACTIONS]
        self.batch.step(None, self.substeps, self.stage)

    def rate(self, seconds: float) -> float:
        """Control steps/s of all the simulations (each the control step's substeps) for
        about ``seconds``."""
        return self.num_envs * calls_per_second(self._step, seconds)


class RolloutPhysics:
    """``num_envs`` simulations stepped by ``mujoco.rollout`` on a thread per CPU: the
    same random servo targets held for each control step's substeps, ``CHUNK`` control
    steps a call. MuJoCo's own fastest way to step many simulations from Python."""

    CHUNK = 20

    def __init__(
        self, env_id: str, kwargs: dict[str, Any], num_envs: int, threads: int | None = None
    ) -> None:
        import mujoco
        from mujoco import rollout

        from gym_soarm import constants

        physics, state = _start(env_id, kwargs, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.model = physics.model.ptr
        self.state = np.tile(state, (num_envs, 1))
        nthread = min(num_envs, threads or cpu_count())
        self.datas = [mujoco.MjData(self.model) for _ in range(nthread)]
        low, high = physics.control_range()
        ctrl = np.tile(physics.data.ctrl, (num_envs, self.CHUNK, 1))
        rng = np.random.default_rng(0)
        ctrl[:, :, physics._actuator_ids] = rng.uniform(low, high, (num_envs, self.CHUNK, len(low)))
        self.control = np.repeat(ctrl, constants.N_SUBSTEPS, axis=1)  # held for the substeps
        self.runner = rollout.Rollout(nthread=nthread)
        self.num_envs = num_envs

    def _call(self, k: int) -> None:
        self.runner.rollout(self.model, self.datas, self.state, self.control)

    def rate(self, seconds: float) -> float:
        """Control steps/s of all the simulations for about ``seconds``."""
        return self.CHUNK * self.num_envs * calls_per_second(self._call, seconds)

    def close(self) -> None:
        self.runner.close()


def _free_runner(
    conn: Connection, env_id: str, kwargs: dict[str, Any], count: int, seed: int
) -> None:
    """A ceiling process: on each message ``seconds``, step ``count`` environments in
    turn flat out for that long; reply their steps/s (or an error's text)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the benchmark's to handle
    try:
        envs = [gym.make(env_id, **kwargs) for _ in range(count)]
    except Exception as exc:  # reported by Ceiling.rate
        conn.send(f"{type(exc).__name__}: {exc}")
        return
    try:
        for index, env in enumerate(envs):
            env.reset(seed=seed + index)
        low, high = envs[0].action_space.low, envs[0].action_space.high
        actions = np.random.default_rng(seed).uniform(low, high, (N_ACTIONS, len(low)))
        actions = actions.astype(np.float32)
        while True:
            try:
                seconds = conn.recv()
            except EOFError:
                return
            if seconds is None:
                return
            conn.send(cycle_rate(envs, actions, seconds))
    finally:
        for env in envs:
            env.close()


class Ceiling:
    """``num_envs`` environments split over ``processes`` processes (default: one per
    CPU; at most ``num_envs``) as the processes vector env splits them, each process
    stepping its share in turn with no hand-off."""

    def __init__(
        self, env_id: str, kwargs: dict[str, Any], num_envs: int, processes: int | None = None
    ) -> None:
        context = worker_context(None, preload=[__name__])
        count = min(num_envs, processes or cpu_count())
        shares = np.array_split(np.arange(num_envs), count)
        self.runners: list[tuple[Any, Connection]] = []
        try:
            for share in shares:
                conn, child = context.Pipe()
                process = context.Process(
                    target=_free_runner,
                    args=(child, env_id, kwargs, len(share), int(share[0])),
                    daemon=True,
                )
                process.start()
                child.close()
                self.runners.append((process, conn))
        except BaseException:
            self.close()
            raise

    def rate(self, seconds: float) -> float:
        """Aggregate steps/s of all processes stepping at once for about ``seconds``."""
        for _, conn in self.runners:
            conn.send(seconds)
        total = 0.0
        for process, conn in self.runners:
            try:
                reply = conn.recv()
            except EOFError:
                reply = f"it exited with code {process.exitcode}"
            if isinstance(reply, str):
                raise RuntimeError(f"a ceiling process could not step its environments: {reply}")
            total += reply
        return total

    def close(self) -> None:
        for process, conn in self.runners:
            with contextlib.suppress(OSError):
                conn.send(None)
            end_process(process, conn, 10)
        self.runners = []


def _round_rates(
    single: gym.Env,
    single_actions: np.ndarray,
    measurers: dict[str, Any],
    rates: dict[str, list[float]],
    seconds: float,
    rounds: int,
) -> None:
    """``rounds`` rounds of every figure in turn (nobody always goes first), appended to
    ``rates``: ``single``, then each of ``measurers`` (a callable ``rate(seconds)``)."""
    order = ["single", *measurers]
    for round_index in range(rounds):
        shift = round_index % len(order)
        for name in order[shift:] + order[:shift]:
            if name == "single":
                rates[name].append(single_rate(single, single_actions, seconds))
            else:
                rates[name].append(measurers[name](seconds))


def _count_rates(
    env_id: str,
    n: int,
    kwargs: dict[str, Any],
    modes: Sequence[str],
    single: tuple[gym.Env, np.ndarray],
    batches: np.ndarray,
    seconds: float,
    rounds: int,
    num_processes: int | None,
) -> dict[str, list[float]]:
    """Every figure of ``n`` environments over ``rounds``: the single env, the ceiling,
    the bare physics, ``mujoco.rollout`` and each vector env of ``modes``."""
    vectors: dict[str, gym.vector.VectorEnv] = {}
    ceiling = Ceiling(env_id, kwargs, n, num_processes)
    physics = BatchPhysics(env_id, kwargs, n, num_processes)
    rollout = RolloutPhysics(env_id, kwargs, n, num_processes)
    names = ["single", "ceiling", "physics", "rollout", *modes]
    rates: dict[str, list[float]] = {name: [] for name in names}
    try:
        for mode in modes:
            vectors[mode] = make_vector(env_id, n, mode, kwargs, num_processes)
            vectors[mode].reset(seed=0)
            vectors[mode].step(batches[0])  # warm up (GL contexts, pipes)
        ceiling.rate(0.05)  # warm up (every process built and stepping)
        measurers = {"ceiling": ceiling.rate, "physics": physics.rate, "rollout": rollout.rate}
        for mode in modes:
            measurers[mode] = lambda t, envs=vectors[mode]: vector_rate(envs, batches, t)
        _round_rates(*single, measurers, rates, seconds, rounds)
    finally:
        for envs in vectors.values():
            envs.close()
        ceiling.close()
        rollout.close()
    return rates


def _median_ratio(a: Sequence[float], b: Sequence[float]) -> float:
    return statistics.median(x / y for x, y in zip(a, b, strict=True))


def _count_rows(n: int, modes: Sequence[str], rates: dict[str, list[float]]) -> list[dict]:
    """The rows of one count: a row per mode, its rates put against the others."""
    single = rates["single"]
    ceiling_per_round = [c / s for c, s in zip(rates["ceiling"], single, strict=True)]
    rows = []
    for mode in modes:
        speedups = [v / s for v, s in zip(rates[mode], single, strict=True)]
        rows.append(
            {
                "mode": mode,
                "num_envs": n,
                "steps_per_s": spread(rates[mode]),
                "single_steps_per_s": statistics.median(single),
                "speedup": statistics.median(speedups),
                "ceiling_speedup": statistics.median(ceiling_per_round),
                "ratio_to_ceiling": _median_ratio(speedups, ceiling_per_round),
                "batch_physics_steps_per_s": statistics.median(rates["physics"]),
                "ratio_to_physics": _median_ratio(rates[mode], rates["physics"]),
                "rollout_steps_per_s": statistics.median(rates["rollout"]),
                "ratio_to_rollout": _median_ratio(rates[mode], rates["rollout"]),
                "single_to_physics": _median_ratio(single, rates["physics"]) if n == 1 else None,
            }
        )
    return rows


def measure(
    env_id: str,
    num_envs: Sequence[int],
    obs: str = "state",
    size: tuple[int, int] = DEFAULT_SIZE,
    seconds: float = 1.0,
    rounds: int = 3,
    num_processes: int | None = None,
    modes: Sequence[str] = VECTOR_MODES,
) -> dict[str, Any]:
    """Steps/s of one env and of each vector env of ``modes`` at each ``num_envs``.

    The vector envs of one count are built together, measured in alternating rounds
    with the single environment, and closed before the next count.

    Raises:
        ValueError: an empty ``num_envs``, a count below 1 or an unknown mode.
    """
    if not num_envs or min(num_envs) < 1:
        raise ValueError(f"num_envs must list counts >= 1; got {list(num_envs)!r}.")
    modes = vector_modes(modes)
    unknown = [m for m in modes if m not in VECTOR_MODES]
    if unknown or not modes:
        raise ValueError(f"modes must be among {', '.join(VECTOR_MODES)}; got {list(modes)!r}.")
    kwargs = env_kwargs(obs, size)
    load_start = os.getloadavg() if hasattr(os, "getloadavg") else None
    single = gym.make(env_id, **kwargs)
    single.reset(seed=0)
    rng = np.random.default_rng(0)
    low, high = single.action_space.low, single.action_space.high
    single_actions = rng.uniform(low, high, (N_ACTIONS, len(low))).astype(np.float32)
    single_rates: list[float] = []
    rows: list[dict[str, Any]] = []
    try:
        for n in num_envs:
            batches = rng.uniform(low, high, (N_ACTIONS, n, len(low))).astype(np.float32)
            rates = _count_rates(
                env_id,
                n,
                kwargs,
                modes,
                (single, single_actions),
                batches,
                seconds,
                rounds,
                num_processes,
            )
            single_rates.extend(rates["single"])
            rows.extend(_count_rows(n, modes, rates))
    finally:
        single.close()
    return {
        "env_id": env_id,
        "obs": obs,
        "size": list(size) if obs != "state" else None,
        "modes": list(modes),
        "num_processes": num_processes,
        "seconds": seconds,
        "rounds": rounds,
        "cpus": os.cpu_count(),
        "load_average_start": load_start,
        "load_average_end": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "single_steps_per_s": statistics.median(single_rates),
        "ceiling_processes": num_processes or cpu_count(),
        "rows": rows,
    }


def format_table(report: dict[str, Any]) -> str:
    """One scaling report as a Markdown table: a row per count, a column pair per mode."""
    modes = report["modes"]
    header = [
        "num_envs",
        *(f"{m} steps/s (speedup)" for m in modes),
        "ceiling speedup",
        "bare batch physics steps/s",
        "mujoco.rollout steps/s",
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    by_key = {(r["mode"], r["num_envs"]): r for r in report["rows"]}
    for n in sorted({r["num_envs"] for r in report["rows"]}):
        cells = [str(n)]
        for mode in modes:
            row = by_key[(mode, n)]
            cells.append(f"{row['steps_per_s']['median']:,.0f} ({row['speedup']:.2f}x)")
        cells.append(f"{by_key[(modes[0], n)]['ceiling_speedup']:.2f}x")
        cells.append(f"{by_key[(modes[0], n)]['batch_physics_steps_per_s']:,.0f}")
        cells.append(f"{by_key[(modes[0], n)]['rollout_steps_per_s']:,.0f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def title(report: dict[str, Any]) -> str:
    """What a scaling report measured, in one line."""
    obs = report["obs"]
    if report.get("size"):
        obs = f"{obs} {report['size'][0]}x{report['size'][1]}"
    load = report["load_average_start"]
    load_text = "" if load is None else f", load average {load[0]:.1f}"
    return (
        f"{report['env_id']}, {obs}: one env {report['single_steps_per_s']:,.0f} steps/s "
        f"({report['cpus']} cores{load_text}); ceiling: the environments on "
        f"{report['ceiling_processes']} free-running processes"
    )


def measure_vector_scaling(
    counts: Sequence[int],
    obs: str,
    size: tuple[int, int],
    seconds: float,
    repeats: int,
    task: str = DEFAULT_TASK,
    modes: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Scaling of the vector envs with ``obs`` observations, in a fresh process.

    What ``python -m gym_soarm.bench --vector-scaling`` runs. Returns :func:`measure`'s
    report, or ``{"obs": obs, "error": ...}`` when the process failed.
    """
    modes = vector_modes(modes or VECTOR_MODES)
    if progress is not None:
        progress(f"measuring vector scaling ({obs}, num_envs {','.join(map(str, counts))}) ...")
    job = {
        "kind": "vector_scaling",
        "env_id": get_task(task).env_id,
        "counts": list(counts),
        "obs": obs,
        "size": list(size),
        "seconds": seconds,
        "repeats": repeats,
        "modes": modes,
    }
    timeout = 300 + len(counts) * (60 + (len(modes) + 1) * repeats * seconds * 3)
    try:
        return one_shot(job, timeout)
    except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
        return {"obs": obs, "error": str(exc)}
