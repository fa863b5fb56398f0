"""Domain randomisation of one environment's own model, and the STS3215 servo model.

:class:`Randomizer` saves the model fields it varies when it is built and, at every
reset, writes them back and then draws a new variation from the environment's
generator, in place on the environment's own copy of the model: nothing is recompiled
and variations never accumulate. ``"none"`` draws nothing (the random stream of the
episode is left as it was) and restores the saved values.

* **Visual** (``visual_randomization``): the lights' direction and intensity, the
  headlight's ambient light, the colour of the table top and the floor, the colour of
  every named-colour material of the task's objects and fixtures (jittered in HSV with
  a bounded hue shift, so a red cube stays red), and each camera's position,
  orientation and field of view.
* **Physics** (``physics_randomization``): every object's mass (and inertia) and
  sliding friction, each servo's proportional and derivative gains, each arm joint's
  damping, and with ``"heavy"`` a control delay of 0 or 1 steps.

:class:`Sts3215Servo` models the Feetech STS3215 of the SO-101 follower (12 V,
1:345): its speed, stall torque, resolution and backlash (see :data:`STS3215`).
"""

from __future__ import annotations

import colorsys
import dataclasses
import math
from typing import Any

import mujoco
import numpy as np

from gym_soarm import constants
from gym_soarm.sim import objects

LEVELS: tuple[str, ...] = ("none", "light", "heavy")
"""Values of ``visual_randomization`` and ``physics_randomization``."""
SERVO_MODELS: tuple[str, ...] = ("ideal", "sts3215")
"""Values of ``servo_model``."""
VISUAL_FIELDS: tuple[str, ...] = (
    "light_dir",
    "light_diffuse",
    "mat_rgba",
    "cam_pos",
    "cam_quat",
    "cam_fovy",
)
"""The ``MjModel`` arrays a visual variation writes (besides the headlight's ambient)."""
PHYSICS_FIELDS: tuple[str, ...] = (
    "body_mass",
    "body_inertia",
    "geom_friction",
    "actuator_gainprm",
    "actuator_biasprm",
    "dof_damping",
)
"""The ``MjModel`` arrays a physics variation writes."""


@dataclasses.dataclass(frozen=True)
class VisualRanges:
    """Half-widths of the uniform visual jitter of one level."""

    light_dir_deg: float
    light_scale: float
    ambient_scale: float
    surface_hue: float
    surface_sv: float
    object_hue: float
    object_sv: float
    camera_pos_m: float
    camera_rot_deg: float
    camera_fovy_deg: float


@dataclasses.dataclass(frozen=True)
class PhysicsRanges:
    """Relative half-width of the physics jitter of one level and its largest delay."""

    scale: float
    max_delay_steps: int


VISUAL_RANGES: dict[str, VisualRanges] = {
    "light": VisualRanges(10.0, 0.15, 0.15, 0.03, 0.08, 0.01, 0.08, 0.01, 2.0, 2.0),
    "heavy": VisualRanges(25.0, 0.35, 0.35, 0.1, 0.2, 0.02, 0.2, 0.03, 5.0, 5.0),
}
"""Hue shifts are fractions of the colour circle (0.02 = 7.2°); saturation and value
shifts are absolute (0 to 1); light and ambient scales are relative."""
PHYSICS_RANGES: dict[str, PhysicsRanges] = {
    "light": PhysicsRanges(0.10, 0),
    "heavy": PhysicsRanges(0.30, 1),
}


@dataclasses.dataclass(frozen=True)
class ServoFigures:
    """Datasheet figures of a position servo.

    Attributes:
        speed_rad_s: no-load speed.
        stall_torque_nm: stall torque, the force range of the simulated servo.
        ticks_per_turn: position resolution.
        backlash_rad: free play of the output (total, both directions).
    """

    speed_rad_s: float
    stall_torque_nm: float
    ticks_per_turn: int
    backlash_rad: float


