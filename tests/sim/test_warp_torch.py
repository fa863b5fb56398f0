"""``array_api="torch"``, the Warp backend's torch views, masked resets and per-world
overflow, on real MuJoCo Warp on Warp's CPU device (``GYM_SOARM_WARP_DEVICE=cuda`` runs
them on a GPU).

The torch view must give the NumPy view's values (the same seeds and actions) as torch
tensors on the env's device; a reset of some worlds must leave the others as they were
and give the episodes the C MuJoCo batched env gives; a world that runs past its budget
of contacts or constraint rows is truncated alone, with a warning naming it.
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest

from gym_soarm.sim import warp_backend
from gym_soarm.sim.warp_backend import warp_available

if not warp_available():
    if os.environ.get("GYM_SOARM_REQUIRE_WARP") == "1":
        raise ImportError(
            'GYM_SOARM_REQUIRE_WARP=1 but MuJoCo Warp is not installed: pip install -e ".[warp]"'
        )
    pytest.skip('MuJoCo Warp: pip install "gym-soarm[warp]"', allow_module_level=True)

torch = pytest.importorskip("torch")

N = 3
DEVICE = os.environ.get("GYM_SOARM_WARP_DEVICE", "cpu")
TASK = "LiftCube-v0"


def _make(vector_env: str, task: str = TASK, **kwargs):
    if vector_env == "warp":
        kwargs.setdefault("device", DEVICE)
    kwargs.setdefault("obs_type", "state")
    return gym.make_vec(
        f"gym_soarm/{task}",
        num_envs=N,
        vectorization_mode="vector_entry_point",
        vector_env=vector_env,
        **kwargs,
    )


def _same(numpy_value, torch_value, where: str, device) -> None:
    """``torch_value`` is ``numpy_value`` as the torch view gives it (a SameStep final
    info: batched tensors where NumPy has per-environment values)."""
    ended_rows = isinstance(numpy_value, np.ndarray) and numpy_value.dtype == object
    if where.endswith("final_obs") and ended_rows:  # one observation per ended environment
        for i, row in enumerate(numpy_value):
            if row is not None:
                _same_leaf(row, torch_value[i], f"{where}[{i}]", device)
        return
    if isinstance(numpy_value, dict):
        assert set(numpy_value) == set(torch_value), (where, set(numpy_value) ^ set(torch_value))
        for key in numpy_value:
            _same(numpy_value[key], torch_value[key], f"{where}.{key}", device)
        return
    _same_leaf(numpy_value, torch_value, where, device)


def _same_leaf(numpy_value, torch_value, where: str, device) -> None:
    numpy_value = np.asarray(numpy_value)
    if numpy_value.dtype == object:
        assert isinstance(torch_value, np.ndarray), where
        np.testing.assert_array_equal(numpy_value, torch_value, err_msg=where)
        return
    assert isinstance(torch_value, torch.Tensor), f"{where}: {type(torch_value)}"
    assert torch_value.device == torch.device(device), where
    if numpy_value.dtype.kind == "f":
        assert torch_value.dtype == torch.float32, where
    got = torch_value.cpu().numpy()
    if numpy_value.dtype == np.bool_:
        np.testing.assert_array_equal(numpy_value, got, err_msg=where)
    else:
        np.testing.assert_allclose(numpy_value, got, rtol=1e-5, atol=1e-6, err_msg=where)


@pytest.mark.parametrize(
    ("vector_env", "mode"),
    [("warp", "NextStep"), ("warp", "SameStep"), ("batched", "SameStep")],
)
def test_the_torch_view_gives_the_numpy_views_values_as_tensors_on_the_device(vector_env, mode):
    common = {"autoreset_mode": mode, "max_episode_steps": 3}
    numpy_env = _make(vector_env, **common)
    torch_env = _make(vector_env, array_api="torch", **common)
    device = DEVICE if vector_env == "warp" else "cpu"
    try:
        assert (numpy_env.unwrapped.array_api, torch_env.unwrapped.array_api) == ("numpy", "torch")
        expected, got = numpy_env.reset(seed=7), torch_env.reset(seed=7)
        _same(expected[0], got[0], "reset obs", device)
        _same(expected[1], got[1], "reset info", device)
        rng = np.random.default_rng(3)
        finals = 0
        for step in range(7):  # two time limits: autoresets of every kind
            actions = rng.uniform(-0.3, 0.3, (N, 6))
            expected = numpy_env.step(actions)
            got = torch_env.step(torch.as_tensor(actions, device=device))
            for k, name in enumerate(("obs", "reward", "terminated", "truncated", "info")):
                _same(expected[k], got[k], f"step {step} {name}", device)
            assert got[0].dtype == torch.float32 and got[2].dtype == torch.bool
            finals += "final_obs" in got[4]
        assert finals == (2 if mode == "SameStep" else 0)
    finally:
        numpy_env.close()
        torch_env.close()


def test_the_tasks_read_the_warp_arrays_in_place():
    import warp as wp

    envs = _make("warp")
    try:
        envs.reset(seed=2)
        backend = envs.unwrapped._backend
        data = backend._data
        sim = envs.unwrapped._sim
        assert isinstance(sim.qpos, torch.Tensor) and sim.qpos.dtype == torch.float32
        pointers = {name: getattr(sim, name).data_ptr() for name in ("qpos", "qvel", "site_xpos")}
        for _ in range(2):
            envs.step(np.zeros((N, 6)))
        envs.reset(seed=3, options={"reset_mask": np.array([False, True, False])})
        for name, pointer in pointers.items():
            assert getattr(envs.unwrapped._sim, name).data_ptr() == pointer, name
            assert wp.to_torch(getattr(data, name)).data_ptr() == pointer, name
        np.testing.assert_array_equal(sim.qpos.cpu().numpy(), data.qpos.numpy())
    finally:
        envs.close()


def test_a_masked_reset_copies_its_worlds_and_leaves_the_others_as_they_were():
    warp, ref = _make("warp"), _make("batched")
    try:
        warp.reset(seed=5)
        ref.reset(seed=5)
        rng = np.random.default_rng(5)
        for _ in range(2):
            actions = rng.uniform(-0.2, 0.2, (N, 6))
            warp.step(actions)
            ref.step(actions)
        sim = warp.unwrapped._sim
        before = {name: getattr(sim, name).clone() for name in ("qpos", "qvel")}
        mask = np.array([False, True, False])
        obs_w, _ = warp.reset(seed=11, options={"reset_mask": mask})
        obs_c, _ = ref.reset(seed=11, options={"reset_mask": mask})
        np.testing.assert_array_equal(obs_w[1], obs_c[1])  # the reset ran on env 1's MjData
        own = warp.unwrapped.envs[1].physics.data
        np.testing.assert_array_equal(sim.qpos[1].cpu().numpy(), own.qpos.astype(np.float32))
        for name, values in before.items():  # the other worlds: not a bit changed
            for i in (0, 2):
                assert torch.equal(getattr(sim, name)[i], values[i]), (name, i)
        names = warp.unwrapped.envs[0].observation_names
        still = [k for k, name in enumerate(names) if "vel" not in name]
        for _ in range(3):  # the same episodes as C MuJoCo's, to float32's tolerance
            actions = rng.uniform(-0.2, 0.2, (N, 6))
            obs_w, reward_w, term_w, *_ = warp.step(actions)
            obs_c, reward_c, term_c, *_ = ref.step(actions)
            np.testing.assert_allclose(obs_w[:, still], obs_c[:, still], atol=2e-3)
            np.testing.assert_allclose(reward_w, reward_c, atol=2e-2)
            np.testing.assert_array_equal(term_w, term_c)
    finally:
        warp.close()
        ref.close()


def _lift_cubes(envs, worlds=(0, 2)) -> None:
    """Raise the cubes of ``worlds`` 5 cm off the table, through the torch view of the
    Warp state: they touch nothing there, so those worlds hold fewer contacts and
    constraint rows than world 1, whose cube lies on the table."""
    sim = envs.unwrapped._sim
    z = sim.index.objects["cube"].qpos + 2
    for i in worlds:
        sim.qpos[i, z] += 0.05


def _counts(envs) -> tuple[np.ndarray, np.ndarray]:
    backend = envs.unwrapped._backend
    return backend.contact_counts().cpu().numpy(), backend._views["nefc"].cpu().numpy()


@pytest.mark.parametrize("budget", ["contacts", "constraint rows"])
def test_only_the_worlds_past_their_budget_are_truncated_with_a_warning_naming_them(
    budget, monkeypatch
):
    probe = _make("warp")
    try:
        probe.reset(seed=1)
        _lift_cubes(probe)
        probe.step(np.zeros((N, 6)))
        contacts, rows = _counts(probe)
    finally:
        probe.close()
    held = contacts if budget == "contacts" else rows
    # A budget that world 1 runs past and worlds 0 and 2 keep to (a pool of 0 contacts
    # would turn collisions off).
    limit = max(int(held[[0, 2]].max()), 1)
    assert held[1] > limit, f"world 1 should hold the most {budget}: {held}"
    name = "CONTACTS_PER_WORLD" if budget == "contacts" else "CONSTRAINTS_PER_WORLD"
    monkeypatch.setattr(warp_backend, name, limit)
    envs = _make("warp")
    try:
        envs.reset(seed=1)
        _lift_cubes(envs)
        with pytest.warns(RuntimeWarning) as caught:
            *_, truncated, info = envs.step(np.zeros((N, 6)))
        messages = [str(w.message) for w in caught if "diverged" in str(w.message)]
        assert truncated.tolist() == [False, True, False]
        assert info["physics_unstable"].tolist() == [False, True, False]
        (message,) = messages
        assert "environment 1 diverged" in message and "world 1 held" in message
        assert budget in message and f"more than its {limit}" in message
        obs, _, _, truncated, _ = envs.step(np.zeros((N, 6)))  # NextStep: world 1 resets
        assert not truncated.any() and np.isfinite(obs).all()
    finally:
        envs.close()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"vector_env": "warp", "array_api": "jax"}, "array_api must be one of"),
        ({"vector_env": "batched", "array_api": 1}, "array_api must be one of"),
        ({"vector_env": "processes", "array_api": "torch"}, "applies to vector_env='batched'"),
        (
            {"vector_env": "auto", "array_api": "torch", "obs_type": "pixels_agent_pos"},
            "applies to vector_env='batched'",
        ),
    ],
)
def test_bad_array_apis_and_torch_for_the_process_env_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message) as raised:
        _make(**kwargs)
    if "must be one of" in message:
        assert "'numpy'" in str(raised.value) and "'torch'" in str(raised.value)


def test_a_grid_cell_read_each_step_stays_in_host_memory():
    # The cube's grid cell, an info that is not a number, is read every step: kept on the
    # host, it never makes a step wait for the device; the yaw stays with the worlds.
    envs = _make("warp", array_api="torch")
    try:
        options = {"cube_grid_position": 4, "cube_rotation_deg": 90.0}
        _, info = envs.reset(seed=0, options=options)
        episode = envs.unwrapped._episode
        assert isinstance(episode["grid_cell"], np.ndarray)
        assert isinstance(episode["yaw_deg"], torch.Tensor)
        assert list(info["cube_grid_position"]) == [4] * N
        for _ in range(2):
            *_, info = envs.step(torch.zeros((N, 6)))
        assert list(info["cube_grid_position"]) == [4] * N
        assert torch.equal(info["cube_rotation_deg"].cpu(), torch.full((N,), 90.0))
    finally:
        envs.close()
