"""Distractors: up to four extra objects on the table that no task's success involves.

``gym.make(id, distractors=N)`` adds the first N objects of :data:`DISTRACTORS` to the
task's scene (compiled once per task, count and render quality). At every reset, after
the task has placed its own objects, they are placed uniformly in the workspace with
random yaws, clear of every object and fixture of the task and of each other, drawn
from the environment's generator.
"""

from __future__ import annotations

import numpy as np

from gym_soarm.sim.objects import Scene, SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement

MAX_DISTRACTORS = 4
DISTRACTORS: tuple[SceneObject, ...] = (
    SceneObject("distractor_0", "cylinder", (0.012, 0.02), "yellow", mass_kg=0.02),
    SceneObject("distractor_1", "box", (0.022, 0.01, 0.01), "purple", mass_kg=0.02),
    SceneObject("distractor_2", "box", (0.012, 0.012, 0.012), "grey", mass_kg=0.02),
    SceneObject("distractor_3", "cylinder", (0.02, 0.008), "brown", mass_kg=0.02),
)
"""A yellow cylinder, a purple bar, a small grey cube and a brown puck, in that order."""

REGION_M: tuple[tuple[float, float], tuple[float, float]] = ((-0.14, 0.14), (0.25, 0.43))
"""Where distractors' centres are drawn: the part of the table the arm works over."""
GAP_M = 0.015
"""Free space left around every distractor."""


def with_distractors(scene: Scene, count: int) -> Scene:
    """``scene`` with the first ``count`` distractors added after its own objects."""
    return Scene(objects=(*scene.objects, *DISTRACTORS[:count]), fixtures=scene.fixtures)


def place_distractors(
    physics: SoArmPhysics, count: int, rng: np.random.Generator
) -> list[dict[str, float]]:
    """Place the scene's ``count`` distractors (inside a reset context, after the task).

    Returns:
        Where each went: ``{"x", "y", "yaw_deg"}`` per distractor, in order.

    Raises:
        RuntimeError: no free spot was found (the task's scene leaves too little room).
    """
    if count == 0:
        return []
    physics.forward_kinematics()  # where the task put its objects, and its fixtures' parts
    ours = {item.name for item in DISTRACTORS[:count]}
    keep_clear: list[tuple[float, float, float]] = []
    for name in (*physics.object_names, *physics.fixture_names):
        if name not in ours:
            keep_clear += physics.geom_discs(name)
    items = DISTRACTORS[:count]
    spots = placement.draw_uniform_positions(
        rng, [item.footprint_radius_m for item in items], REGION_M, keep_clear, gap_m=GAP_M
    )
    placed = []
    for item, (x, y) in zip(items, spots, strict=True):
        yaw = float(rng.uniform(0.0, 90.0))
        physics.set_object_pose(
            item.name, np.array([x, y, item.rest_height_m]), placement.yaw_quaternion(yaw)
        )
        placed.append({"x": round(x, 6), "y": round(y, 6), "yaw_deg": round(yaw, 4)})
    return placed


def distractor_names(count: int) -> tuple[str, ...]:
    """The names of the first ``count`` distractors."""
    return tuple(item.name for item in DISTRACTORS[:count])


__all__ = [
    "DISTRACTORS",
    "MAX_DISTRACTORS",
    "place_distractors",
    "with_distractors",
]
