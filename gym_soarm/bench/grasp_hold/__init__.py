"""A grasp that holds: friction-only lift-and-carry over randomised episodes.

``python -m gym_soarm.bench.grasp_hold --episodes 1000`` measures how well the jaws hold
what they lift, with no weld or attachment: only the pads' friction. Each episode, of one
of three shapes in turn:

* ``cube``: ``LiftCube-v0``'s 3 cm cube;
* ``cylinder``: ``PickAndPlaceCylinder-v0``'s standing cylinder (2.9 cm wide, 5.5 cm tall);
* ``block``: a 3 x 3 x 5 cm upright block on ``LiftCube-v0``'s table (registered here as
  ``HoldBlock-v0``);

is reset with ``physics_randomization="light"`` (masses, friction, gains and damping
drawn around the model's), then the object's mass is drawn uniformly in 20-100 g (its
inertia scaled with it). The task's state expert grasps it and lifts it until its
bottom is 4 cm above the table; then a 5 s carry swings the arm through one cycle of
pan +-0.6 rad, shoulder +-0.15 rad and wrist +-0.2 rad (up to ~0.75 rad/s at the pan),
the jaws commanded as they were at the lift.

Reported over the episodes whose lift succeeded (the lifts that failed are counted
apart): ``held``, the fraction still held by both jaws and off the table after the
carry (goal >= 99 %), and ``slip_mm``, how far the object moved in the jaws' frame
during the carry (median and 95th percentile; goal <= 2 mm), per shape and overall.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import gym_soarm
from gym_soarm import constants
from gym_soarm.sim.objects import Scene, SceneObject
from gym_soarm.tasks import get_task, register_task
from gym_soarm.tasks.base import TaskSpec
from gym_soarm.tasks.cube import CUBE

BLOCK_TASK = "HoldBlock-v0"
LIFTED_HEIGHT_M = 0.04
LIFT_STEPS = 400
"""Control steps the expert has to lift the object before the episode counts as no lift."""
CARRY_S = 5.0
MASS_RANGE_KG = (0.02, 0.10)
SWING_RAD = {"shoulder_pan": 0.6, "shoulder_lift": 0.15, "wrist_flex": 0.2}
"""Amplitude of each joint's one sine cycle during the carry."""


@dataclass(frozen=True)
class Shape:
    """One shape of the benchmark: its task and the object the jaws hold."""

    name: str
    task: str
    obj: str


def _block_spec() -> TaskSpec:
    lift = get_task("LiftCube-v0")
    block = SceneObject(
        name=CUBE.name,
        shape="box",
        size_m=(0.015, 0.015, 0.025),
        colour="yellow",
        mass_kg=0.02,
        position_m=CUBE.position_m,
    )
    return TaskSpec(
        name=BLOCK_TASK,
        task=lift.task,
        expert=lift.expert,
        max_episode_steps=lift.max_episode_steps,
        scene=Scene(objects=(block,)),
        instructions=("Pick up the yellow block and lift it.",),
        summary="lift an upright 3 x 3 x 5 cm block (the grasp benchmark's third shape)",
        default_placement=lift.default_placement,
        aliases=(),
        state_expert=lift.state_expert,
    )


def shapes() -> tuple[Shape, ...]:
    """The three shapes (registers ``HoldBlock-v0`` on first use)."""
    try:
        get_task(BLOCK_TASK)
    except ValueError:
        register_task(_block_spec())
    return (
        Shape("cube", "LiftCube-v0", CUBE.name),
        Shape("cylinder", "PickAndPlaceCylinder-v0", "cylinder"),
        Shape("block", BLOCK_TASK, CUBE.name),
    )


def _set_mass(env: Any, name: str, mass_kg: float) -> None:
    physics = env.unwrapped.physics
    model = physics.model.ptr
    body = physics.model.name2id(name, "body")
    scale = mass_kg / float(model.body_mass[body])
    model.body_mass[body] = mass_kg
    model.body_inertia[body] *= scale


def _in_jaws(physics: Any, name: str) -> np.ndarray:
    """The object's position in the frame of the jaws' grasp site (m)."""
    data = physics.named.data
    site = constants.GRASP_SITE
    rotation = data.site_xmat[site].reshape(3, 3)
    return rotation.T @ (physics.object_position(name) - data.site_xpos[site])


