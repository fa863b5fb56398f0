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
(bounded, see :data:`SCALE_BOUNDS`); :func:`mujoco.sysid.model_residual` builds one
model per candidate and rolls each episode out for all of them at once with
:func:`mujoco.rollout.rollout` (the finite-difference columns of the Jacobian run as
one batch, on every core); :func:`mujoco.sysid.optimize` minimises the residual
(its ``scipy_parallel_fd`` backend: SciPy's trust-region least squares with MuJoCo's
batched finite differences). The residual is the joint angle error in degrees at every
recorded frame but the first of each episode (which places the arm), plus a weak pull
of every factor towards 1 (:data:`PRIOR_WEIGHT`) so figures the data cannot tell apart
stay near the model's.

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

import contextlib
import copy
import io
import logging
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.real.dynamics import (
    JOINT_FIELDS,
    MAX_DELAY_STEPS,
    Dynamics,
    apply_dynamics,
    read_model_dynamics,
)
from gym_soarm.real.replay import (
    SIM_FPS,
    episode_scenes,
    frame_of_steps,
    read_replay_dataset,
    replay_settings,
    scene_envs,
    start_episode,
)
from gym_soarm.real.units import UNITS
from gym_soarm.sim.randomization import arm_indices
from gym_soarm.tasks import get_task
from gym_soarm.validation import check_choice, check_int

logger = logging.getLogger(__name__)

DELAYS: tuple[int, ...] = (0, 1, 2, 3)
"""The control delays (steps of 20 ms) tried."""
SCALE_BOUNDS: dict[str, tuple[float, float]] = {
    "kp": (0.1, 5.0),
    "kv": (0.05, 10.0),
    "damping": (0.01, 10.0),
    "armature": (0.05, 10.0),
    "frictionloss": (0.01, 10.0),
}
"""Bounds of each figure's factor on the model's value (the fit moves their logarithms)."""
PRIOR_WEIGHT = 0.02
"""Weight (degrees per unit of the factor's natural logarithm) of the pull of every
factor towards 1."""
MIN_SECONDS = 2.0
"""The least recorded time (after each episode's first frame) a fit takes."""
DELAY_ITERATIONS = 6
"""Iterations (residual evaluations) of each delay's gains-only fit."""
GRID_KP: tuple[float, ...] = (0.4, 0.6, 0.85, 1.2, 1.7, 2.4)
"""The ``kp`` factors of the coarse grid each delay's fit starts from."""
GRID_KV: tuple[float, ...] = (0.4, 0.6, 0.85, 1.2, 1.7, 2.4, 3.4)
"""The ``kv`` factors of that grid."""
DELAY_SECONDS = 30.0
"""The delay is chosen on the dataset's first episodes, about this many seconds of them."""
FIT_ITERATIONS = 25
SYSID_SETTINGS: tuple[str, ...] = ("servo_model", "object_placement", "distractors")
"""The environment settings a fit takes from a recording (or its ``settings``): the
servo's force range and what is on the table. Randomisation is left out (a fit needs one
model) and so are the dynamics (what is fitted)."""
"""Iterations (residual evaluations) of the final fit, at most."""
FD_STEP = 1e-3
"""Finite-difference step of the factors."""


def _require_sysid() -> Any:
    import mujoco.sysid as sysid

    if not hasattr(sysid, "optimize"):  # the package hides its own missing dependencies
        raise ImportError(
            "Fitting dynamics needs MuJoCo's system-identification toolbox and its "
            'dependencies: pip install "gym-soarm[sysid]" (mujoco[sysid]).'
        )
    return sysid


