"""A real SO-101 follower's calibration file, and its units.

LeRobot calibrates each follower arm once and saves the result as a JSON file (by
default ``~/.cache/huggingface/lerobot/calibration/robots/so_follower/<id>.json``), one
entry per motor::

    {"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": -1470,
                      "range_min": 758, "range_max": 3292}, ...}

``calibration=PATH`` (a ``gym.make`` keyword, the recorder's ``--calibration`` and the
LeRobot config's ``calibration`` field) reads such a file and converts between the
model's radians and *that* arm's LeRobot values exactly as LeRobot's Feetech motor bus
normalises them, instead of the fixed maps of :mod:`gym_soarm.real.units`.

**Ticks.** Each servo reads 0 to 4095 ticks. LeRobot's calibration asks the user to hold
the arm with every joint in the middle of its travel and writes a homing offset that
makes that pose read :data:`HOMING_TICKS` (2047); the user then sweeps each joint and its
lowest and highest readings become ``range_min`` and ``range_max`` (``wrist_roll``, which
turns without end stops, gets the whole 0 to 4095). This module ties ticks to the
model's angles through that held pose: joint ``j`` at ``rad`` radians reads

    ticks = 2047 + sign * (rad - HOMING_POSE_RAD[j]) * 4095 / (2 * pi)

with ``sign`` -1 when the motor's ``drive_mode`` is 1 (its ticks run against the joint)
and +1 otherwise. 4095 ticks a turn is the figure LeRobot's degree formula uses.
:data:`HOMING_POSE_RAD` is the model's angle of the held pose, per joint:

* the five body joints: 0 rad. The model's zero of each body joint is the middle of its
  travel (the "new calibration" SO-101 model: LeRobot feeds its degrees straight into
  that model as radians), which is the pose the user holds.
* ``gripper``: 0.7854 rad, the middle of the model's gripper travel (-10 to 100 degrees).
* ``wrist_roll`` has no travel to be in the middle of: its held angle is where the user
  happened to hold it, taken as the model's 0 rad. ``wrist_roll_offset_deg`` says
  otherwise: with an offset of ``d`` degrees the held pose is the model's wrist_roll at
  ``-d`` degrees, and wrist_roll angles are wrapped to a turn about it (as without a
  calibration, see :mod:`gym_soarm.real.units`). The offset is thus one more calibration
  figure, the one the file cannot hold.

``homing_offset`` and ``id`` are read and checked but not used: the homing offset ties
the servo's raw encoder to the held pose, which the ticks above already start from.

**LeRobot's normalisation** of ticks (``MotorsBus._normalize``), per motor, with
``mid = (range_min + range_max) / 2``:

=========================  ============================================================
norm mode                  value
=========================  ============================================================
``DEGREES`` (body joints,  ``(ticks - mid) * 360 / 4095``: not bounded, and
``units="lerobot"``)       ``drive_mode`` is ignored
``RANGE_M100_100`` (body,  ``(clip(ticks) - range_min) / (range_max - range_min) * 200 -
``"lerobot_range"``)       100``, negated when ``drive_mode`` is 1
``RANGE_0_100``            ``(clip(ticks) - range_min) / (range_max - range_min) * 100``,
(gripper, both units)      ``100 - value`` when ``drive_mode`` is 1
=========================  ============================================================

``clip`` bounds the ticks to ``range_min .. range_max``, so values of the range modes
stay within -100..100 (0..100): a joint beyond its recorded range reads the range's
end, and an action beyond it sends the joint to that end, as on the arm. Degrees are
not bounded. Back from values to ticks (``_unnormalize``) the range modes bound the
value first; LeRobot then truncates to whole ticks (``int``, at most one tick or 0.088
degrees), which this module does not: the simulated servos take the exact angle.

So degrees are measured from the middle of each recorded range, and a range that is
not centred on 2047 moves that joint's zero, exactly as on the real arm: a
``shoulder_pan`` swept from 758 to 3292 (middle 2025) reads +1.93 degrees when the model
is at 0 rad. A calibration whose ranges are centred on 2047 gives the conversions of
:mod:`gym_soarm.real.units` (to float rounding): body degrees ``rad * 180 / pi`` whatever
the widths; the gripper's 0..100, and the body's -100..100 in ``"lerobot_range"``, when
each recorded range also spans the model's (the gripper's 110 degrees are 1251.2
ticks), since those values are fractions of the recorded range.

Only numpy and the standard library are used here: no LeRobot, no torch.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gym_soarm import constants
from gym_soarm.real.unit_maps import (
    LEROBOT,
    LEROBOT_RANGE,
    RADIANS,
    SERVO_RANGE_HIGH_RAD,
    SERVO_RANGE_LOW_RAD,
    UNITS,
    WRIST_ROLL,
    WRIST_ROLL_MIDDLE_RAD,
    JointUnits,
    check_wrist_roll_offset,
    wrap_rad,
)
from gym_soarm.validation import check_fields, read_json_file

MAX_TICKS = 4095
"""The highest reading of the STS3215's 12-bit encoder (readings are 0 to 4095)."""
TICKS_PER_TURN = 4095
"""Ticks a full turn, as LeRobot's degree formula counts them (its ``max_res``)."""
HOMING_TICKS = 2047
"""What every joint reads in the pose held during calibration (half a turn)."""
TICKS_PER_RAD = TICKS_PER_TURN / (2 * math.pi)

