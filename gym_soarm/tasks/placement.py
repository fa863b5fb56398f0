"""Where objects start: the seed's 3 x 3 grid with four yaws, or anywhere in a region.

Tasks choose; both draw only from the generator they are given.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.objects import SceneObject
from gym_soarm.sim.physics import SoArmPhysics

# The 3 x 3 grid of start cells. Cell i sits at GRID_CENTER + (dx, dy) with
# dx = GRID_DX_M[i // 3] and dy = GRID_DY_M[i % 3].
GRID_CENTER_M: tuple[float, float] = (0.0, 0.35)
GRID_DX_M: tuple[float, float, float] = (-0.10, 0.0, 0.10)
GRID_DY_M: tuple[float, float, float] = (-0.075, 0.0, 0.075)
NUM_GRID_CELLS = 9
GRID_YAWS_DEG: tuple[float, ...] = (0.0, 30.0, 45.0, 60.0)


def grid_cell_offset(cell: int) -> tuple[float, float]:
    """Offset (dx, dy) in metres of grid cell ``cell`` from the grid centre."""
    return GRID_DX_M[cell // 3], GRID_DY_M[cell % 3]


def grid_cell_position(cell: int) -> tuple[float, float]:
    """World (x, y) in metres of the centre of grid cell ``cell``."""
    dx, dy = grid_cell_offset(cell)
    return GRID_CENTER_M[0] + dx, GRID_CENTER_M[1] + dy


def yaw_quaternion(yaw_deg: float) -> np.ndarray:
    """The (w, x, y, z) quaternion of a turn of ``yaw_deg`` about the world z axis."""
    half = math.radians(yaw_deg) / 2
    return np.array([math.cos(half), 0.0, 0.0, math.sin(half)])


def draw_grid_start(
    rng: np.random.Generator, cell: int | None, yaw_deg: float | None
) -> tuple[int, float]:
    """The requested cell and yaw, each drawn when None (cell first, then yaw)."""
    if cell is None:
        cell = int(rng.integers(NUM_GRID_CELLS))
    if yaw_deg is None:
        yaw_deg = float(GRID_YAWS_DEG[int(rng.integers(len(GRID_YAWS_DEG)))])
    return cell, float(yaw_deg)


ARM_SHADOW_HALF_WIDTH_M = 0.05
"""Objects kept out of the arm's shadow start at least this far from the line x = 0:
nearer, the arm's home pose hides them from the overview camera."""
MAX_LAYOUT_DRAWS = 1000
"""Whole layouts drawn before :func:`draw_beside_arm` gives up."""

Region = tuple[tuple[float, float], tuple[float, float]]
"""((x_min, x_max), (y_min, y_max)) in metres."""


def _draw_apart(
    rng: np.random.Generator,
    radii_m: Sequence[float],
    region_m: Region,
    keep_clear: Sequence[tuple[float, float, float]],
    gap_m: float,
    max_tries: int,
    draw_x: Callable[[], float],
    where: str,
) -> list[tuple[float, float]]:
    """Object by object, ``(draw_x(), uniform y)`` until the footprint is clear of the rest."""
    _, (y0, y1) = region_m
    placed: list[tuple[float, float, float]] = list(keep_clear)
    positions: list[tuple[float, float]] = []
    for radius in radii_m:
        for _ in range(max_tries):
            x = draw_x()
            y = float(rng.uniform(y0, y1))
            if all(math.hypot(x - px, y - py) >= radius + pr + gap_m for px, py, pr in placed):
                break
        else:
            raise RuntimeError(
                f"no free spot for an object of radius {radius} m in {region_m}{where} after "
                f"{max_tries} draws; the region is too crowded."
            )
        placed.append((x, y, radius))
        positions.append((x, y))
    return positions


