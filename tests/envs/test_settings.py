"""One settings object: EnvSettings checks every gym.make keyword once, the environment
keeps it, every program's flags are generated from it and land in the settings it builds,
and docs/keywords.md is generated from it."""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import re
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from paths import ROOT

import gym_soarm  # noqa: F401 - registers the environments
from gym_soarm import constants
from gym_soarm.bench.bench import BenchConfig
from gym_soarm.cli import bench as bench_cli
from gym_soarm.cli import evaluate as evaluate_cli
from gym_soarm.cli import expert as expert_cli
from gym_soarm.cli import record as record_cli
from gym_soarm.cli import replay as replay_cli
from gym_soarm.cli import settings_table
from gym_soarm.cli import sysid as sysid_cli
from gym_soarm.cli import teleop as teleop_cli
from gym_soarm.cli import train as train_cli
from gym_soarm.cli.docs import KEYWORDS_PATH, keywords_page
from gym_soarm.cli.options import (
    SETTINGS_DEST,
    dataset_scene_keywords,
    settings_flag,
    settings_given,
)
from gym_soarm.envs.env import SoArmEnv
from gym_soarm.envs.settings import EnvSettings, keyword_table, merge_keywords
from gym_soarm.real.calibration import HOMING_TICKS
from gym_soarm.real.replay import ReplayDataset, replay_settings
from gym_soarm.real.sysid import SYSID_SETTINGS
from gym_soarm.record.record import record
from gym_soarm.rl.hyperparams import recipe
from gym_soarm.tasks.suites import SelectedTask

NAMES = EnvSettings.names()
STATE = {"obs_type": "environment_state_agent_pos"}


# --- the dataclass ----------------------------------------------------------------------------
def test_the_fields_are_exactly_the_keywords_of_the_environment():
    parameters = dict(inspect.signature(SoArmEnv.__init__).parameters)
    parameters.pop("self")
    parameters.pop("settings")
    assert parameters.pop("unknown").kind is inspect.Parameter.VAR_KEYWORD  # refused by name
    assert list(parameters) == list(NAMES)
    for item in dataclasses.fields(EnvSettings):
        assert parameters[item.name].default == item.default, item.name
        assert item.metadata["doc"] and "\n" not in item.metadata["doc"], item.name
        assert callable(item.metadata["check"]), item.name


def test_settings_are_frozen_and_normalised():
    s = EnvSettings(
        task="lift",
        camera_config=["wrist_camera", "front_camera"],
        image_modalities=["depth", "rgb"],
        calibration=Path("arm.json"),
        wrist_roll_offset_deg=-90,
        units="lerobot",
        distractors=np.int64(2),
    )
    assert s.task == "LiftCube-v0"
    assert s.camera_config == ("front_camera", "wrist_camera")
    assert s.image_modalities == ("rgb", "depth")
    assert s.calibration == "arm.json"
    assert s.wrist_roll_offset_deg == -90.0 and isinstance(s.wrist_roll_offset_deg, float)
    assert s.distractors == 2 and type(s.distractors) is int
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.task = "PushCube-v0"  # type: ignore[misc]


def test_json_round_trip_and_kwargs():
    s = EnvSettings(task="push", obs_type="state", servo_model="sts3215", dynamics="d.json")
    assert EnvSettings.from_json(s.to_json()) == s
    assert EnvSettings.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    assert EnvSettings.from_kwargs(**s.to_kwargs()) == s
    assert s.changed() == {"obs_type": "state", "servo_model": "sts3215", "dynamics": "d.json"}
    assert s.replace(distractors=1).distractors == 1


def test_unknown_keywords_are_refused_with_the_list_of_known_ones():
    with pytest.raises(
        TypeError, match=r"unknown gym_soarm environment keyword.*'dynamic'"
    ) as info:
        EnvSettings.from_kwargs(dynamic="x.json")
    assert all(name in str(info.value) for name in NAMES)
    with pytest.raises(ValueError, match=r"format must be 'gym_soarm.env_settings/1'"):
        EnvSettings.from_dict({"format": "other/1"})


