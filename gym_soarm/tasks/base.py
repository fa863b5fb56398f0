"""The contract of a task: its declaration (:class:`TaskSpec`) and its episode logic (:class:`Task`).

A task is one module under ``gym_soarm/tasks/``: a :class:`Task` subclass (where objects
start, what the environment state holds, what earns reward, what counts as success),
its scripted expert beside it, and a :class:`TaskSpec` that names the environment id,
the step limit, the scene's objects and fixtures and the instruction. Registering the
spec (:func:`gym_soarm.tasks.register_task`) is all it takes for ``gym.make``, the
expert, the recorder, the LeRobot config and the benchmark to know the task.

The environment (:class:`gym_soarm.envs.env.SoArmEnv`) is a thin adapter: it validates
arguments, steps the physics, renders cameras and calls the task's hooks. dm_control
provides the physics (``dm_control.mujoco.Physics``: named access, reset contexts);
the task is this small protocol of our own, so no hook exists that nobody calls.
Tasks never draw random numbers of their own: the environment hands every hook that
needs them its ``np_random`` generator.

What a task scores is written once, as array code over a batch of environments (as
ManiSkill writes its tasks): :meth:`Task.evaluate`, :meth:`Task.compute_reward_terms`,
:meth:`Task.compute_info` and the state fields read a
:class:`~gym_soarm.sim.arrays.SimArrays` and answer one value per environment. One
environment runs the same code on its own unbatched arrays; the batched vector env
(:mod:`gym_soarm.vector.batched`) scores all its simulations in one call. The code uses the array API only (NumPy here, torch tensors
the same), so another physics backend hands over its arrays and the tasks stay as they
are. Resets and placement stay per environment, on the physics.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from gym_soarm.sim.arrays import Array, SimArrays, item
from gym_soarm.sim.arrays import namespace as sim_namespace
from gym_soarm.sim.objects import Scene
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.tasks.state_fields import (
    GRIPPER_POSITION_FIELD,
    StateField,
    StateReader,
    fixture_position_field,
    object_pose_fields,
    object_position_field,
    object_quaternion_field,
    position_field,
    quaternion_field,
    scalar_field,
)
from gym_soarm.validation import ArgumentTypeError

if TYPE_CHECKING:
    from gym_soarm.tasks.scripted import ScriptedExpert


__all__ = [  # the state fields' helpers stay importable from here, where tasks took them
    "GRIPPER_POSITION_FIELD",
    "Evaluation",
    "RewardWeights",
    "StateField",
    "StateReader",
    "Task",
    "TaskSpec",
    "fixture_position_field",
    "object_pose_fields",
    "object_position_field",
    "object_quaternion_field",
    "position_field",
    "quaternion_field",
    "scalar_field",
]


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """Weights of the dense reward terms; they sum to 1 so the total is in [0, 1]."""

    terms: Mapping[str, float]

    def __post_init__(self) -> None:
        if not math.isclose(sum(self.terms.values()), 1.0):
            raise ValueError(f"reward weights must sum to 1, got {dict(self.terms)!r}")
        object.__setattr__(self, "terms", MappingProxyType(dict(self.terms)))

    def total(self, values: Mapping[str, Array]) -> Array:
        """The weighted sum of the terms (one per environment)."""
        weighted = [w * values[name] for name, w in self.terms.items()]
        total = weighted[0]
        for value in weighted[1:]:
            total = total + value
        return total


Evaluation = dict[str, Any]
"""What :meth:`Task.evaluate` found, one value per environment: ``"success"`` (bool) and
the task's own flags and distances."""


