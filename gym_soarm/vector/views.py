"""What arrays the batched vector env hands out: its ``array_api`` keyword.

``gym.make_vec(..., vectorization_mode="vector_entry_point", vector_env="warp",
array_api="torch")`` (or ``vector_env="batched"``) returns observations, rewards,
terminations, truncations and the numeric infos as torch tensors; the default,
``array_api="numpy"``, returns NumPy arrays (what Stable-Baselines3, LeRobot and
Gymnasium's own wrappers read).

* :class:`NumpyView` (``"numpy"``): NumPy arrays on the host, as ``SyncVectorEnv``
  batches them (rewards and float infos float64). On MuJoCo Warp each value is copied
  from the device: on a GPU every copy waits for it.
* :class:`TorchView` (``"torch"``): torch tensors on the env's device (the Warp device;
  the CPU for the ``mujoco.batch`` env), floats float32, booleans bool, counts int64.
  The values computed on the device stay there; the ones the host keeps (terminations,
  truncations, the ``_key`` masks, a reset's infos) are copied to it. Infos that are not
  numbers (``task``, a colour) stay NumPy object arrays. With ``SameStep``,
  ``info["final_obs"]`` and each entry of ``info["final_info"]`` are batched tensors
  whose rows of the environments that did not end are zeros (``_final_obs`` and the
  ``_key`` masks mark the ones that did), not object arrays of per-environment values.

Every value handed out is a fresh array: none shares memory with the simulations.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gym_soarm.sim.arrays import to_numpy
from gym_soarm.validation import check_choice

ARRAY_APIS: tuple[str, ...] = ("numpy", "torch")
"""Values of ``array_api``: the library of the arrays a batched vector env returns."""

FLOAT = "float"
"""A kind of value: real numbers (rewards, reward terms), float64 or float32 by view."""


def is_tensor(value: Any) -> bool:
    """Whether ``value`` is a torch tensor (without importing torch)."""
    return type(value).__module__.startswith("torch") and hasattr(value, "detach")


def put(array: Any, index: Any, value: Any) -> None:
    """``array[index] = value`` for a NumPy array or a torch tensor, ``value`` any host
    value (a NumPy array or scalar, a Python number) or a tensor."""
    if is_tensor(array) and not is_tensor(value):
        import torch

        value = torch.as_tensor(np.asarray(value), dtype=array.dtype).to(array.device)
    array[index] = value


class NumpyView:
    """NumPy arrays on the host (``array_api="numpy"``)."""

    name = "numpy"

    def values(self, values: Any, kind: Any = None) -> np.ndarray:
        """A fresh NumPy copy of ``values`` (any array or list); ``kind``: a NumPy dtype,
        :data:`FLOAT` (float64) or None (floats float64, the rest as they are)."""
        array = to_numpy(values) if not isinstance(values, list) else np.asarray(values)
        if kind == FLOAT or (kind is None and array.dtype.kind == "f"):
            kind = np.float64
        return np.array(array, dtype=kind if kind is not None else array.dtype)

    def zeros(self, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        return np.zeros(shape, dtype)

    def copy(self, array: Any) -> Any:
        return array.copy()

    def rows(self, array: Any, rows: Any, ids: np.ndarray) -> None:
        """``array[ids] = rows[ids]`` (rows of the same view)."""
        array[ids] = rows[ids]

    def infos(self, infos: dict[str, Any]) -> dict[str, Any]:
        """``infos`` with every numeric array of this view (object arrays kept)."""
        out: dict[str, Any] = {}
        for key, value in infos.items():
            if isinstance(value, dict):
                out[key] = self.infos(value)
            elif hasattr(value, "shape") and not self._is_own(value):
                out[key] = self.values(value)
            else:
                out[key] = value
        return out

    def _is_own(self, value: Any) -> bool:
        """Whether ``infos`` keeps ``value`` as it is: an object array, or already this
        view's array (made by values or _add_info)."""
        return isinstance(value, np.ndarray)

    def matching(self, batched: dict[str, Any], info: dict[str, Any]) -> dict[str, Any]:
        """``info`` (one environment's) with its values as ``batched``'s arrays hold them."""
        return info