def draw_uniform_positions(
    rng: np.random.Generator,
    radii_m: Sequence[float],
    region_m: Region,
    keep_clear: Sequence[tuple[float, float, float]] = (),
    gap_m: float = 0.01,
    max_tries: int = 1000,
) -> list[tuple[float, float]]:
    """(x, y) for objects of footprint ``radii_m``, uniform in ``region_m``, never overlapping.

    Args:
        rng: the episode's generator.
        radii_m: each object's footprint radius, in placing order.
        region_m: ((x_min, x_max), (y_min, y_max)) the centres lie in.
        keep_clear: (x, y, radius) discs no object may overlap (pads, fixtures).
        gap_m: free space left between any two footprints.
        max_tries: draws per object before giving up.

    Raises:
        RuntimeError: an object found no free spot (the region is too crowded).
    """
    (x0, x1), _ = region_m
    return _draw_apart(
        rng, radii_m, region_m, keep_clear, gap_m, max_tries, lambda: float(rng.uniform(x0, x1)), ""
    )


def draw_beside_arm(
    rng: np.random.Generator,
    radii_m: Sequence[float],
    region_m: Region,
    blind_half_width_m: float = ARM_SHADOW_HALF_WIDTH_M,
    keep_clear: Sequence[tuple[float, float, float]] = (),
    gap_m: float = 0.01,
    *,
    by_side: bool = False,
    max_tries: int = 1000,
) -> list[tuple[float, float]]:
    """(x, y) for objects of footprint ``radii_m``, uniform in ``region_m`` outside the arm's
    blind strip (centres at least ``blind_half_width_m`` from x = 0, where the arm's home
    pose hides them from the overview camera), never overlapping.

    Two draws, both uniform over the allowed spots; a task keeps the one its seeds were
    made with. ``by_side=False``: whole layouts of :func:`draw_uniform_positions` are
    drawn until every centre is clear of the strip. ``by_side=True``: object by object, a
    side of the strip, then x on that side (``region_m`` must be symmetric about x = 0).

    Args:
        rng: the episode's generator.
        radii_m: each object's footprint radius, in placing order.
        region_m: ((x_min, x_max), (y_min, y_max)) the centres lie in.
        blind_half_width_m: half width of the strip about x = 0 no centre lies in.
        keep_clear: (x, y, radius) discs no object may overlap (pads, fixtures).
        gap_m: free space left between any two footprints.
        by_side: draw object by object on either side (see above).
        max_tries: draws per object before giving up.

    Raises:
        ValueError: ``by_side`` with a region not symmetric about x = 0 or no room beside
            the strip.
        RuntimeError: no free spot (``by_side``) or no layout in :data:`MAX_LAYOUT_DRAWS`
            draws.
    """
    (x0, x1), _ = region_m
    if by_side:
        if not math.isclose(x0, -x1) or not 0.0 <= blind_half_width_m < x1:
            raise ValueError(
                f"region_m's x range must be symmetric about 0 and wider than the arm's blind "
                f"strip (±{blind_half_width_m} m) to draw by side; got {region_m!r}."
            )

        def draw_x() -> float:
            side = 1.0 if rng.integers(2) else -1.0
            return side * float(rng.uniform(blind_half_width_m, x1))

        return _draw_apart(
            rng, radii_m, region_m, keep_clear, gap_m, max_tries, draw_x, " beside the arm"
        )
    for _ in range(MAX_LAYOUT_DRAWS):
        spots = draw_uniform_positions(rng, radii_m, region_m, keep_clear, gap_m, max_tries)
        if all(abs(x) >= blind_half_width_m for x, _ in spots):
            return spots
    raise RuntimeError(
        f"no layout of objects of radii {list(radii_m)} m in {region_m} kept "
        f"{blind_half_width_m} m from x = 0 after {MAX_LAYOUT_DRAWS} draws."
    )


def set_down(
    physics: SoArmPhysics,
    rng: np.random.Generator,
    items: Sequence[SceneObject],
    positions: Sequence[tuple[float, float]],
    yaw_range_deg: tuple[float, float] = (0.0, 90.0),
) -> None:
    """Rest each object on the table at its (x, y), turned by a yaw drawn uniformly from
    ``yaw_range_deg`` (one draw per object, in order); inside a reset context."""
    for item, (x, y) in zip(items, positions, strict=True):
        yaw = float(rng.uniform(*yaw_range_deg))
        physics.set_object_pose(
            item.name,
            np.array([x, y, constants.TABLE_TOP_Z_M + item.rest_height_m]),
            yaw_quaternion(yaw),
        )
