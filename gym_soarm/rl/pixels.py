"""A pixel student taught by the state expert: behaviour cloning and DAgger from the cameras.

``python -m gym_soarm.train --algo bc|dagger --task T --obs-type pixels_agent_pos
--camera-config front_wrist --observation-height 96 --observation-width 128 --out DIR``
trains a policy that sees only what a real arm gives: the camera images and ``agent_pos``
(the six measured joints). The task's state expert (:func:`gym_soarm.expert.make_expert`)
reads the simulation and labels every state the student visits: the demonstrations (DART
noise on the executed action, the clean label recorded) and, for DAgger, the states the
student itself drives the arm into.

The network (:func:`build_network`): one small convolutional encoder per camera (four
3x3/5x5 convolutions, two of stride 2) ending in a spatial softmax, whose keypoints (x, y of
each channel's soft arg-max) sit beside the normalised proprioception, then a two-layer
MLP to the action. The proprioception is what a real arm's policy has: ``agent_pos``, its
change over the last step (how fast the joints move) and the policy's own last command.
The student sends absolute joint targets (``control_mode="joint_pos"``, normalised) and
its network answers the change from its last command (scaled by :data:`RESIDUAL_SCALE`):
the expert's next target depends on the servo targets it moves from, which the measured
joints alone do not show (the recipe's normalised ``joint_delta``). Training augments the images with a
random shift (DrQ: pad by ``shift_px`` with the edge pixels, crop back at a random offset).

Frames are stored once, as uint8 at the learner's size, in a :class:`FrameStore` whose
size is bounded before anything runs: the recipe's ``max_memory_gb`` against the worst case
(every episode of the run at its step limit); a run that could exceed it is refused with
the figure and how to lower it. Each image is rendered once: the observation the
environment returns is the one stored and the one the student acts on.

The policy folder holds ``model.pt`` (the network's weights, its layout and the
``agent_pos`` statistics), ``settings.json`` (``"policy": "pixels"``, the environment with
its cameras and image size), ``curve.csv``/``curve.png``; :class:`PixelPolicy` loads it
for ``python -m gym_soarm.evaluate``, refusing observations of other cameras or sizes.
DAgger keeps the round that scored best on the protocol.
"""

from __future__ import annotations

import logging
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.rl.runs import check_run_numbers
from gym_soarm.validation import ArgumentTypeError, check_int, check_number

logger = logging.getLogger(__name__)

PIXEL_MODEL_FILE = "model.pt"
PIXEL_POLICY = "pixels"
"""The ``policy`` field of a pixel policy's ``settings.json``."""
PIXEL_OBS_TYPES: tuple[str, ...] = ("pixels_agent_pos",)
"""The observation types a pixel student learns from (the cameras and ``agent_pos``)."""
PROPRIO_STD_FLOOR: tuple[float, float, float] = (1e-2, 1e-3, 1e-2)
"""The smallest standard deviation of a joint angle (rad), of its change over a step (rad)
and of a command (normalised) in the normalisation."""
PROPRIO_DIM = 18
"""The student's proprioception: the six joint angles, their change over the last step
and the last command (six normalised absolute targets)."""
RESIDUAL_SCALE = 0.05
"""The network's output times this is the change of the command (normalised units, about
0.1 rad): outputs of order one for the expert's moves."""
AUX_DIM_BOUND = 32
"""At most this many auxiliary targets a step are counted in the memory bound."""
STUDENT_CONTROL = "joint_pos"
"""The control mode a pixel student acts in (normalised absolute joint targets)."""


def proprioception(agent_pos: Any, previous: Any, command: Any) -> np.ndarray:
    """``agent_pos``, its change since ``previous`` (the last step's; itself at a reset)
    and the last ``command``: (..., 18) float32."""
    pos = np.asarray(agent_pos, np.float32)
    change = pos - np.asarray(previous, np.float32)
    return np.concatenate([pos, change, np.asarray(command, np.float32)], axis=-1)


_NOT_TARGETS = frozenset({"is_success", "physics_unstable", "gripper_pos"})


def privileged_targets(info: Mapping[str, Any]) -> np.ndarray:
    """What the state expert reads, as the encoder's auxiliary targets (training only):
    the jaws' position, every object's position relative to them (each 3-vector
    ``*_pos`` of ``info``), the task's flags (``cube_lifted`` ...) and a cube's yaw as
    (cos, sin) of four times it (a cube looks the same turned by 90 degrees)."""
    gripper = np.asarray(info["gripper_pos"], np.float32)
    parts = [gripper]
    for key in sorted(info):
        value = info[key]
        if key in _NOT_TARGETS:
            continue
        if key.endswith("_pos") and np.shape(value) == (3,):
            parts.append(np.asarray(value, np.float32) - gripper)
        elif isinstance(value, (bool, np.bool_)):
            parts.append(np.float32([value]))
    yaw = info.get("cube_rotation_deg")
    if isinstance(yaw, (int, float, np.floating)) and not isinstance(yaw, bool):
        angle = np.deg2rad(4.0 * float(yaw))
        parts.append(np.float32([np.cos(angle), np.sin(angle)]))
    return np.concatenate(parts).astype(np.float32)


