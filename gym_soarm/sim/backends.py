"""Physics backends: N simulations of one scene behind one small interface.

The step core (:mod:`gym_soarm.envs.core`) is written once over a backend; a backend
(:class:`Backend`, the one protocol every backend implements) only sets the servo
targets, steps, exposes the arrays the tasks read
(:class:`~gym_soarm.sim.arrays.SimArrays`), copies one simulation's state out to an
environment's own ``MjData`` and back in, takes in what resets wrote into the models,
and closes:

* :class:`MjDataBackend`: one environment's own ``MjData`` (N = 1), read without a
  batch axis (the tasks' unbatched fast path);
* :class:`BatchBackend`: N simulations in one ``mujoco.batch.Batch`` (MuJoCo's thread
  pool, the GIL released, bit for bit what stepping each alone gives);
* :class:`~gym_soarm.sim.warp_backend.WarpBackend`: N worlds of MuJoCo Warp (a GPU), its
  arrays torch tensors on the device.

A backend reports which simulations MuJoCo itself found unsound (a raised error, a new
warning) and, where its buffers are fixed (MuJoCo Warp), which ran past them, as a mask
where its arrays are (:meth:`Backend.overflowed`); the core adds its own checks (NaN,
thrown objects, turned joints).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import mujoco
import mujoco.batch
import numpy as np
from dm_control.rl import control

from gym_soarm.sim.arrays import ARRAY_FIELDS, SimArrays, SimIndex
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.sim.randomization import arm_indices

_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
_STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
_WARNINGS: tuple[str, ...] = tuple(mujoco.mjtWarning.__members__)
_SOUND: dict[int, str] = {}  # what a sound step reports (never written to)
_NO_OVERFLOW = "C MuJoCo grows its buffers: no simulation overflows"


def write_targets(
    ctrl: np.ndarray, actuators: np.ndarray, ids: np.ndarray | None, targets: np.ndarray
) -> None:
    """Write the servo targets (``(len(ids), 6)``, rad) of simulations ``ids`` (None:
    all) into the rows of a batch's ``ctrl`` (``(n, nu)``)."""
    rows = slice(None) if ids is None else ids
    for column, actuator in enumerate(actuators.tolist()):
        ctrl[rows, actuator] = targets[:, column]


class Backend(Protocol):
    """N simulations of one scene, as the step core and the environments drive them.

    Every backend implements all of it: :class:`MjDataBackend`, :class:`BatchBackend`
    and :class:`~gym_soarm.sim.warp_backend.WarpBackend`. The environments build their
    simulations with their own ``MjModel``/``MjData`` (resets, snapshots, rendering) and
    move them in and out with :meth:`load` and :meth:`unload`.

    Attributes:
        num_envs: N, the simulations it holds.
        index: where the scene's parts lie (every simulation shares it).
    """

    num_envs: int
    index: SimIndex

    def set_targets(self, ids: np.ndarray | None, targets: np.ndarray) -> None:
        """The servo targets (rad, ``(len(ids), 6)``) of simulations ``ids`` (None: all)."""
        ...

    def step(self, ids: np.ndarray | None, nstep: int) -> dict[int, str]:
        """Advance simulations ``ids`` (None: all) by ``nstep`` physics steps; the
        simulations MuJoCo found unsound on the way, with why."""
        ...

    def arrays(self, episode: dict[str, Any]) -> SimArrays:
        """Live arrays of every simulation, with the tasks' per-episode values (a backend
        may answer the same object each call, its cache cleared)."""
        ...

    def overflowed(self) -> Any:
        """``(n,)`` bool, where the arrays are: the simulations whose last step ran past
        a fixed buffer (MuJoCo Warp's contacts and constraint rows); None where the
        backend has none (C MuJoCo grows its buffers, and warns)."""
        ...

    def overflow_reason(self, i: int) -> str:
        """Why simulation ``i``, marked by :meth:`overflowed`, ran past a buffer."""
        ...

    def load(self, i: int, physics: SoArmPhysics) -> None:
        """Copy ``physics`` (an environment's own simulation, just reset or restored)
        into simulation ``i``."""
        ...

    def unload(self, i: int, physics: SoArmPhysics) -> None:
        """Copy simulation ``i`` into ``physics``, as a step of that environment leaves it."""
        ...

    def set_models(self) -> None:
        """Take in what resets wrote into the simulations' models (poses of fixtures,
        randomisation) and the states :meth:`load` staged."""
        ...

    def close(self) -> None:
        """Release what the backend holds (safe to call twice)."""
        ...


