"""Snapshots of a running episode: ``env.unwrapped.save_state()`` and ``reset(options={"state": s})``.

A :class:`Snapshot` holds everything the next step of a :class:`gym_soarm.SoArmEnv`
depends on, as plain copies (numpy arrays, lists, dicts), so it pickles and can be
restored any number of times, in this environment or in another one made with the same
simulation settings (:data:`SIMULATION_SETTINGS`):

* the MuJoCo state (``mjSTATE_INTEGRATION``: time, positions, velocities, actuator
  activations, the solver's warm start, the servo targets (``ctrl``), applied forces,
  mocap poses, ...),
* the model fields that resets write on the environment's own model copy: every body's
  position and orientation (fixtures moved by the task) and the fields the randomiser
  draws (:data:`MODEL_FIELDS`, plus the headlight's ambient light),
* the commanded servo targets, the control delay and its queue, the STS3215 servo
  model's commanded and output positions, the control mode's own state (the ee modes'
  IK errors),
* the task's episode variables (the attributes of its task object), the step count,
  the reset's variation (``info["variation"]``) and the state of ``np_random``.

Restoring writes all of it back, so the same actions then give bit for bit the same
observations, rewards, terminations and infos as the original environment would.

A snapshot of other simulation settings is refused with a ``ValueError`` naming both
values. The settings that do not change the simulation (``obs_type``, ``control_mode``,
``normalize_actions``, ``units``, ``reward_type``, image size, cameras, render quality)
may differ: restored into another ``control_mode``, that mode starts from its reset state
(the ee modes' ``ik_error_*`` at 0) instead.

``reset(options={"state": s})`` does not draw a new episode: it runs no task placement
or randomisation and returns the restored state's observation and info (with
``info["variation"]`` of the snapshot's episode, as a reset reports it). A ``seed`` given
with it is applied and then overwritten by the snapshot's random state, which wins;
``"state"`` cannot be combined with the task's own options (``ValueError``), and anything
but a snapshot raises ``TypeError``. All checks run before anything changes. The step
count continues from the snapshot's (the success reward uses it), but a ``TimeLimit``
wrapper counts its steps from the restoring reset, so truncation by the step limit comes
that many steps later than in the original episode.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from gym_soarm.sim.randomization import PHYSICS_FIELDS, VISUAL_FIELDS

if TYPE_CHECKING:
    from gym_soarm.envs.world import World

SNAPSHOT_VERSION = 2
"""The layout of :class:`Snapshot`; a snapshot of another layout is refused (2: a task
keeps its per-episode values in its ``episode`` arrays)."""

PHYSICS_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
"""The MuJoCo state components a snapshot holds: everything ``mj_step`` reads."""

MODEL_FIELDS: tuple[str, ...] = (
    # Written by the tasks' resets (fixtures placed on the model).
    "body_pos",
    "body_quat",
    # Written by the randomiser (gym_soarm.sim.randomization.Randomizer).
    *VISUAL_FIELDS,
    *PHYSICS_FIELDS,
)
"""The ``MjModel`` arrays that a reset may change on the environment's own model copy."""
HEADLIGHT_AMBIENT = "vis.headlight.ambient"

SIMULATION_SETTINGS: tuple[str, ...] = (
    "task",
    "distractors",
    "object_placement",
    "servo_model",
    "dynamics",
    "physics_randomization",
    "visual_randomization",
)
"""The environment arguments that shape the simulation: a snapshot is only restored into
an environment whose arguments all equal the snapshot's (its ``settings`` also record
the compiled scene's label, ``"scene"``). The others (``obs_type``,
``control_mode``, ``units``, ``normalize_actions``, ``reward_type``, image size,
cameras, render quality) may differ."""


@dataclasses.dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything the next step of a :class:`gym_soarm.SoArmEnv` depends on.

    Made by ``env.unwrapped.save_state()``; restored by
    ``env.reset(options={"state": snapshot})``. Picklable; two snapshots compare equal
    when every value is equal (arrays bit for bit). Treat it as read-only: its arrays
    are copied in and out.

    Attributes:
        version: :data:`SNAPSHOT_VERSION` of the code that made it.
        settings: the values of :data:`SIMULATION_SETTINGS` of the environment.
        physics: the MuJoCo state (``mjSTATE_INTEGRATION``), float64.
        model: copies of the :data:`MODEL_FIELDS` arrays and the headlight's ambient.
        commanded: the six commanded servo targets (rad), before the delay.
        pending_targets: the control delay's queue of targets (rad), oldest first.
        delay_steps: the control delay in steps.
        servo: the STS3215 model's (commanded, output) positions, or None (``ideal``).
        control_mode: the control mode of the environment.
        control: the control mode's own state (the ee modes' IK errors).
        task_state: the task object's episode variables (its attributes but ``spec``).
        step_count: steps since the episode's reset (the success reward uses it).
        variation: what the episode's reset drew (``info["variation"]``).
        rng: the ``bit_generator.state`` of the environment's ``np_random``.
    """

    version: int
    settings: dict[str, Any]
    physics: np.ndarray
    model: dict[str, np.ndarray]
    commanded: np.ndarray
    pending_targets: tuple[np.ndarray, ...]
    delay_steps: int
    servo: tuple[tuple[float, ...], tuple[float, ...]] | None
    control_mode: str
    control: dict[str, Any]
    task_state: dict[str, Any]
    step_count: int
    variation: dict[str, Any]
    rng: dict[str, Any]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Snapshot):
            return NotImplemented
        return all(
            _same(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (
            f"Snapshot(task={self.settings.get('task')!r}, scene={self.settings.get('scene')!r}, "
            f"step_count={self.step_count}, time={float(self.physics[0]):.4f} s)"
        )


def _same(a: Any, b: Any) -> bool:
    """Equality that compares arrays bit for bit (NaN equal to NaN) and recurses."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(_same, a, b))
    if dataclasses.is_dataclass(a) and not isinstance(a, type) and type(a) is type(b):
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    return bool(a == b)