_GRIPPER = constants.JOINT_NAMES.index(constants.GRIPPER_JOINT_NAME)

HOMING_POSE_RAD: tuple[float, ...] = tuple(
    (SERVO_RANGE_LOW_RAD[i] + SERVO_RANGE_HIGH_RAD[i]) / 2 if i == _GRIPPER else 0.0
    for i in range(len(constants.JOINT_NAMES))
)
"""The model's angle (rad) of the pose held during calibration, in JOINT_NAMES order:
the body joints' zero (the middle of their travel) and the middle of the gripper's."""

FIELDS: tuple[str, ...] = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
"""The integer fields of each motor's entry in a LeRobot calibration file."""


@dataclass(frozen=True)
class MotorCalibration:
    """One motor's entry of a LeRobot calibration file (all integers).

    Attributes:
        id: the motor's bus id (1 to 6 on the SO-101 follower).
        drive_mode: 0, or 1 when the motor's ticks run against the joint.
        homing_offset: what the servo subtracts from its raw encoder reading.
        range_min: the lowest reading (ticks) seen while the joint was swept.
        range_max: the highest reading (ticks).
    """

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int


@dataclass(frozen=True)
class Calibration:
    """A follower arm's calibration file, read and checked by :func:`load_calibration`.

    Attributes:
        path: the file, as given.
        motors: each joint's :class:`MotorCalibration`, in JOINT_NAMES order.
    """

    path: str
    motors: Mapping[str, MotorCalibration]

    def to_json(self) -> dict[str, dict[str, int]]:
        """The file's content: ``{motor: {field: value}}``, as LeRobot writes it."""
        return {
            name: {field: getattr(motor, field) for field in FIELDS}
            for name, motor in self.motors.items()
        }


def _refuse(path: object, problem: str) -> ValueError:
    return ValueError(
        f"calibration file {path}: {problem}. Pass the JSON file that LeRobot's "
        "calibration of the SO-101 follower wrote (lerobot-calibrate; by default "
        "~/.cache/huggingface/lerobot/calibration/robots/so_follower/<id>.json)."
    )


