"""Joint units of the real SO-101 follower arm as LeRobot reads it, and radians.

The simulation works in radians. LeRobot's SO-101 follower reports and takes the six
joint positions as ``<motor>.pos`` values in one of two calibrated conventions:

* ``"lerobot"`` (LeRobot's default since 0.4.4): the five body joints in **degrees**, zero
  at the middle of each joint's range (the same zero as this model, so degrees are
  ``rad * 180 / pi``), and the gripper in **0 to 100** percent of its range, 0 = closed.
* ``"lerobot_range"`` (the older default): the body joints in **-100 to 100** percent of
  their range; ``wrist_roll``, calibrated over a full turn, maps -pi..pi rad onto
  -100..100. The gripper stays 0 to 100.

Every conversion is affine per joint (``value = scale * rad + offset``), except the
wrist_roll offset below; this module holds those figures once and the environment, the
recorder and the dataset use them.

``wrist_roll`` is calibrated over a full turn, so its zero on a real arm is wherever the
wrist was held during calibration, and a leader arm's zero need not be the model's. A
``wrist_roll_offset_deg`` says what the arm reads when the model's wrist_roll is at 0
rad: LeRobot values are then ``wrap(degrees + offset)``, wrapped to -180..180 degrees
(-100..100 in ``"lerobot_range"``), and values coming back map to the model's angle
nearest to the middle of its range.

=============  ===================  ====================  =============================
joint          sim range (rad)      ``"lerobot"``         ``"lerobot_range"``
=============  ===================  ====================  =============================
shoulder_pan   -1.91986 .. 1.91986  deg = rad * 180/pi    rad / 1.91986 * 100
shoulder_lift  -1.74533 .. 1.74533  deg = rad * 180/pi    rad / 1.74533 * 100
elbow_flex     -1.69 .. 1.69        deg = rad * 180/pi    rad / 1.69 * 100
wrist_flex     -1.65806 .. 1.65806  deg = rad * 180/pi    rad / 1.65806 * 100
wrist_roll     -2.74385 .. 2.84121  deg = rad * 180/pi    rad / pi * 100
gripper        -0.17453 .. 1.74533  (rad + 0.17453) / 1.91986 * 100 (both modes)
=============  ===================  ====================  =============================

Only numpy is used here: no LeRobot, no torch.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gym_soarm import constants
from gym_soarm.validation import ArgumentTypeError

RADIANS = "radians"
LEROBOT = "lerobot"
LEROBOT_RANGE = "lerobot_range"
UNITS: tuple[str, ...] = (RADIANS, LEROBOT, LEROBOT_RANGE)
"""Valid values of the ``units`` keyword, the default first."""

FEATURE_NAMES: tuple[str, ...] = tuple(f"{joint}.pos" for joint in constants.JOINT_NAMES)
"""LeRobot's names of the six values: ``shoulder_pan.pos`` ... ``gripper.pos``."""

# Servo target ranges of the model's position actuators (radians), in JOINT_NAMES order.
# They equal the actuator ctrlrange in assets/so101.xml; a test checks that they agree.
SERVO_RANGE_LOW_RAD: tuple[float, ...] = (-1.91986, -1.74533, -1.69, -1.65806, -2.74385, -0.17453)
SERVO_RANGE_HIGH_RAD: tuple[float, ...] = (1.91986, 1.74533, 1.69, 1.65806, 2.84121, 1.74533)

# LeRobot calibrates wrist_roll over the servo's full turn, not over a swept range.
_FULL_TURN_JOINTS = ("wrist_roll",)
_RAD_TO_DEG = 180.0 / math.pi


_WRIST_ROLL = constants.JOINT_NAMES.index("wrist_roll")
_WRIST_ROLL_MIDDLE_RAD = (SERVO_RANGE_LOW_RAD[_WRIST_ROLL] + SERVO_RANGE_HIGH_RAD[_WRIST_ROLL]) / 2


