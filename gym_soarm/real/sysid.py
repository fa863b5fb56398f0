"""Fitting the simulation's servos and joints to a real arm's LeRobot dataset.

:func:`fit_dynamics` replays a LeRobot SO-101 dataset's ``action`` in the simulation, as
:func:`gym_soarm.real.replay.replay` does (same dataset reading, units, calibration,
scenes and 50 Hz resampling), and fits per joint the servo's ``kp`` and ``kv`` and the
joint's ``damping``, ``armature`` and ``frictionloss``, and one control delay in steps,
so that the simulated joints follow the recorded ``observation.state``. The result is a
:mod:`gym_soarm.real.dynamics` file that every program takes (``dynamics=PATH``).

**How.** With MuJoCo's own system-identification toolbox, :mod:`mujoco.sysid` (the
``mujoco[sysid]`` extra, ``pip install "gym-soarm[sysid]"``): each figure is a
:class:`mujoco.sysid.Parameter`, the natural logarithm of a factor on the model's value
(bounded, see :data:`~gym_soarm.real.sysid_problem.SCALE_BOUNDS`);
:func:`mujoco.sysid.model_residual` builds one model per candidate and rolls each
episode out for all of them at once with
:func:`mujoco.rollout.rollout` (the finite-difference columns of the Jacobian run as
one batch, on every core); :func:`mujoco.sysid.optimize` minimises the residual
(its ``scipy_parallel_fd`` backend: SciPy's trust-region least squares with MuJoCo's
batched finite differences). The residual is the joint angle error in degrees at every
recorded frame but the first of each episode (which places the arm), plus a weak pull
of every factor towards 1 (:data:`~gym_soarm.real.sysid_problem.PRIOR_WEIGHT`) so
figures the data cannot tell apart stay near the model's.

The delay is a discrete choice: for each delay of :data:`DELAYS` steps the gains
``kp`` and ``kv`` alone are fitted (a few iterations, on the first
:data:`DELAY_SECONDS` of episodes), each joint starting from the best point of a coarse
grid of gain factors rolled out as one batch; the delay that tracks best is kept, and
all five figures of every joint are then fitted with it on every episode.

Contacts (the jaws on the table, a grasped object) make the error jump as the figures
change, which stalls the local fit: datasets for fitting keep the arm clear of things.

**What the rollouts simulate** is what the environment does with ``dynamics=`` the
fitted file: each 20 ms step holds the action of the frame in force at its start (that
of ``delay`` steps before, the start pose before the first), the arm starts at the
episode's first recorded state at rest, and the scene is the episode's own for a
gym_soarm recording, else the replay's object-free scene.
"""

from __future__ import annotations

import copy
import logging
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.real.dataset import ReplayDataset
from gym_soarm.real.dynamics import JOINT_FIELDS, MAX_DELAY_STEPS, Dynamics
from gym_soarm.real.replay import (
    episode_scenes,
    read_replay_dataset,
    replay_settings,
    scene_envs,
)
from gym_soarm.real.sysid_problem import (
    FitEpisode,
    FitProblem,
    prepare_episode,
    require_sysid,
)
from gym_soarm.real.units import UNITS
from gym_soarm.tasks import get_task
from gym_soarm.validation import check_choice, check_int

logger = logging.getLogger(__name__)

DELAYS: tuple[int, ...] = (0, 1, 2, 3)
"""The control delays (steps of 20 ms) tried."""
MIN_SECONDS = 2.0
"""The least recorded time (after each episode's first frame) a fit takes."""
DELAY_ITERATIONS = 6
"""Iterations (residual evaluations) of each delay's gains-only fit."""
DELAY_SECONDS = 30.0
"""The delay is chosen on the dataset's first episodes, about this many seconds of them."""
FIT_ITERATIONS = 25
"""Iterations (residual evaluations) of the final fit, at most."""
SYSID_SETTINGS: tuple[str, ...] = ("servo_model", "object_placement", "distractors")
"""The environment settings a fit takes from a recording (or its ``settings``): the
servo's force range and what is on the table. Randomisation is left out (a fit needs one
model) and so are the dynamics (what is fitted)."""


