"""Keys and gamepad sticks to jaw motions: the teleoperation's input, free of any device.

A motion is five numbers in [-1, 1], one per degree of freedom of the jaws in the
robot's base frame (:data:`MOTION_AXES`: x forward, y to the robot's left, z up, pitch,
roll); :meth:`TeleopSpeeds.ee_delta` scales it into an ``ee_delta`` action of
:mod:`gym_soarm.envs.control`. Commands (open/close the gripper, save, discard, quit) are
the other inputs.

The keyboard arrives as key presses only (OpenCV windows report no key releases): a
press moves its axis for :data:`KEY_HOLD_S` seconds of wall-clock time, and at least one
step; a held key repeats (the keyboard's auto-repeat) and so keeps moving.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from gym_soarm import constants
from gym_soarm.envs.control import EE_ANGLE_DELTA_LIMIT_RAD, EE_DELTA_LIMIT_M
from gym_soarm.validation import check_dataclass_fields, check_int, check_number

MOTION_AXES: tuple[str, ...] = ("x", "y", "z", "pitch", "roll")
"""The five motion axes: the jaw centre's base-frame x (forward), y (left), z (up), and
the jaws' pitch (positive: tips away from the shoulder) and roll (positive:
counter-clockwise seen from above with the jaws down)."""

GRIPPER = "gripper"
"""Command: open the gripper if it is closed, close it if it is open."""
SAVE = "save"
"""Command: end the episode and save it (its success as the task says)."""
DISCARD = "discard"
"""Command: drop the episode's frames and start it again."""
QUIT = "quit"
"""Command: stop (saved episodes stay)."""
COMMANDS: tuple[str, ...] = (GRIPPER, SAVE, DISCARD, QUIT)

MAX_SPEED_M_S = EE_DELTA_LIMIT_M / constants.CONTROL_TIMESTEP_S
"""The fastest jaw centre motion (m/s): ``ee_delta``'s 1 cm per 20 ms step."""
MAX_TURN_SPEED_RAD_S = EE_ANGLE_DELTA_LIMIT_RAD / constants.CONTROL_TIMESTEP_S
"""The fastest pitch and roll motion (rad/s): ``ee_delta``'s 0.1 rad per step."""

KEY_HOLD_S = 0.12
"""How long one key press keeps its axis moving (s): longer than the gap between a held
key's repeats (25 to 33 a second on most systems), so a held key moves without pause."""

# OpenCV's waitKeyEx codes: letters and control keys as ASCII, the others as X11 keysyms.
_UP, _DOWN, _LEFT, _RIGHT, _PAGE_UP, _PAGE_DOWN = 65362, 65364, 65361, 65363, 65365, 65366
_ENTER, _KEYPAD_ENTER, _BACKSPACE, _DELETE, _ESC = 13, 10, 8, 65535, 27

MOTION_KEYS: dict[str, tuple[int, int]] = {
    "w": (0, +1),
    "s": (0, -1),
    "a": (1, +1),
    "d": (1, -1),
    "r": (2, +1),
    "f": (2, -1),
    "i": (3, +1),
    "k": (3, -1),
    "j": (4, +1),
    "l": (4, -1),
}
"""Letter -> (motion axis, direction). Upper case works the same."""

_EXTRA_MOTION_CODES: dict[int, tuple[int, int]] = {
    _UP: (0, +1),
    _DOWN: (0, -1),
    _LEFT: (1, +1),
    _RIGHT: (1, -1),
    _PAGE_UP: (2, +1),
    _PAGE_DOWN: (2, -1),
}
_COMMAND_CODES: dict[int, str] = {
    ord(" "): GRIPPER,
    _ENTER: SAVE,
    _KEYPAD_ENTER: SAVE,
    _BACKSPACE: DISCARD,
    _DELETE: DISCARD,
    _ESC: QUIT,
    ord("q"): QUIT,
    ord("Q"): QUIT,
}