BAD_VALUES = [
    ("task", "FlyCube-v0", ValueError, "task must be one of"),
    ("task", 3, TypeError, "task must be a task name"),
    ("obs_type", "image", ValueError, "obs_type must be one of"),
    ("camera_config", "left", ValueError, "camera_config must be one of"),
    ("camera_config", 3, TypeError, "camera_config must be one of"),
    ("observation_height", 8, ValueError, "observation_height must be from 16 to 2048"),
    ("observation_width", 64.0, TypeError, "observation_width must be an int"),
    ("render_mode", "window", ValueError, "render_mode must be one of 'human', 'rgb_array'"),
    ("render_camera", "top", ValueError, "render_camera must be one of"),
    ("render_quality", "ultra", ValueError, "render_quality must be one of 'fast', 'high'"),
    ("reward_type", "shaped", ValueError, "reward_type must be one of 'dense', 'sparse'"),
    ("units", "degrees", ValueError, "units must be one of"),
    ("wrist_roll_offset_deg", "90", TypeError, "wrist_roll_offset_deg must be a real number"),
    ("wrist_roll_offset_deg", 10.0, ValueError, "applies to LeRobot's units"),
    ("image_modalities", "rgb", TypeError, "image_modalities must be a tuple"),
    ("image_modalities", ("rgb", "normals"), ValueError, "unknown \\['normals'\\]"),
    ("visual_randomization", "medium", ValueError, "visual_randomization must be one of"),
    ("physics_randomization", True, TypeError, "physics_randomization must be one of"),
    ("servo_model", "sts3032", ValueError, "servo_model must be one of 'ideal', 'sts3215'"),
    ("object_placement", "ring", ValueError, "object_placement must be one of"),
    ("distractors", 5, ValueError, "distractors must be an int from 0 to 4"),
    ("distractors", 1.0, TypeError, "distractors must be an int"),
    ("control_mode", "torque", ValueError, "control_mode must be one of"),
    ("calibration", 3, TypeError, "calibration must be the path of a LeRobot calibration JSON"),
    ("dynamics", "", TypeError, "dynamics must be the path of a gym_soarm.dynamics/1 JSON"),
    ("normalize_actions", 1, TypeError, "normalize_actions must be True or False"),
    ("control_hz", 33, ValueError, "Rates that work: 1, 2, 3"),
    ("control_hz", "30", TypeError, "control_hz must be a whole number"),
]


def test_every_field_has_a_bad_value_case():
    assert {case[0] for case in BAD_VALUES} == set(NAMES)


@pytest.mark.parametrize(("name", "value", "error", "match"), BAD_VALUES)
def test_bad_values_are_refused(name, value, error, match):
    with pytest.raises(error, match=match):
        EnvSettings.from_kwargs(**{name: value})
    if error is TypeError:  # every bad argument is also a ValueError, as the env documents
        with pytest.raises(ValueError, match=match):
            EnvSettings.from_kwargs(**{name: value})


def test_a_placement_the_task_does_not_have_is_refused():
    with pytest.raises(ValueError, match=r"object_placement must be one of .* for ReachTarget"):
        EnvSettings(task="ReachTarget-v0", object_placement="grid")


# --- the environment --------------------------------------------------------------------------
def test_the_env_keeps_its_settings():
    env = gym.make("gym_soarm/LiftCube-v0", servo_model="sts3215", distractors=1, **STATE)
    try:
        expected = EnvSettings(task="LiftCube-v0", servo_model="sts3215", distractors=1, **STATE)
        assert env.unwrapped.settings == expected
    finally:
        env.close()


def test_gym_make_takes_a_settings_object_and_gives_the_same_episode():
    kwargs = {"servo_model": "sts3215", "physics_randomization": "light", **STATE}
    by_keywords = gym.make("gym_soarm/LiftCube-v0", **kwargs)
    settings = EnvSettings(task="LiftCube-v0", **kwargs)
    by_settings = gym.make("gym_soarm/LiftCube-v0", settings=settings)
    try:
        assert by_settings.unwrapped.settings is settings
        obs_a, _ = by_keywords.reset(seed=3)
        obs_b, _ = by_settings.reset(seed=3)
        action = by_keywords.action_space.sample()
        for _ in range(5):
            step_a = by_keywords.step(action)
            step_b = by_settings.step(action)
        for key in obs_a:
            np.testing.assert_array_equal(obs_a[key], obs_b[key])
            np.testing.assert_array_equal(step_a[0][key], step_b[0][key])
    finally:
        by_keywords.close()
        by_settings.close()