# --- MuJoCo ----------------------------------------------------------------------------
def physics_state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """A copy of ``data``'s :data:`PHYSICS_STATE`."""
    state = np.empty(mujoco.mj_stateSize(model, PHYSICS_STATE), dtype=np.float64)
    mujoco.mj_getState(model, data, state, PHYSICS_STATE)
    return state


def set_physics_state(model: mujoco.MjModel, data: mujoco.MjData, state: np.ndarray) -> None:
    """Make ``data`` what it was when ``state`` was taken after a (legacy) step.

    The data is cleared first, so nothing of its own history remains; ``mj_forward``
    then computes the position and velocity quantities that dm_control's legacy step
    leaves current (contacts, sites, passive forces) and that the next ``mj_step2``
    reads. It also overwrites the solver's warm start, so the state is set again.
    """
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, state, PHYSICS_STATE)
    mujoco.mj_forward(model, data)
    mujoco.mj_setState(model, data, state, PHYSICS_STATE)


def model_fields(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Copies of the :data:`MODEL_FIELDS` of ``model`` and its headlight's ambient."""
    fields = {name: np.array(getattr(model, name), copy=True) for name in MODEL_FIELDS}
    fields[HEADLIGHT_AMBIENT] = np.array(model.vis.headlight.ambient, copy=True)
    return fields


def check_model_fields(model: mujoco.MjModel, fields: Mapping[str, np.ndarray]) -> None:
    """Raise ValueError unless ``fields`` fit ``model``'s arrays (names, shapes, dtypes)."""
    mine = model_fields(model)
    if fields.keys() != mine.keys():
        raise ValueError(
            f"the snapshot's model fields {sorted(fields)} are not this environment's "
            f"{sorted(mine)}; take the snapshot with this version of gym_soarm."
        )
    for name, value in fields.items():
        if value.shape != mine[name].shape or value.dtype != mine[name].dtype:
            raise ValueError(
                f"the snapshot's model field {name!r} has shape {value.shape} but this "
                f"environment's model has {mine[name].shape}: the snapshot is of another "
                "scene. Restore it into an environment made with the same settings."
            )


def set_model_fields(model: mujoco.MjModel, fields: Mapping[str, np.ndarray]) -> None:
    """Write ``fields`` (from :func:`model_fields`) into ``model``."""
    for name, value in fields.items():
        if name == HEADLIGHT_AMBIENT:
            model.vis.headlight.ambient[:] = value
        else:
            np.copyto(getattr(model, name), value)


# --- other state -------------------------------------------------------------------------
def task_state(task: Any) -> dict[str, Any]:
    """A deep copy of a task object's episode variables (its attributes but ``spec``)."""
    return copy.deepcopy({k: v for k, v in vars(task).items() if k != "spec"})


def set_task_state(task: Any, state: Mapping[str, Any]) -> None:
    """Make ``task``'s attributes (but ``spec``) a deep copy of ``state``."""
    spec = task.spec
    attributes = vars(task)
    attributes.clear()
    attributes.update(copy.deepcopy(dict(state)))
    attributes["spec"] = spec


def _inner_control(control: Any) -> Any:
    # NormalizedControl wraps the mode whose state it is.
    return vars(control).get("mode", control)


def control_state(control: Any) -> dict[str, Any]:
    """The control mode's own state: the ee modes' last IK errors (none for joint modes)."""
    inner = _inner_control(control)
    errors = vars(inner).get("_errors")
    return {} if errors is None else {"errors": tuple(errors)}


def set_control_state(control: Any, state: Mapping[str, Any]) -> None:
    """Write a :func:`control_state` back into a control mode of the same kind."""
    control.reset()
    if "errors" in state:
        _inner_control(control)._errors = tuple(state["errors"])


def generator_from_state(state: Mapping[str, Any]) -> np.random.Generator:
    """A new ``Generator`` in the bit generator state ``state`` (``bit_generator.state``)."""
    name = state.get("bit_generator")
    bit_generator_class = getattr(np.random, str(name), None)
    if not (
        isinstance(bit_generator_class, type)
        and issubclass(bit_generator_class, np.random.BitGenerator)
    ):
        raise ValueError(f"the snapshot's random state names an unknown bit generator {name!r}.")
    bit_generator = bit_generator_class()
    bit_generator.state = copy.deepcopy(dict(state))
    return np.random.Generator(bit_generator)


def check_snapshot(snapshot: Any, settings: Mapping[str, Any], what: str) -> Snapshot:
    """``snapshot`` if it can be restored into an environment with ``settings``.

    Raises:
        TypeError: ``snapshot`` is not a :class:`Snapshot`.
        ValueError: it is of another version, or a simulation setting differs (naming
            the snapshot's value and the environment's).
    """
    if not isinstance(snapshot, Snapshot):
        raise TypeError(
            f'options["state"] must be a gym_soarm Snapshot from env.unwrapped.save_state(); '
            f"got {type(snapshot).__name__} {snapshot!r:.80}."
        )
    if snapshot.version != SNAPSHOT_VERSION:
        raise ValueError(
            f"the snapshot has layout version {snapshot.version}, this gym_soarm reads "
            f"version {SNAPSHOT_VERSION}; take the snapshot with this version of gym_soarm."
        )
    generator_from_state(snapshot.rng)  # raises on a foreign random state
    different = [
        (name, snapshot.settings.get(name), settings.get(name))
        for name in SIMULATION_SETTINGS
        if snapshot.settings.get(name) != settings.get(name)
    ]
    if different:
        listed = "; ".join(
            f"{name}={theirs!r} in the snapshot but {name}={ours!r} in this environment"
            for name, theirs, ours in different
        )
        fix = ", ".join(f"{name}={theirs!r}" for name, theirs, _ in different)
        raise ValueError(
            f"cannot restore this snapshot into {what}: {listed}. A snapshot is restored "
            f"only into an environment with the same simulation settings: make it with {fix}."
        )
    return snapshot


# --- a world's snapshots ---------------------------------------------------------------
def check_restorable(snapshot: Any, world: World) -> Snapshot:
    """``snapshot`` if it can be restored into ``world`` (see :func:`check_snapshot`;
    also a ``ValueError`` when its model fields or physics state do not fit the model)."""
    where = f"this {world.spec.name} environment"
    snapshot = check_snapshot(snapshot, world.simulation_settings(), where)
    m, d = world.physics.model.ptr, world.physics.data.ptr
    check_model_fields(m, snapshot.model)
    if len(snapshot.physics) != len(physics_state(m, d)):
        raise ValueError(
            "the snapshot's physics state does not fit this environment's model; "
            "restore it into an environment made with the same settings."
        )
    return snapshot


def save(
    world: World, step_count: int, variation: dict[str, Any], rng: np.random.Generator
) -> Snapshot:
    """A snapshot of ``world`` in an episode at ``step_count`` whose reset drew
    ``variation``, with the environment's random generator ``rng``."""
    m, d = world.physics.model.ptr, world.physics.data.ptr
    chain = world.chain
    return Snapshot(
        version=SNAPSHOT_VERSION,
        settings=world.simulation_settings(),
        physics=physics_state(m, d),
        model=model_fields(m),
        commanded=chain.commanded.copy(),
        pending_targets=tuple(np.array(t, dtype=np.float64) for t in chain.pending),
        delay_steps=int(chain.delay_steps),
        servo=None if chain.servo is None else chain.servo.state,
        control_mode=world.settings.control_mode,
        control=control_state(world.control),
        task_state=task_state(world.task),
        step_count=int(step_count),
        variation=copy.deepcopy(variation),
        rng=copy.deepcopy(rng.bit_generator.state),
    )


def restore(world: World, snapshot: Snapshot) -> tuple[dict[str, Any], int, np.random.Generator]:
    """Write ``snapshot`` (checked by :func:`check_restorable`) into ``world``: the model
    fields, the physics, the servo chain, the control mode (its reset state when the
    snapshot is of another mode) and the task.

    Returns:
        The environment's own part: a copy of the episode's variation, its step count and
        a random generator in the snapshot's state.
    """
    m, d = world.physics.model.ptr, world.physics.data.ptr
    set_model_fields(m, snapshot.model)
    set_physics_state(m, d, snapshot.physics)
    chain = world.chain
    chain.delay_steps = snapshot.delay_steps
    chain.pending = [np.array(t, dtype=np.float64) for t in snapshot.pending_targets]
    if chain.servo is not None and snapshot.servo is not None:
        chain.servo.state = snapshot.servo
    if snapshot.control_mode == world.settings.control_mode:
        set_control_state(world.control, snapshot.control)
    else:
        world.control.reset()
    chain.commanded = np.array(snapshot.commanded, dtype=np.float64)
    set_task_state(world.task, snapshot.task_state)
    return (
        copy.deepcopy(snapshot.variation),
        snapshot.step_count,
        generator_from_state(snapshot.rng),
    )
