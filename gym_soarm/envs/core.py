"""The step, written once: N simulations of one task over a physics backend.

A control step of every environment of the package, the single
:class:`~gym_soarm.envs.env.SoArmEnv` (one ``MjData``) and the batched vector env
(one ``mujoco.batch``) alike, is :meth:`StepCore.step`:

1. the servo targets (the control mode's, after the servo chain:
   :class:`~gym_soarm.envs.control.ServoChain`) go to the backend;
2. the backend advances the physics by the control rate's substeps (10 at 50 Hz,
   :mod:`gym_soarm.sim.timing`);
3. divergence: MuJoCo's own errors and warnings, then NaN/inf, an object thrown off the
   table, a joint turned past +-pi (:meth:`StepCore.divergence`);
4. scoring on the arrays of every simulation: the task's evaluation, reward terms,
   success and reward (:meth:`StepCore.score`);
5. the observations that need no camera (:meth:`StepCore.state_observation`) and the
   values of the infos (:meth:`StepCore.info_values`).

The batch's steps run on the arrays' own library and device (NumPy for ``mujoco.batch``,
torch on the device for MuJoCo Warp: :mod:`gym_soarm.sim.arrays`); only what the
episode bookkeeping needs comes to the host, in one transfer a step.

The environments keep what is theirs: argument checks, resets, rendering, and the time
limit and autoreset of a vector env (:mod:`gym_soarm.vector`). One environment is
scored on its unbatched arrays (Python scalars, :data:`gym_soarm.sim.arrays.SCALARS`):
the same code, without NumPy's per-call cost on arrays of one.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import SCALARS, SimArrays, in_namespace, to_numpy
from gym_soarm.sim.backends import Backend
from gym_soarm.tasks.base import Task
from gym_soarm.tasks.state_observation import StateObservation


@dataclasses.dataclass
class StepResult:
    """What one step of the core gives: for ``n`` simulations, or one (unbatched)."""

    sim: SimArrays
    """The arrays after the step (live: valid until the next step or reset)."""
    diverged: dict[int, str]
    """The simulations whose physics diverged on this step, with why; they were not scored
    (their reward, success and terms are meaningless)."""
    evaluation: dict[str, Any]
    success: Any
    terms: dict[str, Any]
    reward: Any
    host_success: Any
    """``success`` on the host (NumPy; a bool for one environment): what the episode
    bookkeeping reads, copied from the device with the divergences in one transfer."""


class StepCore:
    """Steps and scores the simulations of one task held by ``backend``.

    Args:
        task: the task that scores every simulation (its episode values, one row each,
            in ``episode``).
        backend: the simulations (:mod:`gym_soarm.sim.backends`).
        episode: the task's per-episode values of every simulation, ``(n, ...)`` arrays
            by name; None: the task's own (one environment's ``(1, ...)`` arrays).
        before_step: a task hook that sets one environment's targets itself (a task
            that overrides :meth:`~gym_soarm.tasks.base.Task.before_step`); None: the
            backend sets them.
        substeps: physics steps a control step (the control rate's,
            :class:`~gym_soarm.sim.timing.ControlTiming`).
    """

    def __init__(
        self,
        task: Task,
        backend: Backend,
        episode: dict[str, Any] | None = None,
        before_step: Callable[[np.ndarray], None] | None = None,
        substeps: int = constants.N_SUBSTEPS,
    ) -> None:
        self.task = task
        self.substeps = substeps
        self.backend = backend
        self.episode = episode
        self.state_observer = StateObservation(task)
        self._before_step = before_step
        # One environment's arrays come without the batch axis: scored as scalars.
        self._unbatched = self.arrays().qpos.ndim == 1

    def arrays(self) -> SimArrays:
        """The simulations' arrays now."""
        episode = self.task.episode if self.episode is None else self.episode
        return self.backend.arrays(episode)

    # --- the step ------------------------------------------------------------------------
    def step(
        self,
        targets: np.ndarray,
        steps: Any,
        limit: int,
        sparse: Any,
        ids: np.ndarray | None = None,
    ) -> StepResult:
        """One control step of the simulations ``ids`` (None: all).

        Args:
            targets: the servo targets (rad), ``(6,)`` for one environment or
                ``(len(ids), 6)``.
            steps: each episode's step count after this step (the success bonus).
            limit: the episodes' step limit (the success bonus).
            sparse: whether each environment's reward is sparse.

        On a batch the arrays stay where the backend keeps them (torch tensors on
        MuJoCo Warp's device): the scores are computed there, and one ``(3, n)`` boolean
        array comes to the host (the simulations that diverged or overflowed, and those
        that succeeded: :attr:`StepResult.host_success`).
        """
        if self._before_step is not None:
            self._before_step(targets)
        else:
            self.backend.set_targets(ids, targets)
        reasons = self.backend.step(ids, self.substeps)
        sim = self.arrays()
        if self._unbatched:
            diverged = self.divergence(sim, reasons, ids)
            if diverged:
                return StepResult(sim, diverged, {}, False, {}, 0.0, False)
            evaluation, success, terms, reward = self.score(sim, steps, limit, sparse)
            return StepResult(sim, diverged, evaluation, success, terms, reward, success)
        evaluation, success, terms, reward = self.score(sim, steps, limit, sparse)
        xp = sim.xp
        overflow = self.backend.overflowed()
        if overflow is None:
            overflow = xp.zeros_like(success)
        # The step's one transfer from the device: what the episode bookkeeping reads.
        unsound, overflow, success_host = to_numpy(
            xp.stack([self.unsound(sim) | overflow, overflow, success])
        )
        diverged = self._reasons(sim, reasons, unsound, overflow, ids)
        return StepResult(sim, diverged, evaluation, success, terms, reward, success_host)

    def divergence(
        self, sim: SimArrays, reasons: dict[int, str], ids: np.ndarray | None = None
    ) -> dict[int, str]:
        """The simulations (of ``ids``; None: all) that are no longer physical, with why.

        Besides MuJoCo's own errors and warnings (``reasons``, the backend's), an object
        thrown beyond :data:`~gym_soarm.constants.POSITION_BOUND_M`, a joint turned past
        +-pi or NaN/inf in the state can only come from an exploding simulation; so can a
        simulation that ran past a fixed buffer (:meth:`Backend.overflowed
        <gym_soarm.sim.backends.Backend.overflowed>`).
        """
        if self._unbatched:
            if reasons:
                return dict(reasons)
            reason = self._unsound(sim, None)
            return {} if reason is None else {0: reason}
        overflow = self.backend.overflowed()
        unsound = to_numpy(self.unsound(sim))
        overflow = np.zeros_like(unsound) if overflow is None else to_numpy(overflow)
        return self._reasons(sim, reasons, unsound | overflow, overflow, ids)

    def unsound(self, sim: SimArrays) -> Any:
        """``(n,)`` bool, where the arrays are: NaN/inf in the state, an object thrown
        beyond :data:`~gym_soarm.constants.POSITION_BOUND_M`, a joint turned past +-pi."""
        xp = sim.xp
        unsound = ~sim.state_is_finite()
        for name in sim.index.objects:
            far = xp.max(xp.abs(sim.object_position(name)), axis=1)
            unsound = unsound | (far > constants.POSITION_BOUND_M)
        return unsound | xp.any(xp.abs(sim.joint_angles()) > math.pi, axis=1)

    def _reasons(
        self,
        sim: SimArrays,
        reasons: dict[int, str],
        unsound: np.ndarray,
        overflow: np.ndarray,
        ids: np.ndarray | None,
    ) -> dict[int, str]:
        """Why each simulation of ``unsound`` (host masks) is, among those of ``ids``."""
        found = dict(reasons)
        for i in np.flatnonzero(unsound).tolist():
            if overflow[i]:
                found.setdefault(i, self.backend.overflow_reason(i))
            found.setdefault(i, self._unsound(sim, i) or "the simulation is unsound")
        if ids is not None and len(ids) < sim.n:
            stepped = set(ids.tolist())
            found = {i: r for i, r in found.items() if i in stepped}
        return found

    @staticmethod
    def _unsound(sim: SimArrays, i: int | None) -> str | None:
        """Why simulation ``i`` (None: the unbatched one) is unsound, in plain floats (a
        few NumPy reductions would cost more than the rest of one environment's step)."""
        index = sim.index
        # One list each, the objects and joints read from qpos by address.
        qpos, qvel, qacc = [
            (a if i is None else a[i]).tolist() for a in (sim.qpos, sim.qvel, sim.qacc)
        ]
        if not math.isfinite(sum(qpos) + sum(qvel) + sum(qacc)):
            return "the simulation state holds NaN or inf"
        farthest = None
        for name, item in index.objects.items():
            position = qpos[item.qpos : item.qpos + 3]
            distance = max(map(abs, position))
            if farthest is None or distance > farthest[1]:
                farthest = (name, distance, position)
        if farthest is not None and farthest[1] > constants.POSITION_BOUND_M:
            where = [round(v, 2) for v in farthest[2]]
            return (
                f"the {farthest[0]} was thrown to {where} m, more than "
                f"{constants.POSITION_BOUND_M} m from the table"
            )
        angles = [qpos[q] for q in index.arm_qpos]
        if max(map(abs, angles)) > math.pi:
            name, angle = max(
                zip(constants.JOINT_NAMES, angles, strict=True), key=lambda item: abs(item[1])
            )
            return f"joint {name!r} turned to {angle:.2f} rad"
        return None

    def score(
        self, sim: SimArrays, steps: Any, limit: int, sparse: Any
    ) -> tuple[dict[str, Any], Any, dict[str, Any], Any]:
        """The task's evaluation, success, reward terms and reward of every simulation.

        The dense reward is the task's weighted terms; the step that succeeds pays 1 plus
        1 for every step left to ``limit`` (what the rest of the episode could earn at
        the most); a sparse reward is 1 on success, else 0.
        """
        task = self.task
        evaluation = task.evaluate(sim)
        success = evaluation["success"]
        terms = task.batch_reward_terms(evaluation)
        if self._unbatched:
            if sparse:
                reward = float(success)
            elif success:
                reward = float(1 + max(limit - steps, 0))
            else:
                reward = float(task.weights.total(terms))
            return evaluation, bool(success), terms, reward
        xp = sim.xp
        success = xp.astype(success, xp.bool)
        dtype = xp.float64 if xp is np else sim.qpos.dtype  # float32 on MuJoCo Warp
        if np.all(sparse):
            reward = xp.astype(success, dtype)
        else:
            steps, sparse = (in_namespace(xp, values, success) for values in (steps, sparse))
            bonus = 1.0 + xp.maximum(limit - steps, 0)
            dense = xp.astype(task.weights.total(terms), dtype)
            reward = xp.where(sparse, xp.astype(success, dtype), xp.where(success, bonus, dense))
            reward = xp.astype(reward, dtype)
        return evaluation, success, terms, reward

    # --- what the step reports -----------------------------------------------------------
    def state_observation(self, sim: SimArrays, commanded: np.ndarray) -> Any:
        """The ``"state"`` observation (float32, ``(..., size)``)."""
        return self.state_observer.batch(sim, commanded)

    def environment_state(self, sim: SimArrays) -> Any:
        """The task's ``environment_state`` (``(..., size)``)."""
        state = self.task.batch_state(sim)
        return np.asarray(state) if sim.xp in (np, SCALARS) else state

    def info_values(self, sim: SimArrays, evaluation: dict[str, Any]) -> tuple[dict[str, Any], Any]:
        """The task's own info values and the ``gripperframe`` position: unbatched values
        for one environment, ``(n, ...)`` arrays for a batch (the caller formats them)."""
        return self.task.compute_info(sim, evaluation), sim.gripper_position()


__all__ = ["StepCore", "StepResult"]
