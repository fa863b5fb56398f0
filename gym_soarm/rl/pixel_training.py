"""The pixel student's trainer (``python -m gym_soarm.train --algo bc|dagger --obs-type
pixels_agent_pos``): collect expert-labelled steps from the cameras, fit the network of
:mod:`gym_soarm.rl.pixels`, evaluate on the protocol, keep the best round."""

from __future__ import annotations

import csv
import dataclasses
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.expert import make_expert
from gym_soarm.rl.curves import write_curve_png
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
    random_shift,
    store_bound,
)
from gym_soarm.rl.runs import (
    CURVE_CSV,
    CURVE_FIELDS,
    CURVE_PNG,
    training_seeds,
    write_run_settings,
)
from gym_soarm.tasks.suites import EVAL_SEED

logger = logging.getLogger(__name__)


@dataclasses.dataclass
class _Run:
    """What a pixel run holds while it trains."""

    store: FrameStore
    net: Any = None
    optimizer: Any = None
    mean: np.ndarray | None = None
    std: np.ndarray | None = None
    env_steps: int = 0
    episodes: int = 0
    rate: float | None = None
    best: float = -1.0


def train_pixels(
    algo: str,
    spec: Any,
    out_path: Path,
    seed: int,
    settings: dict[str, Any],
    stop: Callable[[], bool],
    device: str = "cpu",
) -> tuple[int, float | None]:
    """Train a pixel student of ``spec``'s state expert into ``out_path`` (see the
    module's documentation); ``settings`` is the checked recipe (``env``, ``algo`` ...).

    Returns:
        The environment steps of the training episodes and the last success rate.
    """
    import torch  # before any GL context: see docs/learning.md (torch and Mesa's LLVM)

    params = settings["algo"]
    env_kwargs = dict(settings["env"])
    cameras, height, width, per_sample, worst, budget = store_bound(algo, spec, settings)
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

    envs = [make_env(spec.name, env_kwargs) for _ in range(settings["n_envs"])]
    act_dim = envs[0].action_space.shape[0]
    command_of_pos = command_map(envs[0])
    run = _Run(FrameStore(cameras, height, width, act_dim, min(worst, budget)))
    rng = np.random.default_rng([seed, 25])
    generator = torch.Generator().manual_seed(seed)
    started = time.perf_counter()
    rows: list[dict[str, Any]] = []
    title = f"{'BC' if algo == 'bc' else 'DAgger'} from pixels on {spec.name}, seed {seed}"
    observation_names = list(envs[0].unwrapped.observation_names)

    def policy() -> PixelPolicy:
        return PixelPolicy(
            run.net, cameras, (height, width), run.mean, run.std, command_of_pos, device
        )

    def write_settings() -> None:
        write_run_settings(
            out_path / SETTINGS_FILE,
            {
                "format": POLICY_FORMAT,
                "policy": PIXEL_POLICY,
                "algo": algo,
                "task": spec.name,
                "seed": seed,
                "steps": run.env_steps,
                "env": env_kwargs,
                "cameras": list(cameras),
                "image_size": [height, width],
                "observation_names": observation_names,
                "recipe": settings,
            },
        )

    def save_model() -> None:
        layout = {
            "cameras": list(cameras),
            "height": height,
            "width": width,
            "act_dim": act_dim,
            "channels": list(params["channels"]),
            "hidden": list(params["hidden"]),
            "downsample": params["downsample"],
        }
        weights = {k: v.detach().cpu() for k, v in run.net.state_dict().items()}
        torch.save(
            {
                "layout": layout,
                "weights": weights,
                "mean": torch.as_tensor(run.mean),
                "std": torch.as_tensor(run.std),
                "command_of_pos": torch.as_tensor(command_of_pos),
            },
            out_path / PIXEL_MODEL_FILE,
        )

    def gather(round_: int, episodes: int, beta: float) -> None:
        experts = [make_expert(env) for env in envs]
        pending = training_seeds(seed, round_, episodes)
        slots: list[list[Any] | None] = [None] * len(envs)
        successes = 0

        def start(i: int) -> None:
            if not pending:
                slots[i] = None
                return
            obs, info = envs[i].reset(seed=pending.pop(0))
            pos = np.asarray(obs["agent_pos"], np.float32)
            slots[i] = [obs, info, run.episodes, pos, command_at_reset(command_of_pos, pos)]
            run.episodes += 1

        for i in range(len(envs)):
            start(i)
        learner = policy() if run.net is not None and beta < 1.0 else None
        while any(slot is not None for slot in slots) and not stop():
            active = [i for i in range(len(envs)) if slots[i] is not None]
            labels = np.clip(
                np.stack([np.asarray(experts[i](*slots[i][:2]), np.float32) for i in active]),
                -1.0,
                1.0,
            )
            executed = labels
            if params["dart_std"] > 0:
                noise = rng.normal(0.0, params["dart_std"], labels.shape).astype(np.float32)
                executed = np.clip(labels + noise, -1.0, 1.0)
            if learner is not None:
                use = rng.random(len(active)) >= beta
                if use.any():
                    executed = executed.copy()
                    chosen = [i for i, u in zip(active, use, strict=True) if u]
                    executed[use] = learner.act(
                        [slots[i][0] for i in chosen],
                        [slots[i][3] for i in chosen],
                        [slots[i][4] for i in chosen],
                    )
            for j, i in enumerate(active):
                run.store.add(
                    slots[i][0],
                    slots[i][3],
                    slots[i][4],
                    labels[j],
                    executed[j],
                    slots[i][2],
                    round_,
                )
                obs, _, terminated, truncated, info = envs[i].step(executed[j])
                run.env_steps += 1
                if terminated or truncated:
                    successes += bool(info.get("is_success", False))
                    start(i)
                else:
                    slots[i][3] = np.asarray(slots[i][0]["agent_pos"], np.float32)
                    slots[i][4] = executed[j]
                    slots[i][0], slots[i][1] = obs, info
        logger.info(
            "%s: round %d, %d steps stored (%.2f GiB held), beta %.2f, %d executed successes",
            title,
            round_,
            len(run.store),
            run.store.nbytes() / 2**30,
            beta,
            successes,
        )

    def fit(epochs: int) -> float:
        # The data as tensors on the training device once per fit (uint8 frames: on a GPU
        # about 74 kB a step); each batch is indexed, shifted and scaled there.
        store = run.store
        n = len(store)
        frames = {c: torch.from_numpy(store.frames[c][:n]).to(device) for c in cameras}
        proprio = (store.proprio[:n] - run.mean) / run.std
        change = (store.labels[:n] - store.proprio[:n, -act_dim:]) / RESIDUAL_SCALE
        proprio_t = torch.as_tensor(proprio, device=device)
        change_t = torch.as_tensor(change, device=device)
        run.net.train()
        loss_value = float("nan")
        for _ in range(epochs):
            order = torch.randperm(n, generator=generator).to(device)
            total = 0.0
            for begin in range(0, n, params["batch_size"]):
                index = order[begin : begin + params["batch_size"]]
                images = {
                    c: random_shift(
                        frames[c][index].permute(0, 3, 1, 2).float().div_(255.0),
                        params["shift_px"],
                        generator,
                    )
                    for c in cameras
                }
                loss = torch.nn.functional.mse_loss(
                    run.net(images, proprio_t[index]), change_t[index]
                )
                run.optimizer.zero_grad()
                loss.backward()
                run.optimizer.step()
                total += loss.item() * len(index)
            loss_value = total / n
            if stop():
                break
        run.net.eval()
        return loss_value

    def evaluate(round_: int, loss: float) -> None:
        result = score(spec.name, env_kwargs, policy(), settings["eval_episodes"], EVAL_SEED)
        run.rate = result["success_rate"]
        rows.append(
            {
                "round": round_,
                "env_steps": run.env_steps,
                "samples": len(run.store),
                "wall_s": round(time.perf_counter() - started, 2),
                "success_rate": run.rate,
                "mean_return": round(result["mean_return"], 4),
                "episodes": settings["eval_episodes"],
            }
        )
        if run.rate >= run.best:  # DAgger keeps its best round
            run.best = run.rate
            save_model()
        write_settings()
        with open(out_path / CURVE_CSV, "w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=CURVE_FIELDS)
            writer.writeheader()
            writer.writerows(rows)
        write_curve_png(rows, out_path / CURVE_PNG, title)
        logger.info(
            "%s: round %d, %d samples, loss %.4f, %.0f s, success %.0f %%",
            title,
            round_,
            len(run.store),
            loss,
            rows[-1]["wall_s"],
            100 * run.rate,
        )

    try:
        write_settings()
        gather(0, params["demos"], 1.0)
        if stop() or not len(run.store):
            return run.env_steps, None
        proprio = run.store.proprio[: len(run.store)]
        floor = np.repeat(np.asarray(PROPRIO_STD_FLOOR, np.float32), PROPRIO_DIM // 3)
        run.mean = proprio.mean(axis=0).astype(np.float32)
        run.std = np.maximum(proprio.std(axis=0), floor).astype(np.float32)
        run.net = build_network(
            cameras, act_dim, params["channels"], params["hidden"], downsample=params["downsample"]
        ).to(device)
        run.optimizer = torch.optim.Adam(run.net.parameters(), lr=params["learning_rate"])
        loss = fit(params["epochs"])
        if not stop():
            evaluate(0, loss)
        for round_ in range(1, (params["rounds"] if algo == "dagger" else 0) + 1):
            if stop():
                break
            gather(
                round_,
                params["episodes_per_round"],
                params["beta0"] * params["beta_decay"] ** round_,
            )
            if stop():
                break
            loss = fit(params["round_epochs"])
            if not stop():
                evaluate(round_, loss)
        if stop() and run.net is not None and not (out_path / PIXEL_MODEL_FILE).exists():
            save_model()
            write_settings()
    finally:
        for env in envs:
            env.close()
    return run.env_steps, run.rate


__all__ = ["train_pixels"]