def episode(shape: Shape, seed: int, mass_kg: float) -> dict[str, Any]:
    """One lift-and-carry; ``lifted``, ``held`` and ``slip_mm`` (None without a lift)."""
    env = gym.make(
        f"gym_soarm/{shape.task}",
        obs_type="state",
        physics_randomization="light",
        max_episode_steps=LIFT_STEPS + 10_000,
    )
    try:
        obs, info = env.reset(seed=seed)
        base = env.unwrapped
        _set_mass(env, shape.obj, mass_kg)
        expert = gym_soarm.make_expert(env)
        task, physics = base.task_logic, base.physics
        lifted = False
        for _ in range(LIFT_STEPS):
            obs, _, _, truncated, info = env.step(expert(obs, info))
            sim = task.arrays(physics)
            if bool(sim.grasped(shape.obj)) and float(sim.object_height(shape.obj)) >= (
                LIFTED_HEIGHT_M
            ):
                lifted = True
                break
            if truncated:
                break
        result: dict[str, Any] = {"shape": shape.name, "seed": seed, "mass_kg": mass_kg}
        if not lifted:
            return {**result, "lifted": False, "held": None, "slip_mm": None}
        start = np.asarray(base.commanded_targets, dtype=np.float64).copy()
        names = list(constants.JOINT_NAMES)
        reference = _in_jaws(physics, shape.obj)
        slip = 0.0
        steps = round(CARRY_S / base.dt)
        for k in range(1, steps + 1):
            phase = math.sin(2 * math.pi * k / steps)
            targets = start.copy()
            for joint, amplitude in SWING_RAD.items():
                targets[names.index(joint)] += amplitude * phase
            env.step(base.control.action_for_targets(targets, base.commanded_targets))
            slip = max(slip, float(np.linalg.norm(_in_jaws(physics, shape.obj) - reference)))
        sim = task.arrays(physics)
        held = bool(sim.grasped(shape.obj)) and float(sim.object_height(shape.obj)) > 0.01
        return {**result, "lifted": True, "held": held, "slip_mm": 1000 * slip}
    finally:
        env.close()


def summarize(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Held fraction and slip (median, 95th percentile) of the rows that lifted."""
    lifted = [r for r in rows if r["lifted"]]
    slips = sorted(r["slip_mm"] for r in lifted)
    return {
        "episodes": len(rows),
        "lifted": len(lifted),
        "held": sum(r["held"] for r in lifted),
        "held_fraction": sum(r["held"] for r in lifted) / len(lifted) if lifted else None,
        "slip_mm_median": statistics.median(slips) if slips else None,
        "slip_mm_p95": slips[min(len(slips) - 1, int(0.95 * len(slips)))] if slips else None,
        "slip_mm_max": slips[-1] if slips else None,
    }


def _number(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    return "-" if value is None else f"{scale * value:.{digits}f}"


def format_summary(summary: dict[str, Any]) -> str:
    """One line: lifts, the held fraction and the slip."""
    return (
        f"lifted {summary['lifted']}/{summary['episodes']}, held "
        f"{_number(summary['held_fraction'], 100, 1)} %, slip median "
        f"{_number(summary['slip_mm_median'])} mm, p95 {_number(summary['slip_mm_p95'])} mm, "
        f"max {_number(summary['slip_mm_max'])} mm"
    )


def measure(episodes: int, seed: int = 0) -> dict[str, Any]:
    """``episodes`` lift-and-carries, the shapes in turn; the report."""
    rng = np.random.default_rng(seed)
    kinds = shapes()
    rows = []
    started = time.perf_counter()
    for k in range(episodes):
        mass = float(rng.uniform(*MASS_RANGE_KG))
        rows.append(episode(kinds[k % len(kinds)], seed + k, mass))
    report = {
        "episodes": episodes,
        "seed": seed,
        "carry_s": CARRY_S,
        "mass_range_kg": MASS_RANGE_KG,
        "physics_randomization": "light",
        "wall_s": round(time.perf_counter() - started, 1),
        "all": summarize(rows),
        "shapes": {s.name: summarize([r for r in rows if r["shape"] == s.name]) for s in kinds},
        "rows": rows,
    }
    return report
