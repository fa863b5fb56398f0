"""A task is one module: a whole new task defined here, registered, and used everywhere.

The task below (lift a yellow bar 3 cm) is declared in this file only — objects,
episode logic, expert and spec — with no edit of the library. Registering it makes it
work with ``gym.make``, ``make_expert``, the recorder (library and command line), the
benchmark's configurations and, in ``tests_lerobot/``, LeRobot's config.
"""

from __future__ import annotations

import json
from typing import ClassVar

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
import gym_soarm.expert
from gym_soarm.record.record import record
from gym_soarm.sim.arrays import SimArrays, namespace
from gym_soarm.sim.objects import Fixture, FixtureGeom, Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import RewardWeights, Task, TaskSpec, position_field, scalar_field
from gym_soarm.tasks.lift_cube import LiftExpert

BLOCK = SceneObject("tall_block", "box", (0.01, 0.018, 0.015), "yellow", mass_kg=0.015)
MARK = Fixture(
    "start_mark",
    (0.0, 0.34, 0.0),
    (FixtureGeom("cylinder", (0.07, 0.0005), "purple", (0.0, 0.0, 0.0005), collides=False),),
)
LIFT_M = 0.03
REGION_M = ((-0.05, 0.05), (0.30, 0.38))


class LiftBlockTask(Task):
    """Lift the yellow bar 3 cm; it starts anywhere in a small region, any yaw."""

    weights = RewardWeights({"grasp": 0.4, "lift": 0.6})
    state_fields: ClassVar = (
        position_field("block_pos", "block", lambda sim, task: sim.object_position(BLOCK.name)),
        scalar_field("block_yaw", 4.0, lambda sim, task: sim.object_yaw(BLOCK.name)),
    )

    def initialize_episode(self, physics: SoArmPhysics, rng: np.random.Generator, options) -> None:
        physics.reset_to_home()
        ((x, y),) = placement.draw_uniform_positions(rng, [BLOCK.footprint_radius_m], REGION_M)
        yaw = float(rng.uniform(0.0, 90.0))
        position = np.array([x, y, BLOCK.rest_height_m])
        physics.set_object_pose(BLOCK.name, position, placement.yaw_quaternion(yaw))

    # Array code over a batch of environments: (n,) values, written once.
    def evaluate(self, sim: SimArrays) -> dict:
        grasped = sim.grasped(BLOCK.name)
        height = sim.object_height(BLOCK.name)
        return {"success": grasped & (height >= LIFT_M), "grasped": grasped, "height_m": height}

    def compute_reward_terms(self, evaluation: dict) -> dict:
        xp = namespace(evaluation["height_m"])
        held = xp.astype(evaluation["grasped"], xp.float64)
        lift = xp.minimum(xp.maximum(evaluation["height_m"] / LIFT_M, 0.0), 1.0)
        return {"grasp": held, "lift": held * lift}

    def compute_info(self, sim: SimArrays, evaluation: dict) -> dict:
        return {"block_pos": sim.object_position(BLOCK.name)}


class LiftBlockExpert(LiftExpert):
    """The lift expert, aimed at the block."""

    def grasp_object(self) -> str:
        return BLOCK.name


SPEC = TaskSpec(
    name="LiftBlock-v0",
    task=LiftBlockTask,
    expert=LiftBlockExpert,
    max_episode_steps=200,
    scene=Scene(objects=(BLOCK,), fixtures=(MARK,)),
    instructions=("Lift the yellow block 3 cm.",),
    summary="lift the tall yellow block 3 cm",
    aliases=("lift_block",),
)


@pytest.fixture(scope="module", autouse=True)
def registered():
    return gym_soarm.register_task(SPEC)


def test_the_new_task_has_an_id_and_runs_through_gym_make():
    assert "gym_soarm/LiftBlock-v0" in gym_soarm.ENV_IDS
    assert gym_soarm.ENV_IDS["gym_soarm/LiftBlock-v0"] == ("LiftBlock-v0", 200)
    assert "LiftBlock-v0" in gym_soarm.task_names()
    assert gym_soarm.get_task("lift_block") is SPEC
    env = gym.make("gym_soarm/LiftBlock-v0", obs_type="environment_state_agent_pos")
    try:
        obs, info = env.reset(seed=3)
        base = env.unwrapped
        assert base.state_layout == (("block_pos", 3), ("block_yaw", 1))
        assert base.state_names == ("block_x", "block_y", "block_z", "block_yaw")
        assert obs["environment_state"].shape == (4,) and env.observation_space.contains(obs)
        assert info["task"] == "Lift the yellow block 3 cm." == base.task_description
        assert set(info["reward_terms"]) == {"grasp", "lift"}
        np.testing.assert_array_equal(info["block_pos"], obs["environment_state"][:3])
        assert env.spec.max_episode_steps == 200
        assert base.physics.object_names == ("tall_block",)
        assert base.physics.fixture_names == ("start_mark",)
    finally:
        env.close()


def test_the_new_tasks_expert_lifts_the_block():
    env = gym.make("gym_soarm/LiftBlock-v0", obs_type="environment_state_agent_pos")
    expert = gym_soarm.make_expert(env)
    try:
        for seed in range(3):
            result = gym_soarm.expert.run_episode(env, expert, seed, None)
            assert result.success, f"seed {seed}"
    finally:
        env.close()


def test_the_new_task_renders_its_objects():
    env = gym.make(
        "gym_soarm/LiftBlock-v0",
        obs_type="pixels",
        camera_config="front_only",
        observation_height=240,
        observation_width=320,
    )
    try:
        obs, _ = env.reset(seed=0)
        image = obs["front_camera"].astype(int)
        r, g, b = image[..., 0], image[..., 1], image[..., 2]
        assert ((r > 150) & (g > 110) & (b < 80)).sum() > 20, "no yellow bar"
        assert ((r > 80) & (b > 110) & (g < 90)).sum() > 20, "no purple mark"
    finally:
        env.close()