@dataclass(frozen=True)
class FitResult:
    """The outcome of :func:`fit_dynamics`.

    Attributes:
        dynamics: the fitted figures (absolute SI values) and delay, with the ``fit``
            report.
        episode_indices: the dataset's episode indices, in the order below.
        times_s: per episode, the compared frames' times.
        recorded_deg: per episode, the recorded joint angles (degrees of the model's
            joints), frames 1 to the last.
        before_deg: per episode, the simulated joint angles with the model's own figures
            and no delay.
        after_deg: the same with the fitted figures and delay.
    """

    dynamics: Dynamics
    episode_indices: tuple[int, ...]
    times_s: tuple[np.ndarray, ...]
    recorded_deg: tuple[np.ndarray, ...]
    before_deg: tuple[np.ndarray, ...]
    after_deg: tuple[np.ndarray, ...]

    @property
    def report(self) -> dict[str, Any]:
        """The ``fit`` report written into the file."""
        return dict(self.dynamics.fit or {})


def _rms_per_joint(error_deg: np.ndarray) -> dict[str, float]:
    return {
        name: round(float(np.sqrt(np.mean(error_deg[:, j] ** 2))), 4)
        for j, name in enumerate(constants.JOINT_NAMES)
    }


def _refuse(root: object, problem: str, fix: str) -> ValueError:
    return ValueError(f"dataset {root}: {problem}. {fix}")


def fit_dynamics(
    root: str | os.PathLike[str],
    episodes: Sequence[int] | None = None,
    units: str | None = None,
    calibration: str | os.PathLike[str] | None = None,
    wrist_roll_offset_deg: float | None = None,
    task: str | None = None,
    seed: int = 0,
    delays: Sequence[int] = DELAYS,
    iterations: int = FIT_ITERATIONS,
    threads: int | None = None,
    settings: Mapping[str, Any] | None = None,
) -> FitResult:
    """Fit the servo gains, joint figures and control delay to a LeRobot SO-101 dataset.

    Args:
        root: a LeRobotDataset v3.0 folder with ``action`` and ``observation.state``
            named as the SO-101 follower's (see :mod:`gym_soarm.real.replay`).
        episodes: episode indices to fit to; None for all.
        units: the dataset's joint units; None as the replay detects them.
        calibration: the recording arm's LeRobot calibration file (LeRobot units).
        wrist_roll_offset_deg: the arm's wrist_roll reading when the model's is at 0 rad.
        task: the scene (see :func:`gym_soarm.real.replay.replay`).
        seed: with ``task``, episode ``k`` resets the scene with ``seed + k``.
        delays: the control delays (steps) to try.
        iterations: at most this many iterations of the final fit.
        threads: rollout threads; None for every core.
        settings: ``gym.make`` keywords of :data:`SYSID_SETTINGS` over the recording's
            own (a gym_soarm recording stores its settings; the fit takes its servo
            model, and with each episode in its own task its placement and
            distractors). Its ``dynamics`` are never taken: they are what is fitted,
            from the model's own.

    Returns:
        The fitted figures (a :class:`gym_soarm.real.dynamics.Dynamics` with its ``fit``
        report) and the recorded and simulated joints before and after.

    Raises:
        ValueError: a bad argument or dataset: no ``action`` or ``observation.state``,
            another robot's names, fewer than :data:`MIN_SECONDS` seconds of frames.
        ImportError: pyarrow or the toolbox's dependencies are missing.
    """

    started = time.perf_counter()
    task, seed, iterations, episodes, delays, threads = _checked_arguments(
        task, units, seed, iterations, episodes, delays, threads, settings
    )
    sysid = require_sysid()
    dataset = read_replay_dataset(root, episodes)
    env_settings = replay_settings(
        dataset, task, units, calibration, wrist_roll_offset_deg, settings, SYSID_SETTINGS
    )
    seconds = _fit_seconds(root, dataset)
    prepared = _prepare_episodes(dataset, env_settings, episode_scenes(dataset, task, seed))

    problem = FitProblem(prepared, sysid, threads)
    nominal = problem.parameters(())
    before = problem.simulate(nominal, 0)
    delay, gains, delay_rms = _choose_delay(problem, delays, sysid, threads)
    fitted, _ = problem.fit(problem.parameters(JOINT_FIELDS, gains), delay, iterations)
    after = problem.simulate(fitted, delay)
    kept_start = problem.rms_deg(after) >= problem.rms_deg(before)
    if kept_start:  # no iteration did better than the model's own figures: keep them
        logger.warning(
            "sysid: the fit (%.6f deg RMS) did not improve on the model's own figures "
            "(%.6f deg RMS); keeping them and no delay",
            problem.rms_deg(after),
            problem.rms_deg(before),
        )
        fitted, delay, after = nominal, 0, before

    about = {
        "dataset": os.path.abspath(root),
        "episodes": [e.index for e in prepared],
        "frames_compared": problem.frames,
        "seconds": round(seconds, 3),
        "fps": dataset.fps,
        "units": env_settings.units,
    }
    return _fit_result(problem, fitted, delay, before, after, about, delay_rms, kept_start, started)


