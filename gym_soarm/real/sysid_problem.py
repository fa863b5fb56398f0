"""The fit's problem: episodes ready to roll out and MuJoCo's sysid residual over them.

:func:`gym_soarm.real.sysid.fit_dynamics` prepares each episode of a dataset
(:func:`prepare_episode`: the scene's model, the arm placed at the first recorded state,
the servo targets of each 50 Hz step) and hands them to a :class:`FitProblem`, which
builds the figures as :class:`mujoco.sysid.Parameter` log factors (bounded by
:data:`SCALE_BOUNDS`), rolls the episodes out with :func:`mujoco.sysid.model_residual`
and fits them with :func:`mujoco.sysid.optimize`. See :mod:`gym_soarm.real.sysid` for
the method.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.real.dynamics import JOINT_FIELDS, apply_dynamics, read_model_dynamics
from gym_soarm.real.replay import SIM_FPS, frame_of_steps, start_episode
from gym_soarm.sim.randomization import arm_indices

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
GRID_KP: tuple[float, ...] = (0.4, 0.6, 0.85, 1.2, 1.7, 2.4)
"""The ``kp`` factors of the coarse grid each delay's fit starts from."""
GRID_KV: tuple[float, ...] = (0.4, 0.6, 0.85, 1.2, 1.7, 2.4, 3.4)
"""The ``kv`` factors of that grid."""
FD_STEP = 1e-3
"""Finite-difference step of the factors."""


def require_sysid() -> Any:
    """MuJoCo's :mod:`mujoco.sysid`, or an ImportError that says how to install it."""
    import mujoco.sysid as sysid

    if not hasattr(sysid, "optimize"):  # the package hides its own missing dependencies
        raise ImportError(
            "Fitting dynamics needs MuJoCo's system-identification toolbox and its "
            'dependencies: pip install "gym-soarm[sysid]" (mujoco[sysid]).'
        )
    return sysid


@dataclass
class FitEpisode:
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


class ModelPool:
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


class FitProblem:
    """The episodes, the model's figures and the toolbox's residual over them.

    Each parameter is the natural logarithm of a figure's factor on the model's value.
    """

    def __init__(self, episodes: list[FitEpisode], sysid: Any, threads: int) -> None:
        self.episodes = episodes
        self.sysid = sysid
        self.threads = threads
        self.nominal = read_model_dynamics(episodes[0].model)
        self.frames = sum(len(e.times_s) for e in episodes)
        self.delay = 0
        self._pools = {e.scene: ModelPool(e.model) for e in episodes}
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

    def _build(self, episode: FitEpisode, params: Any) -> mujoco.MjModel:
        model = self._pools[episode.scene].take()
        model.body_pos[:] = episode.body_pos
        apply_dynamics(model, self.figures(params))
        return model

    def _trajectory(self, episode: FitEpisode, delay: int) -> Any:
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

    def _compare(self, episode: FitEpisode) -> Any:
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


def prepare_episode(
    env: Any,
    scene: str,
    model: mujoco.MjModel,
    index: int,
    actions: np.ndarray,
    states: np.ndarray,
    fps: float,
    seed: int,
) -> FitEpisode:
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
    return FitEpisode(
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
