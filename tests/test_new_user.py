"""What a new user meets first: the extras install nothing harmful, the documented
commands leave the checkout clean, the README and the LeRobot page record to different
folders, and every gym id is listed."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from gym_soarm.bench import bench

ROOT = Path(__file__).resolve().parents[1]


def test_the_lerobot_extra_installs_nothing_below_python_3_12():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = [Requirement(r) for r in extras["optional-dependencies"]["lerobot"]]
    assert requirements and all(r.marker is not None for r in requirements)
    for requirement in requirements:
        assert not requirement.marker.evaluate({"python_version": "3.11"})
        assert requirement.marker.evaluate({"python_version": "3.12"})


def test_the_benchmark_writes_its_results_where_git_does_not_look():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    assert _ignored(bench.DEFAULT_JSON)
    tracked = subprocess.run(
        ["git", "ls-files", "--", "*.json"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    assert not [path for path in tracked if "/" not in path], "a JSON file at the root"


def _ignored(path: str) -> bool:
    done = subprocess.run(["git", "check-ignore", "-q", path], cwd=ROOT)
    return done.returncode == 0


def test_the_readme_and_the_lerobot_page_record_into_different_folders():
    def roots(page: str) -> set[str]:
        return set(re.findall(r"--root (\S+)", (ROOT / page).read_text()))

    readme, lerobot = roots("README.md"), roots("docs/lerobot.md")
    assert readme and lerobot and not readme & lerobot


def test_the_example_takes_a_task_by_name_alias_or_id(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    import example

    for spelling in ("lift", "LiftCube-v0", "gym_soarm/LiftCube-v0"):
        assert example.parse_args(["--task", spelling]).task == "LiftCube-v0"
    with pytest.raises(SystemExit) as refused:
        example.parse_args(["--task", "lfit"])
    assert refused.value.code == 2


def test_an_unknown_gym_make_keyword_names_the_closest_ones_and_the_keyword_page():
    import gymnasium as gym

    import gym_soarm  # noqa: F401

    with pytest.raises(ValueError, match=r"\['camera'\]\. Did you mean camera_config") as error:
        gym.make("gym_soarm/LiftCube-v0", camera="front")
    assert "docs/keywords.md" in str(error.value) and isinstance(error.value, TypeError)


@pytest.mark.parametrize(
    "argv",
    [
        ["gym_soarm.train", "--algo", "bc", "--task", "lift", "--steps", "5", "--out", "x"],
        ["gym_soarm.evaluate", "--task", "nope", "--episodes", "1"],
        ["gym_soarm.record", "--task", "nope", "--episodes", "1"],
        ["gym_soarm.expert", "--task", "nope"],
    ],
)
def test_refused_input_exits_with_argparse_s_usage_code(argv, tmp_path):
    import sys

    done = subprocess.run(
        [sys.executable, "-m", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2, done.stderr
    assert "error:" in done.stderr and not list(tmp_path.iterdir())


def test_the_tabletop_preset_bounds_agent_pos_by_the_joints_ranges():
    import gymnasium as gym
    import numpy as np

    import gym_soarm

    env = gym.make(gym_soarm.TABLETOP_ID, observation_height=48, observation_width=64)
    try:
        space = env.observation_space["agent_pos"]
        np.testing.assert_allclose(space.low, env.action_space.low, rtol=1e-6)
        np.testing.assert_allclose(space.high, env.action_space.high, rtol=1e-6)
        assert (space.low[-1], space.high[-1]) == (0.0, 100.0)  # the gripper, as the follower
        obs, _ = env.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(20):
            assert space.contains(obs["agent_pos"]), obs["agent_pos"]
            obs, *_ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
    finally:
        env.close()