STS3215 = ServoFigures(
    # 0.222 s/60° at 12 V (Feetech STS3215-C018 datasheet; ~45 RPM): 4.72 rad/s.
    speed_rad_s=math.radians(60.0) / 0.222,
    # 30 kg·cm stall torque at 12 V: 30 * 9.80665 / 100 = 2.94 N·m.
    stall_torque_nm=30.0 * 9.80665 / 100.0,
    # 12-bit magnetic encoder: 4096 ticks a turn (0.088°).
    ticks_per_turn=4096,
    # <= 0.5° by datasheet, ~1° measured (TheRobotStudio/SO-ARM100 issue 134).
    backlash_rad=math.radians(1.0),
)
"""The Feetech STS3215 (12 V, 1:345), the servo of the SO-101 follower arm."""


class Sts3215Servo:
    """The target path of six STS3215 servos, one environment step at a time.

    Each step the action is quantised to the encoder's ticks, the commanded position
    moves towards it at most the no-load speed times the step, and the output follows
    it through the backlash: it stays put until the commanded position pulls it more
    than half the free play away (a play operator). The stall torque is the force
    range of the simulated servos (set on the model by the environment).

    Args:
        dt_s: the control step (s).
        figures: the servo's datasheet figures.
    """

    def __init__(self, dt_s: float, figures: ServoFigures = STS3215) -> None:
        self.figures = figures
        self._max_move = figures.speed_rad_s * dt_s
        self._tick = 2.0 * math.pi / figures.ticks_per_turn
        self._half_play = figures.backlash_rad / 2.0
        n = len(constants.JOINT_NAMES)
        self._command = [0.0] * n
        self._output = [0.0] * n

    def reset(self, targets: np.ndarray) -> None:
        """Start from the servo targets of the reset (rad)."""
        self._command = [float(v) for v in targets]
        self._output = list(self._command)

    @property
    def state(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The commanded and the output positions (rad), for a snapshot."""
        return tuple(self._command), tuple(self._output)

    @state.setter
    def state(self, value: tuple[Any, Any]) -> None:
        command, output = value
        self._command = [float(v) for v in command]
        self._output = [float(v) for v in output]

    def __call__(self, target: np.ndarray) -> np.ndarray:
        """The servo target (rad) that the action ``target`` (rad) gives this step."""
        # Six plain floats: cheaper than a dozen numpy calls on arrays of six.
        tick, max_move, half_play = self._tick, self._max_move, self._half_play
        command, output = self._command, self._output
        for i, value in enumerate(target.tolist()):
            move = round(value / tick) * tick - command[i]
            c = command[i] + min(max(move, -max_move), max_move)
            command[i] = c
            output[i] = min(max(output[i], c - half_play), c + half_play)
        return np.array(output)


def arm_indices(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The six servos' actuator ids and the six joints' dof addresses, in JOINT_NAMES order."""
    joint, actuator = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR
    actuators = np.array([mujoco.mj_name2id(model, actuator, n) for n in constants.JOINT_NAMES])
    dofs = np.array(
        [model.jnt_dofadr[mujoco.mj_name2id(model, joint, n)] for n in constants.JOINT_NAMES]
    )
    return actuators, dofs


def set_servo_gains(
    model: mujoco.MjModel, actuators: np.ndarray, kp: np.ndarray, kv: np.ndarray
) -> None:
    """Write position servos' gains in place: force ``kp * (target - q) - kv * qdot``.

    A MuJoCo position actuator keeps ``kp`` as ``gainprm[0]`` and ``-kp``, ``-kv`` as
    ``biasprm[1]``, ``biasprm[2]``; nothing needs recompiling.
    """
    model.actuator_gainprm[actuators, 0] = kp
    model.actuator_biasprm[actuators, 1] = -np.asarray(kp)
    model.actuator_biasprm[actuators, 2] = -np.asarray(kv)


def _rotation_quat(axis: np.ndarray, angle: float) -> np.ndarray:
    half = angle / 2.0
    return np.concatenate([[math.cos(half)], math.sin(half) * axis / np.linalg.norm(axis)])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _jitter_hsv(
    rgba: np.ndarray, rng: np.random.Generator, hue: float, sv: float
) -> tuple[np.ndarray, list[float]]:
    """``rgba`` with hue, saturation and value shifted by uniform draws within bounds."""
    dh, ds, dv = rng.uniform(-1.0, 1.0, 3) * (hue, sv, sv)
    h, s, v = colorsys.rgb_to_hsv(*rgba[:3].tolist())
    s = min(max(s + ds, 0.0), 1.0)
    v = min(max(v + dv, 0.0), 1.0)
    rgb = colorsys.hsv_to_rgb((h + dh) % 1.0, s, v)
    return np.array([*rgb, rgba[3]]), [float(dh), float(ds), float(dv)]


def _round(values: Any) -> Any:
    """Plain floats, rounded for ``info`` (JSON-serialisable)."""
    if isinstance(values, np.ndarray):
        return [round(float(v), 6) for v in values.ravel()]
    if isinstance(values, (list, tuple)):
        return [round(float(v), 6) for v in values]
    return round(float(values), 6)


class Randomizer:
    """Saves, restores and randomises the varied fields of one physics' model.

    Args:
        physics: the environment's own physics (its model is changed in place).
    """

    def __init__(self, physics: Any) -> None:
        m: mujoco.MjModel = physics.model.ptr
        self._model = m
        name = mujoco.mj_id2name
        self._lights = [
            name(m, mujoco.mjtObj.mjOBJ_LIGHT, i) or f"light{i}" for i in range(m.nlight)
        ]
        self._cameras = [name(m, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(m.ncam)]
        materials = [name(m, mujoco.mjtObj.mjOBJ_MATERIAL, i) for i in range(m.nmat)]
        self._surfaces = {n: materials.index(n) for n in ("tabletop", "floor") if n in materials}
        self._coloured = {
            n: i for i, n in enumerate(materials) if n and n.split("_glow")[0] in objects.COLOURS
        }
        body = mujoco.mjtObj.mjOBJ_BODY
        self._object_bodies = {n: mujoco.mj_name2id(m, body, n) for n in physics.object_names}
        self._object_geoms = {
            n: np.flatnonzero(m.geom_bodyid == b) for n, b in self._object_bodies.items()
        }
        self._actuators, self._arm_dofs = arm_indices(m)
        self._saved = {field: getattr(m, field).copy() for field in VISUAL_FIELDS + PHYSICS_FIELDS}
        self._saved_ambient = m.vis.headlight.ambient.copy()

    # --- visual ----------------------------------------------------------------------
    def restore_visual(self) -> None:
        """Write back the visual fields saved at construction."""
        m = self._model
        for field in VISUAL_FIELDS:
            np.copyto(getattr(m, field), self._saved[field])
        m.vis.headlight.ambient[:] = self._saved_ambient

    def visual(self, level: str, rng: np.random.Generator) -> dict[str, Any]:
        """Restore the visual fields, then draw and apply a variation of ``level``."""
        self.restore_visual()
        if level == "none":
            return {}
        r = VISUAL_RANGES[level]
        m = self._model
        saved = self._saved
        lights: dict[str, Any] = {}
        for i, light in enumerate(self._lights):
            axis = rng.normal(size=3)
            angle = math.radians(r.light_dir_deg) * rng.uniform(-1.0, 1.0)
            q = _rotation_quat(axis, angle)
            direction = np.empty(3)
            mujoco.mju_rotVecQuat(direction, saved["light_dir"][i], q)
            scale = 1.0 + r.light_scale * rng.uniform(-1.0, 1.0)
            m.light_dir[i] = direction
            m.light_diffuse[i] = saved["light_diffuse"][i] * scale
            lights[light] = {"dir": _round(direction), "intensity_scale": _round(scale)}
        ambient = 1.0 + r.ambient_scale * rng.uniform(-1.0, 1.0)
        m.vis.headlight.ambient[:] = self._saved_ambient * ambient
        colours: dict[str, Any] = {}
        for group, hue, sv in (
            (self._surfaces, r.surface_hue, r.surface_sv),
            (self._coloured, r.object_hue, r.object_sv),
        ):
            for material, index in group.items():
                rgba, shift = _jitter_hsv(saved["mat_rgba"][index], rng, hue, sv)
                m.mat_rgba[index] = rgba
                colours[material] = {"rgba": _round(rgba), "hsv_shift": _round(shift)}
        cameras: dict[str, Any] = {}
        for i, camera in enumerate(self._cameras):
            offset = r.camera_pos_m * rng.uniform(-1.0, 1.0, 3)
            angles = math.radians(r.camera_rot_deg) * rng.uniform(-1.0, 1.0, 3)
            q = saved["cam_quat"][i]
            for axis, angle in zip(np.eye(3), angles, strict=True):
                q = _quat_mul(q, _rotation_quat(axis, angle))
            fovy = r.camera_fovy_deg * rng.uniform(-1.0, 1.0)
            m.cam_pos[i] = saved["cam_pos"][i] + offset
            m.cam_quat[i] = q / np.linalg.norm(q)
            m.cam_fovy[i] = saved["cam_fovy"][i] + fovy
            cameras[camera] = {
                "pos_offset_m": _round(offset),
                "rotation_deg": _round(np.degrees(angles)),
                "fovy_offset_deg": _round(fovy),
            }
        return {
            "lights": lights,
            "ambient_scale": _round(ambient),
            "colours": colours,
            "cameras": cameras,
        }

    # --- physics ---------------------------------------------------------------------
    def restore_physics(self) -> None:
        """Write back the physics fields saved at construction."""
        m = self._model
        for field in PHYSICS_FIELDS:
            np.copyto(getattr(m, field), self._saved[field])

    def physics(self, level: str, rng: np.random.Generator) -> tuple[dict[str, Any], int]:
        """Restore the physics fields, then draw and apply a variation of ``level``.

        Returns:
            What was drawn (for ``info``) and the control delay in steps.
        """
        self.restore_physics()
        if level == "none":
            return {}, 0
        r = PHYSICS_RANGES[level]
        m = self._model
        saved = self._saved

        def scales(n: int) -> np.ndarray:
            return 1.0 + r.scale * rng.uniform(-1.0, 1.0, n)

        bodies: dict[str, Any] = {}
        for name, body in self._object_bodies.items():
            mass, friction = scales(2)
            m.body_mass[body] = saved["body_mass"][body] * mass
            m.body_inertia[body] = saved["body_inertia"][body] * mass
            geoms = self._object_geoms[name]
            m.geom_friction[geoms, 0] = saved["geom_friction"][geoms, 0] * friction
            bodies[name] = {"mass_scale": _round(mass), "friction_scale": _round(friction)}
        ids = self._actuators
        kp, kv = scales(len(ids)), scales(len(ids))
        set_servo_gains(
            m,
            ids,
            saved["actuator_gainprm"][ids, 0] * kp,
            -saved["actuator_biasprm"][ids, 2] * kv,
        )
        damping = scales(len(self._arm_dofs))
        m.dof_damping[self._arm_dofs] = saved["dof_damping"][self._arm_dofs] * damping
        delay = int(rng.integers(0, r.max_delay_steps + 1)) if r.max_delay_steps else 0
        joints = constants.JOINT_NAMES
        variation = {
            "objects": bodies,
            "kp_scale": dict(zip(joints, _round(kp), strict=True)),
            "kv_scale": dict(zip(joints, _round(kv), strict=True)),
            "damping_scale": dict(zip(joints, _round(damping), strict=True)),
            "control_delay_steps": delay,
        }
        return variation, delay