@dataclass
class _Episode:
    """One episode, ready to roll out: its scene's model and start state, the servo
    targets of each 50 Hz step (rad) and the recorded joint angles (rad) to match."""

    index: int
    scene: str
    model: mujoco.MjModel  # the scene's model, shared by its episodes
    body_pos: np.ndarray  # where this episode's reset put the scene's bodies
    initial_state: np.ndarray
    start_ctrl: np.ndarray
    targets: np.ndarray  # (steps, 6): the target of each 50 Hz step, before any delay
    start_targets: np.ndarray  # (6,): what the servos hold before the first action
    times_s: np.ndarray  # (frames - 1,): the compared frames' times
    recorded_rad: np.ndarray  # (frames - 1, 6)
    qpos_adr: np.ndarray

    def control(self, delay: int) -> np.ndarray:
        """The ctrl of every physics step with ``delay`` steps of delay, plus one row
        (the toolbox drops the last: no measurement follows it)."""
        targets = np.concatenate([np.repeat(self.start_targets[None], delay, 0), self.targets])
        targets = targets[: len(self.targets)]
        ctrl = np.repeat(self.start_ctrl[None], len(targets) * constants.N_SUBSTEPS + 1, 0)
        actuators, _ = arm_indices(self.model)
        ctrl[:-1, actuators] = np.repeat(targets, constants.N_SUBSTEPS, 0)
        ctrl[-1, actuators] = targets[-1]
        return ctrl

    def simulated(self, state: np.ndarray) -> np.ndarray:
        """The joint angles (rad) at the compared frames' times, from a rollout's states
        (one row per physics step, column 0 the time): each 50 Hz step's end, linearly
        interpolated to the frames' times as the replay does."""
        steps = len(self.targets)
        rows = np.arange(1, steps + 1) * constants.N_SUBSTEPS - 1
        ends = state[rows][:, 1 + self.qpos_adr]
        start = self.initial_state[1 + self.qpos_adr]
        positions = np.vstack([start[None], ends])
        step_times = np.arange(steps + 1) / SIM_FPS
        if len(step_times) == len(self.times_s) + 1 and np.allclose(
            step_times[1:], self.times_s, atol=1e-9
        ):
            return positions[1:]
        return np.stack(
            [np.interp(self.times_s, step_times, positions[:, j]) for j in range(6)], axis=1
        )


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


class _ModelPool:
    """Model copies of one scene, reused from one residual to the next (a
    copy costs milliseconds; the toolbox asks for one per finite-difference column)."""

    def __init__(self, base: mujoco.MjModel) -> None:
        self.base = base
        self._models: list[mujoco.MjModel] = []
        self._next = 0

    def rewind(self) -> None:
        self._next = 0

    def take(self) -> mujoco.MjModel:
        if self._next == len(self._models):
            self._models.append(copy.copy(self.base))
        self._next += 1
        return self._models[self._next - 1]


