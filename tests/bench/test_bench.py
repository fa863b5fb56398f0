"""The benchmark command runs and reports every figure; both qualities show the scene.

Speed itself is never asserted here: the benchmark measures it.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys

import cv2
import mujoco
import numpy as np
import pytest
from conftest import colour_counts
from paths import ROOT

from gym_soarm.bench import bench
from gym_soarm.cli import bench as bench_cli
from gym_soarm.render.camera import CameraRenderer
from gym_soarm.sim import scene as model

STAT_FIELDS = {"median", "min", "max", "repeats"}


def _check_spread(spread: dict, repeats: int) -> None:
    assert set(spread) == STAT_FIELDS
    assert len(spread["repeats"]) == repeats
    assert 0 < spread["min"] <= spread["median"] <= spread["max"]


@pytest.mark.subprocess
def test_short_benchmark_run_reports_every_field(tmp_path):
    out = tmp_path / "bench.json"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "gym_soarm.bench",
            "--configs",
            "state,state_30hz,front_only_64x48",
            "--seconds",
            "0.2",
            "--repeats",
            "3",
            "--processes",
            "2",
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "| state |" in proc.stdout and "| front_only_64x48 |" in proc.stdout
    assert "| state_30hz |" in proc.stdout  # the benchmark reports both control rates
    assert "target state steps_per_s >= 4000" in proc.stdout

    report = json.loads(out.read_text())
    assert set(report) == {
        "machine",
        "versions",
        "settings",
        "configs",
        "cold_make",
        "vector_scaling",
        "recording",
        "targets",
    }
    assert report["vector_scaling"] == [] and report["recording"] is None
    assert report["machine"]["cpu_count"] >= 1
    assert report["machine"]["gl_backend"] in ("egl", "osmesa", "glfw")
    assert report["machine"]["gl_renderer"]
    assert report["settings"] == {
        **report["settings"],
        "seconds": 0.2,
        "repeats": 3,
        "processes": 2,
    }
    state, state30, pixels = report["configs"]
    for result in (state, state30, pixels):
        _check_spread(result["steps_per_s"], 3)
        _check_spread(result["ceiling"]["steps_per_s"], 3)
        _check_spread(result["vector"]["steps_per_s"], 3)
        assert result["vector"]["processes"] == 2
        ms = result["ms_per_step"]
        assert ms["total"] == pytest.approx(ms["physics"] + ms["render"], rel=0.05)
        assert ms["physics"] > 0
        assert result["ratio_to_ceiling"] > 0
        assert result["make_s"] > 0 and result["reset_ms"] > 0 and result["first_reset_ms"] > 0
        assert result["peak_rss_mb"] > 50
    assert state["name"] == "state" and state["obs_type"] == "environment_state_agent_pos"
    assert state["ms_per_step"]["render"] == 0
    assert state["ceiling"]["kind"] == "mujoco.mj_step x10"
    # 30 Hz: twenty physics steps of 1/600 s a control step, against their own ceiling.
    assert state30["name"] == "state_30hz" and state30["ceiling"]["kind"] == "mujoco.mj_step x20"
    assert pixels["render_quality"] == "fast" and pixels["camera_config"] == "front_only"
    assert (pixels["observation_width"], pixels["observation_height"]) == (64, 48)
    assert pixels["ms_per_step"]["render"] > 0
    assert pixels["ceiling"]["kind"] == "mujoco.Renderer, 1 camera(s)"
    assert [c["visual"] for c in report["cold_make"]] == ["fast"]
    assert all(c["make_s"] > 0 for c in report["cold_make"])
    checked = {(t["config"], t["figure"]) for t in report["targets"]}
    assert {
        ("state", "steps_per_s"),
        ("state", "reset_ms"),
        ("state", "make_s"),
        ("front_only_64x48", "ratio_to_ceiling"),
    } <= checked
    for target in report["targets"]:
        assert isinstance(target["met"], bool) and target["value"] > 0


def _bench(args: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    proc = subprocess.run(
        [sys.executable, "-m", "gym_soarm.bench", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


@pytest.mark.subprocess
def test_vector_scaling_compares_the_three_vector_envs_and_is_plotted(tmp_path):
    out = tmp_path / "scaling.json"
    proc = _bench(
        ["--configs", "", "--vector-scaling", "1,2", "--vector-obs", "state,front_wrist",
         "--image-size", "48x64", "--seconds", "0.1", "--repeats", "2", "--json", str(out)]
    )  # fmt: skip
    assert (
        "| num_envs | batched steps/s (speedup) | processes steps/s (speedup) | async steps/s "
        "(speedup) |" in proc.stdout
    )
    assert "target processes_vector_state_" in proc.stdout
    assert "target batched_vector_state_2 speedup >= 1.8" in proc.stdout

    report = json.loads(out.read_text())
    assert report["configs"] == [] and report["recording"] is None
    assert report["settings"]["vector_scaling"] == [1, 2]
    state, pixels = report["vector_scaling"]
    assert (state["obs"], state["size"]) == ("state", None)
    assert (pixels["obs"], pixels["size"]) == ("front_wrist", [48, 64])
    for scaling in (state, pixels):
        modes = ["batched", "processes", "async", "sync"]
        assert scaling["modes"] == modes
        assert scaling["single_steps_per_s"] > 0
        assert [(r["mode"], r["num_envs"]) for r in scaling["rows"]] == [
            (mode, n) for n in (1, 2) for mode in modes
        ]
        for row in scaling["rows"]:
            _check_spread(row["steps_per_s"], 2)
            assert row["speedup"] > 0 and row["single_steps_per_s"] > 0
            # The ceiling of the same environments on free-running processes, per round.
            assert row["ceiling_speedup"] > 0
            assert row["ratio_to_ceiling"] > 0
            # The bare mujoco.batch physics of the same simulations: the batched env's ceiling.
            assert row["batch_physics_steps_per_s"] > 0 and row["ratio_to_physics"] > 0
            assert (row["single_to_physics"] is not None) == (row["num_envs"] == 1)
    state_target, pixels_target, batched_target = [
        t for t in report["targets"] if t["figure"] == "speedup"
    ]
    assert batched_target["config"] == "batched_vector_state_2"
    assert batched_target["bound"] == 1.8
    assert state_target["config"] == "processes_vector_state_2" and state_target["bound"] == 1.7
    assert pixels_target["config"] == "processes_vector_front_wrist_2"
    assert pixels_target["bound"] == 1.8
    for target in (state_target, pixels_target):
        assert target["value"] > 0 and isinstance(target["met"], bool)

    picture = tmp_path / "scaling.png"
    script = ROOT / "scripts" / "make_vector_scaling_plot.py"
    subprocess.run(
        [sys.executable, str(script), str(out), "--out", str(picture)], check=True, timeout=60
    )
    image = cv2.imread(str(picture))
    assert image.shape[:2] == (420 + 30, 2 * 520)  # two panels above a legend
    assert (image < 128).any() and (image == 255).any()


@pytest.mark.subprocess
def test_recording_throughput_counts_the_episodes_of_each_recorder(tmp_path):
    out = tmp_path / "recording.json"
    ray = importlib.util.find_spec("ray") is not None  # the ray extra
    proc = _bench(
        ["--configs", "", "--recording", "2", "--recording-episodes", "2",
         "--recording-cameras", "none,front_only", "--image-size", "48x64",
         "--repeats", "1", "--json", str(out), *(["--recording-ray"] if ray else [])]
    )  # fmt: skip
    assert "| none | 2 workers |" in proc.stdout

    recording = json.loads(out.read_text())["recording"]
    assert recording["task"] == "LiftCube-v0" and recording["episodes"] == 2
    assert recording["ray"] is ray
    recorders = [("1 process", 1, False), ("2 workers", 2, False)]
    recorders += [("Ray local (2)", 2, True)] if ray else []
    rows = [(r["camera_config"], r["recorder"], r["workers"], r["ray"]) for r in recording["rows"]]
    assert rows == [
        (camera, *recorder) for camera in ("none", "front_only") for recorder in recorders
    ]
    for row in recording["rows"]:
        assert row["episodes"] == row["dataset_episodes"] == [2]
        assert row["frames"] == row["dataset_frames"] and row["frames"][0] > 0
        _check_spread(row["episodes_per_min"], 1)
        assert row["speedup"] > 0 and row["bytes_on_disk"] > 0
    none, camera = recording["rows"][0], recording["rows"][len(recorders)]
    assert camera["bytes_on_disk"] > none["bytes_on_disk"]  # the videos


@pytest.mark.parametrize(
    "name, expected",
    [
        ("state", ("environment_state_agent_pos", None, 0, 0, "fast")),
        ("front_wrist_640x480", ("pixels_agent_pos", "front_wrist", 640, 480, "fast")),
        ("all_224x224_high", ("pixels_agent_pos", "all", 224, 224, "high")),
        ("front_only_64x48_fast", ("pixels_agent_pos", "front_only", 64, 48, "fast")),
    ],
)
def test_configuration_names(name, expected):
    config = bench.BenchConfig.parse(name)
    assert (
        config.obs_type,
        config.camera_config,
        config.width,
        config.height,
        config.render_quality,
    ) == expected


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["--configs", "front_wrist_640"], "unknown benchmark configuration 'front_wrist_640'"),
        (["--configs", "state", "--seconds", "0"], "seconds must be a positive number"),
        (["--configs", "state", "--repeats", "0"], "repeats must be at least 1"),
        (["--configs", "state", "--processes", "0"], "processes must be at least 1"),
        (["--configs", ""], "configs must name at least one configuration"),
        (["--vector-scaling", "0,2"], "vector scaling counts must be at least 1"),
        (["--vector-scaling", "2", "--vector-modes", "forked"], "vector modes must be among"),
        (["--vector-scaling", "two"], "--vector-scaling must be comma-separated integers"),
        (["--recording", "2", "--image-size", "47x64"], "image size must be even"),
        (
            ["--recording", "2", "--recording-episodes", "0"],
            "recording episodes must be at least 1",
        ),
        (["--vector-scaling", "2", "--vector-obs", "front"], "vector obs must be 'state' or a"),
        (["--recording", "2", "--recording-cameras", "top"], "recording cameras must be 'none'"),
    ],
)
def test_bad_options_are_refused_before_measuring(argv, fragment, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        bench_cli.main([*argv, "--json", str(tmp_path / "never.json")])
    assert exit_info.value.code == 2
    assert fragment in capsys.readouterr().err
    assert not (tmp_path / "never.json").exists()


@pytest.mark.parametrize("quality", ["fast", "high"])
def test_both_qualities_show_the_cube_the_pad_and_the_arm(make_env, quality):
    env = make_env(
        "SoArm-v0",
        obs_type="pixels",
        camera_config="front_wrist",
        render_quality=quality,
        observation_height=240,
        observation_width=320,
    )
    obs, _ = env.reset(seed=0, options={"cube_grid_position": 4})
    front = colour_counts(obs["front_camera"])
    assert front["blue cube"] > 10 and front["green pad"] > 10, front
    assert front["white arm"] > 30, front
    assert obs["front_camera"].std() > 20
    wrist = colour_counts(obs["wrist_camera"])
    assert wrist["white arm"] > 500, wrist  # the gripper fills part of the wrist view


def _render_pose(scene: mujoco.MjModel, camera: str) -> np.ndarray:
    data = mujoco.MjData(scene)
    mujoco.mj_resetDataKeyframe(scene, data, 0)
    data.qpos[:6] = [0.03, -0.33, 0.60, 1.30, 0.61, 0.60]  # jaws open above the cube
    mujoco.mj_forward(scene, data)
    renderer = CameraRenderer(scene, 320, 240, "fast")
    try:
        return renderer.render(data, scene.camera(camera).id).astype(int)
    finally:
        renderer.close()


@pytest.mark.parametrize("camera", ["front_camera", "wrist_camera"])
def test_quality_meshes_render_like_the_provider_meshes(camera):
    """Same renderer settings, three mesh sets: ``high`` is all but identical to the
    provider's meshes, ``fast`` differs by a few grey levels."""
    provider = _render_pose(model.provider_mesh_model(), camera)
    for quality, mean_limit, changed_limit in (("high", 0.5, 0.002), ("fast", 4.0, 0.03)):
        difference = np.abs(_render_pose(model.load_scene_model(visual=quality), camera) - provider)
        assert difference.mean() < mean_limit, quality
        assert (difference.max(axis=2) > 40).mean() < changed_limit, quality


def test_the_earlier_name_native_still_measures_and_reads_the_processes_env():
    from gym_soarm.bench import bench_vector
    from gym_soarm.bench.targets import check_scaling_target

    with pytest.warns(FutureWarning, match="vector mode 'native' is deprecated; pass 'processes'"):
        assert bench_vector.vector_modes(["batched", "native"]) == ["batched", "processes"]
    # A report written before the rename: its processes rows are called native.
    rows = [
        {"mode": mode, "num_envs": n, "speedup": speedup}
        for mode in ("native", "processes")
        for n, speedup in ((1, 0.9), (8, 1.75))
    ]
    for mode in ("native", "processes"):
        report = {"obs": "state", "rows": [r for r in rows if r["mode"] == mode]}
        (target,) = check_scaling_target([report])
        assert target["config"] == "processes_vector_state_8"
        assert target["value"] == 1.75 and target["met"] is True