def _fit_result(
    problem: FitProblem,
    fitted: Any,
    delay: int,
    before: list[np.ndarray],
    after: list[np.ndarray],
    about: dict[str, Any],
    delay_rms: dict[str, float],
    kept_start: bool,
    started: float,
) -> FitResult:
    """The fitted figures with their report (``about`` the dataset first) and the joints
    recorded, simulated before and after, in degrees."""
    prepared = problem.episodes
    recorded = [np.degrees(e.recorded_rad) for e in prepared]
    before_deg = [np.degrees(s) for s in before]
    after_deg = [np.degrees(s) for s in after]
    joints = {
        name: {key: round(value, 6) for key, value in figures.items()}
        for name, figures in problem.figures(fitted).items()
    }
    report = {
        **about,
        **_error_report(recorded, before_deg, after_deg),
        "delay_rms_deg": delay_rms,
        "model_values": problem.nominal,
        "kept_model_values": kept_start,
        "fit_seconds": round(time.perf_counter() - started, 1),
        "method": "mujoco.sysid.optimize (scipy_parallel_fd) on mujoco.rollout, "
        f"MuJoCo {mujoco.__version__}",
    }
    return FitResult(
        Dynamics(joints, delay, report),
        tuple(e.index for e in prepared),
        tuple(e.times_s for e in prepared),
        tuple(recorded),
        tuple(before_deg),
        tuple(after_deg),
    )


def _checked_arguments(
    task: str | None,
    units: str | None,
    seed: int,
    iterations: int,
    episodes: Sequence[int] | None,
    delays: Sequence[int],
    threads: int | None,
    settings: Mapping[str, Any] | None,
) -> tuple[str | None, int, int, list[int] | None, list[int], int]:
    """:func:`fit_dynamics`'s arguments checked (ValueError naming a bad one), before any
    file is read: the task's registered name, the seed, iterations, episodes, the
    sorted delays and the thread count."""
    if task is not None:
        task = get_task(task).name
    check_choice("units", units, UNITS, none_ok=True)
    seed = check_int("seed", seed, 0)
    iterations = check_int("iterations", iterations, 1)
    if episodes is not None:
        episodes = [check_int("episode", e, 0) for e in episodes]
    if isinstance(delays, (str, bytes)) or not isinstance(delays, Sequence) or not delays:
        raise ValueError(f"delays must be a non-empty list of steps >= 0; got {delays!r}.")
    delays = sorted({check_int("delay", d, 0, MAX_DELAY_STEPS) for d in delays})
    threads = check_int("threads", threads if threads is not None else os.cpu_count() or 1, 1)
    unknown = sorted(set(settings or {}) - set(SYSID_SETTINGS))
    if unknown:
        raise ValueError(
            f"settings of a fit may be {', '.join(SYSID_SETTINGS)}; got {unknown}. The "
            "dynamics are what the fit finds; give units, calibration, wrist_roll_offset_deg "
            "and task as its own arguments."
        )
    return task, seed, iterations, episodes, delays, threads


def _fit_seconds(root: object, dataset: ReplayDataset) -> float:
    """The recorded seconds a fit compares, refusing a dataset with too few."""
    for index, (_, states) in dataset.episodes.items():
        if len(states) < 2:
            raise _refuse(
                root,
                f"episode {index} has {len(states)} frame(s)",
                "A fit compares the frames after each episode's first; leave that episode out.",
            )
    seconds = sum((len(s) - 1) / dataset.fps for _, s in dataset.episodes.values())
    if seconds < MIN_SECONDS:
        raise _refuse(
            root,
            f"only {seconds:.2f} s of frames to fit to (after each episode's first frame)",
            f"A fit needs at least {MIN_SECONDS:g} s of motion; record a longer dataset "
            "(see 'Fit the simulation to your arm' in docs/real-arm.md).",
        )
    return seconds


def _prepare_episodes(
    dataset: ReplayDataset, env_settings: Any, scenes: Mapping[int, tuple[str, int]]
) -> list[FitEpisode]:
    """Every episode placed in its scene, ready to roll out (one model per scene)."""
    prepared: list[FitEpisode] = []
    models: dict[str, mujoco.MjModel] = {}
    with scene_envs(env_settings) as env_for:
        for index, (actions, states) in dataset.episodes.items():
            name, episode_seed = scenes[index]
            env = env_for(name)
            # The model as made, before any episode: the fit's starting point.
            model = models.setdefault(name, copy.copy(env.physics.model.ptr))
            prepared.append(
                prepare_episode(env, name, model, index, actions, states, dataset.fps, episode_seed)
            )
    return prepared


