"""The observations of a :class:`~gym_soarm.envs.env.SoArmEnv` and their space, by ``obs_type``.

* ``"pixels"``: ``{camera: uint8 (H, W, 3)}`` for the configured cameras.
* ``"pixels_agent_pos"`` (default): ``{"pixels": {...}, "agent_pos": float64 (6,)}``.
* ``"environment_state_agent_pos"``: ``{"agent_pos": (6,), "environment_state": (N,)}``
  where ``environment_state`` follows the task's ``state_layout`` (pick-and-place: cube
  position (3, m), cube quaternion (w, x, y, z), ``gripperframe`` site position (3, m)
  and goal position (3, m)). Renders nothing.
* ``"state"``: one flat ``float32 (N,)`` vector for state policies: joint angles and
  velocities, the commanded servo targets, the jaws' centre, the task's environment
  state and the vectors from the jaws to each object and from each object to its goal,
  in radians and metres; the env's ``observation_names`` names every value (see
  :mod:`gym_soarm.tasks.state_observation`). Renders nothing.

With ``image_modalities`` beyond ``("rgb",)``, pixel observations hold one dict of
cameras per modality, keyed ``"pixels"`` (uint8 (H, W, 3), when ``"rgb"`` is asked),
``"depth"`` (float32 (H, W), metres along the camera axis, up to the far plane) and
``"segmentation"`` (int32 (H, W), ids of the env's ``segmentation_ids``): ``"pixels"``
observations become ``{"pixels": {...}, "depth": {...}, ...}`` and ``"pixels_agent_pos"``
ones gain the keys beside ``"pixels"`` and ``"agent_pos"``.

``agent_pos`` holds the six joint positions in the units of the action: radians by
default; with ``units="lerobot"`` the body joints in degrees and the gripper in 0 to 100
(0 = closed), as LeRobot's SO-101 follower; with ``units="lerobot_range"`` the body
joints in -100 to 100 (see :mod:`gym_soarm.real.units`). The action bounds follow; the
action space itself is the control mode's (:mod:`gym_soarm.envs.control`).

Dicts keep the order of their keys (Gymnasium sorts a plain dict's). The observations
themselves are built by :class:`gym_soarm.envs.observations.Observer`.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
from gymnasium import spaces

from gym_soarm import constants
from gym_soarm.envs.observations import Observer


def observation_space(observer: Observer) -> spaces.Space:
    """The space of ``observer``'s observations."""
    world = observer.world
    obs_type, cameras = observer.settings.obs_type, observer.cameras
    image = spaces.Box(0, 255, (*observer.size, 3), dtype=np.uint8)
    # Joint limits never come near +-pi rad (wrist_roll's range is the widest).
    n_joints = len(constants.JOINT_NAMES)
    agent_pos = spaces.Box(
        *world.units.bounds(np.full(n_joints, -np.pi), np.full(n_joints, np.pi)),
        dtype=np.float64,
    )
    # OrderedDict keeps our key order; Gymnasium sorts the keys of a plain dict.
    pixels = spaces.Dict(OrderedDict((name, image) for name in cameras))
    if obs_type == "pixels" and observer.settings.image_modalities == ("rgb",):
        return pixels
    if obs_type in ("pixels", "pixels_agent_pos"):
        layout: OrderedDict[str, spaces.Space] = OrderedDict()
        if observer.rgb:
            layout["pixels"] = pixels
        for key, box in _image_boxes(observer).items():
            layout[key] = spaces.Dict(OrderedDict((name, box) for name in cameras))
        if obs_type == "pixels_agent_pos":
            layout["agent_pos"] = agent_pos
        return spaces.Dict(layout)
    if obs_type == "state":
        return world.core.state_observer.space
    env_state = spaces.Box(*world.task.state_bounds(), dtype=np.float64)
    return spaces.Dict(OrderedDict(agent_pos=agent_pos, environment_state=env_state))


def _image_boxes(observer: Observer) -> dict[str, spaces.Box]:
    """The Box of one camera's depth and segmentation images, of those asked."""
    model = observer.world.physics.model
    boxes: dict[str, spaces.Box] = {}
    if observer.depth:  # metres along the camera axis, up to the far plane
        far = float(np.float32(model.vis.map.zfar * model.stat.extent))
        boxes["depth"] = spaces.Box(0.0, far, observer.size, dtype=np.float32)
    if observer.segmentation:
        n_segments = len(observer.world.physics.segmentation_ids())
        boxes["segmentation"] = spaces.Box(0, n_segments - 1, observer.size, dtype=np.int32)
    return boxes
