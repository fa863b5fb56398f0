"""``obs_type="state"``: one flat float32 vector with what a state policy needs.

The layout, in order (every entry named by ``env.unwrapped.observation_names``):

=======================  ====  ==========================================================
names                    size  what
=======================  ====  ==========================================================
``<joint>.pos``          6     the measured joint angles (rad), gripper last
``<joint>.vel``          6     the joint velocities (rad/s)
``<joint>.target``       6     the commanded servo targets (rad): what delta actions move
``jaw_x`` .. ``jaw_z``   3     the jaws' centre (the ``grasp_center`` site, world frame, m)
task state               N     the task's ``environment_state`` (its ``state_names``)
``jaw_to_<p>_x`` ..      3/p   from the jaws' centre to each position ``p`` of the task
                               state (the gripper frame's own excepted), m
``<a>_to_<b>_x`` ..      3/g   from each object to its goal (the task's
                               :attr:`~gym_soarm.tasks.base.Task.goal_pairs`), m
task progress            M     the task's
                               :attr:`~gym_soarm.tasks.base.Task.progress_fields`, if any
=======================  ====  ==========================================================

Angles are radians whatever the env's ``units`` (those apply to actions and
``agent_pos``). Positions are world coordinates in metres: x across the table, y away
from the robot, z up. Nothing is rendered.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from gym_soarm import constants
from gym_soarm.sim.arrays import Array, SimArrays
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.base import Task
from gym_soarm.tasks.state_fields import StateField

GRIPPER_FIELD = "gripper_pos"
"""The gripper frame's position: already beside the jaws' centre, so no vector to it."""
AXES = ("x", "y", "z")


def _is_position(field: StateField) -> bool:
    return field.size == 3 and field.names[0].endswith("_x")


class StateObservation:
    """Builds the flat state observation of one task.

    Args:
        task: the task's episode logic (its state fields and goal pairs).
    """

    def __init__(self, task: Task) -> None:
        self._task = task
        # Each position field's value prefix ("cube") and offset in the task state.
        where: dict[str, tuple[str, int] | None] = {}
        offset = 0
        for field in task.state_fields:
            where[field.name] = (field.names[0][:-2], offset) if _is_position(field) else None
            offset += field.size
        positions = [at for name, at in where.items() if at is not None and name != GRIPPER_FIELD]
        for field_name in (name for pair in task.goal_pairs for name in pair):
            if field_name not in where:
                raise ValueError(
                    f"{type(task).__name__}.goal_pairs names {field_name!r}, which is not one "
                    f"of its state fields {list(where)}; fix the pair."
                )
            if where[field_name] is None:
                raise ValueError(
                    f"{type(task).__name__}.goal_pairs names {field_name!r}, which is not a "
                    "position field (x, y, z); name position fields only."
                )
        self._jaw_to = [start for _, start in positions]
        self._pairs = [(where[a], where[b]) for a, b in task.goal_pairs]
        joints = constants.JOINT_NAMES
        names: list[str] = [f"{j}.pos" for j in joints]
        names += [f"{j}.vel" for j in joints]
        names += [f"{j}.target" for j in joints]
        names += [f"jaw_{a}" for a in AXES]
        names += list(task.state_names)
        names += [f"jaw_to_{prefix}_{a}" for prefix, _ in positions for a in AXES]
        names += [f"{pa}_to_{pb}_{a}" for (pa, _), (pb, _) in self._pairs for a in AXES]
        progress_at = len(names)
        names += [name for field in task.progress_fields for name in field.names]
        if len(set(names)) != len(names):
            repeated = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(
                f"the state observation of {type(task).__name__} repeats names {repeated}; "
                "rename the task's state fields."
            )
        self.names: tuple[str, ...] = tuple(names)
        n_joints = len(joints)
        self._size = len(names)
        self._task_slice = slice(3 * n_joints + 3, 3 * n_joints + 3 + len(task.state_names))
        self._progress_slice = slice(progress_at, self._size)

    @property
    def space(self) -> spaces.Box:
        """``Box(float32, (N,))``: joint angles within +-pi, the task state within its
        bounds, velocities and vectors unbounded."""
        n = len(constants.JOINT_NAMES)
        high = np.full(self._size, np.inf, dtype=np.float32)
        high[:n] = np.pi
        high[2 * n : 3 * n] = np.pi
        high[3 * n : 3 * n + 3] = constants.POSITION_BOUND_M
        _, task_high = self._task.state_bounds()
        high[self._task_slice] = task_high
        fields = self._task.progress_fields
        if fields:
            high[self._progress_slice] = np.concatenate([np.full(f.size, f.bound) for f in fields])
        return spaces.Box(-high, high, dtype=np.float32)

    def batch(self, sim: SimArrays, commanded_rad: Array) -> Array:
        """The observations of ``sim``'s ``n`` states, ``(n, size)`` float32 (``(size,)``
        for one environment's unbatched arrays).

        Args:
            sim: the simulations.
            commanded_rad: ``(n, 6)`` (or ``(6,)``): the commanded servo targets.
        """
        xp = sim.xp
        jaw = sim.grasp_center()
        state = self._task.batch_state(sim)
        parts = [sim.joint_angles(), sim.joint_velocities(), commanded_rad, jaw, state]
        parts += [state[..., start : start + 3] - jaw for start in self._jaw_to]
        parts += [state[..., b : b + 3] - state[..., a : a + 3] for (_, a), (_, b) in self._pairs]
        task = self._task
        parts += [xp.astype(field.read(sim, task), jaw.dtype) for field in task.progress_fields]
        return xp.astype(xp.concat(parts, axis=-1), xp.float32)

    def __call__(self, physics: SoArmPhysics, commanded_rad: np.ndarray) -> np.ndarray:
        """The observation of one environment's state (a new float32 array)."""
        return self.batch(self._task.arrays(physics), commanded_rad)
