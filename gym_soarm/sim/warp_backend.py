"""The MuJoCo Warp backend: N worlds of one scene stepped by MuJoCo Warp.

:class:`WarpBackend` is a backend of the step core (:mod:`gym_soarm.sim.backends`):
``gym.make_vec(..., vectorization_mode="vector_entry_point", vector_env="warp",
device="cuda")`` steps every environment of the batched vector env on it, on a GPU or
on Warp's CPU device (``device="cpu"``, slow but exact enough to test with).

* Warp computes in float32: a world follows C MuJoCo's float64 simulation to about 1e-5
  over a control step, not bit for bit.
* The worlds share one model; what a reset writes into an environment's model (the pose
  of a fixture: ``body_pos``, ``body_quat``) is batched per world. A setting whose
  resets change other model fields (``physics_randomization``, fitted ``dynamics``,
  the STS3215 force limit) is refused by the vector env, naming it.
* Each world's contacts and constraint rows are bounded (:data:`CONTACTS_PER_WORLD`,
  :data:`CONSTRAINTS_PER_WORLD`, sized from the scene); a step that runs past the bound
  truncates every world that stepped with a warning, never a silent NaN.
* The arrays the tasks read are host copies (NumPy) of the Warp arrays, made once a
  step; on Warp's CPU device they cost a copy of a few kB.
* On a GPU a control step (its substeps and the closing position stage) is captured
  once as a CUDA graph and replayed: one launch a step instead of a few hundred kernel
  launches from Python.
* Warp compiles its kernels on first use (about a minute on two CPU cores) and keeps
  them in its kernel cache (``~/.cache/warp/<version>``, or ``WARP_CACHE_PATH``); later
  processes load them in a second or two.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from gym_soarm.sim.arrays import ARRAY_FIELDS, SimArrays, SimIndex
from gym_soarm.sim.backends import write_targets
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.sim.randomization import arm_indices

CONTACTS_PER_WORLD = 48
"""Contacts a world may hold (the scenes hold at most ~20 at rest: jaws, objects, table)."""
CONSTRAINTS_PER_WORLD = 256
"""Constraint rows a world may hold (pyramidal friction cones: 4 rows a contact)."""
_STATE_FIELDS = ("qpos", "qvel", "act", "qacc_warmstart", "mocap_pos", "mocap_quat", "time")
"""The ``MjData`` fields that make a world's state (``mj_step`` reads them)."""
WORLD_MODEL_FIELDS: tuple[str, ...] = ("body_pos", "body_quat")
"""The model fields that differ per world (what the tasks' resets place)."""
DEVICES_HELP = '"cpu", "cuda" or "cuda:N"'


def warp_available() -> bool:
    """Whether MuJoCo Warp and Warp are installed (``pip install "gym-soarm[warp]"``)."""
    return all(importlib.util.find_spec(name) for name in ("warp", "mujoco_warp"))


def check_device(device: Any) -> str:
    """``device`` as Warp names it; refused (``ValueError``) unless it is a Warp device
    of this machine.

    Raises:
        ImportError: MuJoCo Warp is not installed.
    """
    if not isinstance(device, str) or not (
        device == "cpu" or device == "cuda" or (device.startswith("cuda:") and device[5:].isdigit())
    ):
        raise ValueError(f"device must be {DEVICES_HELP}; got {device!r}.")
    wp = _import_warp()
    names = [str(d) for d in wp.get_devices()]
    if device == "cuda":
        device = "cuda:0"
    if device not in names:
        raise ValueError(
            f"device {device!r} is not on this machine: Warp sees {names}. Pass device='cpu' "
            "(Warp's CPU device) or a listed GPU."
        )
    return device


def _import_warp() -> Any:
    if not warp_available():
        raise ImportError(
            'vector_env="warp" needs MuJoCo Warp: pip install "gym-soarm[warp]" '
            "(mujoco-warp and warp-lang)."
        )
    import warp as wp

    wp.config.quiet = True
    wp.config.verbose = False
    wp.init()
    return wp


