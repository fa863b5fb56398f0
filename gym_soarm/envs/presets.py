"""Presets: registered ids that apply a whole interface contract at once.

``gym_soarm/SO101Tabletop-v0`` is LeRobot's SO-101 tabletop contract (Hugging Face's
``so101-tabletop`` simulation and the real arm's datasets) over ``PutCubesInBox-v0``:

* observations ``pixels.front`` and ``pixels.wrist``, 480 x 640 RGB, with ``agent_pos``;
* actions six absolute joint targets in the follower's units (degrees, gripper 0-100);
* 30 control steps (and frames) a second;
* reward the fraction of the four cubes in the green box, ``info["cubes_in_box"]``.

A policy trained on data in that contract (front and wrist images, 30 fps, follower
units) runs on it unchanged. Keywords of ``gym.make`` change a setting (a smaller image,
``render_mode``, randomisation); the camera keys stay ``front`` and ``wrist``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gym_soarm.envs.env import SoArmEnv
from gym_soarm.tasks.put_cubes_in_box import COLOURS
from gym_soarm.tasks.put_cubes_in_box import SPEC as TABLETOP_TASK
from gym_soarm.tasks.registry import register_preset_id

TABLETOP_ID = "gym_soarm/SO101Tabletop-v0"
TABLETOP_STEPS = 1200
"""The preset's step limit: 40 s at 30 Hz."""
TABLETOP_SETTINGS: dict[str, Any] = {
    "task": TABLETOP_TASK.name,
    "obs_type": "pixels_agent_pos",
    "camera_config": ("front_camera", "wrist_camera"),
    "observation_height": 480,
    "observation_width": 640,
    "units": "lerobot",
    "control_mode": "joint_pos",
    "control_hz": 30,
}
"""The contract as ``gym.make`` keywords."""
PIXEL_KEYS: dict[str, str] = {"front_camera": "front", "wrist_camera": "wrist"}
"""This package's camera names -> the contract's pixel keys."""


class TabletopContract(gym.Wrapper):
    """The contract's names and reward over a ``PutCubesInBox-v0`` environment: the
    cameras of ``obs["pixels"]`` renamed as ``keys`` maps them, and the reward the
    fraction of the cubes in the box (``info["cubes_in_box"] / 4``) on every step, the
    last one too (the task itself adds its success bonus there). ``agent_pos`` is bounded
    by the joints' own ranges in the follower's units, as the real follower reports them
    (the gripper 0-100): the bounds of the actions, a reading past them clipped."""

    def __init__(self, env: gym.Env, keys: dict[str, str]) -> None:
        super().__init__(env)
        self.keys = dict(keys)
        inner = env.observation_space["pixels"]
        joints = env.action_space
        self._low = joints.low.astype(np.float64)
        self._high = joints.high.astype(np.float64)
        self.observation_space = spaces.Dict(
            {
                **env.observation_space.spaces,
                "agent_pos": spaces.Box(self._low, self._high, dtype=np.float64),
                "pixels": spaces.Dict(
                    {self.keys.get(name, name): space for name, space in inner.spaces.items()}
                ),
            }
        )

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        """``observation`` with the contract's camera keys and ``agent_pos`` in its bounds."""
        pixels = {self.keys.get(name, name): image for name, image in observation["pixels"].items()}
        agent_pos = np.clip(np.asarray(observation["agent_pos"], np.float64), self._low, self._high)
        return {**observation, "agent_pos": agent_pos, "pixels": pixels}

    def reset(self, **kwargs: Any) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        return self.observation(obs), info

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        obs, _, terminated, truncated, info = self.env.step(action)
        reward = float(info["cubes_in_box"]) / len(COLOURS)
        return self.observation(obs), reward, terminated, truncated, info


def make_tabletop(**kwargs: Any) -> gym.Env:
    """The tabletop contract (:data:`TABLETOP_SETTINGS`, keywords override); the entry
    point of ``gym_soarm/SO101Tabletop-v0``.

    Raises:
        ValueError: a keyword that leaves the contract's observation layout (another
            ``obs_type`` or cameras), or any keyword ``gym.make`` refuses.
    """
    for key in ("obs_type", "camera_config"):
        value = kwargs.get(key, TABLETOP_SETTINGS[key])
        if key == "camera_config" and isinstance(value, (list, tuple)):
            value = tuple(value)
        if value != TABLETOP_SETTINGS[key]:
            raise ValueError(
                f"{TABLETOP_ID} observes {TABLETOP_SETTINGS[key]!r} as its {key}; got "
                f"{kwargs[key]!r}. Make {TABLETOP_TASK.env_id} for other observations."
            )
    return TabletopContract(SoArmEnv(**{**TABLETOP_SETTINGS, **kwargs}), PIXEL_KEYS)


def register_presets() -> None:
    """Register the preset ids (once)."""
    if TABLETOP_ID not in gym.registry:
        gym.register(
            id=TABLETOP_ID,
            entry_point="gym_soarm.envs.presets:make_tabletop",
            max_episode_steps=TABLETOP_STEPS,
        )
    register_preset_id(TABLETOP_ID, TABLETOP_TASK.name, TABLETOP_STEPS)


__all__ = [
    "PIXEL_KEYS",
    "TABLETOP_ID",
    "TABLETOP_SETTINGS",
    "TabletopContract",
    "make_tabletop",
    "register_presets",
]