def _motor(path: str | os.PathLike[str], name: str, entry: Any) -> MotorCalibration:
    """One motor's entry of a calibration file (checked)."""
    entry = check_fields(entry, FIELDS, f"motor {name!r}", lambda problem: _refuse(path, problem))
    values: dict[str, int] = {}
    for field in FIELDS:
        if field not in entry:
            raise _refuse(path, f"motor {name!r} has no {field!r}")
        value = entry[field]
        if isinstance(value, bool) or not isinstance(value, int):
            raise _refuse(path, f"motor {name!r} field {field!r} must be an integer; got {value!r}")
        values[field] = value
    if values["drive_mode"] not in (0, 1):
        raise _refuse(
            path,
            f"motor {name!r} field 'drive_mode' must be 0 or 1; got {values['drive_mode']!r}",
        )
    for field in ("range_min", "range_max"):
        if not 0 <= values[field] <= MAX_TICKS:
            raise _refuse(
                path,
                f"motor {name!r} field {field!r} must be 0 to {MAX_TICKS} ticks; got {values[field]!r}",
            )
    if values["range_min"] >= values["range_max"]:
        raise _refuse(
            path,
            f"motor {name!r} has range_min {values['range_min']} >= range_max "
            f"{values['range_max']}; the lowest reading must come first",
        )
    return MotorCalibration(**values)


def load_calibration(path: str | os.PathLike[str]) -> Calibration:
    """Read and check a LeRobot SO-101 follower calibration file.

    Args:
        path: the JSON file: one object per motor (``shoulder_pan`` ... ``gripper``),
            each with the integers ``id``, ``drive_mode`` (0 or 1), ``homing_offset``,
            ``range_min`` and ``range_max`` (0 to 4095, ``range_min < range_max``).

    Raises:
        TypeError: ``path`` is not a str or path (also a ``ValueError``).
        ValueError: the file is missing or unreadable, not JSON, lacks a motor or a
            field, has an unknown one, or a value is not an integer or out of range;
            the message names the file, the motor and the field.
    """
    content = read_json_file(
        path,
        "calibration must be the path of a LeRobot calibration JSON file (str or "
        "os.PathLike) or None",
        lambda problem: _refuse(path, problem),
    )
    if not isinstance(content, dict):
        raise _refuse(path, f"holds a {type(content).__name__}, not an object of motors")
    names = constants.JOINT_NAMES
    unknown = sorted(set(content) - set(names))
    if unknown:
        raise _refuse(
            path, f"unknown motor {unknown[0]!r}; an SO-101 follower has {', '.join(names)}"
        )
    motors: dict[str, MotorCalibration] = {}
    for name in names:
        if name not in content:
            raise _refuse(
                path, f"motor {name!r} is missing; every one of {', '.join(names)} is needed"
            )
        motors[name] = _motor(path, name, content[name])
    return Calibration(str(path), motors)


