"""The maps between radians and LeRobot's joint units, and the checks of their settings.

:class:`JointUnits` (an affine map per joint, wrist_roll wrapped when offset), the fixed
maps of LeRobot's default calibration (:func:`default_units`) and the figures they are
built from. :mod:`gym_soarm.real.units` documents the conventions and chooses the map of a
setting; :mod:`gym_soarm.real.calibration` builds one arm's map on top of this module, which
imports neither.
"""

from __future__ import annotations

import math
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


WRIST_ROLL = constants.JOINT_NAMES.index("wrist_roll")
"""Index of ``wrist_roll`` among the six joints."""
WRIST_ROLL_MIDDLE_RAD = (SERVO_RANGE_LOW_RAD[WRIST_ROLL] + SERVO_RANGE_HIGH_RAD[WRIST_ROLL]) / 2
"""The middle of wrist_roll's range (rad): angles read back are those nearest to it."""


def wrap_rad(angle_rad: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class JointUnits:
    """The map between radians and one unit of the six joints.

    Each joint is affine, ``value = scale * radians + offset``, except ``wrist_roll``
    when ``wrist_roll_offset_rad`` is not zero: it is then shifted and wrapped, see
    :mod:`gym_soarm.real.units`.

    Attributes:
        name: one of :data:`UNITS`.
        scale: per-joint factor, shape (6,), all positive (but a calibrated arm's
            joint with drive_mode 1 in degrees, see :mod:`gym_soarm.real.calibration`).
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
            roll = np.asarray(radians, dtype=np.float64)[..., WRIST_ROLL]
            values[..., WRIST_ROLL] = (
                wrap_rad(roll + self.wrist_roll_offset_rad) * self.scale[WRIST_ROLL]
            )
        return values

    def to_radians(self, values: np.ndarray | Sequence[float]) -> np.ndarray:
        """Convert joint positions from these units to radians (float64, same shape)."""
        radians = (np.asarray(values, dtype=np.float64) - self.offset) / self.scale
        if self.wrist_roll_offset_rad:
            # Of the angles equal modulo a turn, the one nearest the middle of the range.
            roll = radians[..., WRIST_ROLL] - self.wrist_roll_offset_rad
            radians[..., WRIST_ROLL] = WRIST_ROLL_MIDDLE_RAD + wrap_rad(
                roll - WRIST_ROLL_MIDDLE_RAD
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
                low_rad[WRIST_ROLL] + self.wrist_roll_offset_rad,
                high_rad[WRIST_ROLL] + self.wrist_roll_offset_rad,
            )
            if not (-math.pi <= shifted[0] and shifted[1] <= math.pi):
                shifted = (-math.pi, math.pi)
            low[WRIST_ROLL], high[WRIST_ROLL] = np.multiply(shifted, self.scale[WRIST_ROLL])
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


def default_units(name: str) -> JointUnits:
    """The fixed map of ``name`` (one of :data:`UNITS`, unchecked), without any offset."""
    return _TABLE[name]


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