def _choose_delay(
    problem: FitProblem, delays: Sequence[int], sysid: Any, threads: int
) -> tuple[int, Any, dict[str, float]]:
    """The delay whose gains-only fit tracks best, on the first :data:`DELAY_SECONDS`
    of episodes (whole episodes): the delay, its gains and every delay's RMS (deg)."""
    sample, sampled_s = [], 0.0
    for episode in problem.episodes:
        if sampled_s >= DELAY_SECONDS:
            break
        sample.append(episode)
        sampled_s += episode.times_s[-1]
    chooser = (
        problem if len(sample) == len(problem.episodes) else FitProblem(sample, sysid, threads)
    )
    delay_rms: dict[str, float] = {}
    best: tuple[float, int, Any] | None = None
    for delay in delays:
        gains, rms = chooser.fit(chooser.grid_start(delay), delay, DELAY_ITERATIONS)
        delay_rms[str(delay)] = round(rms, 4)
        if best is None or rms < best[0]:
            best = (rms, delay, gains)
    if best is None:  # unreachable: fit_dynamics refuses an empty list of delays
        raise ValueError("no delay to try: pass at least one.")
    return best[1], best[2], delay_rms


def _error_report(
    recorded: list[np.ndarray], before: list[np.ndarray], after: list[np.ndarray]
) -> dict[str, Any]:
    """The report's tracking errors (deg): per joint and overall, before and after."""
    error_before = np.concatenate([b - r for b, r in zip(before, recorded, strict=True)])
    error_after = np.concatenate([a - r for a, r in zip(after, recorded, strict=True)])
    return {
        "rms_before_deg": _rms_per_joint(error_before),
        "rms_after_deg": _rms_per_joint(error_after),
        "overall_rms_before_deg": round(float(np.sqrt(np.mean(error_before**2))), 4),
        "overall_rms_after_deg": round(float(np.sqrt(np.mean(error_after**2))), 4),
    }


def plot_fit(result: FitResult, path: str | os.PathLike[str]) -> None:
    """Write a PNG: per joint, the recorded angle and the simulated one before and after.

    Six panels; episodes follow one another along the time axis. Drawn with matplotlib
    (imported here only).

    Raises:
        ValueError: ``path`` does not end in ``.png`` or cannot be written.
        ImportError: matplotlib is missing.
    """
    if not str(path).lower().endswith(".png"):
        raise ValueError(f"plot path must end in .png; got {os.fspath(path)!r}.")
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    offsets = np.cumsum([0.0] + [t[-1] for t in result.times_s[:-1]])
    times = np.concatenate([t + o for t, o in zip(result.times_s, offsets, strict=True)])
    recorded = np.concatenate(result.recorded_deg)
    before = np.concatenate(result.before_deg)
    after = np.concatenate(result.after_deg)
    report = result.report
    figure, axes = plt.subplots(3, 2, figsize=(14, 9), sharex=True)
    for j, (name, axis) in enumerate(zip(constants.JOINT_NAMES, axes.ravel(), strict=True)):
        axis.plot(times, recorded[:, j], color="black", linewidth=1.6, label="recorded")
        axis.plot(times, before[:, j], color="tab:blue", linewidth=0.9, label="model's own")
        axis.plot(times, after[:, j], color="tab:orange", linewidth=0.9, label="fitted")
        for offset in offsets[1:]:
            axis.axvline(offset, color="0.8", linewidth=0.8)
        rms_before = report.get("rms_before_deg", {}).get(name, float("nan"))
        rms_after = report.get("rms_after_deg", {}).get(name, float("nan"))
        axis.set_title(f"{name}: RMS {rms_before:.3g} -> {rms_after:.3g} deg", fontsize=10)
        axis.set_ylabel("deg")
        axis.grid(alpha=0.3)
    for axis in axes[-1]:
        axis.set_xlabel("time (s)")
    axes[0, 0].legend(loc="best", fontsize=8)
    figure.suptitle(
        f"{Path(report.get('dataset', '')).name}: recorded vs simulated joints "
        f"(control delay {result.dynamics.delay_steps} steps)"
    )
    figure.tight_layout()
    try:
        figure.savefig(os.fspath(path), dpi=90)
    except OSError as exc:
        raise ValueError(f"plot path {os.fspath(path)!r} cannot be written ({exc}).") from exc
    finally:
        plt.close(figure)