KEY_HELP: tuple[tuple[str, str], ...] = (
    ("W / S  (Up / Down)", "jaw centre forward / back (base x)"),
    ("A / D  (Left / Right)", "jaw centre left / right (base y)"),
    ("R / F  (PageUp / PageDown)", "jaw centre up / down (base z)"),
    ("I / K", "pitch the jaw tips away from / towards the shoulder"),
    ("J / L", "roll the jaws counter-clockwise / clockwise (seen from above)"),
    ("SPACE", "open / close the gripper"),
    ("ENTER", "end the episode and save it (success as the task says)"),
    ("BACKSPACE", "discard the episode and start it again"),
    ("ESC or Q", "quit (saved episodes stay; so does closing the window or Ctrl-C)"),
)
"""The key map as (keys, what they do), for the window, ``--help`` and the docs."""


def motion_code(code: int) -> tuple[int, int] | None:
    """(axis, direction) that a waitKeyEx code moves, or None."""
    if 0 <= code < 128 and chr(code).lower() in MOTION_KEYS:
        return MOTION_KEYS[chr(code).lower()]
    return _EXTRA_MOTION_CODES.get(code)


def command_code(code: int) -> str | None:
    """The command (:data:`COMMANDS`) of a waitKeyEx code, or None."""
    return _COMMAND_CODES.get(code)


class KeyboardInput:
    """Key presses turned into a motion that lasts while the key is held.

    A press of a motion key moves its axis for ``hold_s`` seconds from the press, and
    in at least the next step even if that comes later; pressing the opposite key
    reverses at once.

    Args:
        hold_s: how long a press keeps its axis moving (s).
    """

    def __init__(self, hold_s: float = KEY_HOLD_S) -> None:
        self.hold_s = check_number("hold_s", hold_s, 0.0, "seconds")
        self._until = np.full(len(MOTION_AXES), -np.inf)
        self._direction = np.zeros(len(MOTION_AXES))
        self._pending = np.zeros(len(MOTION_AXES), dtype=bool)

    def press(self, code: int, now_s: float) -> str | None:
        """Take one key press (a waitKeyEx code; -1 for none) at time ``now_s``.

        Returns:
            The key's command (:data:`COMMANDS`), or None for motion and unknown keys.
        """
        motion = motion_code(code)
        if motion is not None:
            axis, direction = motion
            self._direction[axis] = direction
            self._until[axis] = now_s + self.hold_s
            self._pending[axis] = True
            return None
        return command_code(code)

    def motion(self, now_s: float) -> np.ndarray:
        """The motion (:data:`MOTION_AXES`, each -1, 0 or 1) for a step taken now."""
        active = self._pending | (now_s < self._until)
        self._pending[:] = False
        return np.where(active, self._direction, 0.0)

    def clear(self) -> None:
        """Stop every motion (a new episode starts still)."""
        self._until[:] = -np.inf
        self._pending[:] = False


@dataclasses.dataclass(frozen=True)
class GamepadLayout:
    """Which gamepad axes and buttons do what (indices as pygame's joystick numbers them).

    The defaults fit an Xbox-style pad under SDL on Linux: left stick x/y, right stick
    z (vertical) and roll (horizontal), shoulder buttons pitch, A the gripper, Start
    saves, Back discards. A stick pushed up or left reads negative.

    Attributes:
        x_axis: pushed up moves the jaw centre forward.
        y_axis: pushed left moves it to the robot's left.
        z_axis: pushed up moves it up.
        roll_axis: pushed left rolls the jaws counter-clockwise.
        pitch_up_button: held, pitches the tips away from the shoulder.
        pitch_down_button: held, pitches them towards it.
        gripper_button: opens or closes the gripper.
        save_button: ends and saves the episode.
        discard_button: discards the episode.
        dead_zone: stick readings below this magnitude count as 0 (the rest is
            rescaled to reach 1 at full deflection).
    """

    x_axis: int = 1
    y_axis: int = 0
    z_axis: int = 4
    roll_axis: int = 3
    pitch_up_button: int = 5
    pitch_down_button: int = 4
    gripper_button: int = 0
    save_button: int = 7
    discard_button: int = 6
    dead_zone: float = 0.15

    def __post_init__(self) -> None:
        check_dataclass_fields(
            self,
            lambda name: name != "dead_zone",
            lambda name, value, fix: check_int(name, value, 0, fix=fix),
        )
        zone = check_number("dead_zone", self.dead_zone, 0.0)
        if zone >= 1.0:
            raise ValueError(f"dead_zone must be >= 0 and < 1; got {self.dead_zone!r}.")

    @property
    def axes_needed(self) -> int:
        """The number of axes a pad needs for this layout."""
        return 1 + max(self.x_axis, self.y_axis, self.z_axis, self.roll_axis)

    @property
    def buttons_needed(self) -> int:
        """The number of buttons a pad needs for this layout."""
        return 1 + max(
            self.pitch_up_button,
            self.pitch_down_button,
            self.gripper_button,
            self.save_button,
            self.discard_button,
        )


