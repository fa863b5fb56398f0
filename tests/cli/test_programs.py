"""One way into a program: ``python -m gym_soarm <program>``, the plain ``python -m
gym_soarm.<program>`` modules, the earlier module names, and no source run from a string.

Each program is ``main`` of ``gym_soarm/cli/<program>.py``; ``python -m gym_soarm``
dispatches to every console script's, ``gym_soarm/train.py`` (and ``evaluate``,
``replay``, ``sysid``) only gives it its ``-m`` name, and ``gym_soarm.compat`` answers
the modules' earlier names with the new module itself. The benchmark's ceiling is a
real file, run by its path.
"""

from __future__ import annotations

import ast
import importlib
import itertools
import json
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from paths import ROOT

from gym_soarm.bench import ceiling
from gym_soarm.cli import programs

PACKAGE = ROOT / "gym_soarm"


def _python(*argv: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], cwd=cwd, capture_output=True, text=True, timeout=300
    )


# --- python -m gym_soarm <program> ------------------------------------------------------
@pytest.mark.subprocess
@pytest.mark.parametrize(
    "argv, usage",
    [
        (["-m", "gym_soarm", "train", "--help"], "usage: python -m gym_soarm train "),
        (["-m", "gym_soarm.train", "--help"], "usage: python -m gym_soarm.train "),
    ],
    ids=["python -m gym_soarm train", "python -m gym_soarm.train"],
)
def test_both_spellings_run_the_program(argv, usage, tmp_path):
    done = _python(*argv, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith(usage) and "--algo" in done.stdout, done.stdout[:500]
    assert not list(tmp_path.iterdir())


@pytest.mark.subprocess
def test_an_unknown_program_is_refused_with_the_list(tmp_path):
    done = _python("-m", "gym_soarm", "trian", cwd=tmp_path)
    assert done.returncode == 2
    error = done.stderr.strip().splitlines()[-1]
    assert "unknown program 'trian'" in error
    assert all(name in error for name in programs.PROGRAMS), error


@pytest.mark.parametrize("argv, code", [([], 2), (["--help"], 0), (["-h"], 0)])
def test_the_dispatcher_lists_every_program(argv, code, capsys):
    assert programs.main(argv) == code
    out = capsys.readouterr()
    listing = out.out if code == 0 else out.err
    assert listing.startswith("usage: python -m gym_soarm <program>")
    for name, program in programs.PROGRAMS.items():
        assert f"  {name}" in listing and program.summary in listing


@pytest.mark.parametrize("name", list(programs.PROGRAMS))
def test_every_program_takes_its_help_from_the_dispatcher(name, capsys):
    with pytest.raises(SystemExit) as done:
        programs.main([name, "--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m gym_soarm {name} ")
    # Called by itself again, the program names its own -m spelling.
    module = importlib.import_module(programs.PROGRAMS[name].module)
    with pytest.raises(SystemExit):
        module.main(["--help"])
    assert capsys.readouterr().out.startswith(f"usage: python -m gym_soarm.{name} ")


def test_the_dispatcher_passes_a_program_s_exit_code_on(capsys):
    with pytest.raises(SystemExit) as done:
        programs.main(["bench", "--configs", "no_such_config"])
    assert done.value.code == 2
    assert "usage: python -m gym_soarm bench" in capsys.readouterr().err


# --- python -m gym_soarm.<program>: plain modules ---------------------------------------
@pytest.mark.parametrize("name", ["train", "evaluate", "replay", "sysid"])
def test_importing_a_program_module_runs_nothing(name, capsys):
    module = importlib.import_module(f"gym_soarm.{name}")
    assert module.main is importlib.import_module(f"gym_soarm.cli.{name}").main
    assert module.__file__ == str(PACKAGE / f"{name}.py")
    assert capsys.readouterr() == ("", "")


# --- earlier module names ---------------------------------------------------------------
@pytest.fixture
def forget_old_names():
    """Import the old names afresh (the import system keeps a module it handed out)."""
    from gym_soarm.compat import FOLDED, MOVED

    def forget() -> None:
        for name in [*MOVED, *FOLDED]:
            sys.modules.pop(name, None)

    forget()
    yield
    forget()


@pytest.mark.parametrize(
    "old, new",
    [
        ("gym_soarm.env", "gym_soarm.envs.env"),
        ("gym_soarm.data.record", "gym_soarm.record.record"),
        ("gym_soarm.tools.docs", "gym_soarm.cli.docs"),
        ("gym_soarm.tools.episode_hashes", "gym_soarm.cli.episode_hashes"),
        ("gym_soarm.tools.bench", "gym_soarm.bench.bench"),
    ],
)
def test_an_old_module_name_warns_and_gives_the_new_module(old, new, forget_old_names):
    with pytest.warns(DeprecationWarning) as caught:
        module = importlib.import_module(old)
    moved = [w for w in caught if f"{old} moved to {new}; import it from there" in str(w.message)]
    assert len(moved) == 1, [str(w.message) for w in caught]
    assert moved[0].filename == __file__  # the importer's line, not the import machinery's
    assert module is importlib.import_module(new)
    assert module.__name__ == new and module.__spec__.name == new  # untouched


def test_from_an_old_package_import_a_moved_module(forget_old_names):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from gym_soarm.tools import docs  # the folded folder answers as a package

    assert docs is importlib.import_module("gym_soarm.cli.docs")


def test_a_pickle_that_names_an_old_module_loads(forget_old_names):
    from gym_soarm.envs.settings import EnvSettings

    settings = EnvSettings.from_kwargs(task="LiftCube-v0")
    data = pickle.dumps(settings, protocol=0)
    assert b"gym_soarm.envs.settings\n" in data
    old = data.replace(b"gym_soarm.envs.settings\n", b"gym_soarm.settings\n")
    with pytest.warns(DeprecationWarning, match="gym_soarm.settings moved"):
        assert pickle.loads(old) == settings


@pytest.mark.subprocess
def test_an_old_program_name_still_runs(tmp_path):
    done = _python("-m", "gym_soarm.tools.docs", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("| id | task |")


# --- no source run from a string --------------------------------------------------------
def _calls_of_source(path: Path) -> list[str]:
    """Where ``path`` runs source it holds as data: ``exec``/``eval``/``compile`` of a
    string, or ``[sys.executable, "-c", ...]``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        called = node.func if isinstance(node, ast.Call) else None
        if isinstance(called, ast.Name) and called.id in ("exec", "eval", "compile"):
            found.append(f"{path.name}:{node.lineno}: {called.id}()")
        if isinstance(node, ast.List | ast.Tuple):
            for first, second in itertools.pairwise(node.elts):
                if (
                    isinstance(first, ast.Attribute)
                    and first.attr == "executable"
                    and isinstance(second, ast.Constant)
                    and second.value == "-c"
                ):
                    found.append(f"{path.name}:{node.lineno}: python -c")
    return found


def test_no_module_runs_source_from_a_string():
    found = [hit for path in sorted(PACKAGE.rglob("*.py")) for hit in _calls_of_source(path)]
    assert not found, f"run a real module (python -m, or a file by its path): {found}"


def test_the_checker_sees_exec_eval_and_python_c(tmp_path):
    path = tmp_path / "a.py"
    path.write_text(
        "import re, sys\nexec('x = 1')\ncompile('1', 'f', 'eval')\nre.compile('a')\n"
        "spec.compile()\nargs = [sys.executable, '-c', 'print(1)']\n"
    )
    assert [hit.split(": ")[1] for hit in _calls_of_source(path)] == [
        "exec()",
        "compile()",
        "python -c",
    ]


# --- the benchmark's ceiling: a real program, run by its path ---------------------------
def test_the_ceiling_imports_nothing_of_gym_soarm():
    tree = ast.parse(ceiling.PATH.read_text())
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [n for n in names if n.startswith("gym_soarm")], names
    assert ceiling.PATH == PACKAGE / "bench" / "ceiling.py"


@pytest.mark.subprocess
def test_the_ceiling_runs_by_its_path(tmp_path):
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint name='j'/><geom size='.1'/></body></worldbody>"
        "<actuator><position joint='j' ctrlrange='-1 1'/></actuator></mujoco>"
    )
    path = tmp_path / "m.mjb"
    mujoco.mj_saveModel(model, str(path), None)
    state = {"qpos": [0.0], "qvel": [0.0], "ctrl": [0.0]}
    job = {"model": str(path), "state": state, "substeps": 2, "episode_steps": 5, "seed": 0}
    done = subprocess.run(
        [sys.executable, str(ceiling.PATH), json.dumps({**job, "mode": "step"})],
        input="run 0.01\ndone\n",
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    tags = [line.split(" ", 1)[0] for line in done.stdout.splitlines()]
    assert tags == ["READY", "SLICE", "RESULT"]
    slice_ = json.loads(done.stdout.splitlines()[1].split(" ", 1)[1])
    assert slice_["steps"] >= 1 and slice_["seconds"] > 0
    assert "gym_soarm" not in done.stderr
