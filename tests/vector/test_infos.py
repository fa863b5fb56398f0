"""Infos through shared memory batch exactly as Gymnasium's SyncVectorEnv batches them."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm  # noqa: F401  (registers the environments)
from gym_soarm.envs.infos import INFO_NUMBERS, InfoReader, InfoWriter, batch, flatten, unflatten


def reference(infos: list[dict[str, Any]]) -> dict[str, Any]:
    """What SyncVectorEnv gives: Gymnasium's own _add_info, one environment at a time."""
    sync = gym.make_vec("gym_soarm/ReachTarget-v0", num_envs=len(infos), vectorization_mode="sync")
    try:
        merged: dict[str, Any] = {}
        for i, info in enumerate(infos):
            merged = sync._add_info(merged, info, i)
        return merged, sync._add_info
    finally:
        sync.close()


def assert_same(a: Any, b: Any, where: str = "") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), (where, list(a), list(b))
        for key in a:
            assert_same(a[key], b[key], f"{where}/{key}")
        return
    assert type(a) is type(b), (where, type(a), type(b))
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, (where, a.dtype, b.dtype)
        if a.dtype == object:
            for x, y in zip(a, b, strict=True):
                assert_same(x, y, where)
        else:
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), where
    else:
        assert a == b or (a != a and b != b), (where, a, b)


def info(k: int, text: Any = "pick", wide: bool = False) -> dict[str, Any]:
    out = {
        "is_success": k == 1,
        "count": 7 + k,
        "distance": 0.1 * k + 1e-17,
        "single": np.float32(1.0 / 3.0 + k),
        "position": np.array([k, -0.0, np.nan], np.float32),
        "ids": np.arange(3, dtype=np.int32) + k,
        "terms": {"reach": 0.25 * k, "grasp": np.float64(k)},
        "task": text,
    }
    if wide:  # beyond a float64's exact integers: they travel as objects
        out.update(huge=2**60 + k, wide_int=np.int64(2**40 + k), wide_ids=np.arange(2) + 2**60)
        out["flag"] = np.bool_(k % 2)  # numpy bools are no numpy numbers: objects too
    return out


def read(infos: list[dict[str, Any]], blocks: list[range], add_info) -> dict[str, Any]:
    table = np.full((len(infos), INFO_NUMBERS), np.nan)
    writers = [InfoWriter(table, rows) for rows in blocks]
    messages = [w.write([infos[i] for i in rows]) for w, rows in zip(writers, blocks, strict=True)]
    return InfoReader(table, blocks).read(messages, add_info), messages


def test_numbers_travel_through_the_table_and_batch_as_sync_does():
    infos = [info(k) for k in range(3)]
    want, add_info = reference(infos)
    got, messages = read(infos, [range(0, 2), range(2, 3)], add_info)
    assert [m[0] for m in messages] == ["table", "table"]
    assert_same(got, want)
    assert got["single"].dtype == np.float32 and got["position"].dtype == np.float32
    # One numpy call per key over the table's columns gave it.
    layout, objects = messages[0][2], [row for m in messages for row in m[3]]
    table = np.full((3, INFO_NUMBERS), np.nan)
    for k in range(3):
        numbers: list[Any] = []
        flatten(infos[k], numbers, [])
        table[k, : len(numbers)] = numbers
    assert_same(batch(layout, table, objects, np.ones(3, bool)), want)


def test_other_objects_and_other_layouts_fall_back_to_gymnasiums_batching():
    for odd in (
        [info(0), info(1, text=["not", "a", "string"]), info(2)],
        [info(k, wide=True) for k in range(3)],
    ):
        want, add_info = reference(odd)
        got, _ = read(odd, [range(0, 2), range(2, 3)], add_info)
        assert_same(got, want)

    mixed = [info(0), {**info(1), "variation": {"kp": 1.5}}, info(2)]
    want, add_info = reference(mixed)
    got, messages = read(mixed, [range(0, 2), range(2, 3)], add_info)
    assert messages[0][0] == "dicts" and messages[1][0] == "table"
    assert_same(got, want)


def test_a_row_gives_back_the_very_same_info():
    original = info(2, wide=True)
    numbers: list[Any] = []
    objects: list[Any] = []
    layout = flatten(original, numbers, objects)
    row = np.array(numbers, np.float64)
    assert_same(unflatten(layout, row, objects), original)


@pytest.mark.parametrize("size", [INFO_NUMBERS + 1, 4 * INFO_NUMBERS])
def test_an_info_too_large_for_the_table_is_sent_whole(size):
    infos = [{"big": np.full(size, float(k))} for k in range(2)]
    want, add_info = reference(infos)
    got, messages = read(infos, [range(0, 2)], add_info)
    assert messages[0][0] == "dicts"
    assert_same(got, want)
