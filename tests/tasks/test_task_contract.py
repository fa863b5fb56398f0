"""The task contract (SPEC section 19): computed once a step, declared once, shared helpers.

For every registered task: the environment evaluates it once per step and hands that
evaluation on (reward terms, success and info agree with what the public methods compute
from the physics alone); every ``environment_state`` field reads its own ``size`` values
and the state is their concatenation. For the task modules: no task imports a sibling
task, and none reaches MuJoCo's names except through the physics accessors.
"""

from __future__ import annotations

import ast
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.tasks import BUILTIN_TASK_MODULES

TASKS = gym_soarm.task_names()
TASKS_DIR = Path(gym_soarm.__file__).parent / "tasks"
TASK_MODULES = {name.rsplit(".", 1)[-1] for name in BUILTIN_TASK_MODULES}


def _env(task: str) -> gym.Env:
    return gym.make(gym_soarm.get_task(task).env_id, obs_type="environment_state_agent_pos")


@pytest.mark.parametrize("task", TASKS)
def test_one_evaluation_a_step_read_by_reward_success_and_info(task):
    env = _env(task)
    try:
        base = env.unwrapped
        logic = base.task_logic
        calls = []
        evaluate = logic.evaluate

        def counted(physics):
            calls.append(1)
            return evaluate(physics)

        logic.evaluate = counted
        env.reset(seed=0)
        assert len(calls) == 1, "reset evaluates the task once"
        env.action_space.seed(0)
        for _ in range(5):
            calls.clear()
            _, _, terminated, _, info = env.step(env.action_space.sample())
            assert len(calls) == 1, f"{task}: {len(calls)} evaluations in one step"
            physics = base.physics
            assert info["reward_terms"] == logic.reward_terms(physics)
            assert info["is_success"] == logic.is_success(physics) == terminated
            for key, value in logic.episode_info(physics).items():
                np.testing.assert_array_equal(info[key], value)
    finally:
        env.close()


@pytest.mark.parametrize("task", TASKS)
def test_each_state_field_reads_its_own_values(task):
    env = _env(task)
    try:
        obs, _ = env.reset(seed=1)
        base = env.unwrapped
        logic = base.task_logic
        sim = logic.arrays(base.physics)  # the environment's own arrays, unbatched
        parts = [np.asarray(f.read(sim, logic), dtype=np.float64) for f in logic.state_fields]
        assert [p.shape for p in parts] == [(f.size,) for f in logic.state_fields]
        np.testing.assert_array_equal(np.concatenate(parts), obs["environment_state"])
    finally:
        env.close()


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


@pytest.mark.parametrize("module", sorted(TASK_MODULES))
def test_a_task_imports_no_sibling_task_and_no_mujoco(module):
    path = TASKS_DIR / f"{module}.py"
    imports = _imports(path)
    siblings = {f"gym_soarm.tasks.{name}" for name in TASK_MODULES - {module}}
    assert not imports & siblings, (
        f"{module} imports a sibling task: move the helper to a shared module"
    )
    assert "mujoco" not in imports, f"{module} imports mujoco: use the physics accessors"
    source = path.read_text()
    assert "0.1888" not in source, "the pan axis comes from gym_soarm.constants.PAN_AXIS_XY_M"
