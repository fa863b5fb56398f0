"""MuJoCo Warp on a GPU: control steps/s of the Warp vector env, against its bare physics.

``python -m gym_soarm.bench.bench_warp --worlds 256,1024,4096 --device cuda`` measures,
for each number of worlds:

* ``physics``: MuJoCo Warp alone stepping that many worlds of the task's scene (a control
  step's substeps and the closing position stage, captured once as a CUDA graph on a GPU;
  no task, no observation, no host copy): the ceiling of the env;
* ``env``: ``gym.make_vec(..., vectorization_mode="vector_entry_point", vector_env="warp",
  device=...)`` stepped with random actions, resets and scoring included (worlds up to
  ``--env-worlds-max``: every world is also a :class:`~gym_soarm.envs.env.SoArmEnv` of its
  own, built and reset on the CPU);
* ``batched``: the same env on ``mujoco.batch`` (a thread per CPU), the CPU's figure
  (worlds up to ``--batched-worlds-max``).

Figures are aggregate control steps/s (worlds x control steps / s), medians over
``--repeats`` timed windows of ``--seconds`` each; ``env_to_physics`` is the env's
median over the bare physics' median at the same number of worlds. Kernel compilation
(the first capture, or the first step) is timed apart and reported as ``compile_s``.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import gym_soarm  # noqa: F401  (registers the environments)
from gym_soarm import constants
from gym_soarm.bench.bench_vector import N_ACTIONS, calls_per_second, vector_rate

DEFAULT_ENV_ID = "gym_soarm/LiftCube-v0"


def _rates(call: Callable[[int], Any], per_call: int, seconds: float, repeats: int) -> list[float]:
    """``repeats`` rates (``per_call`` units a call) of ``call`` run for ``seconds`` each."""
    return [per_call * calls_per_second(call, seconds) for _ in range(repeats)]


def physics_rate(
    env_id: str, worlds: int, device: str, seconds: float, repeats: int
) -> dict[str, Any]:
    """Bare MuJoCo Warp over ``worlds`` copies of ``env_id``'s scene at its reset pose."""
    import mujoco_warp as mjw
    import warp as wp

    from gym_soarm.sim.warp_backend import CONSTRAINTS_PER_WORLD, CONTACTS_PER_WORLD

    env = gym.make(env_id)
    env.reset(seed=0)
    physics = env.unwrapped.physics
    model, data = physics.model.ptr, physics.data.ptr
    with wp.ScopedDevice(device):
        m = mjw.put_model(model)
        d = mjw.put_data(
            model, data, nworld=worlds, nconmax=CONTACTS_PER_WORLD, njmax=CONSTRAINTS_PER_WORLD
        )
        rng = np.random.default_rng(0)
        low, high = model.actuator_ctrlrange.T
        ctrl = rng.uniform(low, high, size=(worlds, model.nu)).astype(np.float32)
        d.ctrl.assign(ctrl)

        def control_step() -> None:
            for _ in range(constants.N_SUBSTEPS):
                mjw.step(m, d)
            mjw.step1(m, d)

        start = time.perf_counter()
        if wp.get_device(device).is_cuda:
            with wp.ScopedCapture() as capture:
                control_step()
            graph = capture.graph

            def step() -> None:
                wp.capture_launch(graph)
                wp.synchronize()
        else:

            def step() -> None:
                control_step()
                wp.synchronize()

        step()
        compile_s = time.perf_counter() - start
        rates = _rates(lambda k: step(), worlds, seconds, repeats)
        finite = bool(np.isfinite(d.qpos.numpy()).all())
    env.close()
    return {
        "rate": statistics.median(rates),
        "rates": rates,
        "compile_s": compile_s,
        "finite": finite,
    }


def env_rate(
    env_id: str, worlds: int, vector_env: str, device: str | None, seconds: float, repeats: int
) -> dict[str, Any]:
    """The vector env ``vector_env`` (``"warp"`` or ``"batched"``) over ``worlds`` envs."""
    kwargs: dict[str, Any] = {"vector_env": vector_env}
    if vector_env == "warp":
        kwargs["device"] = device
    start = time.perf_counter()
    envs = gym.make_vec(env_id, num_envs=worlds, vectorization_mode="vector_entry_point", **kwargs)
    envs.reset(seed=0)
    build_s = time.perf_counter() - start
    low, high = envs.single_action_space.low, envs.single_action_space.high
    rng = np.random.default_rng(0)
    actions = rng.uniform(low, high, (N_ACTIONS, worlds, len(low))).astype(np.float32)
    start = time.perf_counter()
    envs.step(actions[0])
    first_step_s = time.perf_counter() - start
    rates = [vector_rate(envs, actions, seconds) for _ in range(repeats)]
    envs.close()
    return {
        "rate": statistics.median(rates),
        "rates": rates,
        "build_and_reset_s": build_s,
        "first_step_s": first_step_s,
    }


def measure(
    env_id: str,
    worlds: Sequence[int],
    device: str,
    seconds: float = 3.0,
    repeats: int = 3,
    env_worlds_max: int = 1024,
    batched_worlds_max: int = 256,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """The report: one row per number of worlds (see the module's docstring);
    ``on_row(report)`` is called after each row (to save what is measured so far)."""
    import warp as wp

    wp.config.quiet = True
    wp.init()
    report: dict[str, Any] = {
        "env_id": env_id,
        "device": device,
        "device_name": str(wp.get_device(device).name),
        "control_hz": round(1.0 / constants.CONTROL_TIMESTEP_S),
        "seconds": seconds,
        "repeats": repeats,
        "rows": [],
    }
    for n in worlds:
        row: dict[str, Any] = {"worlds": n}
        report["rows"].append(row)
        row["physics"] = physics_rate(env_id, n, device, seconds, repeats)
        if n <= env_worlds_max:
            row["env"] = env_rate(env_id, n, "warp", device, seconds, repeats)
            row["env_to_physics"] = row["env"]["rate"] / row["physics"]["rate"]
        if n <= batched_worlds_max:
            row["batched"] = env_rate(env_id, n, "batched", None, seconds, repeats)
        if on_row is not None:
            on_row(report)
    return report


def format_table(report: dict[str, Any]) -> str:
    """The report as a Markdown table."""
    lines = [
        f"{report['env_id']} on {report['device_name']} ({report['device']}), aggregate "
        f"control steps/s, medians of {report['repeats']} x {report['seconds']} s",
        "",
        "| worlds | physics | env (warp) | env / physics | batched (CPU) | compile s |",
        "| ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for row in report["rows"]:
        env = f"{row['env']['rate']:,.0f}" if "env" in row else "-"
        ratio = f"{row['env_to_physics']:.2f}" if "env" in row else "-"
        batched = f"{row['batched']['rate']:,.0f}" if "batched" in row else "-"
        lines.append(
            f"| {row['worlds']} | {row['physics']['rate']:,.0f} | {env} | {ratio} | "
            f"{batched} | {row['physics']['compile_s']:.1f} |"
        )
    return "\n".join(lines)
