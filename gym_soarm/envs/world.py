"""One world: the simulation of a task that a :class:`~gym_soarm.envs.env.SoArmEnv` steps.

:meth:`World.build` turns an environment's :class:`~gym_soarm.envs.settings.EnvSettings`
into what it steps: the task object, the physics of its scene (with the distractors,
the render quality's meshes and the control rate's timestep), the joint units, the
fitted dynamics and servo model, the randomiser, the control mode and the servo chain,
and the step core over the physics (:class:`~gym_soarm.envs.core.StepCore`).
:meth:`World.start_episode` is a reset's draw: the task's placement, the distractors and
the randomisation, in that order, inside one reset context.

The files that ``calibration`` and ``dynamics`` name are read first, before anything
is compiled, so a missing file fails fast.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from gym_soarm.envs.control import ControlMode, ServoChain, make_control
from gym_soarm.envs.core import StepCore
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.real.dynamics import apply_dynamics, load_dynamics
from gym_soarm.real.units import JointUnits, joint_units
from gym_soarm.sim.backends import MjDataBackend
from gym_soarm.sim.physics import SoArmPhysics
from gym_soarm.sim.randomization import STS3215, Randomizer, Sts3215Servo
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ, ControlTiming, control_timing
from gym_soarm.tasks import get_task
from gym_soarm.tasks.base import Task, TaskSpec
from gym_soarm.tasks.distractors import place_distractors, with_distractors


@dataclasses.dataclass(eq=False)
class World:
    """The simulation of one environment and the objects that act on it."""

    settings: EnvSettings
    """The environment's settings, held here once (the env's ``settings``); a settable
    field (:func:`~gym_soarm.envs.settings.setting_property`) replaces them."""
    spec: TaskSpec
    """The registered declaration of the task."""
    task: Task
    """The task object: the episode's logic and values."""
    physics: SoArmPhysics
    scene_label: str
    """The compiled scene's name: the task's, with ``+<n>d`` for ``n`` distractors."""
    placement: str
    """The object placement in use (the task's default when the settings name none)."""
    timing: ControlTiming
    units: JointUnits
    control: ControlMode
    chain: ServoChain
    core: StepCore
    randomizer: Randomizer | None
    fitted_delay_steps: int
    """The fitted dynamics' control delay at this control rate (0 without dynamics)."""

    @classmethod
    def build(cls, settings: EnvSettings) -> World:
        """The world of an environment with ``settings`` (already checked)."""
        s = settings
        spec = get_task(s.task)
        units = joint_units(s.units, s.wrist_roll_offset_deg, s.calibration)  # reads the file
        fitted = None if s.dynamics is None else load_dynamics(s.dynamics)  # reads the file
        task = spec.make_task(s.object_placement)
        # The render quality picks the visual meshes; the physics is the same for both.
        scene, label = spec.scene, spec.name
        if s.distractors:
            scene, label = with_distractors(scene, s.distractors), f"{spec.name}+{s.distractors}d"
        physics = SoArmPhysics.from_scene(scene, s.render_quality, label)
        timing = control_timing(s.control_hz)
        physics.model.opt.timestep = timing.timestep_s
        servo = None
        if s.servo_model == "sts3215":
            physics.set_servo_force_limit(STS3215.stall_torque_nm)
            servo = Sts3215Servo(timing.control_timestep_s)
        if fitted is not None:  # before the randomiser saves the values it draws around
            apply_dynamics(physics.model.ptr, fitted.joints)
        # A fitted delay is counted in steps of the rate fits run at (the default): the
        # same time at this rate.
        hz = timing.control_hz
        delay = 0 if fitted is None else round(fitted.delay_steps * hz / DEFAULT_CONTROL_HZ)
        randomized = s.visual_randomization != "none" or s.physics_randomization != "none"
        randomizer = Randomizer(physics) if randomized else None
        # The control mode turns an action into servo targets (clipped in radians).
        control = make_control(s.control_mode, physics, units, normalize=s.normalize_actions)
        chain = ServoChain(control, servo, delay)
        chain.commanded = physics.joint_targets().copy()
        hook = None
        if type(task).before_step is not Task.before_step:
            hook = lambda targets: task.before_step(targets, physics)  # noqa: E731
        core = StepCore(task, MjDataBackend(physics), None, hook, timing.substeps)
        return cls(
            settings=s,
            spec=spec,
            task=task,
            physics=physics,
            scene_label=label,
            placement=task.placement,
            timing=timing,
            units=units,
            control=control,
            chain=chain,
            core=core,
            randomizer=randomizer,
            fitted_delay_steps=delay,
        )

    # --- episodes ------------------------------------------------------------------------
    @property
    def reports_variation(self) -> bool:
        """Whether a reset's info holds ``"variation"``: with randomisation, the STS3215
        servo model, distractors or a placement other than the task's default."""
        s = self.settings
        return (
            self.randomizer is not None
            or s.servo_model != "ideal"
            or s.distractors > 0
            or self.placement != self.spec.default_placement
        )

    def first_variation(self) -> dict[str, Any]:
        """The variation before the first reset: the settings, nothing drawn yet (empty
        when resets report none)."""
        if not self.reports_variation:
            return {}
        s = self.settings
        return {
            "visual_randomization": s.visual_randomization,
            "visual": {},
            "physics_randomization": s.physics_randomization,
            "physics": {},
            "servo_model": s.servo_model,
            "object_placement": self.placement,
            "distractors": [],
        }

    def start_episode(
        self, rng: np.random.Generator, options: dict[str, Any], variation: dict[str, Any]
    ) -> None:
        """Draw a new episode with ``rng``: the task's placement (with its checked
        ``options``), the distractors, the randomisation; write what was drawn into
        ``variation`` (when resets report it). The servos then hold the reset's targets."""
        physics, s = self.physics, self.settings
        with physics.reset_context():
            self.task.initialize_episode(physics, rng, options)
            placed = place_distractors(physics, s.distractors, rng)
            if self.reports_variation:
                variation["distractors"] = placed
            if self.randomizer is not None:
                # Drawn after the task's placement, so a seed places the objects the
                # same way at every level; applied before the reset's forward pass.
                visual = self.randomizer.visual(s.visual_randomization, rng)
                physical, drawn_delay = self.randomizer.physics(s.physics_randomization, rng)
                self.chain.delay_steps = self.fitted_delay_steps + drawn_delay
                variation.update(
                    visual_randomization=s.visual_randomization,
                    visual=visual,
                    physics_randomization=s.physics_randomization,
                    physics=physical,
                    servo_model=s.servo_model,
                )
        # The servos hold the reset's targets until the first actions reach them.
        self.chain.reset(physics.joint_targets())

    def hold_targets(self, targets: np.ndarray) -> None:
        """Make the servos hold ``targets`` (rad, six) from now until the first actions
        reach them (through the control delay, if any)."""
        self.physics.set_joint_targets(targets)
        self.chain.hold(targets)

    def simulation_settings(self) -> dict[str, Any]:
        """The settings a snapshot must share to be restored here (with the scene's label;
        :data:`gym_soarm.envs.snapshot.SIMULATION_SETTINGS`)."""
        s = self.settings
        return {
            "task": self.spec.name,
            "scene": self.scene_label,
            "distractors": s.distractors,
            "object_placement": self.placement,
            "servo_model": s.servo_model,
            "dynamics": s.dynamics,
            "physics_randomization": s.physics_randomization,
            "visual_randomization": s.visual_randomization,
        }