def test_settings_and_keywords_together_are_refused():
    settings = EnvSettings(task="LiftCube-v0", **STATE)
    with pytest.raises(TypeError, match=r"either settings or keywords.*servo_model"):
        gym.make("gym_soarm/LiftCube-v0", settings=settings, servo_model="sts3215")
    with pytest.raises(TypeError, match=r"either settings or keywords.*task"):
        gym.make("gym_soarm/PushCube-v0", settings=settings)
    with pytest.raises(TypeError, match=r"settings must be a gym_soarm.envs.settings.EnvSettings"):
        gym.make("gym_soarm/LiftCube-v0", settings={"obs_type": "state"})


def test_merge_keywords_checks_the_whole():
    base = recipe("ppo", "ReachTarget-v0")["env"]
    merged = merge_keywords(base, "ReachTarget-v0", {"dynamics": "d.json"})
    assert merged == {**base, "dynamics": "d.json"}
    with pytest.raises(ValueError, match="servo_model must be one of"):
        merge_keywords(base, "ReachTarget-v0", {"servo_model": "x"})


# --- every program's flags --------------------------------------------------------------------
def _calibration(tmp_path: Path) -> str:
    content = {
        name: {
            "id": i + 1,
            "drive_mode": 0,
            "homing_offset": 0,
            "range_min": HOMING_TICKS - 1000,
            "range_max": HOMING_TICKS + 1000,
        }
        for i, name in enumerate(constants.JOINT_NAMES)
    }
    path = tmp_path / "arm.json"
    path.write_text(json.dumps(content))
    return str(path)


def samples(tmp_path: Path) -> dict[str, tuple[list[str], object]]:
    """Per field: flags that set a value other than any program's default, and the value
    the settings should then hold."""
    return {
        "task": (["--task", "lift"], "LiftCube-v0"),
        "obs_type": (["--obs-type", "state"], "state"),
        "camera_config": (["--camera-config", "all"], constants.CAMERA_CONFIGS["all"]),
        "observation_height": (["--observation-height", "96"], 96),
        "observation_width": (["--observation-width", "128"], 128),
        "render_mode": (["--render-mode", "rgb_array"], "rgb_array"),
        "render_camera": (["--render-camera", "wrist_camera"], "wrist_camera"),
        "render_quality": (["--render-quality", "high"], "high"),
        "reward_type": (["--reward-type", "sparse"], "sparse"),
        "units": (["--units", "lerobot_range"], "lerobot_range"),
        "wrist_roll_offset_deg": (["--units", "lerobot", "--wrist-roll-offset-deg", "-90"], -90.0),
        "image_modalities": (["--image-modalities", "depth,rgb"], ("rgb", "depth")),
        "visual_randomization": (["--visual-randomization", "light"], "light"),
        "physics_randomization": (["--physics-randomization", "heavy"], "heavy"),
        "servo_model": (["--servo-model", "sts3215"], "sts3215"),
        "object_placement": (["--object-placement", "uniform"], "uniform"),
        "distractors": (["--distractors", "2"], 2),
        "control_mode": (["--control-mode", "ee_delta"], "ee_delta"),
        "calibration": (["--units", "lerobot", "--calibration", _calibration(tmp_path)], None),
        "dynamics": (["--dynamics", "fitted.json"], "fitted.json"),
        "normalize_actions": (["--normalize-actions"], True),
        "control_hz": (["--control-hz", "30"], 30),
    }


def _fake_dataset() -> ReplayDataset:
    frames = np.zeros((3, 6))
    return ReplayDataset(Path("."), 50, "gym_soarm", "radians", {0: (frames, frames)})


def _replay(args: argparse.Namespace) -> EnvSettings:
    kw = dataset_scene_keywords(args)
    return replay_settings(
        _fake_dataset(),
        kw["task"],
        kw["units"],
        kw["calibration"],
        kw["wrist_roll_offset_deg"],
        kw["settings"],
    )