class MjDataBackend:
    """One environment's simulation: its own :class:`~gym_soarm.sim.physics.SoArmPhysics`.

    Its arrays are the ``MjData``'s own, without the batch axis, so the tasks score it
    with plain scalars (:data:`gym_soarm.sim.arrays.SCALARS`). The simulation is the
    environment's: loading or unloading that same physics copies nothing, and the
    model's edits need no :meth:`set_models`.
    """

    num_envs = 1

    def __init__(self, physics: SoArmPhysics) -> None:
        self.physics = physics
        self.index = physics.sim_index
        self._sim: SimArrays | None = None
        self._sim_of: tuple[Any, Any] = (None, None)

    def set_targets(self, ids: np.ndarray | None, targets: np.ndarray) -> None:
        self.physics.set_joint_targets(targets)

    def step(self, ids: np.ndarray | None, nstep: int) -> dict[int, str]:
        try:
            self.physics.step(nstep)
        except control.PhysicsError as exc:
            return {0: str(exc)}
        return _SOUND

    def arrays(self, episode: dict[str, Any]) -> SimArrays:
        # The arrays are live views: made once for these episode values and this MjData
        # (a snapshot's restore brings new episode values), forgotten between reads.
        views = self.physics.array_views
        made_of = self._sim_of
        if self._sim is None or made_of[0] is not episode or made_of[1] is not views:
            self._sim = SimArrays.of_physics(self.physics, episode)
            self._sim_of = (episode, views)
        else:
            self._sim.clear()
        return self._sim

    def overflowed(self) -> None:
        """None: MuJoCo grows its buffers (and warns)."""
        return None

    def overflow_reason(self, i: int) -> str:
        return _NO_OVERFLOW

    def load(self, i: int, physics: SoArmPhysics) -> None:
        """Copy ``physics`` (a simulation of the same scene) into this one: all of its
        ``MjData``."""
        _check_single(i, "load")
        if physics is not self.physics:
            mujoco.mj_copyData(self.physics.data.ptr, self.physics.model.ptr, physics.data.ptr)

    def unload(self, i: int, physics: SoArmPhysics) -> None:
        """Copy this simulation into ``physics`` (of the same scene): all of its ``MjData``."""
        _check_single(i, "unload")
        if physics is not self.physics:
            mujoco.mj_copyData(physics.data.ptr, physics.model.ptr, self.physics.data.ptr)

    def set_models(self) -> None:
        """Nothing to take in: the simulation steps on the environment's own model."""

    def close(self) -> None:
        """Nothing to release: the simulation is the environment's, which frees it."""


def _check_single(i: int, method: str) -> None:
    if i != 0:
        raise ValueError(
            f"MjDataBackend.{method}: simulation {i!r} does not exist; expected 0 (the "
            "backend holds one simulation). Use BatchBackend for N simulations."
        )


class BatchBackend:
    """N simulations in one ``mujoco.batch.Batch``, one model each.

    Args:
        models: each simulation's ``MjModel`` (compiled from one scene; resets may edit
            them: call :meth:`set_models` after).
        num_threads: the threads that step the batch.
        index: where the scene's parts lie (every model shares it).
    """

    def __init__(self, models: Sequence[mujoco.MjModel], num_threads: int, index: SimIndex) -> None:
        self.num_envs = len(models)
        self.index = index
        self._models = list(models)
        self._batch = mujoco.batch.Batch(self._models[0], self.num_envs, num_threads)
        self._batch.set_models(self._models)
        self._fields = {name: self._batch.bind(name) for name in ARRAY_FIELDS}
        self._ctrl = self._batch.bind("ctrl")
        self._actuators, _ = arm_indices(self._models[0])

    def set_models(self) -> None:
        """Take in what resets wrote into the models (poses of fixtures, randomisation)."""
        self._batch.set_models(self._models)

    def set_targets(self, ids: np.ndarray | None, targets: np.ndarray) -> None:
        write_targets(self._ctrl, self._actuators, ids, targets)

    def step(self, ids: np.ndarray | None, nstep: int) -> dict[int, str]:
        batch = self._batch
        if ids is not None and len(ids) == 0:
            return {}
        before = batch.warning[:, :, 1].copy()  # (lastinfo, number) per warning
        reasons: dict[int, str] = {}
        try:
            batch.step(None if ids is None or len(ids) == self.num_envs else ids, nstep, _STAGE_VEL)
        except mujoco.batch.SimulationError as exc:
            for i in exc.ids.tolist():
                reasons[i] = f"MuJoCo raised: {batch.error(i)}"
        after = batch.warning[:, :, 1]
        for i in np.flatnonzero((after > before).any(axis=1)).tolist():
            names = [
                w for w, old, new in zip(_WARNINGS, before[i], after[i], strict=False) if new > old
            ]
            reasons.setdefault(
                i, f"Physics state is invalid. Warning(s) raised: {', '.join(names)}"
            )
        return reasons

    def arrays(self, episode: dict[str, Any]) -> SimArrays:
        return SimArrays(self.index, self._fields, episode)

    def overflowed(self) -> None:
        """None: MuJoCo grows its buffers (and warns)."""
        return None

    def overflow_reason(self, i: int) -> str:
        return _NO_OVERFLOW

    def load(self, i: int, physics: SoArmPhysics) -> None:
        """Copy ``physics`` (an environment's own simulation) into simulation ``i``."""
        mujoco.mj_getState(physics.model.ptr, physics.data.ptr, self._batch.state[i], _STATE_SPEC)

    def unload(self, i: int, physics: SoArmPhysics) -> None:
        """Copy simulation ``i`` into ``physics``, as a step of that environment leaves it."""
        data = physics.data.ptr
        self._batch.get_data(i, data)
        mujoco.mj_step1(physics.model.ptr, data)  # positions and velocities, as a step
        # The last substep's accelerations and sensors, as a step leaves them.
        data.qacc[:] = self._fields["qacc"][i]
        data.sensordata[:] = self._fields["sensordata"][i]

    def close(self) -> None:
        """Release the batch and its threads (every reference to it goes)."""
        self._batch = self._ctrl = None
        self._fields = {}


__all__ = ["Backend", "BatchBackend", "MjDataBackend", "write_targets"]