class TorchView(NumpyView):
    """Torch tensors on ``device`` (``array_api="torch"``)."""

    name = "torch"

    def __init__(self, device: str) -> None:
        import torch

        self._torch = torch
        self.device = torch.device(device)

    def _dtype(self, array: Any, kind: Any) -> Any:
        torch = self._torch
        if kind == FLOAT or (kind is None and array.dtype.is_floating_point):
            return torch.float32
        if kind is None:
            return torch.int64 if array.dtype in (torch.int32, torch.int16) else array.dtype
        return torch.from_numpy(np.zeros(0, dtype=kind)).dtype

    def values(self, values: Any, kind: Any = None) -> Any:
        """A fresh tensor on the device; ``kind`` as :meth:`NumpyView.values` says,
        floats float32."""
        if not is_tensor(values):  # a host value: copied once, into a tensor of its own
            values = self._torch.from_numpy(np.array(values))
            return values.to(device=self.device, dtype=self._dtype(values, kind))
        return values.to(device=self.device, dtype=self._dtype(values, kind), copy=True)

    def zeros(self, shape: tuple[int, ...], dtype: Any) -> Any:
        return self.values(np.zeros(shape, dtype), dtype)

    def copy(self, array: Any) -> Any:
        return array.clone()

    def rows(self, array: Any, rows: Any, ids: np.ndarray) -> None:
        if len(ids) == len(array):
            array.copy_(rows)
        else:
            index = self._torch.as_tensor(ids, device=self.device)
            array[index] = rows[index]

    def _is_own(self, value: Any) -> bool:
        if isinstance(value, np.ndarray):
            return value.dtype == object
        return is_tensor(value) and value.device == self.device  # by values, or a final_info's

    def matching(self, batched: dict[str, Any], info: dict[str, Any]) -> dict[str, Any]:
        out = {}
        for key, value in info.items():
            target = batched.get(key)
            if isinstance(value, dict) and isinstance(target, dict):
                value = self.matching(target, value)
            elif is_tensor(target) and not isinstance(value, dict):
                value = self._torch.as_tensor(np.asarray(value), dtype=target.dtype)
                value = value.to(self.device)
            out[key] = value
        return out

    def finals(self, infos: dict[str, Any], ended: Any, host: np.ndarray) -> dict[str, Any]:
        """The ended environments' rows of ``infos`` (the step's, before their resets),
        the other rows zeros, with ``ended`` (a device bool mask; ``host``, its host
        copy) as every mask."""
        out: dict[str, Any] = {}
        for key, value in infos.items():
            if key.startswith("_"):
                continue
            if isinstance(value, dict):
                out[key] = self.finals(value, ended, host)
            elif isinstance(value, np.ndarray):  # objects: None where none ended
                out[key] = np.where(host, value, None)
            else:
                out[key] = self.ended_rows(value, ended)
            out[f"_{key}"] = ended
        return out

    def ended_rows(self, array: Any, ended: Any) -> Any:
        """A copy of ``array`` whose rows outside ``ended`` are zeros."""
        mask = ended.reshape(ended.shape + (1,) * (array.ndim - 1))
        return self._torch.where(mask, array, self._torch.zeros_like(array))


def zeros_where(shape: tuple[int, ...], physics: str, device: str) -> Any:
    """Zeros where the simulations' arrays live: NumPy float64 for ``mujoco.batch``,
    torch float32 on the device for MuJoCo Warp (the tasks' per-episode values)."""
    if physics == "warp":
        import torch

        return torch.zeros(shape, dtype=torch.float32, device=device)
    return np.zeros(shape)


def row_of(value: Any, i: int) -> Any:
    """Environment ``i``'s value of one batched info entry, as a single env gives it."""
    if isinstance(value, dict):
        return {k: row_of(v, i) for k, v in value.items() if not k.startswith("_")}
    entry = value[i]
    if value.dtype == np.bool_:
        return bool(entry)
    if value.dtype == object:
        return entry
    if value.ndim == 1:
        return int(entry) if value.dtype.kind in "iu" else float(entry)
    return entry.copy()


def column(values: Any, n: int, view: NumpyView) -> Any:
    """One info entry for the batch as ``SyncVectorEnv`` batches it: an array of the
    view (a list of values that are not numbers: a NumPy object array)."""
    if isinstance(values, list):
        kinds = set(map(type, values))
        if len(kinds) == 1 and kinds <= {bool, int, float}:
            return view.values(np.array(values, dtype=kinds.pop()))
        out = np.empty(n, dtype=object)
        out[:] = values
        return out
    return view.values(values)


View = NumpyView
"""The type of a view (:class:`NumpyView` or :class:`TorchView`)."""


def make_view(array_api: Any, device: str | None) -> NumpyView:
    """The view ``array_api`` names, on ``device`` (torch's name of the env's device).

    Raises:
        ValueError: not one of :data:`ARRAY_APIS`.
    """
    check_choice("array_api", array_api, ARRAY_APIS)
    if array_api == "torch":
        return TorchView(device or "cpu")
    return NumpyView()


__all__ = [
    "ARRAY_APIS",
    "FLOAT",
    "NumpyView",
    "TorchView",
    "column",
    "is_tensor",
    "make_view",
    "put",
    "row_of",
    "zeros_where",
]
