"""What the tasks with an open box share: experts that carry an object over its walls.

``PlaceInBin-v0`` and ``PutCubesInBox-v0`` drop cubes into an open box (its geometry:
:func:`gym_soarm.sim.objects.open_box_geoms`). Their experts carry the held cube with
its bottom above the rim and let go with the jaws half open, clear of the walls; each
task gives the rim's height (``rim_z_m``) and where the cube goes (``place_target``).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gym_soarm import constants
from gym_soarm.tasks.cube import CUBE_HALF_M
from gym_soarm.tasks.scripted import PlaceExpert
from gym_soarm.tasks.state_expert import PlaceStateExpert

CARRY_RIM_CLEARANCE_M = 0.02
"""Height of the held cube's bottom above the rim while carried."""
RELEASE_GRIPPER_RAD = 0.4
"""Gripper target for the release inside a box: open enough to let go, clear of walls."""


def over_rim_height(carry_height_m: float, rim_z_m: float) -> float:
    """Height of the held cube's centre while carried: ``carry_height_m``, or higher so
    that its bottom (and the jaw tips just above it) pass over a rim ``rim_z_m`` high."""
    return max(
        carry_height_m,
        constants.TABLE_TOP_Z_M + rim_z_m + CARRY_RIM_CLEARANCE_M + CUBE_HALF_M,
    )


class OverRimExpert(PlaceExpert):
    """The timed script of a box task: carry over the rim, release half open."""

    rim_z_m: ClassVar[float]
    """The height of the walls the carried object passes over."""

    def _begin_carry(self) -> None:
        if not self._holding():
            return
        target = self.place_target()
        carry = over_rim_height(self.config.carry_height_m, self.rim_z_m)
        self._arc_move(self._site_target(np.array([target[0], target[1], carry])))

    def _release_opening(self) -> float:
        return min(RELEASE_GRIPPER_RAD, self.config.gripper_open_rad)


class OverRimStateExpert(PlaceStateExpert):
    """The state expert of a box task: carry over the rim, release half open."""

    rim_z_m: ClassVar[float]
    """The height of the walls the carried object passes over."""

    def carry_height(self, target: np.ndarray) -> float:
        return over_rim_height(self.config.carry_height_m, self.rim_z_m)

    def release_opening(self) -> float:
        return min(RELEASE_GRIPPER_RAD, self.config.gripper_open_rad)
