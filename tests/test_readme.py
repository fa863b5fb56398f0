"""The README and the docs pages stay true.

The README's generated table matches the registry, the snippets run wherever they now
live (the README or a page of docs/, see ``doc_files``), every relative link leads to a
file and heading that exist, and the README stays a short page that maps the others.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from doc_files import DOCS, README, ROOT, code_after, documentation_files

from gym_soarm.cli.docs import ENV_TABLE_END, ENV_TABLE_START, env_table

README_MAX_LINES = 300
# The README's two commands, byte for byte: .ci/run runs the second one.
TWO_COMMANDS = (
    "pip install -e . && python examples/example.py",
    'pip install -e ".[test]" && python -m pytest -n 2',
)
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"^```.*?^```", re.DOTALL | re.MULTILINE)


def _run(code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    script = tmp_path / "snippet.py"
    script.write_text(code)
    return subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path
    )


def _anchors(page: Path) -> set[str]:
    """The anchors GitHub gives the headings of ``page`` (a repeated one gets -1, -2, ...)."""
    anchors: set[str] = set()
    for heading in re.findall(r"^#+ (.+)$", FENCE.sub("", page.read_text()), re.MULTILINE):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        anchor, n = slug, 0
        while anchor in anchors:
            n += 1
            anchor = f"{slug}-{n}"
        anchors.add(anchor)
    return anchors


def _relative_links(page: Path) -> list[str]:
    links = LINK.findall(FENCE.sub("", page.read_text()))
    return [link for link in links if not re.match(r"[a-z]+:", link)]


def test_the_environment_table_is_the_registrys():
    text = README.read_text()
    block = text[text.index(ENV_TABLE_START) + len(ENV_TABLE_START) : text.index(ENV_TABLE_END)]
    assert block.strip() == env_table(), "run python -m gym_soarm.cli.docs and paste its table"


def test_the_readme_is_short_and_keeps_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; move detail to docs/"
    for command in TWO_COMMANDS:
        assert any(line.startswith(command) for line in lines), f"README.md lost {command!r}"


def test_every_docs_page_is_reached_from_the_readme():
    reached, todo = {README.resolve()}, [README]
    while todo:
        page = todo.pop()
        for link in _relative_links(page):
            target = (page.parent / link.partition("#")[0]).resolve()
            if target.suffix == ".md" and target.exists() and target not in reached:
                reached.add(target)
                todo.append(target)
    missing = [p.name for p in sorted(DOCS.glob("*.md")) if p.resolve() not in reached]
    assert not missing, f"no link from README.md (or the pages it links) leads to {missing}"


@pytest.mark.parametrize("page", documentation_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_leads_to_a_file_and_a_heading(page):
    broken = []
    for link in _relative_links(page):
        path, _, anchor = link.partition("#")
        target = (page.parent / path).resolve() if path else page
        if not target.exists():
            broken.append(f"{link} (no file {target.relative_to(ROOT)})")
        elif anchor and target.suffix == ".md" and anchor not in _anchors(target):
            broken.append(f"{link} (no heading #{anchor} in {target.name})")
    assert not broken, f"{page.relative_to(ROOT)}: {broken}"


@pytest.mark.subprocess
def test_the_own_task_snippet_registers_a_task_whose_expert_succeeds(tmp_path):
    code = code_after("Your own task needs no edit of gym_soarm")
    code += (
        "\nenv.close()\n"
        "env = gym.make('gym_soarm/LiftBar-v0', obs_type='environment_state_agent_pos')\n"
        "expert = gym_soarm.make_expert(env)\n"
        "from gym_soarm.expert import run_episode\n"
        "print('success', all(run_episode(env, expert, s, None).success for s in range(2)))\n"
    )
    result = _run(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "success True" in result.stdout


@pytest.mark.subprocess
def test_the_vector_snippet_runs_when_pasted_into_a_script(tmp_path):
    code = code_after("Vector environments render in their workers")
    code = code.replace("num_envs=8", "num_envs=2")
    code = code.replace(
        "    envs.close()", "    print(obs['pixels']['front_camera'].shape)\n    envs.close()"
    )
    result = _run(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "(2, 96, 128, 3)" in result.stdout


@pytest.mark.subprocess
def test_the_quick_start_runs(tmp_path):
    code = code_after("## Quick start").replace("range(200)", "range(20)")
    code += "print(obs['agent_pos'].shape)\n"
    result = _run(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "['front_camera', 'wrist_camera']" in result.stdout
    assert "(6,)" in result.stdout


@pytest.mark.subprocess
def test_the_readme_expert_snippet_succeeds(tmp_path):
    result = _run(code_after("The expert also drives any"), tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("True")
