"""What the single-cube tasks share: the 3 cm blue cube, its grid start and its info keys.

``LiftCube-v0`` and ``PickAndPlaceCube-v0`` start the cube on one of the seed's nine
grid cells with one of four yaws (reset options ``cube_grid_position`` and
``cube_rotation_deg`` choose them for one reset).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.sim.arrays import SimArrays, per_env
from gym_soarm.sim.objects import SceneObject
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks import placement
from gym_soarm.tasks.base import Evaluation, Task
from gym_soarm.tasks.state_fields import GRIPPER_POSITION_FIELD, object_pose_fields
from gym_soarm.validation import check_int, check_number

CUBE_SIZE_M = 0.03
CUBE_HALF_M = CUBE_SIZE_M / 2
CUBE = SceneObject(
    name="cube",
    shape="box",
    size_m=(CUBE_HALF_M, CUBE_HALF_M, CUBE_HALF_M),
    colour="blue",
    mass_kg=0.02,
    position_m=placement.GRID_CENTER_M,
)
"""The 3 cm, 20 g blue cube."""


def coloured_cubes(
    colours: Sequence[str], first_x_m: float, step_m: float, y_m: float
) -> tuple[SceneObject, ...]:
    """One 3 cm, 20 g cube of each colour, named ``<colour>_cube``, declared in a row
    along x (the resets place them)."""
    return tuple(
        SceneObject(
            name=f"{colour}_cube",
            shape="box",
            size_m=(CUBE_HALF_M, CUBE_HALF_M, CUBE_HALF_M),
            colour=colour,
            mass_kg=0.02,
            position_m=(first_x_m + step_m * i, y_m),
        )
        for i, colour in enumerate(colours)
    )


def cube_reach(sim: SimArrays, name: str, half_m: float = CUBE_HALF_M) -> tuple[Any, Any, Any]:
    """How far cube ``name`` reaches from its centre along world x, y and z (m, ``(n,)``
    each): its half size through its rotation."""
    xp = sim.xp
    q = sim.object_quaternion(name)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    # Rows of the cube's rotation matrix.
    r0 = (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y))
    r1 = (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x))
    r2 = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
    return tuple(half_m * (xp.abs(r[0]) + xp.abs(r[1]) + xp.abs(r[2])) for r in (r0, r1, r2))


GRID_OPTION_KEYS: tuple[str, ...] = ("cube_grid_position", "cube_rotation_deg")
"""Reset options of the grid tasks: the start cell and the yaw of the cube."""


def validate_grid_options(options: Mapping[str, Any]) -> dict[str, Any]:
    """Check ``cube_grid_position`` (int 0-8 or None) and ``cube_rotation_deg`` (finite or None)."""
    cell = options.get("cube_grid_position")
    if cell is not None:
        last = placement.NUM_GRID_CELLS - 1
        cell = check_int("cube_grid_position", cell, 0, last, fix="Pass None for a random cell.")
    yaw = options.get("cube_rotation_deg")
    if yaw is not None:
        fix = f"Pass e.g. 45.0, or None for a random pick from {placement.GRID_YAWS_DEG}."
        yaw = check_number("cube_rotation_deg", yaw, unit="degrees", fix=fix)
    return {"cube_grid_position": cell, "cube_rotation_deg": yaw}


def grid_evaluation_resets(seeds: Sequence[int]) -> list[tuple[int, dict[str, Any]]]:
    """Every grid cell x every seed yaw x ``seeds``: the part-one expert sweep."""
    return [
        (seed, {"cube_grid_position": cell, "cube_rotation_deg": yaw})
        for cell in range(placement.NUM_GRID_CELLS)
        for yaw in placement.GRID_YAWS_DEG
        for seed in seeds
    ]


UNIFORM_REGION_M: tuple[tuple[float, float], tuple[float, float]] = (
    (
        placement.GRID_CENTER_M[0] + placement.GRID_DX_M[0],
        placement.GRID_CENTER_M[0] + placement.GRID_DX_M[-1],
    ),
    (
        placement.GRID_CENTER_M[1] + placement.GRID_DY_M[0],
        placement.GRID_CENTER_M[1] + placement.GRID_DY_M[-1],
    ),
)
"""``object_placement="uniform"``: the cube's centre anywhere in the grid's bounding box."""


@dataclasses.dataclass(frozen=True)
class GridStart:
    """Where the cube started: its grid cell (None when placed anywhere) and its yaw."""

    grid_cell: int | None
    yaw_deg: float


class CubeGridTask(Task):
    """A task with one cube that starts on a grid cell (base of lift and pick-and-place)."""

    option_keys: ClassVar[tuple[str, ...]] = GRID_OPTION_KEYS
    placements: ClassVar[tuple[str, ...]] = ("grid", "uniform")
    episode_shapes: ClassVar = MappingProxyType({"grid_cell": (), "yaw_deg": ()})
    """The cube's start cell (-1 when placed anywhere) and yaw, for the info."""
    host_episode_values: ClassVar = frozenset({"grid_cell"})
    cube = CUBE.name

    def __init__(self, spec) -> None:
        super().__init__(spec)
        self.start: GridStart | None = None

    def validate_options(self, options: Mapping[str, Any]) -> dict[str, Any]:
        checked = validate_grid_options(options)
        if self.placement == "uniform" and checked["cube_grid_position"] is not None:
            raise ValueError(
                "cube_grid_position applies to object_placement='grid'; this environment "
                f"places the cube anywhere (object_placement='uniform'); got "
                f"{checked['cube_grid_position']!r}. Remove the option or make the environment "
                "with object_placement='grid'."
            )
        return checked

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        physics.reset_to_home()
        if self.placement == "uniform":
            # Anywhere in the grid's bounding box, any yaw in [0, 90) unless asked for.
            (x0, x1), (y0, y1) = UNIFORM_REGION_M
            x, y = float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))
            yaw = options.get("cube_rotation_deg")
            yaw = float(rng.uniform(0.0, 90.0)) if yaw is None else yaw
            cell = None
        else:
            cell, yaw = placement.draw_grid_start(
                rng, options.get("cube_grid_position"), options.get("cube_rotation_deg")
            )
            x, y = placement.grid_cell_position(cell)
        physics.set_object_pose(
            self.cube,
            np.array([x, y, constants.TABLE_TOP_Z_M + CUBE_HALF_M]),
            placement.yaw_quaternion(yaw),
        )
        self.start = GridStart(cell, yaw)
        self.episode["grid_cell"][0] = -1 if cell is None else cell
        self.episode["yaw_deg"][0] = yaw

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Any]:
        return {
            "cube_grid_position": per_env(
                sim.episode["grid_cell"], lambda c: None if c < 0 else int(c)
            ),
            "cube_rotation_deg": sim.episode["yaw_deg"],
            "cube_pos": sim.object_position(self.cube),
        }

    def evaluation_resets(self, seeds: int) -> list[tuple[int, dict[str, Any] | None]]:
        """The grid sweep: 9 cells x 4 yaws x ``seeds`` seeds; seeds 0 .. seeds-1 if uniform."""
        if self.placement == "uniform":
            return super().evaluation_resets(seeds)
        return grid_evaluation_resets(range(seeds))


CUBE_STATE_FIELDS = (*object_pose_fields(CUBE.name), GRIPPER_POSITION_FIELD)
