"""The speed work keeps behaviour: simplified meshes, the model cache and the step path."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from dm_control import mujoco as dm_mujoco
from dm_control.rl import control

import gym_soarm
from gym_soarm.sim import cache, meshes, visual_meshes
from gym_soarm.sim import scene as model
from gym_soarm.sim.arrays import ARRAY_FIELDS, SimArrays, xy_distance
from gym_soarm.sim.objects import EMPTY_SCENE
from gym_soarm.sim.physics import SoArmPhysics

N_SUBSTEPS = 10
PICK_AND_PLACE_SCENE = gym_soarm.get_task("PickAndPlaceCube-v0").scene


def _drive(physics: SoArmPhysics, steps: int, seed: int = 0) -> np.ndarray:
    """Step with random servo targets; return every qpos and qvel along the way."""
    rng = np.random.default_rng(seed)
    low, high = physics.control_range()
    physics.reset_to_home()
    physics.forward()
    trace = []
    for _ in range(steps):
        physics.set_joint_targets(rng.uniform(low, high))
        physics.step(N_SUBSTEPS)
        trace.append(np.concatenate([physics.data.qpos, physics.data.qvel]))
    return np.array(trace)


def test_fast_and_high_visual_meshes_give_bit_identical_physics():
    fast, high = (
        SoArmPhysics.from_scene(PICK_AND_PLACE_SCENE, visual="fast"),
        SoArmPhysics.from_scene(PICK_AND_PLACE_SCENE, visual="high"),
    )
    assert fast.model.ptr.nmeshface < 0.2 * high.model.ptr.nmeshface
    assert (fast.model.ptr.nq, fast.model.ptr.nbody, fast.model.ptr.ngeom) == (
        high.model.ptr.nq,
        high.model.ptr.nbody,
        high.model.ptr.ngeom,
    )
    np.testing.assert_array_equal(fast.model.ptr.body_mass, high.model.ptr.body_mass)
    np.testing.assert_array_equal(fast.model.ptr.body_inertia, high.model.ptr.body_inertia)
    assert _drive(fast, 150).tobytes() == _drive(high, 150).tobytes()


def test_physics_step_matches_dm_control_step_bit_for_bit():
    ours = SoArmPhysics.from_scene(PICK_AND_PLACE_SCENE)
    reference = ours.copy(share_model=False)
    rng = np.random.default_rng(3)
    low, high = ours.control_range()
    for physics in (ours, reference):
        physics.reset_to_home()
        physics.forward()
    for _ in range(60):
        target = rng.uniform(low, high)
        ours.set_joint_targets(target)
        reference.set_joint_targets(target)
        ours.step(N_SUBSTEPS)
        dm_mujoco.Physics.step(reference, N_SUBSTEPS)  # dm_control's own implementation
        for field in ("qpos", "qvel", "qacc", "xpos", "site_xpos", "sensordata"):
            assert getattr(ours.data, field).tobytes() == getattr(reference.data, field).tobytes()
        assert ours.data.ncon == reference.data.ncon
        assert ours.data.time == reference.data.time


def test_a_new_mujoco_warning_raises_physics_error_or_is_logged(caplog):
    physics = SoArmPhysics.from_scene(PICK_AND_PLACE_SCENE)
    physics.reset_to_home()
    physics.forward()
    physics.data.qvel[:] = 1e12  # beyond MuJoCo's bound: it resets and warns BADQVEL
    with pytest.raises(control.PhysicsError, match="BADQVEL"):
        physics.step(N_SUBSTEPS)
    physics.step(N_SUBSTEPS)  # no new warning: nothing raised
    physics.reset()  # clears MuJoCo's warning counters
    physics.data.qvel[:] = 1e12
    with caplog.at_level(logging.WARNING), physics.suppress_physics_errors():
        physics.step(N_SUBSTEPS)
    logged = [r.getMessage() for r in caplog.records if r.name == "gym_soarm.sim.physics"]
    assert len(logged) == 1 and "BADQVEL" in logged[0]


def test_diverging_physics_truncates_the_episode(state_env):
    state_env.reset(seed=0)
    state_env.unwrapped.physics.data.qvel[:] = 1e12
    with pytest.warns(RuntimeWarning, match="diverged"):
        _, reward, terminated, truncated, info = state_env.step(np.zeros(6, dtype=np.float32))
    assert (reward, terminated, truncated, info["physics_unstable"]) == (0.0, False, True, True)
    with pytest.raises(RuntimeError, match="reset"):
        state_env.step(np.zeros(6, dtype=np.float32))


def test_state_is_finite_notices_nan_and_inf():
    physics = SoArmPhysics.from_scene(PICK_AND_PLACE_SCENE)
    physics.forward()
    assert physics.state_is_finite()
    physics.data.qvel[2] = np.inf
    assert not physics.state_is_finite()
    physics.data.qvel[2] = 0.0
    physics.data.qpos[0] = np.nan
    assert not physics.state_is_finite()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_huge_finite_actions_are_clipped_and_the_caller_array_is_untouched(state_env, dtype):
    state_env.reset(seed=0)
    huge = np.finfo(dtype).max / 2
    action = np.array([1, -1, 1, 1, -1, 1], dtype=dtype) * huge
    sent = action.copy()
    state_env.step(action)
    np.testing.assert_array_equal(action, sent)
    low, high = state_env.action_space.low, state_env.action_space.high
    expected = np.where(sent > 0, high, low)
    np.testing.assert_allclose(state_env.unwrapped.physics.joint_targets(), expected, atol=1e-6)


@pytest.mark.parametrize(
    "quality, kept_at_most, extent_m", [("fast", 0.1, 1e-3), ("high", 0.5, 3e-4)]
)
def test_quality_meshes_keep_the_extent_of_each_part(quality, kept_at_most, extent_m):
    sources = meshes.load_meshes()
    rebuilt = visual_meshes.quality_meshes(quality)
    assert set(rebuilt) == set(sources)
    kept = 0
    for name, data in sources.items():
        v_src, _ = visual_meshes.parse_binary_stl(data)
        v_new, t_new = visual_meshes.parse_binary_stl(rebuilt[name])
        assert len(t_new) > 0, name
        kept += len(t_new)
        for new, src in (
            (v_new.min(axis=0), v_src.min(axis=0)),
            (v_new.max(axis=0), v_src.max(axis=0)),
        ):
            np.testing.assert_allclose(new, src, atol=extent_m, err_msg=name)
    total = sum(visual_meshes.stl_triangle_count(data) for data in sources.values())
    assert kept < kept_at_most * total


def test_unknown_mesh_quality_is_refused():
    with pytest.raises(ValueError, match="quality must be one of"):
        visual_meshes.quality_meshes("ultra")


def test_stl_round_trip_and_rejects_non_stl_bytes():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    data = visual_meshes.write_binary_stl(vertices, triangles)
    v, t = visual_meshes.parse_binary_stl(data)
    assert len(v) == 4 and len(t) == 4
    np.testing.assert_array_equal(np.sort(v, axis=0), np.sort(vertices, axis=0))
    with pytest.raises(ValueError, match="binary STL"):
        visual_meshes.parse_binary_stl(b"solid ascii\nendsolid\n")
    with pytest.raises(ValueError, match="binary STL"):
        visual_meshes.parse_binary_stl(data[:-7])


def test_cache_dir_follows_the_environment_variable(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.CACHE_DIR_ENV, str(tmp_path / "here"))
    assert cache.cache_dir() == tmp_path / "here"
    assert cache.write("a/b.bin", b"xyz") == tmp_path / "here" / "a" / "b.bin"
    assert cache.read("a/b.bin") == b"xyz"
    assert cache.read("a/missing.bin") is None
    cache.write("a/c.bin", b"old")
    cache.write("a/other.txt", b"kept")
    cache.prune("a/*.bin", keep="a/b.bin")
    assert sorted(p.name for p in (tmp_path / "here" / "a").iterdir()) == ["b.bin", "other.txt"]
    monkeypatch.setenv(cache.CACHE_DIR_ENV, "")
    assert cache.cache_dir() is None
    assert cache.write("a/b.bin", b"xyz") is None
    assert cache.read("a/b.bin") is None


_LOAD_AND_DESCRIBE = """
import json, sys
from gym_soarm.sim import scene as model
from gym_soarm.sim.objects import EMPTY_SCENE
m = model.load_scene_model(visual=sys.argv[1])
print(json.dumps({"nmeshface": int(m.nmeshface), "mesh_vert": float(m.mesh_vert.sum()),
                  "body_mass": m.body_mass.tolist(), "name": model.model_cache_name(EMPTY_SCENE, sys.argv[1])}))