class Task:
    """Episode logic of one task; one subclass per task.

    Subclasses set :attr:`weights` and :attr:`state_fields` (each field declared with what
    it reads) and implement :meth:`initialize_episode`, :meth:`evaluate` and
    :meth:`compute_reward_terms`; tasks with reset options set :attr:`option_keys` and
    override :meth:`validate_options`; :meth:`compute_info` adds the task's own ``info``
    keys; :attr:`episode_shapes` declares what the task keeps between steps.

    :meth:`evaluate`, :meth:`compute_reward_terms`, :meth:`compute_info` and the state
    fields are array code over a batch of environments (a
    :class:`~gym_soarm.sim.arrays.SimArrays`): the environment evaluates the task once a
    step (the success flag and the predicates and distances the reward and the info
    need, as ManiSkill's ``evaluate()``) and hands the evaluation to the others.
    :meth:`is_success`, :meth:`reward_terms`, :meth:`episode_info` and
    :meth:`environment_state` answer the same for one environment's physics (a batch of
    one), as plain values.

    Args:
        spec: the task's registered declaration (scene, instructions, step limit).
    """

    weights: ClassVar[RewardWeights]
    state_fields: ClassVar[tuple[StateField, ...]]
    """The ``environment_state`` fields, in order, each with what it reads."""
    option_keys: ClassVar[tuple[str, ...]] = ()
    placements: ClassVar[tuple[str, ...]] = ("uniform",)
    """The ``object_placement`` values the task supports: ``"grid"`` and/or ``"uniform"``."""
    goal_pairs: ClassVar[tuple[tuple[str, str], ...]] = ()
    """(object, goal) position fields of :attr:`state_fields`: ``obs_type="state"`` adds
    the vector from each object to its goal (``("cube_pos", "goal_pos")``)."""
    progress_fields: ClassVar[tuple[StateField, ...]] = ()
    """Fields that ``obs_type="state"`` adds last (``environment_state`` does not hold
    them): the task's progress where the positions alone leave a policy to work it out
    (sort: which cubes are sorted, and the cube worked on now)."""
    episode_shapes: ClassVar[Mapping[str, tuple[int, ...]]] = MappingProxyType({})
    """The values the task keeps per episode, by name, with their shape for one
    environment (``()`` for a number): its reset sets them and :meth:`evaluate` may
    update them (:attr:`SimArrays.episode <gym_soarm.sim.arrays.SimArrays.episode>`)."""
    host_episode_values: ClassVar[frozenset[str]] = frozenset()
    """Those of :attr:`episode_shapes` that only a reset writes and only infos that are
    not numbers read (a grid cell): a vector env on a device keeps them in host memory,
    so that reading them each step never waits for the device."""

    def __init__(self, spec: TaskSpec) -> None:
        self.spec = spec
        self.instruction = spec.instructions[0]
        self.placement = spec.default_placement
        self.episode: dict[str, np.ndarray] = {
            name: np.zeros((1, *shape)) for name, shape in self.episode_shapes.items()
        }
        """This environment's :attr:`episode_shapes` values, each ``(1, *shape)``: written
        in place (``episode["k"][0] = ...``), never replaced, since the arrays a step
        reads view them."""

    def set_placement(self, placement: str | None) -> None:
        """Choose how objects start (``None``: the task's default); ValueError if unsupported."""
        placement = self.spec.default_placement if placement is None else placement
        if placement not in self.placements:
            raise ValueError(
                f"object_placement must be one of {', '.join(map(repr, self.placements))} for "
                f"{self.spec.name}; got {placement!r}. Leave it unset for the task's default "
                f"({self.spec.default_placement!r})."
            )
        self.placement = placement

    # --- layout ------------------------------------------------------------------------
    @property
    def state_layout(self) -> tuple[tuple[str, int], ...]:
        """The ``environment_state`` layout: ordered (field, size) pairs."""
        return tuple((field.name, field.size) for field in self.state_fields)

    @property
    def state_names(self) -> tuple[str, ...]:
        """The name of every value of ``environment_state``, in order."""
        return tuple(name for field in self.state_fields for name in field.names)

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of ``environment_state``."""
        high = np.concatenate(
            [np.full(f.size, f.bound, dtype=np.float64) for f in self.state_fields]
        )
        return -high, high

    # --- episode -------------------------------------------------------------------------
    def validate_options(self, options: Mapping[str, Any]) -> dict[str, Any]:
        """Check this task's reset options (only keys of :attr:`option_keys` reach here).

        Returns the validated values; raises ``ValueError`` naming what was expected.
        """
        return dict(options)

    def initialize_episode(
        self, physics: SoArmPhysics, rng: np.random.Generator, options: Mapping[str, Any]
    ) -> None:
        """Place the arm and the objects for a new episode (inside a reset context)."""
        raise NotImplementedError

    def before_step(self, action: np.ndarray, physics: SoArmPhysics) -> None:
        """Apply the (validated, clipped) joint targets in radians."""
        physics.set_joint_targets(action)

    # --- the batched definitions ---------------------------------------------------------
    def evaluate(self, sim: SimArrays) -> Evaluation:
        """The task's predicates and distances now, computed once a step.

        Args:
            sim: the simulations to score, ``n`` of them.

        Returns:
            A dict of ``(n,)`` arrays: ``"success"`` (bool) and whatever
            :meth:`compute_reward_terms` and :meth:`compute_info` read (``"grasped"``,
            ``"goal_distance_m"``, ...).
        """
        raise NotImplementedError(
            f"{type(self).__name__} must implement evaluate(sim) -> dict with 'success'."
        )

    def compute_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        """The named reward terms, each ``(n,)`` in [0, 1], of states that are not a success
        (no side effects: one environment does not call it on a success).

        Read from ``evaluation`` (:meth:`evaluate`'s); :meth:`batch_reward_terms` scores
        every term of a success 1.
        """
        raise NotImplementedError(
            f"{type(self).__name__} must implement compute_reward_terms(evaluation)."
        )

    def compute_info(self, sim: SimArrays, evaluation: Evaluation) -> dict[str, Array]:
        """The task's own ``info`` keys, each ``(n, ...)`` (the environment adds the common ones)."""
        return {}

    def batch_reward_terms(self, evaluation: Evaluation) -> dict[str, Array]:
        """The named reward terms, ``(n,)`` each in [0, 1], that never fall as the task
        progresses: :meth:`compute_reward_terms`, every term 1 on a success."""
        success = evaluation["success"]
        if isinstance(success, (np.bool_, bool)):  # one environment: the same, as scalars
            if success:
                return dict.fromkeys(self.weights.terms, 1.0)
            terms = self.compute_reward_terms(evaluation)
            return {name: terms[name] for name in self.weights.terms}
        terms = self.compute_reward_terms(evaluation)
        xp = sim_namespace(success)
        return {name: xp.where(success, 1.0, terms[name]) for name in self.weights.terms}

    def batch_state(self, sim: SimArrays) -> Array:
        """``(n, size)``: the values of :attr:`state_fields`, concatenated."""
        return sim.xp.concat([field.read(sim, self) for field in self.state_fields], axis=-1)

    def arrays(self, physics: SoArmPhysics) -> SimArrays:
        """One environment's simulation, unbatched, with this task's episode values."""
        return SimArrays.of_physics(physics, self.episode)

    # --- one environment, as plain values ------------------------------------------------
    def environment_state(self, physics: SoArmPhysics) -> np.ndarray:
        """The values of :attr:`state_fields`, each as its ``read`` finds it, concatenated."""
        return np.asarray(self.batch_state(self.arrays(physics)))

    def is_success(self, physics: SoArmPhysics, evaluation: Evaluation | None = None) -> bool:
        """Whether the task is done (``evaluation``: :meth:`evaluate`'s, when the caller has it)."""
        if evaluation is None:
            evaluation = self.evaluate(self.arrays(physics))
        return bool(evaluation["success"])

    def reward_terms(
        self, physics: SoArmPhysics, evaluation: Evaluation | None = None
    ) -> dict[str, float]:
        """The named reward terms, each in [0, 1], that never fall as the task progresses.

        Args:
            physics: the simulation to score.
            evaluation: :meth:`evaluate`'s of it (unbatched), when the caller has it.
        """
        if evaluation is None:
            evaluation = self.evaluate(self.arrays(physics))
        return {name: float(value) for name, value in self.batch_reward_terms(evaluation).items()}

    def episode_info(
        self, physics: SoArmPhysics, evaluation: Evaluation | None = None
    ) -> dict[str, Any]:
        """The task's own ``info`` keys (``evaluation``: :meth:`evaluate`'s, when the caller has it)."""
        sim = self.arrays(physics)
        if evaluation is None:
            evaluation = self.evaluate(sim)
        return {key: item(value) for key, value in self.compute_info(sim, evaluation).items()}

    def evaluation_resets(self, seeds: int) -> list[tuple[int, dict[str, Any] | None]]:
        """(seed, options) of the episodes the expert is measured on: seeds 0 .. seeds-1."""
        return [(seed, None) for seed in range(seeds)]


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """Everything the registry knows of a task.

    Attributes:
        name: the task's one name, also its id's: ``"LiftCube-v0"`` gives
            ``gym_soarm/LiftCube-v0``.
        task: the :class:`Task` subclass.
        expert: the scripted expert class (``expert(env, config)``), or None.
        max_episode_steps: the step limit (50 steps a second).
        scene: the objects and fixtures on the table.
        instructions: the instruction sentence; a task with a choice lists one
            template per choice and picks it at reset.
        summary: a short description for tables (``"lift the cube 5 cm"``).
        default_placement: ``"grid"`` or ``"uniform"``: how objects start by default.
        aliases: other spellings every command line accepts (``"lift"``).
        extra_env_ids: gym ids beside ``gym_soarm/<name>`` (``"SoArm-v0"``).
        state_expert: the expert that acts from the state
            (:class:`~gym_soarm.tasks.state_expert.StateExpert`, ``state_expert(env)``),
            or None: ``make_expert`` then gives the scripted one.
    """

    name: str
    task: type[Task]
    expert: type[ScriptedExpert] | None
    max_episode_steps: int
    scene: Scene
    instructions: tuple[str, ...]
    summary: str
    default_placement: str = "uniform"
    aliases: tuple[str, ...] = ()
    extra_env_ids: tuple[str, ...] = ()
    state_expert: type | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.endswith(("-v0", "-v1", "-v2")):
            raise ValueError(
                f"a task name ends with its version, e.g. 'StackCube-v0'; got {self.name!r}."
            )
        if not (isinstance(self.task, type) and issubclass(self.task, Task)):
            raise ArgumentTypeError(f"task must be a Task subclass; got {self.task!r}.")
        steps = self.max_episode_steps
        if isinstance(steps, bool) or not isinstance(steps, numbers.Integral) or steps < 1:
            raise ValueError(f"max_episode_steps must be an int >= 1; got {steps!r}.")
        if not isinstance(self.scene, Scene):
            raise ArgumentTypeError(
                f"scene must be a gym_soarm.sim.objects.Scene; got {self.scene!r}."
            )
        object.__setattr__(self, "instructions", tuple(self.instructions))
        if not self.instructions or not all(isinstance(s, str) and s for s in self.instructions):
            raise ValueError(
                f"instructions must be non-empty sentences; got {self.instructions!r}."
            )
        if self.default_placement not in ("grid", "uniform"):
            raise ValueError(
                f"default_placement must be 'grid' or 'uniform'; got {self.default_placement!r}."
            )
        object.__setattr__(self, "aliases", tuple(self.aliases))
        object.__setattr__(self, "extra_env_ids", tuple(self.extra_env_ids))

    @property
    def env_id(self) -> str:
        """The task's gym id, ``gym_soarm/<name>``."""
        return f"gym_soarm/{self.name}"

    @property
    def env_ids(self) -> tuple[str, ...]:
        """Every gym id of the task: ``gym_soarm/<name>`` first."""
        return (self.env_id, *self.extra_env_ids)

    def make_task(self, placement: str | None = None) -> Task:
        """A new instance of the task's episode logic (``placement``: None for the default)."""
        task = self.task(self)
        task.set_placement(placement)
        return task
