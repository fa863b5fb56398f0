"""A gamepad read through pygame (``pip install pygame``, or ``gym-soarm[teleop]``).

pygame is optional: only ``--gamepad`` needs it, and :class:`Gamepad` says how to
install it when it is missing. The mapping from axes and buttons to motions and
commands is :func:`gym_soarm.teleop.input.gamepad_motion` and
:func:`~gym_soarm.teleop.input.gamepad_commands`.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from gym_soarm.teleop.input import GamepadLayout, gamepad_commands, gamepad_motion
from gym_soarm.validation import check_int

PYGAME_FIX = "pip install pygame (or pip install 'gym-soarm[teleop]')"


def import_pygame() -> Any:
    """The pygame module, or an ImportError that says how to install it."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # no greeting on stdout
    try:
        import pygame
    except ImportError as exc:
        raise ImportError(
            f"the gamepad is read with pygame, which is not installed: {PYGAME_FIX}"
        ) from exc
    return pygame


class Gamepad:
    """The gamepad number ``index`` (0: the first one SDL finds).

    Args:
        index: which connected gamepad.
        layout: which axis and button does what.

    Raises:
        ImportError: pygame is not installed (the message names the command).
        RuntimeError: no gamepad with that index is connected.
        ValueError: the pad has fewer axes or buttons than ``layout`` uses.
    """

    def __init__(self, index: int = 0, layout: GamepadLayout | None = None) -> None:
        index = check_int("gamepad index", index, 0)
        pygame = import_pygame()
        self._pygame = pygame
        self.layout = layout or GamepadLayout()
        # Joystick state is updated by SDL's event pump, which needs its video subsystem
        # (no window is opened).
        pygame.display.init()
        pygame.joystick.init()
        count = pygame.joystick.get_count()
        if index >= count:
            self.close()
            raise RuntimeError(
                f"no gamepad number {index}: pygame finds {count} connected. Connect a "
                "gamepad (check that it shows up in /dev/input/js*), or leave out --gamepad "
                "to drive with the keyboard."
            )
        self._joystick = pygame.joystick.Joystick(index)
        self._joystick.init()
        self.name: str = self._joystick.get_name()
        axes, buttons = self._joystick.get_numaxes(), self._joystick.get_numbuttons()
        if axes < self.layout.axes_needed or buttons < self.layout.buttons_needed:
            self.close()
            raise ValueError(
                f"gamepad {self.name!r} has {axes} axes and {buttons} buttons; the layout "
                f"needs {self.layout.axes_needed} axes and {self.layout.buttons_needed} "
                "buttons. Use another gamepad."
            )
        self._previous: list[bool] = [False] * buttons

    def read(self) -> tuple[np.ndarray, list[str]]:
        """The current motion (five values in [-1, 1]) and the commands pressed since the last read."""
        self._pygame.event.pump()
        joystick = self._joystick
        axes = [joystick.get_axis(i) for i in range(joystick.get_numaxes())]
        buttons = [bool(joystick.get_button(i)) for i in range(joystick.get_numbuttons())]
        commands = gamepad_commands(self._previous, buttons, self.layout)
        self._previous = buttons
        return gamepad_motion(axes, buttons, self.layout), commands

    def close(self) -> None:
        """Release the gamepad and SDL (safe to call twice)."""
        self._pygame.joystick.quit()
        self._pygame.display.quit()
