"""The pixel student's trainer (``python -m gym_soarm.train --algo bc|dagger --obs-type
pixels_agent_pos``): the DAgger loop of :mod:`gym_soarm.rl.dagger` with a student that
sees the cameras (:mod:`gym_soarm.rl.pixels`).

:class:`PixelTrainer` holds the student's side: its frame store, its network and
optimiser, the normalisation of the proprioception and of the auxiliary targets (what
the state expert reads, :func:`privileged_targets <gym_soarm.rl.pixels.privileged_targets>`:
trained beside the action, never used to act). Each fit pools the frames gathered since
the last one down by ``downsample`` once, so an epoch costs the network alone.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.rl.dagger import Gathering, ImitationTrainer
from gym_soarm.rl.pixels import (
    PIXEL_MODEL_FILE,
    PIXEL_POLICY,
    PROPRIO_DIM,
    PROPRIO_STD_FLOOR,
    RESIDUAL_SCALE,
    FrameStore,
    PixelPolicy,
    build_network,
    command_at_reset,
    command_map,
    privileged_targets,
    random_shift,
    store_bound,
)
from gym_soarm.rl.runs import episode_weights

logger = logging.getLogger(__name__)

AUX_STD_FLOOR = 1e-3
"""The smallest standard deviation of an auxiliary target in its normalisation."""


def camera_obs(obs: Any, index: int) -> dict[str, Any]:
    """Environment ``index``'s observation out of a vector env's pixel observation."""
    return {
        "pixels": {camera: image[index] for camera, image in obs["pixels"].items()},
        "agent_pos": obs["agent_pos"][index],
    }


class PixelTrainer(ImitationTrainer):
    """A pixel student of ``spec``'s state expert (see :class:`ImitationTrainer
    <gym_soarm.rl.dagger.ImitationTrainer>` for the arguments and the loop): the frames
    in a :class:`FrameStore`, the network of :func:`build_network`, trained on the change
    of command plus the auxiliary targets."""

    rng_stream = 25

    def setup(self) -> None:
        import torch  # before any GL context: see docs/learning.md (torch and Mesa's LLVM)

        algo, spec, settings, seed = self.algo, self.spec, self.settings, self.seed
        self.cameras, self.height, self.width, per_sample, worst, budget = store_bound(
            algo, spec, settings
        )
        logger.info(
            "pixel store: %d bytes a step, at most %d steps (%.2f GiB)",
            per_sample,
            worst,
            worst * per_sample / 2**30,
        )
        torch.set_num_threads(settings["torch_threads"])
        torch.manual_seed(seed)
        # The first optimizer imports its optional compilers now, before a GL context exists.
        torch.optim.Adam([torch.zeros(1, requires_grad=True)])
        self.capacity = min(worst, budget)
        self.store: FrameStore | None = None
        self.net: Any = None
        self.optimizer: Any = None
        self.mean = self.std = self.aux_mean = self.aux_std = None
        self._pooled: dict[str, Any] = {}
        self.generator = torch.Generator().manual_seed(seed)
        kind = "BC" if algo == "bc" else "DAgger"
        self.title = f"{kind} from pixels on {spec.name}, seed {seed}"

    def make_vector_env(self) -> Any:
        venv = super().make_vector_env()
        first = venv.envs[0]
        self.command_of_pos = command_map(first)
        act_dim = venv.single_action_space.shape[0]
        self.previous = np.zeros((venv.num_envs, 6), np.float32)
        self.command = np.zeros((venv.num_envs, act_dim), np.float32)
        return venv

    @property
    def aux_input(self) -> bool:
        """Whether the auxiliary estimate feeds the action (the recipe's, when there are
        auxiliary targets)."""
        return bool(self.params.get("aux_input", False)) and self.store.aux_dim > 0

    @property
    def model_path(self) -> Path:
        return self.out_path / PIXEL_MODEL_FILE

    # ----------------------------------------------------------------------- gathering
    def stored(self) -> int:
        return 0 if self.store is None else len(self.store)

    def begin_episodes(self, run: Gathering, mask: np.ndarray) -> None:
        pos = np.asarray(run.obs["agent_pos"], np.float32)
        self.previous[mask] = pos[mask]
        self.command[mask] = command_at_reset(self.command_of_pos, pos[mask])
        if self.store is None:
            aux_dim = len(privileged_targets(run.infos[0])) if self.params["aux_weight"] else 0
            self.store = FrameStore(
                self.cameras, self.height, self.width, self.command.shape[1], self.capacity,
                aux_dim=aux_dim,
            )  # fmt: skip

    def after_step(self, before: Any, executed: np.ndarray) -> None:
        self.previous = np.asarray(before["agent_pos"], np.float32).copy()
        self.command = np.asarray(executed, np.float32).copy()

    def record(
        self, run: Gathering, live: np.ndarray, labels: Any, executed: Any, round_: int
    ) -> None:
        for i in np.flatnonzero(live):
            self.store.add(
                camera_obs(run.obs, i), self.previous[i], self.command[i], labels[i],
                executed[i], run.episode[i], round_, privileged_targets(run.infos[i]),
            )  # fmt: skip

    def student_actions(self, run: Gathering, mask: np.ndarray) -> np.ndarray:
        chosen = np.flatnonzero(mask)
        return self.policy().act(
            [camera_obs(run.obs, i) for i in chosen], self.previous[mask], self.command[mask]
        )

    # ----------------------------------------------------------------------- the network
    def start_learning(self) -> None:
        """The normalisations (from the demonstrations) and a fresh network and optimiser."""
        import torch

        store, params = self.store, self.params
        n = len(store)
        floor = np.repeat(np.asarray(PROPRIO_STD_FLOOR, np.float32), PROPRIO_DIM // 3)
        self.mean = store.proprio[:n].mean(axis=0).astype(np.float32)
        self.std = np.maximum(store.proprio[:n].std(axis=0), floor).astype(np.float32)
        self.aux_mean = store.aux[:n].mean(axis=0).astype(np.float32)
        self.aux_std = np.maximum(store.aux[:n].std(axis=0), AUX_STD_FLOOR).astype(np.float32)
        self.net = build_network(
            self.cameras,
            store.act_dim,
            params["channels"],
            params["hidden"],
            downsample=params["downsample"],
            aux_dim=store.aux_dim,
            aux_input=self.aux_input,
        ).to(self.device)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=params["learning_rate"])

    def pooled_frames(self) -> dict[str, Any]:
        """Every stored frame averaged down by ``downsample`` (uint8, (N, 3, h, w), on the
        training device), pooled once: each fit pools only the steps gathered since."""
        import torch
        from torch.nn import functional

        n, factor = len(self.store), self.params["downsample"]
        for camera in self.cameras:
            done = self._pooled.get(camera)
            begin = 0 if done is None else len(done)
            parts = [] if done is None else [done]
            for chunk in range(begin, n, 1024):
                end = min(chunk + 1024, n)
                images = torch.from_numpy(self.store.frames[camera][chunk:end]).to(self.device)
                images = images.permute(0, 3, 1, 2).float()
                if factor > 1:
                    images = functional.avg_pool2d(images, factor)
                parts.append(images.round_().to(torch.uint8))
            self._pooled[camera] = torch.cat(parts) if len(parts) > 1 else parts[0]
        return self._pooled

    def fit(self, epochs: int) -> float:
        """``epochs`` passes of regression over everything stored: the expert's change of
        command (mean squared error) plus ``aux_weight`` times that of the auxiliary
        targets; returns the last pass's mean action loss."""
        import torch

        store, params, device = self.store, self.params, self.device
        n, act_dim = len(store), store.act_dim
        frames = self.pooled_frames()
        shift = params["shift_px"] // params["downsample"]
        proprio = torch.as_tensor((store.proprio[:n] - self.mean) / self.std, device=device)
        change = (store.labels[:n] - store.proprio[:n, -act_dim:]) / RESIDUAL_SCALE
        change = torch.as_tensor(change, device=device)
        aux = torch.as_tensor((store.aux[:n] - self.aux_mean) / self.aux_std, device=device)
        weight = torch.as_tensor(episode_weights(store.episode[:n], params), device=device)
        batch = params["batch_size"]
        schedule = self.fit_rates(epochs, n)
        self.net.train()
        loss_value, began = float("nan"), time.perf_counter()
        for epoch in range(epochs):
            order = torch.randperm(n, generator=self.generator).to(device)
            total = 0.0
            for step, begin in enumerate(range(0, n, batch)):
                for group in self.optimizer.param_groups:
                    group["lr"] = schedule(epoch, step)
                index = order[begin : begin + batch]
                images = {
                    c: random_shift(frames[c][index].float().div_(255.0), shift, self.generator)
                    for c in self.cameras
                }
                total += self.update(
                    images, proprio[index], change[index], aux[index], weight[index]
                )
            loss_value = total / n
            if self.stop():
                break
        self.net.eval()
        seconds = time.perf_counter() - began
        logger.info(
            "%s: %d epochs over %d samples in %.0f s (%.0f samples a second)",
            self.title, epochs, n, seconds, epochs * n / max(seconds, 1e-9),
        )  # fmt: skip
        return loss_value

    def update(
        self, images: dict[str, Any], proprio: Any, change: Any, aux: Any, weight: Any
    ) -> float:
        """One optimiser step on a minibatch (each sample's squared errors times its
        ``weight``); returns its summed action loss."""
        import torch

        keypoints = self.net.encode(images, pooled=True)
        squared = (self.net.act_from(keypoints, proprio) - change).square().mean(dim=1)
        action_loss = (squared * weight).mean()
        loss = action_loss
        if self.net.aux is not None:
            aux_squared = (self.net.aux(keypoints) - aux).square().mean(dim=1)
            loss = loss + self.params["aux_weight"] * (aux_squared * weight).mean()
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        with torch.no_grad():
            return action_loss.item() * len(change)

    # ----------------------------------------------------------------------- the folder
    def policy(self) -> PixelPolicy:
        return PixelPolicy(
            self.net,
            self.cameras,
            (self.height, self.width),
            self.mean,
            self.std,
            self.command_of_pos,
            self.device,
        )

    def on_interrupt(self) -> None:
        if self.net is not None and not self.model_path.exists():
            self.save()
            self.write_settings()

    def extra_settings(self) -> dict[str, Any]:
        return {
            "policy": PIXEL_POLICY,
            "cameras": list(self.cameras),
            "image_size": [self.height, self.width],
        }

    def save(self) -> None:
        import torch

        params = self.params
        layout = {
            "cameras": list(self.cameras),
            "height": self.height,
            "width": self.width,
            "act_dim": self.store.act_dim,
            "channels": list(params["channels"]),
            "hidden": list(params["hidden"]),
            "downsample": params["downsample"],
            "aux_dim": self.store.aux_dim,
            "aux_input": self.aux_input,
        }
        weights = {k: v.detach().cpu() for k, v in self.net.state_dict().items()}
        torch.save(
            {
                "layout": layout,
                "weights": weights,
                "mean": torch.as_tensor(self.mean),
                "std": torch.as_tensor(self.std),
                "command_of_pos": torch.as_tensor(self.command_of_pos),
            },
            self.model_path,
        )


__all__ = ["PixelTrainer"]
