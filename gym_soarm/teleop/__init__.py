"""Cartesian teleoperation: drive the jaw centre from the keyboard or a gamepad, record it.

Run ``python -m gym_soarm.teleop --help`` (also ``gym-soarm-teleop``). One OpenCV window
shows the cameras side by side over a status panel; keys move the jaw centre in the
robot's base frame (x forward, y to the robot's left, z up) and turn the jaws:

==========================  ======================================================
key (window focused)        does
==========================  ======================================================
W / S  (Up / Down)          jaw centre forward / back (base x)
A / D  (Left / Right)       jaw centre left / right (base y)
R / F  (PageUp / PageDown)  jaw centre up / down (base z)
I / K                       pitch the jaw tips away from / towards the shoulder
J / L                       roll the jaws counter-clockwise / clockwise (from above)
SPACE                       open / close the gripper
ENTER                       end the episode and save it (success as the task says)
BACKSPACE                   discard the episode and start it again
ESC or Q                    quit (saved episodes stay; so on closing the window, Ctrl-C)
==========================  ======================================================

A held key keeps moving (0.1 m/s and 1 rad/s of simulated time by default). With
``--root`` or ``--repo-id`` the episodes are recorded as a LeRobotDataset v3.0 with the
recorder's writer and features (:mod:`gym_soarm.record.record`): the action in the chosen
control mode, each episode's instruction, ``next.success`` per frame.

* :mod:`~gym_soarm.teleop.input`: keys and gamepad readings to motions and commands
  (no device needed).
* :mod:`~gym_soarm.teleop.session`: :class:`TeleopSession`, the window and the loop.
* :mod:`~gym_soarm.teleop.gamepad`: :class:`Gamepad`, read with the optional pygame.
"""

from __future__ import annotations

from gym_soarm.teleop.input import (
    COMMANDS,
    KEY_HELP,
    MOTION_AXES,
    GamepadLayout,
    KeyboardInput,
    TeleopSpeeds,
    gamepad_commands,
    gamepad_motion,
)
from gym_soarm.teleop.session import TeleopSession, TeleopSummary

__all__ = [
    "COMMANDS",
    "KEY_HELP",
    "MOTION_AXES",
    "GamepadLayout",
    "KeyboardInput",
    "TeleopSession",
    "TeleopSpeeds",
    "TeleopSummary",
    "gamepad_commands",
    "gamepad_motion",
]
