"""The pixel student's trainer (``python -m gym_soarm.train --algo bc|dagger --obs-type
pixels_agent_pos``): collect expert-labelled steps from the cameras, fit the network of
:mod:`gym_soarm.rl.pixels`, evaluate on the protocol, keep the best round.

:class:`PixelTrainer` holds a run: its frame store, its network and optimiser, the
normalisation of the proprioception and of the auxiliary targets, the curve. DAgger's
rounds are warm-started (the network goes on from the last round, ``round_epochs`` passes
over everything gathered) and stop once ``patience`` rounds in a row failed to beat the
best evaluation, or after ``rounds``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.expert import make_expert
from gym_soarm.rl.evaluation import POLICY_FORMAT, SETTINGS_FILE, make_env, score
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
from gym_soarm.rl.runs import Curve, dart_noise, training_seeds, write_run_settings
from gym_soarm.tasks.suites import EVAL_SEED

logger = logging.getLogger(__name__)

AUX_STD_FLOOR = 1e-3
"""The smallest standard deviation of an auxiliary target in its normalisation."""


class _Episode:
    """One environment's episode while the trainer gathers: its observation and info,
    the episode's number, the last step's ``agent_pos`` and the last command sent."""

    def __init__(self, obs: Any, info: dict[str, Any], number: int, command: np.ndarray) -> None:
        self.obs, self.info, self.number = obs, info, number
        self.previous = np.asarray(obs["agent_pos"], np.float32)
        self.command = command

    def advance(self, obs: Any, info: dict[str, Any], command: np.ndarray) -> None:
        self.previous = np.asarray(self.obs["agent_pos"], np.float32)
        self.obs, self.info, self.command = obs, info, command


class PixelTrainer:
    """A pixel student of ``spec``'s state expert trained into ``out_path``.

    Args:
        algo: ``"bc"`` or ``"dagger"``.
        spec: the task's spec (it must have a state expert).
        out_path: the run folder (``model.pt``, ``settings.json``, the curve).
        seed: the training seed (network, noise and the training episodes' resets).
        settings: the checked recipe (``env``, ``algo`` ...).
        stop: polled between steps and batches; True ends the run cleanly.
        device: where the network trains (``"cpu"``, ``"cuda"``).
    """

    def __init__(
        self,
        algo: str,
        spec: Any,
        out_path: Path,
        seed: int,
        settings: dict[str, Any],
        stop: Callable[[], bool],
        device: str = "cpu",
    ) -> None:
        import torch  # before any GL context: see docs/learning.md (torch and Mesa's LLVM)

        self.algo, self.spec, self.out_path, self.seed = algo, spec, out_path, seed
        self.settings, self.params, self.stop, self.device = (
            settings,
            settings["algo"],
            stop,
            device,
        )
        self.env_kwargs = dict(settings["env"])
        cameras, self.height, self.width, per_sample, worst, budget = store_bound(
            algo, spec, settings
        )
        self.cameras = cameras
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
        self.envs: list[Any] = []
        self.store: FrameStore | None = None
        self.net: Any = None
        self.optimizer: Any = None
        self.mean = self.std = self.aux_mean = self.aux_std = None
        self.env_steps = self.episodes = 0
        self.rate: float | None = None
        self.best = -1.0
        self._pooled: dict[str, Any] = {}
        self.rng = np.random.default_rng([seed, 25])
        self.generator = torch.Generator().manual_seed(seed)
        kind = "BC" if algo == "bc" else "DAgger"
        self.title = f"{kind} from pixels on {spec.name}, seed {seed}"
        self.curve = Curve(out_path, self.title)

    # ----------------------------------------------------------------------- the run
    def run(self) -> tuple[int, float | None]:
        """Train; returns the environment steps of the training episodes and the last
        success rate (None when stopped before the first evaluation)."""
        self.envs = [
            make_env(self.spec.name, self.env_kwargs) for _ in range(self.settings["n_envs"])
        ]
        try:
            self.command_of_pos = command_map(self.envs[0])
            self.observation_names = list(self.envs[0].unwrapped.observation_names)
            self.write_settings()
            self.gather(0, self.params["demos"], 1.0)
            if self.stop() or not len(self.store):
                return self.env_steps, None
            self.start_network()
            self.train_round(0, self.params["epochs"])
            if self.algo == "dagger":
                self.dagger_rounds()
            if self.stop() and self.net is not None and not self.model_path.exists():
                self.save_model()
                self.write_settings()
        finally:
            for env in self.envs:
                env.close()
        return self.env_steps, self.rate

    def dagger_rounds(self) -> None:
        """The student drives (a share ``beta0 * beta_decay ** r`` of the steps left to
        the expert), the expert labels; warm-started rounds until the evaluation stops
        rising for ``patience`` rounds, reaches 100 %, or ``rounds`` are done."""
        params, since_best = self.params, 0
        for round_ in range(1, params["rounds"] + 1):
            if self.stop() or self.best >= 1.0 or since_best >= params["patience"]:
                return
            best = self.best
            beta = params["beta0"] * params["beta_decay"] ** round_
            self.gather(round_, params["episodes_per_round"], beta)
            if self.stop():
                return
            self.train_round(round_, params["round_epochs"])
            since_best = 0 if self.best > best else since_best + 1

    def train_round(self, round_: int, epochs: int) -> None:
        loss = self.fit(epochs)
        if not self.stop():
            self.evaluate(round_, loss)

    @property
    def model_path(self) -> Path:
        return self.out_path / PIXEL_MODEL_FILE

    # ----------------------------------------------------------------------- gathering
    def gather(self, round_: int, episodes: int, beta: float) -> None:
        """Run ``episodes`` training episodes on the environments side by side, storing
        every step with the expert's label; the executed action is the label with DART
        noise, or (DAgger, a share ``1 - beta`` of the steps) the student's."""
        experts = [make_expert(env) for env in self.envs]
        pending = training_seeds(self.seed, round_, episodes)
        slots: list[_Episode | None] = [self.start(env, pending) for env in self.envs]
        learner = self.policy() if self.net is not None and beta < 1.0 else None
        successes = 0
        while any(slots) and not self.stop():
            active = [i for i, slot in enumerate(slots) if slot is not None]
            episodes_now = [slots[i] for i in active]
            labels = np.clip(
                np.stack([np.asarray(experts[i](slots[i].obs, slots[i].info)) for i in active]),
                -1.0,
                1.0,
            ).astype(np.float32)
            executed = dart_noise(labels, self.params["dart_std"], self.rng)
            if learner is not None:
                executed = self.student_share(learner, episodes_now, executed, beta)
            for j, i in enumerate(active):
                slot = slots[i]
                self.store.add(
                    slot.obs, slot.previous, slot.command, labels[j], executed[j],
                    slot.number, round_, privileged_targets(slot.info),
                )  # fmt: skip
                obs, _, terminated, truncated, info = self.envs[i].step(executed[j])
                self.env_steps += 1
                if terminated or truncated:
                    successes += bool(info.get("is_success", False))
                    slots[i] = self.start(self.envs[i], pending)
                else:
                    slot.advance(obs, info, executed[j])
        logger.info(
            "%s: round %d, %d steps stored (%.2f GiB held), beta %.2f, %d of the gathered "
            "episodes succeeded",
            self.title, round_, len(self.store), self.store.nbytes() / 2**30, beta, successes,
        )  # fmt: skip

    def start(self, env: Any, pending: list[int]) -> _Episode | None:
        """Reset ``env`` to the next pending seed (None when none is left)."""
        if not pending:
            return None
        obs, info = env.reset(seed=pending.pop(0))
        if self.store is None:
            act_dim = env.action_space.shape[0]
            aux_dim = len(privileged_targets(info)) if self.params["aux_weight"] > 0 else 0
            self.store = FrameStore(
                self.cameras, self.height, self.width, act_dim, self.capacity, aux_dim=aux_dim
            )
        command = command_at_reset(self.command_of_pos, np.asarray(obs["agent_pos"], np.float32))
        self.episodes += 1
        return _Episode(obs, info, self.episodes - 1, command)

    def student_share(
        self, learner: PixelPolicy, episodes: list[_Episode], executed: np.ndarray, beta: float
    ) -> np.ndarray:
        """``executed`` with the student's actions in place of a share ``1 - beta``."""
        use = self.rng.random(len(episodes)) >= beta
        if not use.any():
            return executed
        chosen = [episode for episode, u in zip(episodes, use, strict=True) if u]
        executed = executed.copy()
        executed[use] = learner.act(
            [e.obs for e in chosen], [e.previous for e in chosen], [e.command for e in chosen]
        )
        return executed

    # ----------------------------------------------------------------------- the network
    def start_network(self) -> None:
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
        self.net.train()
        loss_value = float("nan")
        for _ in range(epochs):
            order = torch.randperm(n, generator=self.generator).to(device)
            total = 0.0
            for begin in range(0, n, params["batch_size"]):
                index = order[begin : begin + params["batch_size"]]
                images = {
                    c: random_shift(frames[c][index].float().div_(255.0), shift, self.generator)
                    for c in self.cameras
                }
                total += self.update(images, proprio[index], change[index], aux[index])
            loss_value = total / n
            if self.stop():
                break
        self.net.eval()
        return loss_value

    def update(self, images: dict[str, Any], proprio: Any, change: Any, aux: Any) -> float:
        """One optimiser step on a minibatch; returns its summed action loss."""
        import torch
        from torch.nn import functional

        keypoints = self.net.encode(images, pooled=True)
        action_loss = functional.mse_loss(self.net.act_from(keypoints, proprio), change)
        loss = action_loss
        if self.net.aux is not None:
            weight = self.params["aux_weight"]
            loss = loss + weight * functional.mse_loss(self.net.aux(keypoints), aux)
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

    def evaluate(self, round_: int, loss: float) -> None:
        """Score the student on the protocol's first episodes, keep it if it is the best
        round so far, extend the curve."""
        episodes = self.settings["eval_episodes"]
        result = score(self.spec.name, self.env_kwargs, self.policy(), episodes, EVAL_SEED)
        self.rate = result["success_rate"]
        self.curve.add(round_, self.env_steps, len(self.store), self.rate, result, episodes)
        if self.rate >= self.best:  # DAgger keeps its best round
            self.best = self.rate
            self.save_model()
        self.write_settings()
        logger.info(
            "%s: round %d, %d samples, loss %.4f, %.0f s, success %.0f %%",
            self.title, round_, len(self.store), loss, self.curve.rows[-1]["wall_s"],
            100 * self.rate,
        )  # fmt: skip

    def write_settings(self) -> None:
        write_run_settings(
            self.out_path / SETTINGS_FILE,
            {
                "format": POLICY_FORMAT,
                "policy": PIXEL_POLICY,
                "algo": self.algo,
                "task": self.spec.name,
                "seed": self.seed,
                "steps": self.env_steps,
                "env": self.env_kwargs,
                "cameras": list(self.cameras),
                "image_size": [self.height, self.width],
                "observation_names": self.observation_names,
                "recipe": self.settings,
            },
        )

    def save_model(self) -> None:
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


def train_pixels(
    algo: str,
    spec: Any,
    out_path: Path,
    seed: int,
    settings: dict[str, Any],
    stop: Callable[[], bool],
    device: str = "cpu",
) -> tuple[int, float | None]:
    """Train a pixel student (:class:`PixelTrainer`); returns the environment steps of the
    training episodes and the last success rate."""
    return PixelTrainer(algo, spec, out_path, seed, settings, stop, device).run()


__all__ = ["PixelTrainer", "train_pixels"]