class _Problem:
    """The episodes, the model's figures and the toolbox's residual over them.

    Each parameter is the natural logarithm of a figure's factor on the model's value.
    """

    def __init__(self, episodes: list[_Episode], sysid: Any, threads: int) -> None:
        self.episodes = episodes
        self.sysid = sysid
        self.threads = threads
        self.nominal = read_model_dynamics(episodes[0].model)
        self.frames = sum(len(e.times_s) for e in episodes)
        self.delay = 0
        self._pools = {e.scene: _ModelPool(e.model) for e in episodes}
        self._trajectories: dict[tuple[int, int], Any] = {}

    def parameters(self, fields: Sequence[str], start: Any = None) -> Any:
        """A ParameterDict of log factors, one per joint and figure; those not in
        ``fields`` are frozen (at their value in ``start``, else 0: the model's value)."""
        params = self.sysid.ParameterDict()
        for name in constants.JOINT_NAMES:
            for key in JOINT_FIELDS:
                label = f"{name}.{key}"
                low, high = SCALE_BOUNDS[key]
                parameter = self.sysid.Parameter(
                    label, 0.0, math.log(low), math.log(high), frozen=key not in fields
                )
                if start is not None:
                    parameter.value = np.atleast_1d(float(start[label].value[0]))
                params.add(parameter)
        return params

    def figures(self, params: Any) -> dict[str, dict[str, float]]:
        """Joint -> field -> absolute value of ``params``."""
        return {
            name: {
                key: self.nominal[name][key] * math.exp(float(params[f"{name}.{key}"].value[0]))
                for key in JOINT_FIELDS
            }
            for name in constants.JOINT_NAMES
        }

    def _build(self, episode: _Episode, params: Any) -> mujoco.MjModel:
        model = self._pools[episode.scene].take()
        model.body_pos[:] = episode.body_pos
        apply_dynamics(model, self.figures(params))
        return model

    def _trajectory(self, episode: _Episode, delay: int) -> Any:
        key = (episode.index, delay)
        if key not in self._trajectories:
            ctrl = episode.control(delay)
            dt = episode.model.opt.timestep
            ts = self.sysid.TimeSeries
            self._trajectories[key] = self.sysid.SystemTrajectory(
                model=episode.model,
                control=ts(np.arange(len(ctrl)) * dt, ctrl),
                sensordata=ts(episode.times_s, episode.recorded_rad),
                initial_state=episode.initial_state,
                state=None,
            )
        return self._trajectories[key]

    def _compare(self, episode: _Episode) -> Any:
        scale = math.degrees(1.0) / math.sqrt(self.frames * len(constants.JOINT_NAMES))

        def compare(params, predicted, measured, model, return_pred_all, state):
            simulated = episode.simulated(state)
            residual = (simulated - measured.data).ravel() * scale
            return residual, self.sysid.TimeSeries(measured.times, simulated), measured

        return compare

    def residual(self, x: np.ndarray, params: Any, **_: Any) -> tuple[list, list, list]:
        """The toolbox's residual of every episode, then the pull towards the model."""
        residuals, predicted, measured = [], [], []
        for episode in self.episodes:
            self._pools[episode.scene].rewind()
            res, pred, meas = self.sysid.model_residual(
                x,
                params,
                lambda p, episode=episode: self._build(episode, p),
                self._trajectory(episode, self.delay),
                modify_residual=self._compare(episode),
                n_threads=self.threads,
                resample_true=False,
            )
            residuals.append(res)
            predicted.extend(pred)
            measured.extend(meas)
        residuals.append(PRIOR_WEIGHT / math.sqrt(max(x.shape[0], 1)) * x)
        return residuals, predicted, measured

    def simulate(self, params: Any, delay: int) -> list[np.ndarray]:
        """Per episode, the simulated joint angles (rad) at the compared frames."""
        self.delay = delay
        _, predicted, _ = self.residual(params.as_vector(), params)
        return [p.data for p in predicted]

    def rms_deg(self, simulated: list[np.ndarray]) -> float:
        """The tracking RMS (deg) of simulated joint angles over every compared frame."""
        error = np.concatenate(
            [s - e.recorded_rad for s, e in zip(simulated, self.episodes, strict=True)]
        )
        return float(np.degrees(np.sqrt(np.mean(error**2))))

    def grid_start(self, delay: int) -> Any:
        """Gains-only parameters started, per joint, at the best point of a coarse grid
        of ``kp`` and ``kv`` factors (:data:`GRID_KP`, :data:`GRID_KV`).

        Every grid point sets the same factors on all joints and the whole grid rolls
        out as one batch; each joint then takes the point where it tracked best. A
        start near the answer keeps the local fit out of the valleys that torque
        saturation carves into the error (a fast move is bounded by the force range
        whatever the gains).
        """
        self.delay = delay
        params = self.parameters(("kp", "kv"))
        names = params.get_non_frozen_parameter_names()
        points = [(kp, kv) for kp in GRID_KP for kv in GRID_KV]
        columns = np.zeros((len(names), len(points)))
        for g, (kp, kv) in enumerate(points):
            for i, label in enumerate(names):
                columns[i, g] = math.log(kp if label.endswith(".kp") else kv)
        residuals, _, _ = self.residual(columns, params)
        squared = np.zeros((len(constants.JOINT_NAMES), len(points)))
        for res in residuals[:-1]:  # the last is the pull towards the model
            squared += (res.reshape(-1, len(constants.JOINT_NAMES), len(points)) ** 2).sum(0)
        best = squared.argmin(axis=1)
        for j, name in enumerate(constants.JOINT_NAMES):
            kp, kv = points[best[j]]
            params[f"{name}.kp"].value = np.atleast_1d(math.log(kp))
            params[f"{name}.kv"].value = np.atleast_1d(math.log(kv))
        return params

    def fit(self, params: Any, delay: int, iterations: int) -> tuple[Any, float]:
        """Fit the free factors with ``delay``; returns them and the tracking RMS (deg)."""
        self.delay = delay
        # The scipy backend prints its progress whatever is asked (the toolbox keeps
        # its own ``verbose`` argument): keep stdout clean for the caller.
        with contextlib.redirect_stdout(io.StringIO()):
            fitted, _ = self.sysid.optimize(
                params,
                self.residual,
                optimizer="scipy_parallel_fd",
                verbose=False,
                max_iters=iterations,
                diff_step=FD_STEP,
            )
        return fitted, self.rms_deg(self.simulate(fitted, delay))


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
    sysid = _require_sysid()
    dataset = read_replay_dataset(root, episodes)
    unknown = sorted(set(settings or {}) - set(SYSID_SETTINGS))
    if unknown:
        raise ValueError(
            f"settings of a fit may be {', '.join(SYSID_SETTINGS)}; got {unknown}. The "
            "dynamics are what the fit finds; give units, calibration, wrist_roll_offset_deg "
            "and task as its own arguments."
        )
    env_settings = replay_settings(
        dataset, task, units, calibration, wrist_roll_offset_deg, settings, SYSID_SETTINGS
    )
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
    scenes = episode_scenes(dataset, task, seed)

    prepared: list[_Episode] = []
    models: dict[str, mujoco.MjModel] = {}
    with scene_envs(env_settings) as env_for:
        for index, (actions, states) in dataset.episodes.items():
            name, episode_seed = scenes[index]
            env = env_for(name)
            # The model as made, before any episode: the fit's starting point.
            model = models.setdefault(name, copy.copy(env.physics.model.ptr))
            prepared.append(
                _prepare(env, name, model, index, actions, states, dataset.fps, episode_seed)
            )

    problem = _Problem(prepared, sysid, threads)
    nominal = problem.parameters(())
    before = problem.simulate(nominal, 0)
    # The delay is chosen on the first DELAY_SECONDS of episodes (whole episodes).
    sample, sampled_s = [], 0.0
    for episode in prepared:
        if sampled_s >= DELAY_SECONDS:
            break
        sample.append(episode)
        sampled_s += episode.times_s[-1]
    chooser = problem if len(sample) == len(prepared) else _Problem(sample, sysid, threads)
    delay_rms: dict[str, float] = {}
    best: tuple[float, int, Any] | None = None
    for delay in delays:
        gains, rms = chooser.fit(chooser.grid_start(delay), delay, DELAY_ITERATIONS)
        delay_rms[str(delay)] = round(rms, 4)
        if best is None or rms < best[0]:
            best = (rms, delay, gains)
    assert best is not None
    _, delay, gains = best
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

    recorded = [np.degrees(e.recorded_rad) for e in prepared]
    before_deg = [np.degrees(s) for s in before]
    after_deg = [np.degrees(s) for s in after]
    joints = {
        name: {key: round(value, 6) for key, value in figures.items()}
        for name, figures in problem.figures(fitted).items()
    }
    error_before = np.concatenate([b - r for b, r in zip(before_deg, recorded, strict=True)])
    error_after = np.concatenate([a - r for a, r in zip(after_deg, recorded, strict=True)])
    report = {
        "dataset": os.path.abspath(root),
        "episodes": [e.index for e in prepared],
        "frames_compared": problem.frames,
        "seconds": round(seconds, 3),
        "fps": dataset.fps,
        "units": env_settings.units,
        "rms_before_deg": _rms_per_joint(error_before),
        "rms_after_deg": _rms_per_joint(error_after),
        "overall_rms_before_deg": round(float(np.sqrt(np.mean(error_before**2))), 4),
        "overall_rms_after_deg": round(float(np.sqrt(np.mean(error_after**2))), 4),
        "delay_rms_deg": delay_rms,
        "model_values": problem.nominal,
        "kept_model_values": kept_start,
        "fit_seconds": round(time.perf_counter() - started, 1),
        "method": "mujoco.sysid.optimize (scipy_parallel_fd) on mujoco.rollout, "
        f"MuJoCo {mujoco.__version__}",
    }
    dynamics = Dynamics(joints, delay, report)
    return FitResult(
        dynamics,
        tuple(e.index for e in prepared),
        tuple(e.times_s for e in prepared),
        tuple(recorded),
        tuple(before_deg),
        tuple(after_deg),
    )


