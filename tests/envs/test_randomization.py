"""Visual and physics randomisation and the STS3215 servo model."""

from __future__ import annotations

import colorsys
import json
import math

import numpy as np
import pytest

from gym_soarm import constants
from gym_soarm.sim.randomization import STS3215

pytestmark = pytest.mark.gl

STATE = {"obs_type": "environment_state_agent_pos"}
FIELDS = ("light_dir", "light_diffuse", "mat_rgba", "cam_pos", "cam_quat", "cam_fovy")
PHYSICS_FIELDS = ("body_mass", "geom_friction", "actuator_gainprm", "actuator_biasprm")


def _fields(env, names=FIELDS + PHYSICS_FIELDS + ("dof_damping",)) -> dict[str, np.ndarray]:
    model = env.unwrapped.physics.model
    return {name: getattr(model, name).copy() for name in names}


def test_defaults_report_and_change_nothing(make_env):
    default = make_env(**STATE)
    explicit = make_env(
        **STATE, visual_randomization="none", physics_randomization="none", servo_model="ideal"
    )
    a, info = default.reset(seed=4)
    b, _ = explicit.reset(seed=4)
    assert "variation" not in info
    np.testing.assert_array_equal(a["environment_state"], b["environment_state"])
    for name, value in _fields(default).items():
        np.testing.assert_array_equal(value, _fields(explicit)[name])


@pytest.mark.parametrize("level", ["light", "heavy"])
def test_visual_variation_is_drawn_at_reset_and_never_accumulates(make_env, level):
    env = make_env(**STATE, visual_randomization=level)
    saved = _fields(env)
    _, info = env.reset(seed=1)
    first = _fields(env)
    variation = info["variation"]
    json.dumps(variation)  # plain numbers
    assert set(variation["visual"]) == {"lights", "ambient_scale", "colours", "cameras"}
    assert variation["physics"] == {}
    for name in FIELDS:
        assert not np.array_equal(first[name], saved[name]), name
    for name in PHYSICS_FIELDS:
        np.testing.assert_array_equal(first[name], saved[name])
    env.reset(seed=2)
    assert not np.array_equal(_fields(env)["cam_pos"], first["cam_pos"])
    for _ in range(3):
        _, again = env.reset(seed=1)
    assert again["variation"] == variation
    for name, value in _fields(env).items():
        np.testing.assert_array_equal(value, first[name])


@pytest.mark.parametrize(
    ("level", "pos_m", "fovy_deg", "hue"), [("light", 0.01, 2, 0.01), ("heavy", 0.03, 5, 0.02)]
)
def test_visual_bounds(make_env, level, pos_m, fovy_deg, hue):
    env = make_env("gym_soarm/SortCubes-v0", **STATE, visual_randomization=level)
    saved = _fields(env)
    model = env.unwrapped.physics.model
    names = [model.material(i).name for i in range(model.nmat)]
    for seed in range(5):
        env.reset(seed=seed)
        assert np.abs(model.cam_pos - saved["cam_pos"]).max() <= pos_m + 1e-12
        assert np.abs(model.cam_fovy - saved["cam_fovy"]).max() <= fovy_deg + 1e-12
        for colour in ("red", "green", "blue"):
            i = names.index(colour)
            h0 = colorsys.rgb_to_hsv(*saved["mat_rgba"][i][:3])[0]
            h = colorsys.rgb_to_hsv(*model.mat_rgba[i][:3])[0]
            assert min(abs(h - h0), 1 - abs(h - h0)) <= hue + 1e-9, colour


def test_placement_does_not_depend_on_the_level(make_env):
    states = [
        make_env(**STATE, visual_randomization=v, physics_randomization=p).reset(seed=7)[0]
        for v, p in (("none", "none"), ("heavy", "heavy"))
    ]
    np.testing.assert_array_equal(*(s["environment_state"] for s in states))