def is_pixel_env(env_kwargs: Mapping[str, Any]) -> bool:
    """Whether ``gym.make`` keywords ask for camera observations."""
    return str(env_kwargs.get("obs_type", "state")).startswith("pixels")


# --------------------------------------------------------------------------- data


class FrameStore:
    """Growable arrays of expert-labelled steps: uint8 frames per camera, the
    proprioception (:func:`proprioception`), the expert's label, the executed action, the
    auxiliary targets (:func:`privileged_targets`), the episode and the round of each step.

    Capacity grows by doubling up to ``max_samples`` (a ValueError past it), so the
    memory held is at most :meth:`bytes_per_sample` times twice the samples stored.
    """

    def __init__(
        self,
        cameras: Sequence[str],
        height: int,
        width: int,
        act_dim: int,
        max_samples: int,
        pos_dim: int = PROPRIO_DIM,
        aux_dim: int = 0,
    ) -> None:
        self.cameras = tuple(cameras)
        self.aux_dim = aux_dim
        self.aux = np.zeros((0, aux_dim), np.float32)
        self.shape = (height, width, 3)
        self.act_dim = act_dim
        self.pos_dim = pos_dim
        self.max_samples = max_samples
        self.size = 0
        self._capacity = 0
        self.frames: dict[str, np.ndarray] = {}
        self.proprio = np.zeros((0, pos_dim), np.float32)
        self.labels = np.zeros((0, act_dim), np.float32)
        self.executed = np.zeros((0, act_dim), np.float32)
        self.episode = np.zeros(0, np.int64)
        self.round = np.zeros(0, np.int64)
        self._grow(256)

    @staticmethod
    def bytes_per_sample(n_cameras: int, height: int, width: int, act_dim: int = 6) -> int:
        """Bytes one stored step takes: its frames, proprioception, two actions, two ids."""
        return n_cameras * height * width * 3 + 4 * (PROPRIO_DIM + 2 * act_dim + AUX_DIM_BOUND) + 16

    def __len__(self) -> int:
        return self.size

    def _grow(self, capacity: int) -> None:
        capacity = min(capacity, self.max_samples)
        n = self.size

        def grown(old: np.ndarray | None, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
            new = np.zeros((capacity, *shape), dtype)
            if old is not None and n:
                new[:n] = old[:n]
            return new

        for camera in self.cameras:
            self.frames[camera] = grown(self.frames.get(camera), self.shape, np.uint8)
        self.proprio = grown(self.proprio, (self.pos_dim,), np.float32)
        self.labels = grown(self.labels, (self.act_dim,), np.float32)
        self.executed = grown(self.executed, (self.act_dim,), np.float32)
        self.aux = grown(self.aux, (self.aux_dim,), np.float32)
        self.episode = grown(self.episode, (), np.int64)
        self.round = grown(self.round, (), np.int64)
        self._capacity = capacity

    def add(
        self,
        obs: dict[str, Any],
        previous: np.ndarray,
        command: np.ndarray,
        label: np.ndarray,
        executed: np.ndarray,
        episode: int,
        round_: int,
        aux: np.ndarray | None = None,
    ) -> None:
        """Store one step (its images are copied); ``previous``: the last step's
        ``agent_pos``, ``command``: the last action sent, ``aux``: its auxiliary targets."""
        if self.size == self._capacity:
            if self.size >= self.max_samples:
                raise ValueError(
                    f"the frame store is full ({self.max_samples} steps); raise max_memory_gb "
                    "or collect fewer episodes."
                )
            self._grow(2 * self._capacity)
        i = self.size
        for camera in self.cameras:
            self.frames[camera][i] = obs["pixels"][camera]
        self.proprio[i] = proprioception(obs["agent_pos"], previous, command)
        self.labels[i] = label
        self.executed[i] = executed
        if self.aux_dim:
            self.aux[i] = aux
        self.episode[i] = episode
        self.round[i] = round_
        self.size += 1

    def nbytes(self) -> int:
        """Bytes the arrays hold now (their capacity, not just the samples stored)."""
        arrays = [*self.frames.values(), self.proprio, self.labels, self.executed, self.aux]
        return sum(a.nbytes for a in arrays) + self.episode.nbytes + self.round.nbytes


# --------------------------------------------------------------------------- network


def build_network(
    cameras: Sequence[str],
    act_dim: int,
    channels: Sequence[int] = (16, 32, 32, 32),
    hidden: Sequence[int] = (256, 256),
    pos_dim: int = PROPRIO_DIM,
    downsample: int = 1,
    aux_dim: int = 0,
    aux_input: bool = False,
) -> Any:
    """The student: an encoder per camera (convolutions, spatial softmax), the
    proprioception beside their keypoints, an MLP to the action. Its ``forward(images,
    proprio)`` takes a dict of float images (N, 3, H, W) in [0, 1] and the normalised
    proprioception (N, 18). With ``aux_dim`` > 0 a second head (``aux``) reads the
    keypoints alone and answers the auxiliary targets of training
    (:func:`privileged_targets`); with ``aux_input`` its answer is also an input of the
    action's MLP (an estimate of the state from the images alone)."""
    from gym_soarm.rl.pixel_net import PixelNet

    return PixelNet(cameras, act_dim, channels, hidden, pos_dim, downsample, aux_dim, aux_input)


def random_shift(images: Any, pad: int, generator: Any) -> Any:
    """Shift each image of a (N, C, H, W) batch by up to ``pad`` pixels (edge padding,
    integer offsets drawn from ``generator``): DrQ's augmentation."""
    import torch
    from torch.nn import functional

    if pad <= 0:
        return images
    n, _, h, w = images.shape
    padded = functional.pad(images, (pad, pad, pad, pad), mode="replicate")
    c, device = images.shape[1], images.device
    shift = torch.randint(0, 2 * pad + 1, (n, 2), generator=generator).to(device)
    rows = (torch.arange(h, device=device)[None, :] + shift[:, :1]).view(n, 1, h, 1)
    picked = torch.gather(padded, 2, rows.expand(n, c, h, w + 2 * pad))
    cols = (torch.arange(w, device=device)[None, :] + shift[:, 1:]).view(n, 1, 1, w)
    return torch.gather(picked, 3, cols.expand(n, c, h, w))


def to_tensors(
    frames: Mapping[str, np.ndarray],
    proprio: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    device: Any,
) -> tuple[dict[str, Any], Any]:
    """uint8 (N, H, W, 3) frames and raw proprioception as the network's inputs."""
    import torch

    images = {
        camera: torch.as_tensor(np.ascontiguousarray(array), device=device)
        .permute(0, 3, 1, 2)
        .float()
        .div_(255.0)
        for camera, array in frames.items()
    }
    pos = torch.as_tensor((np.asarray(proprio, np.float32) - mean) / std, device=device)
    return images, pos


# --------------------------------------------------------------------------- policy


def command_map(env: Any) -> np.ndarray:
    """(scale, offset), each (6,): the student's normalised absolute command that sends
    the servos to joint angles ``q`` (rad) is ``q * scale + offset``, read off ``env``'s
    control mode."""
    control = env.unwrapped.control
    here = np.asarray(env.unwrapped.commanded_targets, np.float64)
    zero = np.asarray(control.action_for_targets(np.zeros(6), here), np.float64)
    one = np.asarray(control.action_for_targets(np.ones(6), here), np.float64)
    return np.stack([one - zero, zero]).astype(np.float32)


def command_at_reset(command_of_pos: np.ndarray, agent_pos: np.ndarray) -> np.ndarray:
    """The command that holds the joints at ``agent_pos`` (rad)."""
    scale, offset = command_of_pos
    return np.clip(np.asarray(agent_pos, np.float32) * scale + offset, -1.0, 1.0)


class PixelPolicy:
    """A pixel policy folder (or a network being trained) acting on observations.

    ``policy(obs, info)`` gives the action of one observation of an episode (it keeps
    the last ``agent_pos`` to see how the joints move; :meth:`reset` after each
    ``env.reset``); :meth:`act` of a list of them with their last ``agent_pos``.
    Observations of other cameras or image sizes than it was trained on are refused.
    """

    def __init__(
        self,
        net: Any,
        cameras: Sequence[str],
        image_shape: tuple[int, int],
        mean: np.ndarray,
        std: np.ndarray,
        command_of_pos: np.ndarray,
        device: Any = "cpu",
    ) -> None:
        self.net = net
        self.cameras = tuple(cameras)
        self.image_shape = tuple(image_shape)
        self.mean = np.asarray(mean, np.float32)
        self.std = np.asarray(std, np.float32)
        self.device = device
        self.command_of_pos = np.asarray(command_of_pos, np.float32)
        self._previous: np.ndarray | None = None
        self._command: np.ndarray | None = None

    @classmethod
    def load(cls, folder: str | os.PathLike[str], device: Any = "cpu") -> PixelPolicy:
        """Load the ``model.pt`` of a pixel policy folder."""
        import torch

        saved = torch.load(Path(folder) / PIXEL_MODEL_FILE, map_location=device, weights_only=True)
        layout = saved["layout"]
        net = build_network(
            layout["cameras"],
            layout["act_dim"],
            layout["channels"],
            layout["hidden"],
            downsample=layout.get("downsample", 1),
            aux_dim=layout.get("aux_dim", 0),
            aux_input=layout.get("aux_input", False),
        )
        net.load_state_dict(saved["weights"])
        net.to(device).eval()
        return cls(
            net,
            layout["cameras"],
            (layout["height"], layout["width"]),
            saved["mean"].numpy(),
            saved["std"].numpy(),
            saved["command_of_pos"].numpy(),
            device,
        )

    def check(self, obs: Any) -> None:
        """A ValueError unless ``obs`` holds this policy's cameras at its image size."""
        pixels = obs.get("pixels") if isinstance(obs, Mapping) else None
        if not isinstance(pixels, Mapping) or "agent_pos" not in obs:
            raise ValueError(
                "a pixel policy acts on obs_type='pixels_agent_pos' observations (a dict with "
                f"'pixels' and 'agent_pos'); got {type(obs).__name__}"
                + (f" with keys {sorted(obs)}" if isinstance(obs, Mapping) else "")
                + ". Make the environment with the policy's settings.json env."
            )
        got = {camera: tuple(np.shape(image)[:2]) for camera, image in pixels.items()}
        wanted = dict.fromkeys(self.cameras, self.image_shape)
        if got != wanted:
            raise ValueError(
                f"this policy was trained on cameras {list(self.cameras)} at "
                f"{self.image_shape[0]}x{self.image_shape[1]}; the observation has "
                + ", ".join(f"{camera} at {h}x{w}" for camera, (h, w) in got.items())
                + ". Evaluate it with the camera_config, observation_height and "
                "observation_width of its settings.json, or train one for these cameras."
            )

    def act(
        self,
        observations: Sequence[Any],
        previous: Sequence[np.ndarray] | None = None,
        commands: Sequence[np.ndarray] | None = None,
    ) -> np.ndarray:
        """The actions (float32, clipped to [-1, 1]) of a list of observations, given the
        ``agent_pos`` of each one's last step and the last action sent to each (None:
        right after a reset)."""
        import torch

        for obs in observations:
            self.check(obs)
        frames = {c: np.stack([obs["pixels"][c] for obs in observations]) for c in self.cameras}
        pos = np.stack([obs["agent_pos"] for obs in observations])
        if previous is None:
            previous = pos
        if commands is None:
            commands = self.command_at_reset(pos)
        commands = np.asarray(commands, np.float32)
        proprio = proprioception(pos, np.stack(previous), commands)
        images, pos_t = to_tensors(frames, proprio, self.mean, self.std, self.device)
        with torch.no_grad():
            change = self.net(images, pos_t).cpu().numpy()
        return np.clip(commands + RESIDUAL_SCALE * change, -1.0, 1.0).astype(np.float32)

    def command_at_reset(self, agent_pos: np.ndarray) -> np.ndarray:
        """The command that holds the joints at ``agent_pos``: the last command an episode
        starts from."""
        return command_at_reset(self.command_of_pos, agent_pos)

    def reset(self) -> None:
        """Forget the last step: the next call starts an episode."""
        self._previous = None
        self._command = None

    def __call__(self, obs: Any, info: dict[str, Any] | None = None) -> np.ndarray:
        if self._previous is None:
            action = self.act([obs])[0]
        else:
            action = self.act([obs], [self._previous], [self._command])[0]
        self._previous = np.array(obs["agent_pos"], np.float32)
        self._command = action
        return action


# --------------------------------------------------------------------------- settings


def check_pixel_settings(algo: str, settings: dict[str, Any]) -> dict[str, Any]:
    """Check the numbers of a pixel bc/dagger recipe; ValueError naming the key."""
    check_run_numbers(algo, settings, max_rounds=98)
    params = settings["algo"]
    params["shift_px"] = check_int("shift_px", params["shift_px"], 0)
    params["downsample"] = check_int("downsample", params["downsample"], 1, 8)
    params["max_memory_gb"] = check_number("max_memory_gb", params["max_memory_gb"], 0.0)
    params["aux_weight"] = check_number("aux_weight", params.get("aux_weight", 0.0), 0.0)
    aux_input = params.get("aux_input", False)
    if not isinstance(aux_input, bool):
        raise ArgumentTypeError(
            f"aux_input must be true or false (the auxiliary estimate as an input of the "
            f"action's MLP); got {aux_input!r}."
        )
    if params["max_memory_gb"] == 0:
        raise ValueError("max_memory_gb must be a number > 0; got 0.")
    for key, size in (("channels", 4), ("hidden", None)):
        value = params[key]
        if (
            not isinstance(value, (list, tuple))
            or not value
            or (size is not None and len(value) != size)
            or any(isinstance(u, bool) or not isinstance(u, int) or u < 1 for u in value)
        ):
            count = f"{size} " if size else ""
            raise ValueError(
                f"{key} must be a list of {count}layer widths >= 1 (e.g. "
                f"{list(PIXEL_DEFAULTS[key])}); got {value!r}."
            )
        params[key] = list(value)
    return settings


PIXEL_DEFAULTS: dict[str, Any] = {"channels": (16, 32, 32, 32), "hidden": (256, 256)}


# --------------------------------------------------------------------------- memory


def worst_case_samples(algo: str, params: Mapping[str, Any], max_episode_steps: int) -> int:
    """Steps a run stores if every episode lasts its step limit."""
    episodes = params["demos"]
    if algo == "dagger":
        episodes += params["rounds"] * params["episodes_per_round"]
    return episodes * max_episode_steps


def demos_within_store(algo: str, spec: Any, settings: dict[str, Any], floor: int) -> None:
    """Lower the recipe's ``demos`` towards ``floor`` (the recipe's own without the
    :data:`DRAWN_LOOKS <gym_soarm.rl.hyperparams.DRAWN_LOOKS>` row), to as many episodes
    as ``max_memory_gb`` holds beside the rounds' episodes, each counted at its step limit
    (the row's 300 on a 400-step task: 170); a warning says so. Never below ``floor``: a
    run that does not fit then is left for :func:`store_bound` to refuse, as is a
    ``demos`` the user passed (the caller does not lower that)."""
    params = settings["algo"]
    _, _, _, per_sample, worst, budget = store_bound(algo, spec, settings, check=False)
    rounds = worst // spec.max_episode_steps - params["demos"]  # the rounds' episodes
    fits = max(budget // spec.max_episode_steps - rounds, floor)
    if fits < params["demos"]:
        needed = worst * per_sample / 2**30
        warnings.warn(
            f"the recipe's {params['demos']} demonstrations under drawn looks would pass "
            f"max_memory_gb={params['max_memory_gb']} on {spec.name}; gathering {fits}. "
            f"To keep them pass max_memory_gb={math.ceil(needed)} (--hyperparams "
            f"max_memory_gb={math.ceil(needed)}), or demos=N to choose.",
            stacklevel=3,
        )
        params["demos"] = fits


def store_bound(
    algo: str, spec: Any, settings: Mapping[str, Any], check: bool = True
) -> tuple[tuple[str, ...], int, int, int, int, int]:
    """The cameras, image height and width, bytes a stored step, the steps a run could
    store at most and the steps ``max_memory_gb`` holds; a ValueError when the first is
    over the second (before anything runs)."""
    from gym_soarm.envs.settings import EnvSettings

    params = settings["algo"]
    resolved = EnvSettings.from_kwargs(task=spec.name, **settings["env"])
    cameras = tuple(resolved.camera_config)
    height, width = resolved.observation_height, resolved.observation_width
    per_sample = FrameStore.bytes_per_sample(len(cameras), height, width)
    worst = worst_case_samples(algo, params, spec.max_episode_steps)
    budget = int(params["max_memory_gb"] * 2**30 / per_sample)
    if check and worst > budget:
        raise ValueError(
            f"this run could store {worst} steps of {per_sample} bytes "
            f"({worst * per_sample / 2**30:.1f} GiB: {len(cameras)} cameras at {height}x{width}), "
            f"over max_memory_gb={params['max_memory_gb']}; collect fewer episodes, use smaller "
            "images or raise max_memory_gb (--hyperparams max_memory_gb=N)."
        )
    return cameras, height, width, per_sample, worst, budget


__all__ = [
    "PIXEL_MODEL_FILE",
    "PIXEL_OBS_TYPES",
    "FrameStore",
    "PixelPolicy",
    "build_network",
    "demos_within_store",
    "is_pixel_env",
    "privileged_targets",
    "random_shift",
    "store_bound",
]
