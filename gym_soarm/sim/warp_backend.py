"""The MuJoCo Warp backend: N worlds of one scene stepped by MuJoCo Warp.

:class:`WarpBackend` is a backend of the step core (:mod:`gym_soarm.sim.backends`):
``gym.make_vec(..., vectorization_mode="vector_entry_point", vector_env="warp",
device="cuda")`` steps every environment of the batched vector env on it, on a GPU or
on Warp's CPU device (``device="cpu"``, slow but exact enough to test with).

* Warp computes in float32: a world follows C MuJoCo's float64 simulation to about 1e-5
  over a control step, not bit for bit.
* The arrays the tasks read (:data:`~gym_soarm.sim.arrays.ARRAY_FIELDS`) are torch
  tensors that share the Warp arrays' memory (``warp.to_torch``, float32, on the
  device), taken once when the backend is built: MuJoCo Warp writes its arrays in place
  (a step never rebinds them), so the tasks' array code scores the worlds where they
  are, without a copy.
* The worlds share one model; what a reset writes into an environment's model (the pose
  of a fixture: ``body_pos``, ``body_quat``) is batched per world. A setting whose
  resets change other model fields (``physics_randomization``, fitted ``dynamics``,
  the STS3215 force limit) is refused by the vector env, naming it.
* A reset copies only the rows of the worlds that reset into the device's state and
  their fixtures' poses into the model (indexed assignments into torch views of
  ``qpos``, ``qvel`` ... and ``body_pos``, ``body_quat``), then computes the positions
  stage.
* Each world is held to its own budget of contacts and constraint rows
  (:data:`CONTACTS_PER_WORLD`, :data:`CONSTRAINTS_PER_WORLD`), checked on the device
  after every physics step: MuJoCo Warp's per-world overflow flags (``Data.overflow``:
  constraint rows past ``njmax`` ...) and each world's contacts, counted by a kernel of
  this package (:mod:`gym_soarm.sim.warp_kernels`) from the contacts' ``worldid``.
  :meth:`WarpBackend.overflowed` answers the worlds that ran past a budget as a device
  mask; the vector env truncates those worlds only, with a warning naming each. The
  shared contact pool holds :data:`CONTACT_POOL` times every world's budget, so one
  world past its budget cannot drop another's contacts; were the pool itself to
  overflow, MuJoCo Warp flags every world (it cannot tell whose contacts it dropped),
  and every world that stepped is truncated.
* On a GPU a control step (its substeps, the contact counts and the closing position
  stage) is captured once as a CUDA graph and replayed: one launch a step instead of a
  few hundred kernel launches from Python. Torch's stream waits for Warp's after a step
  (an event, no host synchronisation), and Warp's for torch's after a reset's copies.
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
"""Contacts a world may hold (the scenes hold at most ~20 at rest: jaws, objects, table);
read when a backend is built."""
CONSTRAINTS_PER_WORLD = 256
"""Constraint rows a world may hold (pyramidal friction cones: 4 rows a contact); read
when a backend is built."""
CONTACT_POOL = 2
"""The shared contact pool holds this many times the worlds' budgets together."""
_STATE_FIELDS = ("qpos", "qvel", "act", "qacc_warmstart", "mocap_pos", "mocap_quat", "time")
"""The ``MjData`` fields that make a world's state (``mj_step`` reads them)."""
_UNLOADED = ("qpos", "qvel", "qacc", "sensordata", "time")
"""The fields :meth:`WarpBackend.unload` copies out of a world."""
WORLD_MODEL_FIELDS: tuple[str, ...] = ("body_pos", "body_quat")
"""The model fields that differ per world (what the tasks' resets place)."""
DEVICES_HELP = '"cpu", "cuda" or "cuda:N"'
_POOL_BITS = ("BROADPHASE", "NARROWPHASE", "CCD")
"""MuJoCo Warp's overflow flags of the shared contact pool (set in every world)."""
_SOLVER_BITS = ("ITERATIONS", "LS_ITERATIONS")
"""Flags that drop nothing (the solver's iteration limits, which C MuJoCo reaches
silently too): not an overflow."""


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

    Attributes:
        torch_device: the torch device of the arrays (``"cpu"``, ``"cuda:0"`` ...).
    """

    def __init__(self, models: Sequence[mujoco.MjModel], device: str, index: SimIndex) -> None:
        wp = _import_warp()
        import mujoco_warp as mjw

        from gym_soarm.sim import warp_kernels

        self._wp, self._mjw, self._kernels = wp, mjw, warp_kernels
        self.num_envs = n = len(models)
        self.index = index
        self.device = device
        self.torch_device = wp.device_to_torch(device)
        self._cuda = wp.get_device(device).is_cuda
        self._models = list(models)
        model = self._models[0]
        self._actuators, _ = arm_indices(model)
        self.contacts_per_world = CONTACTS_PER_WORLD
        self.constraints_per_world = CONSTRAINTS_PER_WORLD
        with wp.ScopedDevice(device):
            self._model = mjw.put_model(model, batch_sizes=dict.fromkeys(WORLD_MODEL_FIELDS, n))
            self._data = mjw.make_data(
                model,
                nworld=n,
                naconmax=CONTACT_POOL * self.contacts_per_world * n,
                njmax=self.constraints_per_world,
            )
        names = {*ARRAY_FIELDS, *_STATE_FIELDS, "nefc", "overflow"}
        # Views of MuJoCo Warp's arrays, never rebound: a step writes into them in place.
        self._views = {name: wp.to_torch(getattr(self._data, name)) for name in names}
        self._ctrl = np.zeros((n, model.nu))
        self._graphs: dict[int, Any] = {}  # nstep -> the CUDA graph of a control step
        self._counts: dict[int, tuple[Any, list[Any]]] = {}  # nstep -> contact counts
        self._overflowed: Any = None  # the last step's worlds past a budget (device)
        self._most: Any = None  # the last step's most contacts of each world (device)
        self._host: dict[str, np.ndarray] = {}  # host copies of _UNLOADED, until a step
        self._staged: dict[int, dict[str, np.ndarray]] = {}  # loaded worlds' states
        self._model_views: dict[str, Any] = {}  # WORLD_MODEL_FIELDS, once set_models ran
        flags = mjw.OverflowType
        self._pool_bits = sum(int(getattr(flags, b, 0)) for b in _POOL_BITS)
        self._dropping = int(flags.ALL) & ~sum(int(getattr(flags, b, 0)) for b in _SOLVER_BITS)
        self.set_models()

    # --- the model ---------------------------------------------------------------------
    def set_models(self) -> None:
        """Take in what resets wrote into the models of the worlds loaded since (fixture
        poses; every world's the first time) and the states :meth:`load` staged: the
        rows of those worlds only."""
        import torch

        worlds = sorted(self._staged) if self._model_views else list(range(self.num_envs))
        if not self._model_views:
            model = self._model
            self._model_views = {
                n: self._wp.to_torch(getattr(model, n)) for n in WORLD_MODEL_FIELDS
            }
        if worlds:
            rows = torch.as_tensor(worlds, device=self.torch_device)
            for name, view in self._model_views.items():
                values = np.stack([getattr(self._models[w], name) for w in worlds])
                view[rows] = torch.as_tensor(values, dtype=view.dtype).to(self.torch_device)
            self._warp_waits()
        self._push()

    # --- stepping ----------------------------------------------------------------------
    def set_targets(self, ids: np.ndarray | None, targets: np.ndarray) -> None:
        write_targets(self._ctrl, self._actuators, ids, targets)

    def step(self, ids: np.ndarray | None, nstep: int) -> dict[int, str]:
        """Step every world ``nstep`` times (the worlds outside ``ids`` are those that
        reset right after, so they step too: one launch for all). The worlds that ran
        past a budget are reported by :meth:`overflowed`, on the device; nothing here
        waits for the device."""
        wp = self._wp
        self._push()
        counts, rows = self._contact_counts(nstep)
        with wp.ScopedDevice(self.device):
            self._data.ctrl.assign(self._ctrl.astype(np.float32))
            if not self._cuda:
                self._control_step(nstep, rows)
            else:
                if nstep not in self._graphs:
                    with wp.ScopedCapture() as capture:
                        self._control_step(nstep, rows)
                    self._graphs[nstep] = capture.graph
                wp.capture_launch(self._graphs[nstep])
        self._torch_waits()
        views = self._views
        self._most = counts.amax(0)
        self._overflowed = (
            ((views["overflow"] & self._dropping) != 0)
            | (self._most > self.contacts_per_world)
            | (views["nefc"] > self.constraints_per_world)
        )
        return {}

    def _contact_counts(self, nstep: int) -> tuple[Any, list[Any]]:
        """The per-world contact counts of a control step of ``nstep`` physics steps, a
        row after each physics step and the closing stage: their torch view
        ``(nstep + 1, n)`` and the Warp rows the kernel fills."""
        if nstep not in self._counts:
            counts = self._wp.zeros((nstep + 1, self.num_envs), dtype=int, device=self.device)
            rows = [counts[k] for k in range(nstep + 1)]
            self._counts[nstep] = (self._wp.to_torch(counts), rows)
        return self._counts[nstep]

    def _control_step(self, nstep: int, counts: list[Any]) -> None:
        wp, mjw, data = self._wp, self._mjw, self._data
        data.overflow.zero_()  # MuJoCo Warp's flags only ever add up: this step's
        for row in counts:
            row.zero_()
        contacts = self._kernels.count_contacts
        args = (data.nacon, data.naconmax, data.contact.worldid)
        for k in range(nstep):
            mjw.step(self._model, data)
            wp.launch(contacts, dim=data.naconmax, inputs=args, outputs=[counts[k]])
        # Positions, velocities and their sensors of the new state (C MuJoCo's legacy
        # step ends on mj_step1 too): the sites and contacts the tasks read.
        mjw.step1(self._model, data)
        wp.launch(contacts, dim=data.naconmax, inputs=args, outputs=[counts[nstep]])

    def _torch_waits(self) -> None:
        """Order torch's work after what Warp queued (a GPU's streams; an event)."""
        self._host = {}
        if self._cuda:
            import torch

            stream = torch.cuda.current_stream(self.torch_device)
            stream.wait_stream(self._wp.stream_to_torch(self.device))

    def _warp_waits(self) -> None:
        """Order Warp's work after what torch queued (a GPU's streams; an event)."""
        if self._cuda:
            wp = self._wp
            wp.get_stream(self.device).wait_stream(wp.stream_from_torch(self.torch_device))

    def overflowed(self) -> Any:
        """``(n,)`` bool on the device: the worlds whose last control step ran past a
        budget (None before the first step)."""
        return self._overflowed

    def contact_counts(self) -> Any:
        """``(n,)`` int32 on the device: the most contacts each world held after any
        physics step of the last control step (None before the first step)."""
        return self._most

    def overflow_reason(self, i: int) -> str:
        """Why world ``i`` ran past a budget on the last step (reads its flags: a
        transfer from the device, for a world already found to overflow)."""
        flags = int(self._views["overflow"][i])
        most = int(self._most[i])
        rows = int(self._views["nefc"][i])
        why = []
        if most > self.contacts_per_world:
            why.append(f"world {i} held {most} contacts, more than its {self.contacts_per_world}")
        if flags & self._pool_bits:
            why.append(
                f"the worlds' contacts ran past the shared pool of {self._data.naconmax} "
                "(MuJoCo Warp cannot tell whose were dropped)"
            )
        if rows > self.constraints_per_world or flags & int(self._mjw.OverflowType.NEFC):
            why.append(
                f"world {i} held {rows} constraint rows, more than its "
                f"{self.constraints_per_world}: rows beyond them were dropped"
            )
        other = flags & self._dropping & ~self._pool_bits & ~int(self._mjw.OverflowType.NEFC)
        if other:
            why.append(f"MuJoCo Warp flagged {self._mjw.OverflowType(other)!r}")
        return "; ".join(why) or f"world {i} overflowed"

    def arrays(self, episode: dict[str, Any]) -> SimArrays:
        return SimArrays(self.index, self._views, episode)

    # --- one world in and out ----------------------------------------------------------
    def load(self, i: int, physics: SoArmPhysics) -> None:
        """Stage ``physics`` (an environment's own simulation) as world ``i``'s state; the
        staged worlds go to the device together, at :meth:`set_models` or the next step
        (their rows only, one copy of each field for a whole reset)."""
        data = physics.data.ptr
        self._staged[i] = {name: np.array(getattr(data, name)) for name in _STATE_FIELDS}
        self._ctrl[i] = data.ctrl

    def _push(self) -> None:
        """The staged worlds' rows into the device's state, and the positions stage."""
        if not self._staged:
            return
        import torch

        worlds = sorted(self._staged)
        rows = torch.as_tensor(worlds, device=self.torch_device)
        for name in _STATE_FIELDS:
            view = self._views[name]
            if view.numel():
                values = np.stack([self._staged[w][name] for w in worlds])
                view[rows] = torch.as_tensor(values, dtype=view.dtype).to(self.torch_device)
        self._staged = {}
        self._warp_waits()
        with self._wp.ScopedDevice(self.device):
            self._mjw.forward(self._model, self._data)
        self._torch_waits()

    def unload(self, i: int, physics: SoArmPhysics) -> None:
        """Copy world ``i`` into ``physics``: its state, then C MuJoCo's positions and
        velocities stage on it (the last substep's accelerations and sensors are Warp's).
        The first unload after a step copies the unloaded fields of every world to the
        host, once."""
        if not self._host:
            self._host = {name: self._views[name].cpu().numpy() for name in _UNLOADED}
        host = self._host
        model, data = physics.model.ptr, physics.data.ptr
        data.qpos[:] = host["qpos"][i]
        data.qvel[:] = host["qvel"][i]
        data.ctrl[:] = self._ctrl[i]
        data.time = float(host["time"][i])
        mujoco.mj_step1(model, data)
        data.qacc[:] = host["qacc"][i]
        data.sensordata[:] = host["sensordata"][i]

    def close(self) -> None:
        """Release the worlds (every reference to the Warp arrays goes)."""
        self._model = self._data = None
        self._graphs, self._counts, self._views, self._host = {}, {}, {}, {}
        self._model_views = {}
        self._overflowed = self._most = None


__all__ = [
    "CONSTRAINTS_PER_WORLD",
    "CONTACTS_PER_WORLD",
    "CONTACT_POOL",
    "WORLD_MODEL_FIELDS",
    "WarpBackend",
    "check_device",
    "warp_available",
]
