"""Same seeds, same episodes, bit for bit, on the machine that runs the tests.

Every task's expert episodes and seeded random steps (:mod:`gym_soarm.cli.episode_hashes`)
hash the same twice in this process and once more in a fresh Python process. Nothing is
compared with hashes made elsewhere: floating point differs across CPUs. A guard across a
refactor records before and checks after, on one machine
(``python -m gym_soarm.cli.episode_hashes record|check FILE``).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from gym_soarm.cli import episode_hashes as hashes
from gym_soarm.tasks import BUILTIN_TASKS


@pytest.fixture(scope="module")
def first_run() -> dict[str, str]:
    return hashes.episode_hashes()


@pytest.mark.parametrize("task", BUILTIN_TASKS)
def test_same_seed_twice_in_one_process_gives_the_same_episodes(task, first_run):
    assert hashes.episode_hash(task) == first_run[task]


@pytest.mark.subprocess
def test_a_fresh_process_gives_the_same_episodes(first_run):
    out = subprocess.run(
        [sys.executable, "-m", "gym_soarm.cli.episode_hashes", "print"],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    assert json.loads(out.stdout) == first_run


def test_each_task_has_its_own_episodes(first_run):
    assert len(set(first_run.values())) == len(first_run)


def test_check_refuses_a_recording_from_another_machine(tmp_path):
    path = tmp_path / "hashes.json"
    key = dict(hashes.machine_key(), processor="another CPU")
    path.write_text(json.dumps({"key": key, "hashes": {"ReachTarget-v0": "0" * 64}}))
    with pytest.raises(ValueError, match="only compare on one machine"):
        hashes.check(path)


def test_check_names_the_changed_task(tmp_path):
    path = tmp_path / "hashes.json"
    reach = hashes.episode_hash("ReachTarget-v0")
    path.write_text(
        json.dumps(
            {
                "key": hashes.machine_key(),
                "hashes": {"ReachTarget-v0": reach, "LiftCube-v0": "0" * 64},
            }
        )
    )
    assert hashes.check(path) == ["LiftCube-v0"]
