"""What a new user meets first, from the README and the docs: the extras install nothing
harmful, the documented commands leave the checkout clean, the README and the LeRobot
page record to different folders, every program takes a task the same way and refuses
bad input with argparse's usage code, an unknown ``gym.make`` keyword names the fix, and
the tabletop preset's observation bounds are the follower's."""

from __future__ import annotations

import importlib
import importlib.util
import multiprocessing
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from doc_files import documentation_files
from packaging.requirements import Requirement

import gym_soarm
from gym_soarm.bench import bench
from gym_soarm.real.units import radians_to_lerobot
from gym_soarm.tasks.registry import task_aliases
from gym_soarm.tasks.suites import resolve_selection

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SPELLINGS = ("lift", "LiftCube-v0", "gym_soarm/LiftCube-v0")
"""One task as a user may name it: its alias, its name and its gym id."""


def _git(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)


needs_git = pytest.mark.skipif(
    not (ROOT / ".git").exists() or _git("status").returncode != 0, reason="not a git checkout"
)


def _python(argv: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """Run ``python *argv`` in ``cwd`` as a user would, capturing its output."""
    return subprocess.run(
        [sys.executable, *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


def _tracked(path: str) -> list[str]:
    return _git("ls-files", "--", path).stdout.split()


def _ignored(path: str) -> bool:
    return _git("check-ignore", "-q", "--no-index", path).returncode == 0


# --- 1. the lerobot extra --------------------------------------------------------------
def test_the_lerobot_extra_installs_nothing_below_python_3_12():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = [Requirement(r) for r in extras["optional-dependencies"]["lerobot"]]
    assert requirements and all(r.marker is not None for r in requirements)
    for requirement in requirements:
        assert not requirement.marker.evaluate({"python_version": "3.11"})
        assert requirement.marker.evaluate({"python_version": "3.12"})


@pytest.mark.subprocess
def test_without_lerobot_its_module_says_what_to_install_and_on_which_python():
    if importlib.util.find_spec("lerobot") is not None:
        pytest.skip("LeRobot is installed")
    done = subprocess.run(
        [sys.executable, "-c", "import gym_soarm.lerobot"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    message = done.stderr.strip().splitlines()[-1]
    assert message.startswith("ImportError: gym_soarm.lerobot needs LeRobot"), message
    assert "Python >= 3.12" in message and "gym-soarm[lerobot]" in message
    if sys.version_info < (3, 12):
        assert "installs nothing" in message


# --- 2. the documented commands leave the checkout clean -------------------------------
@pytest.mark.subprocess
@needs_git
def test_the_readme_s_commands_write_only_where_git_does_not_look(tmp_path):
    # The README's bench command and its example, shortened, run where a user runs them.
    commands = [
        ["-m", "gym_soarm.bench", "--configs", "state", "--seconds", "0.2"],
        [str(EXAMPLES / "example.py"), "--task", "lift", "--steps", "3"],
    ]
    commands[0] += ["--repeats", "1"]
    commands[1] += ["--height", "48", "--width", "64", "--viewer", "off"]
    for command in commands:
        done = _python(command, tmp_path, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    assert bench.DEFAULT_JSON in written and any(p.endswith(".mp4") for p in written), written
    for path in written:
        assert _ignored(path) and not _tracked(path), f"{path} would show in git status"


OUTPUT_FLAGS = ("--root", "--out", "--json", "--plot", "--output-dir")


def documented_outputs() -> list[str]:
    """Every relative path a documented gym_soarm command writes (its output flags)."""
    paths = []
    for page in documentation_files():
        for language, block in re.findall(r"^```(\w*)\n(.*?)^```", page.read_text(), re.S | re.M):
            if language not in ("bash", "sh", "console", ""):
                continue
            for line in block.replace("\\\n", " ").splitlines():
                if not re.search(r"python (-m gym_soarm|examples/)", line):
                    continue
                command = line.split(" #")[0]
                for flag, value in re.findall(r"(--[\w-]+)[ =]['\"]?([^\s'\"]+)", command):
                    if flag in OUTPUT_FLAGS and not value.startswith(("~", "/", "$", "<")):
                        paths.append(value)
    return sorted(set(paths))


@pytest.mark.subprocess
@needs_git
def test_no_documented_command_writes_a_tracked_file():
    outputs = documented_outputs()
    assert "datasets/lift_demos" in outputs and "runs/bc_lift" in outputs, outputs
    assert not [path for path in outputs if _tracked(path)]
    # Where the programs write by default, and the README's folders, git ignores.
    for path in (bench.DEFAULT_JSON, "videos/front_camera_1.mp4", "runs/x", "datasets/x"):
        assert _ignored(path), path
    root_json = [path for path in _tracked("*.json") if "/" not in path]
    assert not root_json, f"results at the repository's root: {root_json}"


def test_the_readme_and_the_lerobot_page_record_into_different_folders():
    def roots(page: str) -> set[str]:
        return set(re.findall(r"--root (\S+)", (ROOT / page).read_text()))

    readme, lerobot = roots("README.md"), roots("docs/lerobot.md")
    assert readme and lerobot and not readme & lerobot


# --- 4. one task argument in every program ---------------------------------------------
def _example(name: str) -> Any:
    sys.path.insert(0, str(EXAMPLES))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(EXAMPLES))


def _cli(name: str) -> Any:
    return importlib.import_module(f"gym_soarm.cli.{name}")


PROGRAMS: dict[str, tuple[Callable[[], Any], list[str]]] = {
    # program: (its module, the other arguments it needs)
    "examples/example.py": (lambda: _example("example"), []),
    "examples/vector_env.py": (lambda: _example("vector_env"), []),
    "expert": (lambda: _cli("expert"), []),
    "record": (lambda: _cli("record"), []),
    "teleop": (lambda: _cli("teleop"), []),
    "replay": (lambda: _cli("replay"), ["--root", "data"]),
    "sysid": (lambda: _cli("sysid"), ["--root", "data", "--out", "arm.json"]),
    "bench": (lambda: _cli("bench"), []),
    "evaluate": (lambda: _cli("evaluate"), ["--policy", "expert"]),
    "train": (lambda: _cli("train"), ["--algo", "bc", "--out", "runs/x"]),
}


def _parse(module: Any, argv: list[str]) -> Any:
    parser = module.build_parser() if hasattr(module, "build_parser") else None
    return parser.parse_args(argv) if parser else module.parse_args(argv)


@pytest.mark.parametrize("program", list(PROGRAMS))
def test_every_program_takes_a_task_by_name_alias_or_id(program, capsys):
    load, needed = PROGRAMS[program]
    module = load()
    for spelling in SPELLINGS:
        task = _parse(module, [*needed, "--task", spelling]).task
        for selection in task if isinstance(task, list) else [task]:
            assert [s.task for s in resolve_selection(selection)] == ["LiftCube-v0"], spelling
    with pytest.raises(SystemExit) as refused:
        module.main([*needed, "--task", "lfit"])
    assert refused.value.code == 2
    error = capsys.readouterr().err
    assert "--task" in error and "'lfit'" in error and "LiftCube-v0" in error
    assert all(alias in error for alias in task_aliases()), error


# --- 5. an unknown gym.make keyword -----------------------------------------------------
MAKERS: dict[str, Callable[..., Any]] = {
    "gym.make": lambda **kw: gym.make("gym_soarm/LiftCube-v0", **kw),
    "the preset": lambda **kw: gym.make(gym_soarm.TABLETOP_ID, **kw),
    "batched": lambda **kw: gym.make_vec(
        "gym_soarm/LiftCube-v0", 2, "vector_entry_point", obs_type="state", **kw
    ),
    "processes": lambda **kw: gym.make_vec(
        "gym_soarm/LiftCube-v0", 2, "vector_entry_point", vector_env="processes", **kw
    ),
}


@pytest.mark.parametrize("maker", list(MAKERS))
def test_an_unknown_keyword_names_the_closest_ones_and_the_keyword_page(maker, tmp_path):
    children = set(multiprocessing.active_children())
    # Another keyword is wrong too (a file that does not exist): the unknown one is named
    # first, before anything is read, built or started.
    with pytest.raises(ValueError, match=r"\['camera'\]\. Did you mean camera_config") as error:
        MAKERS[maker](camera="front", dynamics=str(tmp_path / "missing.json"))
    assert isinstance(error.value, TypeError)  # also what Python says of a bad keyword
    assert "docs/keywords.md" in str(error.value)
    assert set(multiprocessing.active_children()) == children


# --- 8. refused input: argparse's usage code in every program --------------------------
@pytest.mark.subprocess
@pytest.mark.parametrize(
    "argv",
    [
        ["-m", "gym_soarm.train", "--algo", "bc", "--task", "lift", "--steps", "5", "--out", "x"],
        ["-m", "gym_soarm.train", "--algo", "bc", "--task", "lift", "--init", "x", "--out", "x"],
        ["-m", "gym_soarm.evaluate", "--policy", "no_such_folder", "--task", "lift"],
        ["-m", "gym_soarm.record", "--task", "lift", "--episodes", "0"],
        ["-m", "gym_soarm.expert", "--task", "lift", "--seeds", "0"],
        ["-m", "gym_soarm.teleop", "--max-steps", "0"],
        ["-m", "gym_soarm.replay", "--root", "no_such_folder"],
        ["-m", "gym_soarm.sysid", "--root", "no_such_folder", "--out", "arm.json"],
        ["-m", "gym_soarm.bench", "--configs", "no_such_config"],
        [str(EXAMPLES / "example.py"), "--episodes", "0"],
        [str(EXAMPLES / "vector_env.py"), "--num-envs", "0"],
    ],
    ids=lambda argv: " ".join(Path(a).name for a in argv),
)
def test_refused_input_exits_with_argparse_s_usage_code(argv, tmp_path):
    done = _python(argv, tmp_path)
    assert done.returncode == 2, done.stderr
    assert "error:" in done.stderr and not list(tmp_path.iterdir())


@pytest.mark.subprocess
@pytest.mark.parametrize("flag, value", [("--init", "runs/x"), ("--vec-env", "dummy")])
def test_an_imitation_run_says_why_it_refuses_a_ppo_flag(flag, value, tmp_path):
    argv = ["--algo", "bc", "--task", "lift", "--out", "runs/x", flag, value]
    done = _python(["-m", "gym_soarm.train", *argv], tmp_path)
    assert done.returncode == 2
    error = done.stderr.strip().splitlines()[-1]
    assert f"{flag} does not apply to --algo bc: " in error and f"Drop {flag}." in error
    assert error.count("(") == error.count(")") <= 1, error  # no reason inside a reason
    if flag == "--init":
        assert "--algo ppo --init DIR" in error


# --- 9. the tabletop preset's observation bounds ---------------------------------------
def test_the_tabletop_preset_bounds_agent_pos_by_the_joints_ranges():
    env = gym.make(gym_soarm.TABLETOP_ID, observation_height=48, observation_width=64)
    try:
        space = env.observation_space["agent_pos"]
        low, high = (radians_to_lerobot(r) for r in env.unwrapped.physics.joint_range())
        np.testing.assert_allclose(space.low, low, atol=1e-3)  # the joints' own ranges,
        np.testing.assert_allclose(space.high, high, atol=1e-3)  # in the follower's units
        assert (space.low[-1], space.high[-1]) == (0.0, 100.0)  # the gripper, as LeRobot's
        np.testing.assert_allclose(space.low, env.action_space.low, atol=1e-4)
        np.testing.assert_allclose(space.high, env.action_space.high, atol=1e-4)
        obs, _ = env.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(20):
            assert space.contains(obs["agent_pos"]), obs["agent_pos"]
            obs, *_ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
    finally:
        env.close()


# --- 11. messages a user reads ----------------------------------------------------------
@pytest.mark.subprocess
def test_one_episode_is_one_episode_and_the_control_rate_message_parses(tmp_path):
    argv = ["--policy", "expert", "--task", "reach", "--episodes", "1"]
    done = _python(["-m", "gym_soarm.evaluate", *argv], tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "ReachTarget-v0: success 100 % over 1 episode (seeds 1000-1000)" in done.stdout
    with pytest.raises(ValueError, match=r"must be a control rate whose period is a whole number"):
        gym.make("gym_soarm/ReachTarget-v0", obs_type="state", control_hz=7)
