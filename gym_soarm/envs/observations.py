"""What one environment reports: its observation, its info and its camera images.

An :class:`Observer` belongs to one :class:`~gym_soarm.envs.env.SoArmEnv`: it builds the
observation of its ``obs_type`` (state observations from the step core's arrays, pixel
observations rendered by one renderer per image size, created on first use and reused),
the info of a sound state, and a diverged step's copies of the last ones.
"""

from __future__ import annotations

import copy
import warnings
from typing import Any

import numpy as np

from gym_soarm import constants
from gym_soarm.envs.settings import STATE_OBS_TYPES, EnvSettings
from gym_soarm.envs.world import World
from gym_soarm.render.camera import CameraRenderer
from gym_soarm.sim.arrays import SimArrays, item
from gym_soarm.validation import check_choice, check_image_size


class Observer:
    """The observations and infos of ``world``'s environment.

    Args:
        world: the environment's world (its settings pick the observation).
    """

    def __init__(self, world: World) -> None:
        self.world = world
        s = world.settings
        self.cameras: tuple[str, ...] = s.camera_config if s.obs_type not in STATE_OBS_TYPES else ()
        """The cameras of pixel observations (none for state observations)."""
        self.size = (s.observation_height, s.observation_width)
        self.rgb, self.depth = "rgb" in s.image_modalities, "depth" in s.image_modalities
        self.segmentation = "segmentation" in s.image_modalities
        physics = world.physics
        self.camera_ids = {
            name: physics.model.name2id(name, "camera") for name in constants.CAMERA_NAMES
        }
        self.segment_of_geom = physics.geom_segments() if self.segmentation else None
        self.renderers: dict[tuple[int, int], CameraRenderer] = {}
        """The renderers made so far, by (height, width)."""
        self.last_obs: Any = None
        self.last_info: dict[str, Any] = {}

    @property
    def settings(self) -> EnvSettings:
        """The environment's settings (its world's)."""
        return self.world.settings

    # --- images ----------------------------------------------------------------------------
    def renderer(self, height: int, width: int) -> CameraRenderer:
        """The renderer of images of this size (created once, reused)."""
        renderer = self.renderers.get((height, width))
        if renderer is None:
            model = self.world.physics.model.ptr
            renderer = CameraRenderer(model, width, height, self.settings.render_quality)
            self.renderers[(height, width)] = renderer
        return renderer

    def image(self, camera: str, height: int | None = None, width: int | None = None) -> np.ndarray:
        """A fresh uint8 (H, W, 3) image of ``camera`` now (``height``/``width``: the
        observation's by default).

        Raises:
            ValueError: an unknown camera or a size outside 16 to 2048 pixels.
        """
        check_choice("camera", camera, constants.CAMERA_NAMES)
        h = self.size[0] if height is None else check_image_size("height", height)
        w = self.size[1] if width is None else check_image_size("width", width)
        data = self.world.physics.data.ptr
        return self.renderer(h, w).render(data, self.camera_ids[camera])

    def close(self) -> None:
        """Free every renderer and forget the last observation; safe to call twice."""
        for renderer in self.renderers.values():
            renderer.close()
        self.renderers.clear()
        self.last_obs = None

    # --- observations --------------------------------------------------------------------
    def observation(self, sim: SimArrays | None = None) -> Any:
        """The observation now (``sim``: this step's arrays of the simulation, if made)."""
        world, obs_type = self.world, self.settings.obs_type
        if obs_type == "state":
            sim = world.core.arrays() if sim is None else sim
            obs = world.core.state_observation(sim, world.chain.commanded)
        elif obs_type == "environment_state_agent_pos":
            sim = world.core.arrays() if sim is None else sim
            obs = {
                "agent_pos": world.units.from_radians(world.physics.joint_angles()),
                "environment_state": world.core.environment_state(sim),
            }
        elif self.settings.image_modalities != ("rgb",):
            obs = self._modality_observation()
        else:
            renderer = self.renderer(*self.size)
            data, ids = world.physics.data.ptr, self.camera_ids
            pixels = {name: renderer.render(data, ids[name]) for name in self.cameras}
            if obs_type == "pixels":
                obs = pixels
            else:
                obs = {
                    "pixels": pixels,
                    "agent_pos": world.units.from_radians(world.physics.joint_angles()),
                }
        self.last_obs = obs
        return obs

    def _modality_observation(self) -> dict[str, Any]:
        """A pixel observation with a dict of cameras per asked image modality."""
        renderer = self.renderer(*self.size)
        data = self.world.physics.data.ptr
        asked = (("pixels", self.rgb), ("depth", self.depth), ("segmentation", self.segmentation))
        images: dict[str, dict[str, np.ndarray]] = {key: {} for key, on in asked if on}
        for name in self.cameras:
            rgb, depth, segmentation = renderer.render_images(
                data, self.camera_ids[name], self.rgb, self.depth, self.segment_of_geom
            )
            for key, image in (("pixels", rgb), ("depth", depth), ("segmentation", segmentation)):
                if image is not None:
                    images[key][name] = image
        obs: dict[str, Any] = dict(images)
        if self.settings.obs_type == "pixels_agent_pos":
            obs["agent_pos"] = self.world.units.from_radians(self.world.physics.joint_angles())
        return obs

    # --- infos -----------------------------------------------------------------------------
    def info(
        self,
        sim: SimArrays | None = None,
        evaluation: dict[str, Any] | None = None,
        terms: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """The info of a sound state (a diverged step's comes from :meth:`diverged`).

        ``sim``, ``evaluation`` and ``terms``: the step's arrays, task evaluation and
        reward terms (one environment, unbatched); a reset evaluates the task here, once.
        """
        world = self.world
        task = world.task
        if sim is None:
            sim = world.core.arrays()
        if evaluation is None:
            evaluation = task.evaluate(sim)
        if terms is None:
            terms = task.batch_reward_terms(evaluation)
        task_info, gripper = world.core.info_values(sim, evaluation)
        self.last_info = {
            "is_success": bool(evaluation["success"]),
            **{key: item(value) for key, value in task_info.items()},
            "gripper_pos": gripper.copy(),
            "reward_terms": {name: float(value) for name, value in terms.items()},
            "task": task.instruction,
            "physics_unstable": False,
            **world.control.info(),
        }
        return self.last_info

    def diverged(self, reason: str) -> tuple[Any, dict[str, Any]]:
        """Warn that the physics diverged (``reason``: how) and that the episode is
        truncated; the observation and info of the diverged step: fresh copies of the last
        sound ones (the diverged state is not observed), not a success, every term 0.

        The warning names the caller of the environment's ``step`` (which calls this).
        """
        warnings.warn(
            f"The physics diverged ({reason}); the episode is truncated. Call reset() to "
            "start a clean episode.",
            RuntimeWarning,
            stacklevel=3,
        )
        info = copy.deepcopy(self.last_info)
        info.update(
            is_success=False,
            reward_terms=dict.fromkeys(info["reward_terms"], 0.0),
            physics_unstable=True,
        )
        return copy.deepcopy(self.last_obs), info