def _sysid(args: argparse.Namespace) -> EnvSettings:
    return replay_settings(
        _fake_dataset(),
        args.task,
        args.units,
        args.calibration,
        args.wrist_roll_offset_deg,
        settings_given(args),
        SYSID_SETTINGS,
    )


def _expert(args: argparse.Namespace) -> EnvSettings:
    settings = expert_cli.env_settings(args, SelectedTask("tasks", 0, "LiftCube-v0", {}))
    assert expert_cli.env_kwargs(settings) == {
        k: v for k, v in settings.to_kwargs().items() if k not in ("task", "obs_type")
    }
    return settings


def _train(args: argparse.Namespace) -> EnvSettings:
    base = recipe(args.algo, args.task)["env"]
    return EnvSettings(
        task=args.task, **merge_keywords(base, args.task, train_cli.env_changes(args))
    )


def _evaluate(args: argparse.Namespace) -> EnvSettings:
    return EnvSettings(task="LiftCube-v0", **evaluate_cli.env_kwargs(args, {}, "LiftCube-v0"))


def _bench(args: argparse.Namespace) -> EnvSettings:
    config = BenchConfig.parse("state", args.task, args.control_mode, bench_cli.env_changes(args))
    return EnvSettings(task=config.task, **config.env_kwargs())


# program: (parser, argv every run needs, the settings the program builds from its args,
# fields it sets itself or does not take)
Program = tuple[Callable[[], argparse.ArgumentParser], list[str], Callable, tuple[str, ...]]
PROGRAMS: dict[str, Program] = {
    "record": (
        record_cli.build_parser,
        [],
        record_cli.env_settings,
        record_cli.RECORD_EXCLUDES,
    ),
    "teleop": (teleop_cli.build_parser, [], teleop_cli.env_settings, teleop_cli.TELEOP_EXCLUDES),
    "replay": (
        replay_cli.build_parser,
        ["--root", "x"],
        _replay,
        # the replay's state observations and absolute targets
        (
            "obs_type",
            "camera_config",
            "observation_height",
            "observation_width",
            "render_mode",
            "render_camera",
            "render_quality",
            "reward_type",
            "image_modalities",
            "control_mode",
            "normalize_actions",
        ),
    ),
    "sysid": (
        sysid_cli.build_parser,
        ["--root", "x", "--out", "x.json"],
        _sysid,
        (
            "obs_type",
            "camera_config",
            "observation_height",
            "observation_width",
            "render_mode",
            "render_camera",
            "render_quality",
            "reward_type",
            "image_modalities",
            "control_mode",
            "normalize_actions",
            "visual_randomization",  # a fit needs one model
            "physics_randomization",
            "dynamics",  # what is fitted
            "control_hz",  # a fit steps at the model's own rate
        ),
    ),
    "expert": (expert_cli.build_parser, [], _expert, expert_cli.EXPERT_EXCLUDES),
    "train": (
        train_cli.build_parser,
        ["--algo", "ppo", "--task", "LiftCube-v0", "--out", "x"],
        _train,
        train_cli.TRAIN_EXCLUDES,
    ),
    "evaluate": (
        evaluate_cli.build_parser,
        ["--policy", "expert"],
        _evaluate,
        tuple(n for n in NAMES if n not in evaluate_cli.EVALUATE_SETTINGS),
    ),
    "bench": (
        bench_cli.build_parser,
        [],
        _bench,
        tuple(n for n in bench_cli.BENCH_EXCLUDES if n not in ("task", "control_mode")),
    ),
}
CASES = [(p, f) for p in PROGRAMS for f in NAMES if f not in PROGRAMS[p][3]]


def test_every_program_takes_every_field_it_does_not_set_itself():
    for name, (parser, _, _, excluded) in PROGRAMS.items():
        assert set(excluded) <= set(NAMES), name
        flags = {a.dest for a in parser()._actions}
        for field in NAMES:
            if field not in excluded:
                assert field in flags, f"{name} has no flag for {field}"