@dataclass(frozen=True)
class CalibratedUnits(JointUnits):
    """LeRobot units of one calibrated arm (see the module docstring).

    ``scale`` and ``offset`` hold the same map as an affine one per joint (before the
    range modes' bounds), for what only needs a change's size; ``from_radians`` and
    ``to_radians`` go through ticks as LeRobot's bus does. ``scale`` is negative for a
    joint with ``drive_mode`` 1 in degrees (LeRobot ignores the drive mode there).

    Attributes:
        calibration: the arm's calibration file.
        homing_rad: per joint, the model's angle of the held pose (with the wrist_roll
            offset applied).
        ticks_sign: per joint, -1 where ``drive_mode`` is 1, else +1.
        range_min: per joint, ``range_min`` (ticks, float).
        range_max: per joint, ``range_max`` (ticks, float).
        degrees: per joint, whether LeRobot's norm mode is ``DEGREES``.
        percent: per joint, whether it is ``RANGE_0_100`` (else ``RANGE_M100_100``).
        drive: per joint, whether ``drive_mode`` is 1.
    """

    calibration: Calibration | None = None
    homing_rad: np.ndarray | None = None
    ticks_sign: np.ndarray | None = None
    range_min: np.ndarray | None = None
    range_max: np.ndarray | None = None
    degrees: np.ndarray | None = None
    percent: np.ndarray | None = None
    drive: np.ndarray | None = None

    def radians_to_ticks(self, radians: np.ndarray | Sequence[float]) -> np.ndarray:
        """Joint angles (rad, last axis the six joints) as servo ticks (float, unrounded)."""
        relative = np.asarray(radians, dtype=np.float64) - self.homing_rad
        if self.wrist_roll_offset_rad:
            relative[..., WRIST_ROLL] = wrap_rad(relative[..., WRIST_ROLL])
        return HOMING_TICKS + self.ticks_sign * relative * TICKS_PER_RAD

    def ticks_to_radians(self, ticks: np.ndarray | Sequence[float]) -> np.ndarray:
        """Servo ticks (last axis the six joints) as joint angles (rad)."""
        relative = (np.asarray(ticks, dtype=np.float64) - HOMING_TICKS) / TICKS_PER_RAD
        radians = self.homing_rad + self.ticks_sign * relative
        if self.wrist_roll_offset_rad:
            # Of the angles equal modulo a turn, the one nearest the middle of the range.
            roll = radians[..., WRIST_ROLL]
            radians[..., WRIST_ROLL] = WRIST_ROLL_MIDDLE_RAD + wrap_rad(
                roll - WRIST_ROLL_MIDDLE_RAD
            )
        return radians

    def normalize(self, ticks: np.ndarray | Sequence[float]) -> np.ndarray:
        """Ticks to LeRobot values: the formulas of LeRobot's ``MotorsBus._normalize``."""
        ticks = np.asarray(ticks, dtype=np.float64)
        low, high = self.range_min, self.range_max
        middle = (low + high) / 2
        degrees = (ticks - middle) * 360 / TICKS_PER_TURN
        fraction = (np.minimum(high, np.maximum(low, ticks)) - low) / (high - low)
        symmetric = fraction * 200 - 100
        symmetric = np.where(self.drive, -symmetric, symmetric)
        percent = fraction * 100
        percent = np.where(self.drive, 100 - percent, percent)
        return np.where(self.degrees, degrees, np.where(self.percent, percent, symmetric))

    def unnormalize(self, values: np.ndarray | Sequence[float]) -> np.ndarray:
        """LeRobot values to ticks: ``MotorsBus._unnormalize`` without its ``int``."""
        values = np.asarray(values, dtype=np.float64)
        low, high = self.range_min, self.range_max
        middle = (low + high) / 2
        degrees = values * TICKS_PER_TURN / 360 + middle
        symmetric = np.minimum(100.0, np.maximum(-100.0, np.where(self.drive, -values, values)))
        symmetric = ((symmetric + 100) / 200) * (high - low) + low
        percent = np.minimum(100.0, np.maximum(0.0, np.where(self.drive, 100 - values, values)))
        percent = (percent / 100) * (high - low) + low
        return np.where(self.degrees, degrees, np.where(self.percent, percent, symmetric))

    def from_radians(self, radians: np.ndarray | Sequence[float]) -> np.ndarray:
        """Joint angles (rad) to this arm's LeRobot values (float64, same shape)."""
        return self.normalize(self.radians_to_ticks(radians))

    def to_radians(self, values: np.ndarray | Sequence[float]) -> np.ndarray:
        """This arm's LeRobot values to joint angles (rad); range values are bounded."""
        return self.ticks_to_radians(self.unnormalize(values))

    def bounds(
        self, low_rad: np.ndarray | Sequence[float], high_rad: np.ndarray | Sequence[float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint bounds of the values of joints in [low_rad, high_rad].

        With a wrist_roll offset whose shifted interval crosses +-180 degrees, the
        wrist_roll bounds are those of the whole turn.
        """
        low = np.asarray(low_rad, dtype=np.float64) - self.homing_rad
        high = np.asarray(high_rad, dtype=np.float64) - self.homing_rad
        if self.wrist_roll_offset_rad and not (
            -math.pi <= low[WRIST_ROLL] and high[WRIST_ROLL] <= math.pi
        ):
            low[WRIST_ROLL], high[WRIST_ROLL] = -math.pi, math.pi
        first = self.normalize(HOMING_TICKS + self.ticks_sign * low * TICKS_PER_RAD)
        second = self.normalize(HOMING_TICKS + self.ticks_sign * high * TICKS_PER_RAD)
        return np.minimum(first, second), np.maximum(first, second)


def calibrated_units(
    units: str,
    calibration: Calibration | str | os.PathLike[str],
    wrist_roll_offset_deg: float = 0.0,
) -> CalibratedUnits:
    """The LeRobot units ``units`` of the arm that ``calibration`` describes.

    Args:
        units: ``"lerobot"`` (body joints in LeRobot's ``DEGREES``) or
            ``"lerobot_range"`` (``RANGE_M100_100``); the gripper is ``RANGE_0_100``.
        calibration: a :class:`Calibration`, or the path of the JSON file.
        wrist_roll_offset_deg: the real arm's wrist_roll reading (degrees, -180 to 180)
            when the model's wrist_roll is at 0 rad: it moves wrist_roll's held pose to
            the model's ``-wrist_roll_offset_deg``.

    Raises:
        ValueError: ``units`` is not a LeRobot unit, the file is bad (see
            :func:`load_calibration`) or the offset is invalid.
        TypeError: ``calibration`` or the offset has the wrong type.
    """
    if not isinstance(units, str) or units not in UNITS:
        raise ValueError(
            f"units must be one of {', '.join(repr(u) for u in UNITS)}; got {units!r}."
        )
    if units == RADIANS:
        raise ValueError(
            f"calibration converts to a real arm's LeRobot values; got it with units='radians', "
            f"where radians need no calibration. Use units='{LEROBOT}' (degrees) or "
            f"'{LEROBOT_RANGE}' (-100 to 100), or leave calibration=None."
        )
    offset_deg = check_wrist_roll_offset(units, wrist_roll_offset_deg)
    if not isinstance(calibration, Calibration):
        calibration = load_calibration(calibration)
    motors = [calibration.motors[name] for name in constants.JOINT_NAMES]
    n = len(motors)
    homing = np.array(HOMING_POSE_RAD)
    offset_rad = math.radians(offset_deg)
    homing[WRIST_ROLL] -= offset_rad
    drive = np.array([m.drive_mode == 1 for m in motors])
    sign = np.where(drive, -1.0, 1.0)
    low = np.array([float(m.range_min) for m in motors])
    high = np.array([float(m.range_max) for m in motors])
    percent = np.arange(n) == _GRIPPER
    degrees = ~percent if units == LEROBOT else np.zeros(n, dtype=bool)

    # The same map as value = scale * rad + offset (before the range modes' bounds).
    start = HOMING_TICKS - sign * homing * TICKS_PER_RAD  # ticks at 0 rad
    slope = sign * TICKS_PER_RAD  # ticks per rad
    span = high - low
    d = np.where(drive, -1.0, 1.0)
    scale = np.where(degrees, slope * 360 / TICKS_PER_TURN, 0.0)
    offset = np.where(degrees, (start - (low + high) / 2) * 360 / TICKS_PER_TURN, 0.0)
    symmetric = ~degrees & ~percent
    scale = np.where(symmetric, d * slope * 200 / span, scale)
    offset = np.where(symmetric, d * ((start - low) * 200 / span - 100), offset)
    gripper_fraction = (start - low) * 100 / span
    scale = np.where(percent, d * slope * 100 / span, scale)
    offset = np.where(percent, np.where(drive, 100 - gripper_fraction, gripper_fraction), offset)
    return CalibratedUnits(
        name=units,
        scale=scale,
        offset=offset,
        wrist_roll_offset_rad=offset_rad,
        calibration=calibration,
        homing_rad=homing,
        ticks_sign=sign,
        range_min=low,
        range_max=high,
        degrees=degrees,
        percent=percent,
        drive=drive,
    )