"""


def _load_in_subprocess(cache_dir: Path, visual: str) -> dict:
    env = dict(os.environ, **{cache.CACHE_DIR_ENV: str(cache_dir)})
    out = subprocess.run(
        [sys.executable, "-c", _LOAD_AND_DESCRIBE, visual],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.subprocess
def test_compiled_model_is_cached_reused_and_rebuilt_when_damaged(tmp_path):
    stale = tmp_path / "models" / "scene-fast-0123456789abcdef01234567.mjb"  # same label
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"a model built from older sources")
    first = _load_in_subprocess(tmp_path, "fast")
    cached = tmp_path / first["name"]
    assert cached.is_file()
    assert not stale.exists()  # superseded files are pruned
    assert len(list((tmp_path / "meshes" / "fast").glob("*.stl"))) == len(meshes.MESH_SHA256)
    stamp = cached.stat().st_mtime_ns
    # The cached binary gives the same model as compiling the XML.
    compiled = model.build_spec(EMPTY_SCENE, "fast").compile()
    assert first["nmeshface"] == compiled.nmeshface
    assert first["mesh_vert"] == float(compiled.mesh_vert.sum())
    assert first["body_mass"] == compiled.body_mass.tolist()
    assert _load_in_subprocess(tmp_path, "fast") == first
    assert cached.stat().st_mtime_ns == stamp  # read, not rewritten
    cached.write_bytes(b"not a MuJoCo model")
    assert _load_in_subprocess(tmp_path, "fast") == first
    assert mujoco.MjModel.from_binary_path(str(cached)).nmeshface == first["nmeshface"]


def test_unknown_visual_variant_is_refused():
    with pytest.raises(ValueError, match="fast"):
        model.load_scene_model(visual="ultra")


def test_actions_whose_sum_overflows_are_still_accepted(state_env):
    state_env.reset(seed=0)
    action = np.full(6, np.finfo(np.float64).max / 2)  # each finite, their sum is not
    state_env.step(action)
    np.testing.assert_allclose(
        state_env.unwrapped.physics.joint_targets(), state_env.action_space.high, atol=1e-6
    )
    with pytest.raises(ValueError, match="finite"):
        state_env.step(np.array([0.0, np.inf, 0.0, 0.0, -np.inf, 0.0]))


@pytest.mark.parametrize(
    "fault, reason",
    [
        ("cube_far", "cube was thrown"),
        ("joint_turned", "joint 'wrist_roll' turned"),
        ("qacc_nan", "NaN or inf"),
        (None, None),
    ],
)
def test_one_environments_divergence_check_finds_what_the_batchs_finds(state_env, fault, reason):
    env = state_env.unwrapped
    state_env.reset(seed=0)
    state_env.step(np.zeros(6, dtype=np.float32))
    core = env._world.core
    sim = core.arrays()
    if fault == "cube_far":
        sim.qpos[sim.index.objects["cube"].qpos + 1] = -7.0
    elif fault == "joint_turned":
        sim.qpos[sim.index.arm_qpos[4]] = -3.5
    elif fault == "qacc_nan":
        sim.qacc[0] = np.nan
    found = core.divergence(sim, {}, None)
    # The batch's masks, on the same state seen as a batch of one.
    batch = SimArrays(sim.index, {name: getattr(sim, name)[None] for name in ARRAY_FIELDS})
    assert bool(core.unsound(batch)[0]) is (fault is not None)
    if fault is None:
        assert found == {}
    else:
        assert list(found) == [0] and reason in found[0]


def test_xy_distance_is_the_horizontal_distance_for_a_batch_and_for_one_environment():
    points = np.array([[0.0, 0.0, 5.0], [1.0, 1.0, 0.0]])
    others = np.array([[3.0, 4.0, -2.0], [1.0, 1.0, 9.0]])
    np.testing.assert_array_equal(xy_distance(points, others), [5.0, 0.0])
    one = xy_distance(points[0], others[0])
    assert type(one) is np.float64 and one == 5.0
