"""The README stays true: its generated table matches the registry, its snippets run."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from gym_soarm.tools.docs import ENV_TABLE_END, ENV_TABLE_START, env_table

README = Path(__file__).resolve().parents[1] / "README.md"


def _section_code(heading: str, language: str = "python") -> str:
    """The first ``language`` code block after ``heading`` in the README."""
    text = README.read_text()
    start = text.index(heading)
    match = re.compile(rf"```{language}\n(.*?)```", re.DOTALL).search(text, start)
    assert match, f"no {language} block after {heading!r}"
    return match.group(1)


def _run(code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    script = tmp_path / "snippet.py"
    script.write_text(code)
    return subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path
    )


def test_the_environment_table_is_the_registrys():
    text = README.read_text()
    block = text[text.index(ENV_TABLE_START) + len(ENV_TABLE_START) : text.index(ENV_TABLE_END)]
    assert block.strip() == env_table(), "run python -m gym_soarm.tools.docs and paste its table"


def test_the_own_task_snippet_registers_a_task_whose_expert_succeeds(tmp_path):
    code = _section_code("Your own task needs no edit of gym_soarm")
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


def test_the_vector_snippet_runs_when_pasted_into_a_script(tmp_path):
    code = _section_code("Vector environments render in their workers")
    code = code.replace("num_envs=8", "num_envs=2")
    code = code.replace(
        "    envs.close()", "    print(obs['pixels']['front_camera'].shape)\n    envs.close()"
    )
    result = _run(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "(2, 96, 128, 3)" in result.stdout