def _prepare(
    env: Any,
    scene: str,
    model: mujoco.MjModel,
    index: int,
    actions: np.ndarray,
    states: np.ndarray,
    fps: float,
    seed: int,
) -> _Episode:
    """Place the arm at the episode's first state in its scene (``env``, whose model
    ``model`` copies); the rollout's inputs."""
    start_episode(env, states[0], seed)
    physics = env.physics
    data = physics.data.ptr
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)
    frames = len(states)
    steps = math.ceil((frames - 1) * SIM_FPS / fps - 1e-9)
    low, high = physics.control_range()
    to_radians = env.joint_units.to_radians
    targets = np.clip(to_radians(actions.astype(np.float32)), low, high)
    targets = targets[frame_of_steps(steps, frames, fps)]
    qpos_adr = np.array(
        [model.jnt_qposadr[model.joint(n).id] for n in constants.JOINT_NAMES], dtype=np.intp
    )
    return _Episode(
        index=index,
        scene=scene,
        model=model,
        body_pos=physics.model.ptr.body_pos.copy(),  # a reset places fixtures there
        initial_state=initial,
        start_ctrl=data.ctrl.copy(),
        targets=targets,
        start_targets=physics.joint_targets().copy(),
        times_s=np.arange(1, frames) / fps,
        recorded_rad=to_radians(states[1:]),
        qpos_adr=qpos_adr,
    )


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