def _wrap(angle_rad: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class JointUnits:
    """The map between radians and one unit of the six joints.

    Each joint is affine, ``value = scale * radians + offset``, except ``wrist_roll``
    when ``wrist_roll_offset_rad`` is not zero: it is then shifted and wrapped, see the
    module docstring.

    Attributes:
        name: one of :data:`UNITS`.
        scale: per-joint factor, shape (6,), all positive (but a calibrated arm's
            joint with drive_mode 1 in degrees, see :mod:`gym_soarm.calibration`).
        offset: per-joint offset, shape (6,).
        wrist_roll_offset_rad: the real arm's wrist_roll reading, in radians, when the
            model's wrist_roll is at 0 rad.
    """

    name: str
    scale: np.ndarray
    offset: np.ndarray
    wrist_roll_offset_rad: float = 0.0

    def from_radians(self, radians: np.ndarray | Sequence[float]) -> np.ndarray:
        """Convert joint positions from radians to these units (float64, same shape).

        The last axis must hold the six joints; leading axes (e.g. time) are kept.
        """
        values = np.asarray(radians, dtype=np.float64) * self.scale + self.offset
        if self.wrist_roll_offset_rad:
            roll = np.asarray(radians, dtype=np.float64)[..., _WRIST_ROLL]
            values[..., _WRIST_ROLL] = (
                _wrap(roll + self.wrist_roll_offset_rad) * self.scale[_WRIST_ROLL]
            )
        return values

    def to_radians(self, values: np.ndarray | Sequence[float]) -> np.ndarray:
        """Convert joint positions from these units to radians (float64, same shape)."""
        radians = (np.asarray(values, dtype=np.float64) - self.offset) / self.scale
        if self.wrist_roll_offset_rad:
            # Of the angles equal modulo a turn, the one nearest the middle of the range.
            roll = radians[..., _WRIST_ROLL] - self.wrist_roll_offset_rad
            radians[..., _WRIST_ROLL] = _WRIST_ROLL_MIDDLE_RAD + _wrap(
                roll - _WRIST_ROLL_MIDDLE_RAD
            )
        return radians

    def bounds(
        self, low_rad: np.ndarray | Sequence[float], high_rad: np.ndarray | Sequence[float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint bounds, in these units, of the values of joints in [low_rad, high_rad].

        With a wrist_roll offset whose shifted interval crosses +-180 degrees, the
        wrist_roll bounds are the whole turn.
        """
        low = np.asarray(low_rad, dtype=np.float64) * self.scale + self.offset
        high = np.asarray(high_rad, dtype=np.float64) * self.scale + self.offset
        if self.wrist_roll_offset_rad:
            shifted = (
                low_rad[_WRIST_ROLL] + self.wrist_roll_offset_rad,
                high_rad[_WRIST_ROLL] + self.wrist_roll_offset_rad,
            )
            if not (-math.pi <= shifted[0] and shifted[1] <= math.pi):
                shifted = (-math.pi, math.pi)
            low[_WRIST_ROLL], high[_WRIST_ROLL] = np.multiply(shifted, self.scale[_WRIST_ROLL])
        return low, high


def _gripper_percent(low: float, high: float) -> tuple[float, float]:
    # 0 at the closed (lower) end, 100 at the open (upper) end.
    scale = 100.0 / (high - low)
    return scale, -low * scale


def _build(name: str) -> JointUnits:
    n = len(constants.JOINT_NAMES)
    if name == RADIANS:
        return JointUnits(name, np.ones(n), np.zeros(n))
    scale = np.empty(n)
    offset = np.zeros(n)
    for i, joint in enumerate(constants.JOINT_NAMES):
        low, high = SERVO_RANGE_LOW_RAD[i], SERVO_RANGE_HIGH_RAD[i]
        if joint == constants.GRIPPER_JOINT_NAME:
            scale[i], offset[i] = _gripper_percent(low, high)
        elif name == LEROBOT:
            scale[i] = _RAD_TO_DEG
        elif joint in _FULL_TURN_JOINTS:
            scale[i] = 100.0 / math.pi
        else:
            # Body joints are symmetric about zero: -100 at the lower end, +100 at the upper.
            scale[i] = 100.0 / high
    return JointUnits(name, scale, offset)


_TABLE: dict[str, JointUnits] = {name: _build(name) for name in UNITS}


def check_wrist_roll_offset(units: str, wrist_roll_offset_deg: object) -> float:
    """``wrist_roll_offset_deg`` as a float, once it is valid for ``units``.

    Raises:
        TypeError: the offset is not a real number.
        ValueError: the offset is outside -180..180 or not finite, or it is not 0 while
            ``units`` is ``"radians"``.
    """
    offset = wrist_roll_offset_deg
    if isinstance(offset, bool) or not isinstance(offset, (int, float, np.integer, np.floating)):
        raise ArgumentTypeError(
            f"wrist_roll_offset_deg must be a real number of degrees; got {offset!r} "
            f"({type(offset).__name__}). Pass e.g. wrist_roll_offset_deg=-90.0."
        )
    offset = float(offset)
    if not -180.0 <= offset <= 180.0:  # also refuses NaN
        raise ValueError(
            f"wrist_roll_offset_deg must be between -180 and 180 degrees; got {offset!r}. "
            "Give the real arm's wrist_roll reading when the model's wrist_roll is at 0 rad, "
            "wrapped to that range (e.g. 270 is -90)."
        )
    if offset and units == RADIANS:
        raise ValueError(
            f"wrist_roll_offset_deg applies to LeRobot's units; got {offset!r} with "
            f"units='radians'. Use units='lerobot' or 'lerobot_range', or leave it at 0."
        )
    return offset


def joint_units(
    units: str,
    wrist_roll_offset_deg: float = 0.0,
    calibration: str | os.PathLike[str] | None = None,
) -> JointUnits:
    """The conversion of ``units`` (one of :data:`UNITS`).

    Args:
        units: one of :data:`UNITS`.
        wrist_roll_offset_deg: the real arm's wrist_roll reading (degrees, -180..180)
            when the model's wrist_roll is at 0 rad; LeRobot units only.
        calibration: a LeRobot SO-101 follower calibration file: the LeRobot units of
            that arm instead of the fixed maps here (see :mod:`gym_soarm.calibration`).

    Raises:
        ValueError: ``units`` is not one of :data:`UNITS`, the offset is invalid (see
            :func:`check_wrist_roll_offset`), or the calibration file is missing or
            malformed, or comes with ``units="radians"``.
        TypeError: the offset is not a real number, or ``calibration`` not a path.
    """
    if not isinstance(units, str) or units not in _TABLE:
        raise ValueError(
            f"units must be one of {', '.join(repr(u) for u in UNITS)}; got {units!r}."
        )
    if calibration is not None:
        from gym_soarm.calibration import calibrated_units

        return calibrated_units(units, calibration, wrist_roll_offset_deg)
    offset = check_wrist_roll_offset(units, wrist_roll_offset_deg)
    if not offset:
        return _TABLE[units]
    table = _TABLE[units]
    return JointUnits(units, table.scale, table.offset, math.radians(offset))


def radians_to_units(
    radians: np.ndarray | Sequence[float], units: str, wrist_roll_offset_deg: float = 0.0
) -> np.ndarray:
    """Convert six joint positions (last axis) from radians to ``units``."""
    return joint_units(units, wrist_roll_offset_deg).from_radians(radians)


def units_to_radians(
    values: np.ndarray | Sequence[float], units: str, wrist_roll_offset_deg: float = 0.0
) -> np.ndarray:
    """Convert six joint positions (last axis) from ``units`` to radians."""
    return joint_units(units, wrist_roll_offset_deg).to_radians(values)


def radians_to_lerobot(radians: np.ndarray | Sequence[float]) -> np.ndarray:
    """Radians to LeRobot follower units: body joints in degrees, gripper 0 to 100."""
    return _TABLE[LEROBOT].from_radians(radians)


def lerobot_to_radians(values: np.ndarray | Sequence[float]) -> np.ndarray:
    """LeRobot follower units (body degrees, gripper 0 to 100) to radians."""
    return _TABLE[LEROBOT].to_radians(values)