def test_the_programs_take_dynamics_render_quality_and_variation():
    """What was missing before the flags were generated."""
    wanted = {
        "expert": ["dynamics"],
        "train": ["dynamics"],
        "evaluate": ["dynamics"],
        "bench": ["dynamics"],
        "record": ["render_quality"],
        "teleop": ["visual_randomization", "physics_randomization", "servo_model", "distractors"],
    }
    for program, fields in wanted.items():
        assert all((program, f) in CASES for f in fields), program


@pytest.mark.parametrize(("program", "field"), CASES, ids=[f"{p}-{f}" for p, f in CASES])
def test_a_flag_lands_in_the_settings_the_program_builds(program, field, tmp_path):
    parser, required, build, _ = PROGRAMS[program]
    argv, expected = samples(tmp_path)[field]
    if field == "calibration":
        expected = argv[-1]
    if field == "object_placement" and program in ("replay", "sysid"):
        argv = [*argv, "--task", "lift"]  # the replay's own scene has one placement
    args = parser().parse_args([*required, *argv])
    settings = build(args)
    assert isinstance(settings, EnvSettings)
    assert getattr(settings, field) == expected
    if field == "normalize_actions" and program != "train":  # the recipe's is True
        assert not build(parser().parse_args(required)).normalize_actions


def test_bad_flag_values_are_usage_errors(capsys):
    parser = record_cli.build_parser()
    for argv, message in (
        (["--distractors", "7"], "distractors must be an int from 0 to 4"),
        (["--servo-model", "sts3032"], "invalid choice: 'sts3032'"),
        (["--wrist-roll-offset-deg", "400"], "between -180 and 180 degrees"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            parser.parse_args(argv)
        assert exit_info.value.code == 2
        assert message in capsys.readouterr().err


def test_the_recorder_refuses_a_combination_with_its_reason(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        record_cli.main(
            ["--root", str(tmp_path / "d"), "--units", "radians", "--wrist-roll-offset-deg", "10"]
        )
    assert exit_info.value.code == 2
    assert "applies to LeRobot's units" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_the_generated_flags_are_recorded_in_the_namespace():
    args = record_cli.build_parser().parse_args([])
    assert set(getattr(args, SETTINGS_DEST)) == set(NAMES) - set(record_cli.RECORD_EXCLUDES)
    assert settings_flag("wrist_roll_offset_deg") == "--wrist-roll-offset-deg"


# --- the docs ---------------------------------------------------------------------------------
def test_docs_keywords_md_is_current():
    page = (ROOT / KEYWORDS_PATH).read_text(encoding="utf-8")
    assert page == keywords_page(), "run python -m gym_soarm.cli.settings_table"
    for name in NAMES:
        assert f"| `{name}` |" in keyword_table()


def test_the_table_program_writes_and_checks(tmp_path):
    out = tmp_path / "keywords.md"
    assert settings_table.main(["--out", str(out), "--check"]) == 1
    assert settings_table.main(["--out", str(out)]) == 0
    assert settings_table.main(["--out", str(out), "--check"]) == 0
    assert out.read_text(encoding="utf-8") == keywords_page()


def test_the_settings_page_snippets_run():
    text = (ROOT / "docs" / "settings.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert blocks
    for block in blocks:
        scope: dict = {}
        exec(compile(block, "docs/settings.md", "exec"), scope)
        scope["env"].close()


def test_the_vector_env_keeps_the_settings_of_its_environments():
    envs = gym.make_vec(
        "gym_soarm/LiftCube-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        num_processes=1,
        obs_type="state",
        servo_model="sts3215",
    )
    try:
        assert envs.unwrapped.settings == EnvSettings(
            task="LiftCube-v0", obs_type="state", servo_model="sts3215"
        )
    finally:
        envs.close()


def test_the_recorder_refuses_settings_a_dataset_cannot_hold(tmp_path):
    lift = EnvSettings(task="LiftCube-v0", normalize_actions=True)
    with pytest.raises(ValueError, match=r"cannot record with .*normalize_actions"):
        record(tmp_path / "a", task="LiftCube-v0", settings=lift)
    with pytest.raises(ValueError, match=r"either settings or the keywords \['units'\]"):
        record(tmp_path / "b", task="LiftCube-v0", units="radians", settings=EnvSettings())
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
