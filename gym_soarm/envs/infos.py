"""Infos of a vector env: carried as numbers in shared memory, batched as Gymnasium does.

A step's info dicts are small but many; pickling them in every worker and merging
them key by key in the caller cost more than the pipes. So a worker writes the numbers
of each info (bools, ints, floats, numpy scalars and arrays, nested dicts) into its
environment's row of a shared ``float64`` table, in the order of the info's
*layout* (its keys, value types and shapes), and sends only the layout's number and
the values that are not numbers (the instruction text, ...). The caller then builds
each batched value with one numpy call over the column of the table.

Everything here gives exactly what ``gymnasium.vector.SyncVectorEnv`` gives: the same
keys, dtypes, ``_key`` masks and values (a float64 holds every value it carries
exactly: integers only up to 2**53 and numpy integers of 32 bits or fewer travel as
numbers, the others as objects).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

Layout = tuple[tuple[Any, ...], ...]
"""An info's layout: per key ``(key, kind)``, ``(key, kind, dtype, shape)`` for an array,
``(key, dict, sub_layout)`` for a nested dict; kind ``object`` travels pickled."""

INFO_NUMBERS = 128
"""Numbers one environment's info may hold in the shared table (more: sent pickled)."""

_EXACT_INT = 2**53


def _number_dtype(dtype: np.dtype) -> bool:
    """Whether every value of ``dtype`` survives a round trip through float64."""
    return dtype.kind in "bf" or (dtype.kind in "iu" and dtype.itemsize <= 4)


def flatten(info: dict[str, Any], numbers: list[Any], objects: list[Any]) -> Layout:
    """Append ``info``'s numbers to ``numbers`` and other values to ``objects``, in key
    order; return its layout."""
    layout = []
    for key, value in info.items():
        kind = type(value)
        if kind is bool or kind is float or (kind is int and abs(value) <= _EXACT_INT):
            numbers.append(value)
            layout.append((key, kind))
        elif kind is np.ndarray and _number_dtype(value.dtype):
            numbers.extend(value.ravel().tolist())
            layout.append((key, kind, value.dtype.str, value.shape))
        elif kind is dict:
            layout.append((key, kind, flatten(value, numbers, objects)))
        elif issubclass(kind, np.number) and _number_dtype(np.dtype(kind)):
            # (numpy bools are not numpy numbers: Gymnasium batches them as objects)
            numbers.append(value.item())
            layout.append((key, kind))
        else:
            objects.append(value)
            layout.append((key, object))
    return tuple(layout)


def unflatten(layout: Layout, numbers: np.ndarray, objects: Sequence[Any]) -> dict[str, Any]:
    """The info dict that :func:`flatten` wrote as ``numbers`` (one row) and ``objects``."""
    position = [0, 0]  # next number, next object

    def build(entries: Layout) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for entry in entries:
            key, kind = entry[0], entry[1]
            if kind is dict:
                out[key] = build(entry[2])
            elif kind is object:
                out[key] = objects[position[1]]
                position[1] += 1
            elif kind is np.ndarray:
                size = int(np.prod(entry[3], dtype=np.int64))
                start = position[0]
                out[key] = numbers[start : start + size].astype(entry[2]).reshape(entry[3])
                position[0] += size
            else:
                value = numbers[position[0]].item()
                out[key] = kind(value)
                position[0] += 1
        return out

    return build(layout)


def batch(
    layout: Layout, table: np.ndarray, objects: Sequence[Sequence[Any]], ones: np.ndarray
) -> dict[str, Any] | None:
    """The batched info of N environments whose infos all have ``layout``.

    Args:
        layout: the shared layout.
        table: the ``(N, INFO_NUMBERS)`` numbers, a row per environment.
        objects: the non-number values of each environment, in layout order.
        ones: an all-True bool array of shape ``(N,)`` (copied for each ``_key`` mask).

    Returns:
        What ``SyncVectorEnv`` batches, or None where an object value is not a string
        in every environment (the caller then batches the rebuilt dicts one by one).
    """
    n = len(ones)
    position = [0, 0]

    def build(entries: Layout) -> dict[str, Any] | None:
        out: dict[str, Any] = {}
        for entry in entries:
            key, kind = entry[0], entry[1]
            if kind is dict:
                value: Any = build(entry[2])
                if value is None:
                    return None
            elif kind is object:
                column = [row[position[1]] for row in objects]
                position[1] += 1
                if any(type(item) is not str for item in column):
                    return None
                value = np.empty(n, dtype=object)
                value[:] = column
            elif kind is np.ndarray:
                shape = entry[3]
                size = int(np.prod(shape, dtype=np.int64))
                start = position[0]
                value = table[:, start : start + size].astype(entry[2]).reshape(n, *shape)
                position[0] += size
            else:
                value = table[:, position[0]].astype(kind)
                position[0] += 1
            out[key] = value
            out[f"_{key}"] = ones.copy()
        return out

    return build(layout)


