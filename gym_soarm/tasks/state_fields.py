"""The fields of a task's ``environment_state``, each declared with what it reads.

A task lists its fields in :attr:`~gym_soarm.tasks.base.Task.state_fields`; the helpers
here declare the usual ones (an object's position and orientation, a fixture's position,
the gripper's). Each field reads a :class:`~gym_soarm.sim.arrays.SimArrays` and answers
``(n, size)`` values, one row per environment.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays

if TYPE_CHECKING:
    from gym_soarm.tasks.base import Task

StateReader = Callable[[SimArrays, "Task"], Array]
"""What a state field reads: ``read(sim, task)`` -> its ``(n, size)`` values."""


class StateField(NamedTuple):
    """One named field of ``environment_state``, declared with what it reads.

    Attributes:
        name: the field (``"cube_pos"``).
        names: the name of each value, for datasets (``("cube_x", "cube_y", "cube_z")``).
        bound: every value lies within [-bound, bound] (metres for positions).
        read: ``read(sim, task)`` -> the field's values now, ``(n, size)``.
    """

    name: str
    names: tuple[str, ...]
    bound: float
    read: StateReader

    @property
    def size(self) -> int:
        return len(self.names)


def position_field(name: str, prefix: str, read: StateReader) -> StateField:
    """A world position (m): ``{prefix}_x``, ``_y``, ``_z``, read by ``read``."""
    return StateField(
        name, (f"{prefix}_x", f"{prefix}_y", f"{prefix}_z"), constants.POSITION_BOUND_M, read
    )


def quaternion_field(name: str, prefix: str, read: StateReader) -> StateField:
    """An orientation quaternion (w, x, y, z): ``{prefix}_qw`` ... ``_qz``, read by ``read``."""
    return StateField(name, tuple(f"{prefix}_q{c}" for c in "wxyz"), 1.0, read)


def scalar_field(name: str, bound: float, read: StateReader) -> StateField:
    """One number within [-bound, bound], read by ``read`` (``(n,)``: one per environment)."""
    return StateField(name, (name,), bound, lambda sim, task: read(sim, task)[..., None])


def object_position_field(name: str) -> StateField:
    """``{name}_pos``: the position (m) of object ``name``'s centre."""
    return position_field(f"{name}_pos", name, lambda sim, task: sim.object_position(name))


def object_quaternion_field(name: str) -> StateField:
    """``{name}_quat_wxyz``: the orientation of object ``name``."""
    return quaternion_field(
        f"{name}_quat_wxyz", name, lambda sim, task: sim.object_quaternion(name)
    )


def object_pose_fields(name: str) -> tuple[StateField, StateField]:
    """Object ``name``'s position (``{name}_pos``) and quaternion (``{name}_quat_wxyz``)."""
    return object_position_field(name), object_quaternion_field(name)


def fixture_position_field(name: str, fixture: str) -> StateField:
    """``{name}_pos``: the position (m) of fixture ``fixture``'s site."""
    return position_field(f"{name}_pos", name, lambda sim, task: sim.fixture_position(fixture))


GRIPPER_POSITION_FIELD = position_field(
    "gripper_pos", "gripper", lambda sim, task: sim.gripper_position()
)
"""``gripper_pos``: the position (m) of the ``gripperframe`` site."""