def test_the_recorder_records_the_new_task_with_its_layout(tmp_path):
    summary = record(tmp_path / "ds", task="LiftBlock-v0", episodes=1, camera_config="none")
    assert summary.episodes == 1 and summary.successes == 1
    info = json.loads((tmp_path / "ds" / "meta" / "info.json").read_text())
    feature = info["features"]["observation.environment_state"]
    assert feature["names"] == ["block_x", "block_y", "block_z", "block_yaw"]
    assert feature["shape"] == [4]
    import pyarrow.parquet as pq

    tasks = pq.read_table(tmp_path / "ds" / "meta" / "tasks.parquet").to_pylist()
    assert [row["task"] for row in tasks] == ["Lift the yellow block 3 cm."]


def test_recorder_workers_register_the_new_task_themselves(tmp_path):
    # The workers start without the parent's registrations; the spec travels to them.
    summary = record(
        tmp_path / "ds", task="LiftBlock-v0", episodes=2, camera_config="none", workers=2
    )
    assert summary.episodes == 2 and summary.successes == 2


def test_the_record_command_line_accepts_the_new_task(tmp_path, capsys):
    from gym_soarm.cli.record import main

    code = main(
        ["--task", "lift_block", "--episodes", "1", "--camera-config", "none",
         "--root", str(tmp_path / "cli"), "--no-progress"]
    )  # fmt: skip
    assert code == 0
    assert "1 episodes" in capsys.readouterr().out


def test_the_expert_command_line_reports_the_new_task(capsys):
    from gym_soarm.cli.expert import main

    main(["--task", "LiftBlock-v0", "--seeds", "2"])
    assert capsys.readouterr().out.startswith("LiftBlock-v0: 2/2 = 100.0 % success")


def test_the_benchmark_accepts_the_new_task():
    from gym_soarm.bench.bench import BenchConfig

    config = BenchConfig.parse("front_only_64x48", task="lift_block")
    assert config.task == "LiftBlock-v0" and config.env_id == "gym_soarm/LiftBlock-v0"


def test_registering_a_clashing_or_malformed_task_is_refused():
    with pytest.raises(ValueError, match="already name"):
        gym_soarm.register_task(TaskSpec(**{**SPEC.__dict__, "aliases": ("lift",)}))
    with pytest.raises(ValueError, match="already name"):
        gym_soarm.register_task(TaskSpec(**{**SPEC.__dict__, "summary": "another"}))
    with pytest.raises(TypeError, match="TaskSpec"):
        gym_soarm.register_task({"name": "X-v0"})
    with pytest.raises(ValueError, match="version"):
        TaskSpec(**{**SPEC.__dict__, "name": "NoVersion"})
    with pytest.raises(TypeError, match="Task subclass"):
        TaskSpec(**{**SPEC.__dict__, "task": object})
    with pytest.raises(ValueError, match="max_episode_steps"):
        TaskSpec(**{**SPEC.__dict__, "max_episode_steps": 0})
    with pytest.raises(ValueError, match="unique"):
        Scene(objects=(BLOCK, BLOCK))
    with pytest.raises(ValueError, match="colour must be one of"):
        SceneObject("x", "box", (0.01, 0.01, 0.01), "teal", 0.01)
    with pytest.raises(ValueError, match="size_m"):
        SceneObject("x", "cylinder", (0.01, 0.01, 0.01), "red", 0.01)
    with pytest.raises(ValueError, match="name"):
        SceneObject("Bad Name", "sphere", (0.01,), "red", 0.01)


def test_an_unknown_task_names_the_registered_ones():
    with pytest.raises(ValueError, match=r"task must be one of .*LiftCube-v0"):
        gym_soarm.SoArmEnv(task="FlyToTheMoon-v0")
    with pytest.raises(ValueError, match="LiftCube-v0"):
        gym_soarm.get_task("lift_cube_please")


def test_physics_accessors_refuse_unknown_names():
    env = gym.make("gym_soarm/LiftBlock-v0", obs_type="environment_state_agent_pos")
    try:
        env.reset(seed=0)
        physics = env.unwrapped.physics
        with pytest.raises(ValueError, match="tall_block"):
            physics.object_position("cube")
        with pytest.raises(ValueError, match="start_mark"):
            physics.fixture_position("goal")
        with pytest.raises(ValueError, match="table"):
            physics.touching("tall_block", "moon")
        env.step(physics.joint_angles().astype(np.float32))  # settle: contacts are computed
        assert physics.touching("tall_block", "table")
        assert not physics.touching("tall_block", "start_mark")  # the mark never collides
        assert physics.object_height("tall_block") == pytest.approx(0.0, abs=1e-3)
    finally:
        env.close()


def test_env_ids_are_every_registered_gym_soarm_id():
    registered = {env_id for env_id in gym.registry if env_id.startswith("gym_soarm/")}
    registered |= {env_id for env_id in gym.registry if env_id == "SoArm-v0"}
    assert set(gym_soarm.ENV_IDS) == registered
    assert gym_soarm.ENV_IDS[gym_soarm.TABLETOP_ID] == ("PutCubesInBox-v0", 1200)
    assert gym_soarm.TABLETOP_ID not in gym_soarm.TASK_ENV_IDS
    assert set(gym_soarm.TASK_ENV_IDS) == set(gym_soarm.ENV_IDS) - {gym_soarm.TABLETOP_ID}