def merge(
    infos: Sequence[dict[str, Any] | None],
    ones: np.ndarray,
    add_info: Callable[[dict[str, Any], dict[str, Any], int], dict[str, Any]],
) -> dict[str, Any]:
    """Batch per-environment infos (None: no info) exactly as ``SyncVectorEnv`` does.

    ``add_info`` is the vector env's ``_add_info`` (Gymnasium's own, one environment
    at a time); where every environment has the same keys and value types one numpy
    call per key gives the same.
    """
    present = [i for i, info in enumerate(infos) if info is not None]
    if len(present) == len(infos):
        fast = _merge_same_keys(infos, ones)  # type: ignore[arg-type]
        if fast is not None:
            return fast
    merged: dict[str, Any] = {}
    for i in present:
        merged = add_info(merged, infos[i], i)  # type: ignore[arg-type]
    return merged


def _merge_same_keys(infos: Sequence[dict[str, Any]], ones: np.ndarray) -> dict[str, Any] | None:
    first_info = infos[0]
    keys = list(first_info)
    if "final_obs" in first_info:
        return None  # kept unbatched, as _add_info keeps it
    for info in infos:
        if list(info) != keys:
            return None
    merged: dict[str, Any] = {}
    n = len(infos)
    for key in keys:
        values = [info[key] for info in infos]
        first = values[0]
        kind = type(first)
        for value in values:
            if type(value) is not kind:
                return None
        if kind is dict:
            array: Any = _merge_same_keys(values, ones)
            if array is None:
                return None
        elif kind in (bool, int, float) or issubclass(kind, np.number):
            array = np.array(values, dtype=kind)
        elif kind is np.ndarray:
            try:
                array = np.array(values, dtype=first.dtype)
            except ValueError:
                return None  # shapes differ
            if array.shape != (n, *first.shape):
                return None
        elif kind is str:
            array = np.empty(n, dtype=object)
            array[:] = values
        else:
            return None
        merged[key] = array
        merged[f"_{key}"] = ones.copy()
    return merged


class InfoWriter:
    """One block's side: writes its environments' infos into their rows of the table.

    :meth:`write` returns what the block sends with its step: ``("table", layout
    number, new layout or None, objects per environment)`` when every info fits the
    table under one layout, else ``("dicts", infos)``.
    """

    def __init__(self, table: np.ndarray, rows: range) -> None:
        self.table = table
        self.rows = rows
        self.numbers: dict[Layout, int] = {}

    def write(self, infos: Sequence[dict[str, Any]]) -> tuple[Any, ...]:
        layouts: list[Layout] = []
        objects: list[list[Any]] = []
        for row, info in zip(self.rows, infos, strict=True):
            numbers: list[Any] = []
            found: list[Any] = []
            layouts.append(flatten(info, numbers, found))
            if len(numbers) > INFO_NUMBERS or layouts[-1] != layouts[0]:
                return ("dicts", list(infos))
            self.table[row, : len(numbers)] = numbers
            objects.append(found)
        shared = layouts[0]
        number = self.numbers.get(shared)
        new = None
        if number is None:
            number = self.numbers[shared] = len(self.numbers)
            new = shared
        return ("table", number, new, objects)


class InfoReader:
    """The caller's side: turns every block's message into the batched info."""

    def __init__(self, table: np.ndarray, blocks: Sequence[range]) -> None:
        self.table = table
        self.blocks = list(blocks)
        self.layouts: list[dict[int, Layout]] = [{} for _ in self.blocks]
        self.ones = np.ones(table.shape[0], dtype=np.bool_)

    def read(
        self,
        messages: Sequence[tuple[Any, ...]],
        add_info: Callable[[dict[str, Any], dict[str, Any], int], dict[str, Any]],
    ) -> dict[str, Any]:
        """The batched info of one step, given each block's :meth:`InfoWriter.write`."""
        layouts = self.note(messages)
        first = layouts[0]
        if first is not None and all(layout is first or layout == first for layout in layouts[1:]):
            objects = [row for message in messages for row in message[3]]
            batched = batch(first, self.table, objects, self.ones)
            if batched is not None:
                return batched
        return merge(self.dicts(messages, layouts), self.ones, add_info)

    def note(self, messages: Sequence[tuple[Any, ...] | None]) -> list[Layout | None]:
        """Learn the new layouts the messages bring (None: a block that sent nothing, as
        when it raised); each message's layout, None for whole dicts."""
        layouts: list[Layout | None] = []
        for block, message in enumerate(messages):
            if message is None or message[0] != "table":
                layouts.append(None)
                continue
            _, number, new, _ = message
            if new is not None:
                self.layouts[block][number] = new
            layouts.append(self.layouts[block][number])
        return layouts

    def dicts(
        self, messages: Sequence[tuple[Any, ...]], layouts: Sequence[Layout | None]
    ) -> list[dict[str, Any]]:
        """Every environment's own info dict, rebuilt from the messages."""
        infos: list[dict[str, Any]] = []
        for rows, message, layout in zip(self.blocks, messages, layouts, strict=True):
            if layout is None:
                infos.extend(message[1])
                continue
            for row, objects in zip(rows, message[3], strict=True):
                infos.append(unflatten(layout, self.table[row], objects))
        return infos
