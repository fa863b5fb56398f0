"""Task suites: selections of tasks, and multi-task datasets from the recorder."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pyarrow.parquet as pq
import pytest

from gym_soarm.cli import record as record_cli
from gym_soarm.record.record import record
from gym_soarm.tasks import BUILTIN_TASKS, get_task
from gym_soarm.tasks.suites import (
    EVAL_SEED,
    SUITE_NAMES,
    TASK_GROUP,
    get_suite,
    resolve_selection,
    selection_tasks,
    shared_state_names,
)

CORE = ("ReachTarget-v0", "LiftCube-v0", "PickAndPlaceCube-v0", "PushCube-v0")


def test_the_suites_hold_the_specified_tasks():
    assert SUITE_NAMES == (
        "soarm_core",
        "soarm_multi",
        "soarm_language",
        "soarm_robust",
        "soarm_all",
    )
    assert get_suite("soarm_core").tasks == CORE
    assert get_suite("soarm_robust").tasks == CORE
    assert dict(get_suite("soarm_robust").variation) == {
        "visual_randomization": "heavy",
        "physics_randomization": "light",
    }
    assert get_suite("soarm_language").tasks == ("PickColoredCube-v0",)
    # soarm_all covers every built-in task, each suite reported as its own group.
    selected = resolve_selection("soarm_all")
    assert set(selection_tasks("soarm_all")) == set(BUILTIN_TASKS)
    assert [item.group for item in selected if item.index == 0] == list(SUITE_NAMES[:-1])


def test_a_selection_groups_suites_and_single_tasks():
    selected = resolve_selection(" soarm_core , StackCube-v0,lift, stack")
    groups = [(item.group, item.index, item.task) for item in selected]
    assert groups == [
        ("soarm_core", 0, "ReachTarget-v0"),
        ("soarm_core", 1, "LiftCube-v0"),
        ("soarm_core", 2, "PickAndPlaceCube-v0"),
        ("soarm_core", 3, "PushCube-v0"),
        (TASK_GROUP, 0, "StackCube-v0"),
        (TASK_GROUP, 1, "LiftCube-v0"),
    ]
    assert resolve_selection("gym_soarm/LiftCube-v0")[0].task == "LiftCube-v0"
    assert selection_tasks("soarm_core,soarm_robust") == CORE


@pytest.mark.parametrize(
    ("selection", "error", "words"),
    [
        ("soarm_bogus", ValueError, ("soarm_core", "LiftCube-v0", "'soarm_bogus'")),
        ("LiftCube-v0,nope", ValueError, ("'nope'",)),
        (" , ", ValueError, ("at least one",)),
        (3, TypeError, ("comma list", "int")),
    ],
)
def test_a_bad_selection_says_what_is_expected(selection, error, words):
    with pytest.raises(error) as raised:
        resolve_selection(selection)
    for word in words:
        assert word in str(raised.value)


def test_the_protocol_seeds_give_the_same_episodes():
    """Episode k resets with EVAL_SEED + k: two runs of the protocol see the same scenes."""
    assert EVAL_SEED == 1000
    for task in CORE:
        env = gym.make(get_task(task).env_id, obs_type="environment_state_agent_pos")
        first = [env.reset(seed=EVAL_SEED + k)[0]["environment_state"] for k in range(3)]
        again = [env.reset(seed=EVAL_SEED + k)[0]["environment_state"] for k in range(3)]
        env.close()
        for a, b in zip(first, again, strict=True):
            np.testing.assert_array_equal(a, b)
        assert not np.array_equal(first[0], first[1])


def episode_tasks(root) -> list[str]:
    table = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    return [tasks[0] for tasks in table.column("tasks").to_pylist()]


def test_the_recorder_writes_a_suite_into_one_dataset(tmp_path):
    root = tmp_path / "core"
    summary = record(
        root,
        task="soarm_core",
        episodes=1,
        camera_config="front_only",
        size=(48, 64),
    )
    assert summary.tasks == CORE and summary.episodes == 4 and summary.successes == 4
    instructions = [get_task(task).instructions[0] for task in CORE]
    assert episode_tasks(root) == instructions
    tasks = pq.read_table(root / "meta" / "tasks.parquet").to_pydict()
    assert tasks["task"] == instructions and tasks["task_index"] == [0, 1, 2, 3]
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 4 and info["total_tasks"] == 4
    # Each frame's task index names its own episode's instruction.
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet").to_pydict()
    for episode, task_index in zip(data["episode_index"], data["task_index"], strict=True):
        assert task_index == episode


def test_a_task_recorded_in_a_selection_equals_its_own_recording(tmp_path):
    """Task i's attempt k resets with seed + k whatever else is recorded with it."""
    options = {"episodes": 2, "seed": 5, "camera_config": "front_only", "size": (48, 64)}
    record(tmp_path / "pair", task="ReachTarget-v0,LiftCube-v0", **options)
    record(tmp_path / "lift", task="LiftCube-v0", **options)
    pair = pq.read_table(tmp_path / "pair" / "data" / "chunk-000" / "file-000.parquet")
    lift = pq.read_table(tmp_path / "lift" / "data" / "chunk-000" / "file-000.parquet")
    episodes = np.asarray(pair.column("episode_index").to_pylist())
    for key in ("action", "observation.state", "next.reward"):
        ours = np.asarray(pair.column(key).to_pylist())[episodes >= 2]
        np.testing.assert_array_equal(ours, np.asarray(lift.column(key).to_pylist()))


