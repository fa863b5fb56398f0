"""The physics backends: one protocol (:class:`gym_soarm.sim.backends.Backend`) that
declares every method its callers use, implemented by every backend (real MuJoCo)."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.sim.backends import Backend, BatchBackend, MjDataBackend
from gym_soarm.sim.warp_backend import WarpBackend

BACKENDS = [MjDataBackend, BatchBackend, WarpBackend]
PACKAGE = Path(gym_soarm.__file__).parent
ENV = "gym_soarm/ReachTarget-v0"


def _protocol_methods() -> dict[str, inspect.Signature]:
    return {
        name: inspect.signature(value)
        for name, value in vars(Backend).items()
        if inspect.isfunction(value) and not name.startswith("_")
    }


def test_the_protocol_declares_every_method_its_callers_use():
    """Every ``<object>.backend.<name>`` and ``self._backend.<name>`` the package reads
    (outside the backends themselves) is a member of the protocol."""
    used: set[str] = set()
    for path in PACKAGE.rglob("*.py"):
        if path.name in {"backends.py", "warp_backend.py"}:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Attribute)
                and node.value.attr in {"backend", "_backend"}
            ):
                used.add(node.attr)
    declared = set(_protocol_methods()) | set(Backend.__annotations__)
    assert used, "no backend call found: the scan is broken"
    assert used <= declared, f"used but not in the Backend protocol: {sorted(used - declared)}"
    assert {"load", "unload", "set_models", "close"} <= declared


@pytest.mark.parametrize("backend", BACKENDS, ids=lambda cls: cls.__name__)
def test_every_backend_implements_the_protocol(backend):
    for name, expected in _protocol_methods().items():
        method = getattr(backend, name, None)
        assert inspect.isfunction(method), f"{backend.__name__} lacks {name}()"
        assert method is not getattr(Backend, name), f"{backend.__name__}.{name} is the stub"
        got = list(inspect.signature(method).parameters)
        assert got == list(expected.parameters), (
            f"{backend.__name__}.{name}{inspect.signature(method)}; expected {name}{expected}"
        )


def _physics(seed: int):
    env = gym.make(ENV, obs_type="environment_state_agent_pos")
    env.reset(seed=seed)
    return env, env.unwrapped.physics


def test_every_built_backend_is_a_backend():
    env, physics = _physics(0)
    try:
        single = MjDataBackend(physics)
        batch = BatchBackend([physics.model.ptr] * 2, 1, physics.sim_index)
        for backend in (single, batch):
            assert isinstance(backend.num_envs, int) and backend.index is physics.sim_index
            for name in _protocol_methods():
                assert callable(getattr(backend, name))
        assert (single.num_envs, batch.num_envs) == (1, 2)
        batch.close()
        batch.close()  # twice is safe
    finally:
        env.close()


def test_an_mjdata_backend_loads_and_unloads_another_simulation():
    first, a = _physics(0)
    second, b = _physics(1)
    try:
        a.step(5)
        backend = MjDataBackend(b)
        backend.load(0, a)
        np.testing.assert_array_equal(b.data.qpos, a.data.qpos)
        np.testing.assert_array_equal(b.data.site_xpos, a.data.site_xpos)
        backend.set_targets(None, a.joint_targets() + 0.05)
        assert backend.step(None, 10) == {}
        backend.unload(0, a)
        np.testing.assert_array_equal(a.data.qpos, b.data.qpos)
        assert a.data.time == b.data.time
        qpos = b.data.qpos.copy()
        backend.load(0, b)  # its own simulation: nothing moves
        backend.set_models()
        np.testing.assert_array_equal(b.data.qpos, qpos)
        with pytest.raises(ValueError, match="simulation 1 does not exist; expected 0"):
            backend.load(1, a)
        with pytest.raises(ValueError, match="expected 0"):
            backend.unload(2, a)
        backend.close()
        backend.close()
    finally:
        first.close()
        second.close()
