"""The package's shape: no import cycles, and every program has one home in gym_soarm.cli.

One rule for programs: each lives in ``gym_soarm/cli/<name>.py`` (its ``main``); the
console scripts point there, ``python -m gym_soarm <name>`` dispatches there, and
``python -m gym_soarm.<name>`` runs a plain module (``gym_soarm/<name>.py`` or a
package's ``__main__.py``) that only calls that ``main``. No other module holds a
``__main__`` block but the benchmark's ceiling, a program run by its path.

The import graph is read from the source with :mod:`ast`, so it sees every import, the
lazy ones inside functions included: ``import a.b`` and ``from a import b`` (``b`` a
submodule of ``a`` when there is such a file, else a name defined in ``a``), absolute
or relative. Two kinds of edge are left out: imports under ``if TYPE_CHECKING:``, which
never run, and the parent packages' ``__init__`` that importing a module also runs
(every submodule would otherwise be in a cycle with ``gym_soarm/__init__.py``, which
imports the environment).
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest
from doc_files import documentation_files

PACKAGE = Path(__file__).resolve().parents[1] / "gym_soarm"
PYPROJECT = PACKAGE.parent / "pyproject.toml"


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_modules(root: Path = PACKAGE) -> dict[str, Path]:
    """Every module of the package under ``root``, by dotted name."""
    return {_module_name(path, root): path for path in sorted(root.rglob("*.py"))}


def _resolve_relative(module: str, is_package: bool, level: int, target: str | None) -> str:
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _is_type_checking(node: ast.AST) -> bool:
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` but those under ``if TYPE_CHECKING:`` (its ``else`` kept)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if _is_type_checking(node):
            stack.extend(node.orelse)
        else:
            stack.extend(ast.iter_child_nodes(node))


def imports_of(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of the package that ``module`` imports anywhere in its source."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in _runtime_nodes(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            source = (
                _resolve_relative(module, is_package, node.level, node.module)
                if node.level
                else node.module or ""
            )
            for alias in node.names:
                submodule = f"{source}.{alias.name}"
                found.add(submodule if submodule in modules else source)
    return {name for name in found if name in modules and name != module}


def import_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    """Each module of the package with the package's modules it imports."""
    modules = package_modules(root)
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as ``[a, b, ..., a]``, or None when it has none."""
    state: dict[str, int] = {}  # 1: on the current path, 2: finished
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for child in sorted(graph.get(node, ())):
            if state.get(child) == 1:
                return [*path[path.index(child) :], child]
            if child not in state:
                cycle = visit(child)
                if cycle:
                    return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def has_main_block(path: Path) -> bool:
    """Whether the module holds an ``if __name__ == "__main__":`` block."""
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Compare):
            names = [node.test.left, *node.test.comparators]
            if any(isinstance(n, ast.Name) and n.id == "__name__" for n in names) and any(
                isinstance(n, ast.Constant) and n.value == "__main__" for n in names
            ):
                return True
    return False


def test_the_package_has_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_graph_sees_lazy_relative_and_from_imports(tmp_path):
    # The checker itself: a cycle closed only by a lazy relative import is found.
    root = tmp_path / "pkg"
    (root / "sub").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "sub" / "__init__.py").write_text("from pkg.sub.b import g\n")
    (root / "a.py").write_text("from pkg import sub\n")
    (root / "sub" / "b.py").write_text("def g():\n    from ..a import f\n")
    (root / "c.py").write_text(
        "from typing import TYPE_CHECKING\nimport pkg.a\nfrom pkg.sub.b import g\n"
        "if TYPE_CHECKING:\n    from pkg import d\n"
    )
    (root / "d.py").write_text("from . import c\n")
    graph = import_graph(root)
    assert graph["pkg.a"] == {"pkg.sub"}
    assert graph["pkg.sub.b"] == {"pkg.a"}
    assert graph["pkg.c"] == {"pkg.a", "pkg.sub.b"}  # d only for the type checker
    assert graph["pkg.d"] == {"pkg.c"}
    assert find_cycle(graph) == ["pkg.a", "pkg.sub", "pkg.sub.b", "pkg.a"]
    (root / "sub" / "b.py").write_text("def g():\n    pass\n")
    assert find_cycle(import_graph(root)) is None


def program_modules(root: Path = PACKAGE) -> list[Path]:
    """The plain modules that give a program its ``python -m gym_soarm.<name>``."""
    from gym_soarm.cli.programs import PROGRAMS

    return [root / f"{name}.py" for name in PROGRAMS if (root / f"{name}.py").is_file()]


RUN_BY_PATH = (PACKAGE / "bench" / "ceiling.py",)
"""Programs run by their path, in a process that must not import gym_soarm."""


def test_library_modules_hold_no_main_block():
    allowed = {*program_modules(), *RUN_BY_PATH}
    offenders = [
        str(path.relative_to(PACKAGE.parent))
        for path in sorted(PACKAGE.rglob("*.py"))
        if has_main_block(path)
        and path.name != "__main__.py"
        and path.parent != PACKAGE / "cli"
        and path not in allowed
    ]
    assert not offenders, (
        "a program's home is gym_soarm/cli/<name>.py (python -m runs it through a "
        f"__main__.py package); move these __main__ blocks there: {offenders}"
    )


def console_scripts(pyproject: Path = PYPROJECT) -> dict[str, str]:
    """The ``[project.scripts]`` table: script name -> ``module:function``."""
    text = pyproject.read_text()
    table = re.search(r"^\[project\.scripts\]\n(.*?)(?=^\[|\Z)", text, re.MULTILINE | re.DOTALL)
    assert table, f"no [project.scripts] in {pyproject}"
    return dict(re.findall(r'^([\w-]+)\s*=\s*"([^"]+)"', table.group(1), re.MULTILINE))


def test_every_way_in_leads_to_gym_soarm_cli():
    scripts = console_scripts()
    assert "gym-soarm-record" in scripts
    modules = package_modules()
    for script, target in scripts.items():
        module, _, function = target.partition(":")
        assert module.startswith("gym_soarm.cli.") and function == "main", (
            f"console script {script} = {target!r}; point it at gym_soarm.cli.<program>:main"
        )
        assert module in modules, f"console script {script}: no module {module}"
    shims = sorted(PACKAGE.rglob("__main__.py")) + program_modules()
    assert len(program_modules()) == 5, (
        "gym_soarm/train.py, evaluate.py, replay.py, sysid.py, kernels.py"
    )
    for path in shims:
        imported = imports_of(_module_name(path, PACKAGE), path, modules)
        assert len(imported) == 1 and next(iter(imported)).startswith("gym_soarm.cli."), (
            f"{path.relative_to(PACKAGE.parent)} should only call gym_soarm.cli.<program>.main; "
            f"it imports {sorted(imported)}"
        )
    from gym_soarm.cli.programs import PROGRAMS

    dispatched = {f"gym-soarm-{name}": f"{p.module}:main" for name, p in PROGRAMS.items()}
    assert dispatched == scripts, "python -m gym_soarm <program> runs every console script"


def test_the_main_block_checker_sees_both_spellings(tmp_path):
    block = tmp_path / "a.py"
    block.write_text('import sys\nif __name__ == "__main__":\n    sys.exit(0)\n')
    reversed_ = tmp_path / "b.py"
    reversed_.write_text("if '__main__' == __name__:\n    pass\n")
    other = tmp_path / "c.py"
    other.write_text("if __name__ == 'gym_soarm':\n    pass\n")
    assert has_main_block(block) and has_main_block(reversed_)
    assert not has_main_block(other)


def documented_programs(files: list[Path] | None = None) -> list[str]:
    """Every ``python -m gym_soarm...`` module name the README and docs/ give, sorted."""
    text = "\n".join(path.read_text() for path in files or documentation_files())
    return sorted(set(re.findall(r"python -m (gym_soarm(?:\.\w+)+)", text)))


@pytest.mark.parametrize("module", documented_programs())
def test_every_python_m_name_of_the_docs_runs(module):
    result = subprocess.run(
        [sys.executable, "-m", module, "--help"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=PACKAGE.parent,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    expected = "| id | task |" if module == "gym_soarm.cli.docs" else f"usage: python -m {module}"
    assert expected in result.stdout, result.stdout[-3000:]