def _stick(value: float, dead_zone: float) -> float:
    magnitude = abs(float(value))
    if not np.isfinite(magnitude) or magnitude <= dead_zone:
        return 0.0
    return float(np.sign(value)) * min(1.0, (magnitude - dead_zone) / (1.0 - dead_zone))


def gamepad_motion(
    axes: Sequence[float], buttons: Sequence[bool], layout: GamepadLayout
) -> np.ndarray:
    """The motion (:data:`MOTION_AXES`, each in [-1, 1]) of a gamepad's axes and buttons.

    Args:
        axes: every axis reading in [-1, 1] (pygame's ``Joystick.get_axis``).
        buttons: every button, pressed or not.
        layout: which axis and button does what.

    Raises:
        ValueError: the pad has fewer axes or buttons than ``layout`` uses.
    """
    if len(axes) < layout.axes_needed or len(buttons) < layout.buttons_needed:
        raise ValueError(
            f"the gamepad layout needs {layout.axes_needed} axes and {layout.buttons_needed} "
            f"buttons; got {len(axes)} axes and {len(buttons)} buttons. Choose a "
            "GamepadLayout whose indices fit the pad."
        )
    zone = layout.dead_zone
    pitch = float(bool(buttons[layout.pitch_up_button])) - float(
        bool(buttons[layout.pitch_down_button])
    )
    return np.array(
        [
            -_stick(axes[layout.x_axis], zone),
            -_stick(axes[layout.y_axis], zone),
            -_stick(axes[layout.z_axis], zone),
            pitch,
            -_stick(axes[layout.roll_axis], zone),
        ]
    )


def gamepad_commands(
    previous: Sequence[bool], buttons: Sequence[bool], layout: GamepadLayout
) -> list[str]:
    """The commands of the buttons pressed since ``previous`` (pressed now, not before)."""
    pressed = [
        (layout.gripper_button, GRIPPER),
        (layout.save_button, SAVE),
        (layout.discard_button, DISCARD),
    ]
    return [
        command
        for button, command in pressed
        if buttons[button] and not (button < len(previous) and previous[button])
    ]


@dataclasses.dataclass(frozen=True)
class TeleopSpeeds:
    """How fast a full motion moves the jaws, in simulated time.

    Attributes:
        linear_m_s: the jaw centre's speed along each base axis (m/s, at most 0.5:
            ``ee_delta``'s 1 cm per 20 ms step).
        angular_rad_s: the pitch's and roll's speed (rad/s, at most 5).
        step_s: the environment's step (s).
    """

    linear_m_s: float = 0.1
    angular_rad_s: float = 1.0
    step_s: float = 0.02

    def __post_init__(self) -> None:
        step = check_number("step_s", self.step_s, 0.0, "seconds")
        if step <= 0.0:
            raise ValueError(f"step_s must be above 0 seconds; got {step!r}.")
        limits = {
            "linear_m_s": (EE_DELTA_LIMIT_M / step, "m/s"),
            "angular_rad_s": (EE_ANGLE_DELTA_LIMIT_RAD / step, "rad/s"),
        }
        for name, (limit, unit) in limits.items():
            value = check_number(name, getattr(self, name), 0.0, unit)
            if not 0.0 < value <= limit + 1e-9:
                raise ValueError(
                    f"{name} must be above 0 and at most {limit:g} {unit}; got {value!r}."
                )

    def ee_delta(self, motion: np.ndarray, gripper: float) -> np.ndarray:
        """The ``ee_delta`` action ``[dx, dy, dz, d_pitch, d_roll, gripper]`` of a motion.

        Args:
            motion: five values in [-1, 1] (:data:`MOTION_AXES`).
            gripper: the gripper's absolute target.
        """
        scale = np.array([self.linear_m_s] * 3 + [self.angular_rad_s] * 2) * self.step_s
        change = np.clip(np.asarray(motion, dtype=np.float64), -1.0, 1.0) * scale
        return np.append(change, float(gripper))