def test_robust_suite_episodes_carry_their_randomisation(tmp_path):
    root = tmp_path / "robust"
    record(root, task="soarm_robust", episodes=1, camera_config="front_only", size=(48, 64))
    lines = [
        json.loads(line) for line in (root / "meta" / "variation.jsonl").read_text().splitlines()
    ]
    assert [line["task"] for line in lines] == list(CORE)
    assert [line["episode_index"] for line in lines] == [0, 1, 2, 3]
    assert all(line["visual_randomization"] == "heavy" for line in lines)
    assert all(line["physics_randomization"] == "light" for line in lines)


def test_a_stateless_multi_task_dataset_needs_one_state_layout(tmp_path):
    root = tmp_path / "refused"
    with pytest.raises(ValueError, match="one layout for every selected task") as raised:
        record(root, task="soarm_core", episodes=1, camera_config="none")
    assert "LiftCube-v0 (cube_x" in str(raised.value)
    # The same size is not enough: 13 values each, but a goal and a target mean other things.
    with pytest.raises(ValueError, match="they differ"):
        record(root, task="PickAndPlaceCube-v0,PushCube-v0", episodes=1, camera_config="none")
    assert not root.exists()
    # One task under two suites' settings shares its layout.
    lifts = [i for i in resolve_selection("LiftCube-v0,soarm_robust") if i.task == "LiftCube-v0"]
    assert len(lifts) == 2
    names = shared_state_names(tuple(lifts))
    assert names[0] == "cube_x"


def test_the_record_cli_takes_a_suite_and_refuses_an_unknown_one(tmp_path, capsys):
    root = tmp_path / "cli"
    code = record_cli.main(
        ["--task", "ReachTarget-v0,PushCube-v0", "--episodes", "1", "--camera-config",
         "front_only", "--size", "48x64", "--root", str(root), "--no-progress"]
    )  # fmt: skip
    assert code == 0
    assert episode_tasks(root) == [
        get_task("ReachTarget-v0").instructions[0],
        get_task("PushCube-v0").instructions[0],
    ]
    with pytest.raises(SystemExit) as raised:
        record_cli.main(["--task", "soarm_bogus", "--root", str(tmp_path / "x")])
    assert raised.value.code == 2
    assert "soarm_core" in capsys.readouterr().err


def test_the_expert_runs_on_the_protocol_of_a_suite(capsys):
    from gym_soarm.cli import expert as expert_cli
    from gym_soarm.expert import evaluate_protocol

    results = evaluate_protocol("ReachTarget-v0", 3)
    assert [r.seed for r in results] == [EVAL_SEED, EVAL_SEED + 1, EVAL_SEED + 2]
    assert all(r.success and r.options is None for r in results)
    expert_cli.main(["--task", "soarm_language", "ReachTarget-v0", "--protocol", "2"])
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["PickColoredCube-v0", "ReachTarget-v0"]
    assert all("2/2 = 100.0 % success" in line for line in lines)
    with pytest.raises(SystemExit):
        expert_cli.main(["--task", "soarm_nothing"])
