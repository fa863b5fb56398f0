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
wrist_roll offset below; :mod:`gym_soarm.real.unit_maps` holds those figures once and the
environment, the recorder and the dataset use them through this module.

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

import numpy as np

from gym_soarm.real.calibration import calibrated_units
from gym_soarm.real.unit_maps import (
    FEATURE_NAMES,
    LEROBOT,
    LEROBOT_RANGE,
    RADIANS,
    SERVO_RANGE_HIGH_RAD,
    SERVO_RANGE_LOW_RAD,
    UNITS,
    JointUnits,
    check_wrist_roll_offset,
    default_units,
)

__all__ = [
    "FEATURE_NAMES",
    "LEROBOT",
    "LEROBOT_RANGE",
    "RADIANS",
    "SERVO_RANGE_HIGH_RAD",
    "SERVO_RANGE_LOW_RAD",
    "UNITS",
    "JointUnits",
    "check_wrist_roll_offset",
    "joint_units",
    "lerobot_to_radians",
    "radians_to_lerobot",
    "radians_to_units",
    "units_to_radians",
]


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
            that arm instead of the fixed maps here (see :mod:`gym_soarm.real.calibration`).

    Raises:
        ValueError: ``units`` is not one of :data:`UNITS`, the offset is invalid (see
            :func:`check_wrist_roll_offset`), or the calibration file is missing or
            malformed, or comes with ``units="radians"``.
        TypeError: the offset is not a real number, or ``calibration`` not a path.
    """
    if not isinstance(units, str) or units not in UNITS:
        raise ValueError(
            f"units must be one of {', '.join(repr(u) for u in UNITS)}; got {units!r}."
        )
    if calibration is not None:
        return calibrated_units(units, calibration, wrist_roll_offset_deg)
    offset = check_wrist_roll_offset(units, wrist_roll_offset_deg)
    if not offset:
        return default_units(units)
    table = default_units(units)
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
    return default_units(LEROBOT).from_radians(radians)


def lerobot_to_radians(values: np.ndarray | Sequence[float]) -> np.ndarray:
    """LeRobot follower units (body degrees, gripper 0 to 100) to radians."""
    return default_units(LEROBOT).to_radians(values)