class WarpBackend:
    """N worlds of one scene on MuJoCo Warp.

    Args:
        models: each environment's ``MjModel`` (compiled from one scene; only the
            fields of :data:`WORLD_MODEL_FIELDS` may differ between them).
        device: a Warp device (:func:`check_device`).
        index: where the scene's parts lie.
    """

    def __init__(self, models: Sequence[mujoco.MjModel], device: str, index: SimIndex) -> None:
        wp = _import_warp()
        import mujoco_warp as mjw

        self._wp, self._mjw = wp, mjw
        self.num_envs = n = len(models)
        self.index = index
        self.device = device
        self._models = list(models)
        model = self._models[0]
        self._actuators, _ = arm_indices(model)
        with wp.ScopedDevice(device):
            self._model = mjw.put_model(model, batch_sizes=dict.fromkeys(WORLD_MODEL_FIELDS, n))
            self._data = mjw.make_data(
                model,
                nworld=n,
                nconmax=CONTACTS_PER_WORLD,
                njmax=CONSTRAINTS_PER_WORLD,
            )
        self._ctrl = np.zeros((n, model.nu))
        self._graphs: dict[int, Any] = {}  # nstep -> the CUDA graph of a control step
        self._host: dict[str, np.ndarray] = {}
        self._staged: dict[str, np.ndarray] = {}  # loaded states not yet on the device
        self.set_models()
        self._read()

    # --- the model ---------------------------------------------------------------------
    def set_models(self) -> None:
        """Take in what resets wrote into the environments' models (fixture poses) and
        the states :meth:`load` staged."""
        for name in WORLD_MODEL_FIELDS:
            values = np.stack([getattr(m, name) for m in self._models])
            getattr(self._model, name).assign(values.astype(np.float32))
        self._push()

    # --- stepping ----------------------------------------------------------------------
    def set_targets(self, ids: np.ndarray | None, targets: np.ndarray) -> None:
        write_targets(self._ctrl, self._actuators, ids, targets)

    def step(self, ids: np.ndarray | None, nstep: int) -> dict[int, str]:
        """Step every world ``nstep`` times (the worlds outside ``ids`` are those that
        reset right after, so they step too: one launch for all)."""
        wp = self._wp
        self._push()
        with wp.ScopedDevice(self.device):
            self._data.ctrl.assign(self._ctrl.astype(np.float32))
            if not wp.get_device(self.device).is_cuda:
                self._control_step(nstep)
            else:
                if nstep not in self._graphs:
                    with wp.ScopedCapture() as capture:
                        self._control_step(nstep)
                    self._graphs[nstep] = capture.graph
                wp.capture_launch(self._graphs[nstep])
        self._read()
        reasons: dict[int, str] = {}
        overflow = self._overflow()
        if overflow:
            rows = range(self.num_envs) if ids is None else ids.tolist()
            for i in rows:
                reasons[i] = overflow
        return reasons

    def _control_step(self, nstep: int) -> None:
        for _ in range(nstep):
            self._mjw.step(self._model, self._data)
        # Positions, velocities and their sensors of the new state (C MuJoCo's legacy
        # step ends on mj_step1 too): the sites and contacts the tasks read.
        self._mjw.step1(self._model, self._data)

    def _overflow(self) -> str | None:
        """Why the step ran past the contact or constraint budget, or None."""
        data = self._data
        contacts = int(data.nacon.numpy()[0])
        if contacts >= data.naconmax:
            return (
                f"the worlds held {contacts} contacts, the budget of {data.naconmax} "
                f"({CONTACTS_PER_WORLD} a world): contacts beyond it were dropped"
            )
        rows = data.nefc.numpy()
        if rows.size and int(rows.max()) >= data.njmax:
            return (
                f"a world held {int(rows.max())} constraint rows, the budget of {data.njmax}: "
                "rows beyond it were dropped"
            )
        return None

    def _read(self) -> None:
        """Host copies of the arrays the tasks read (float64, as C MuJoCo's)."""
        for name in ARRAY_FIELDS:
            self._host[name] = getattr(self._data, name).numpy().astype(np.float64)

    def arrays(self, episode: dict[str, Any]) -> SimArrays:
        return SimArrays(self.index, self._host, episode)

    # --- one world in and out ----------------------------------------------------------
    def load(self, i: int, physics: SoArmPhysics) -> None:
        """Stage ``physics`` (an environment's own simulation) as world ``i``'s state; the
        staged worlds go to the device together, at :meth:`set_models` or the next step
        (one copy of each array for a whole reset, not one per world)."""
        data = physics.data.ptr
        if not self._staged:  # the device's state, into which the loaded worlds go
            self._staged = {name: getattr(self._data, name).numpy() for name in _STATE_FIELDS}
        for name in _STATE_FIELDS:
            if self._staged[name].size:
                self._staged[name][i] = getattr(data, name)
        self._ctrl[i] = data.ctrl

    def _push(self) -> None:
        """The staged states onto the device, and their positions stage computed."""
        if not self._staged:
            return
        for name, values in self._staged.items():
            if values.size:
                getattr(self._data, name).assign(values)
        self._staged = {}
        with self._wp.ScopedDevice(self.device):
            self._mjw.forward(self._model, self._data)
        self._read()

    def unload(self, i: int, physics: SoArmPhysics) -> None:
        """Copy world ``i`` into ``physics``: its state, then C MuJoCo's positions and
        velocities stage on it (the last substep's accelerations and sensors are Warp's)."""
        model, data = physics.model.ptr, physics.data.ptr
        data.qpos[:] = self._host["qpos"][i]
        data.qvel[:] = self._host["qvel"][i]
        data.ctrl[:] = self._ctrl[i]
        data.time = float(self._data.time.numpy()[i])
        mujoco.mj_step1(model, data)
        data.qacc[:] = self._host["qacc"][i]
        data.sensordata[:] = self._host["sensordata"][i]

    def close(self) -> None:
        """Release the worlds (every reference to the Warp arrays goes)."""
        self._model = self._data = None
        self._graphs = {}
        self._host = {}


__all__ = [
    "CONSTRAINTS_PER_WORLD",
    "CONTACTS_PER_WORLD",
    "WORLD_MODEL_FIELDS",
    "WarpBackend",
    "check_device",
    "warp_available",
]