@pytest.mark.parametrize(("level", "scale"), [("light", 0.1), ("heavy", 0.3)])
def test_physics_variation(make_env, level, scale):
    env = make_env(**STATE, physics_randomization=level)
    saved = _fields(env)
    model = env.unwrapped.physics.model
    cube = model.body("cube").id
    delays = set()
    for seed in range(8):
        _, info = env.reset(seed=seed)
        physics = info["variation"]["physics"]
        json.dumps(physics)
        ratio = model.body_mass[cube] / saved["body_mass"][cube]
        assert abs(ratio - 1) <= scale and ratio == pytest.approx(
            physics["objects"]["cube"]["mass_scale"], rel=1e-5
        )
        kp = model.actuator_gainprm[:6, 0] / saved["actuator_gainprm"][:6, 0]
        assert np.all(np.abs(kp - 1) <= scale) and not np.allclose(kp, 1)
        np.testing.assert_allclose(model.actuator_biasprm[:6, 1], -model.actuator_gainprm[:6, 0])
        arm = [model.joint(name).dofadr[0] for name in constants.JOINT_NAMES]
        damping = model.dof_damping[arm] / saved["dof_damping"][arm]
        assert np.all(np.abs(damping - 1) <= scale + 1e-12) and not np.allclose(damping, 1)
        others = np.setdiff1d(np.arange(model.nv), arm)
        np.testing.assert_array_equal(model.dof_damping[others], saved["dof_damping"][others])
        delays.add(physics["control_delay_steps"])
    assert delays == ({0, 1} if level == "heavy" else {0})


def test_control_delay_applies_the_previous_action(make_env):
    env = make_env(**STATE, physics_randomization="heavy")
    seed = next(
        s for s in range(20) if env.reset(seed=s)[1]["variation"]["physics"]["control_delay_steps"]
    )
    env.reset(seed=seed)
    physics = env.unwrapped.physics
    start = physics.joint_targets().copy()
    first = np.full(6, 0.1, dtype=np.float32)
    env.step(first)
    np.testing.assert_array_equal(physics.joint_targets(), start)
    env.step(np.zeros(6, dtype=np.float32))
    np.testing.assert_allclose(physics.joint_targets(), first, atol=1e-7)


def test_sts3215_servo(make_env):
    env = make_env(**STATE, servo_model="sts3215")
    _, info = env.reset(seed=0)
    assert info["variation"]["servo_model"] == "sts3215"
    physics = env.unwrapped.physics
    np.testing.assert_allclose(physics.model.actuator_forcerange[:6, 1], 2.94, atol=0.01)
    assert STS3215.speed_rad_s == pytest.approx(4.717, abs=1e-3)
    step = STS3215.speed_rad_s * constants.CONTROL_TIMESTEP_S
    previous = physics.joint_targets().copy()
    action = np.array([1.0, -1.0, 0.5, 0.3, -0.2, 1.0], dtype=np.float32)
    for _ in range(40):
        env.step(action)
        target = physics.joint_targets()
        assert np.abs(target - previous).max() <= step + 1e-9
        previous = target.copy()
    # Settled within the backlash and a tick of the action.
    tick = 2 * math.pi / 4096
    assert np.abs(previous - action).max() <= STS3215.backlash_rad / 2 + tick


def test_randomized_episodes_are_deterministic(make_env):
    kwargs = {**STATE, "visual_randomization": "heavy", "physics_randomization": "heavy"}
    runs = []
    for _ in range(2):
        env = make_env(servo_model="sts3215", **kwargs)
        obs, info = env.reset(seed=11)
        rng = np.random.default_rng(0)
        for _ in range(10):
            obs, *_ = env.step(rng.uniform(-0.5, 0.5, 6).astype(np.float32))
        runs.append((obs["environment_state"], info["variation"]))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]


def test_visual_randomization_changes_the_image(make_env):
    small = {
        "obs_type": "pixels",
        "camera_config": "front_only",
        "observation_height": 48,
        "observation_width": 64,
    }
    plain = make_env(**small).reset(seed=0)[0]["front_camera"]
    heavy = make_env(**small, visual_randomization="heavy").reset(seed=0)[0]["front_camera"]
    assert np.abs(plain.astype(int) - heavy).mean() > 5


@pytest.mark.parametrize("keyword", ["visual_randomization", "physics_randomization"])
def test_bad_levels_raise(make_env, keyword):
    with pytest.raises(ValueError, match=f"{keyword} must be one of 'none', 'light', 'heavy'"):
        make_env(**{keyword: "extreme"})


def test_bad_servo_model_raises(make_env):
    with pytest.raises(ValueError, match="servo_model must be one of 'ideal', 'sts3215'"):
        make_env(servo_model="sts3032")
