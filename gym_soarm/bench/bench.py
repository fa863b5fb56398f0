"""Speed benchmark of the SO-101 environments: ``python -m gym_soarm.bench``.

For each configuration it measures, in a fresh process of its own (so that peak memory
and GL contexts of one configuration never touch another):

* env steps per second through ``gym.make`` (median, min and max of the repeats), with
  random actions from a seeded generator; resets are not counted;
* milliseconds per step, split into rendering (time inside the camera renderer) and
  everything else (physics, reward, observation: reported as ``physics``);
* ``make`` time (the first ``gym.make`` in the process), ``reset`` time (median of warm
  resets) and the first reset (which creates the GL context for pixel observations);
* peak resident memory of the process.

In the same run it measures the ceiling each configuration is compared with, in another
fresh process that does not import gym_soarm: bare ``mujoco.mj_step`` with the same
number of substeps for state observations, and a bare ``mujoco.Renderer`` on the same
compiled model, cameras, image size and quality settings (shadows, reflections,
multisampling) for pixel observations. The repeats of a configuration and of its
ceiling alternate, so both see the same machine load; the ratio to the ceiling (the
median of the per-repeat ratios) shows how much the environment costs on top of what
MuJoCo itself needs.

``--control-mode`` measures another control mode (:mod:`gym_soarm.envs.control`) with its
own random actions, uniform in its action space; the floors of ``TARGETS`` are those of
the default ``joint_pos`` and are checked only there.

``--processes N`` adds the aggregate throughput of ``N`` environments stepped together
by ``gymnasium.vector.AsyncVectorEnv``. The cold ``make`` time (an empty model cache:
rebuild the meshes and compile) is measured once per visual variant.

``--vector-scaling 1,2,4,8,16`` adds the scaling of vector environments
(:mod:`gym_soarm.bench.bench_vector`): aggregate steps/s of the batched vector env (one
``mujoco.batch``), the native vector env (worker processes), ``AsyncVectorEnv`` and ``SyncVectorEnv`` at each ``num_envs``, and the speedup
of each over one environment measured in the same rounds, beside the ceiling of free-running
processes; state observations, and the camera configs of ``--vector-obs`` at
``--image-size``. Its targets (the native env's best speedup at ``num_envs`` >= 8: at
least 1.7 with state observations, 1.8 with cameras; the batched env's at 64 environments,
or the most measured, at least 1.8 with state observations) join the checked targets.

``--recording N`` adds recording throughput (:mod:`gym_soarm.bench.bench_record`):
episodes per minute of ``LiftCube-v0``'s scripted expert recorded by one process and by
``N`` worker processes (and as Ray tasks on a local cluster with ``--recording-ray``),
without cameras and with the ``--recording-cameras`` at ``--image-size``. Each recording
runs in a fresh process and its dataset is read back to count what it holds.

Timings on a shared machine are noisy: read the medians and the ratios.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from gym_soarm.bench.timings import spread
from gym_soarm.tasks import DEFAULT_TASK

DEFAULT_CONFIGS: tuple[str, ...] = (
    "state",
    "state_30hz",
    "front_only_640x480",
    "front_wrist_640x480",
    "all_640x480",
    "front_wrist_224x224",
    "front_wrist_640x480_high",
)
DEFAULT_SECONDS = 3.0
DEFAULT_REPEATS = 3
DEFAULT_JSON = "bench_results.json"
"""Where the results go without --json: a name the repository ignores, so the checkout stays clean."""
DEFAULT_CONTROL_MODE = "joint_pos"
ACTION_SEED = 0
N_ACTIONS = 1024  # random actions drawn up front and cycled, so drawing costs nothing
SLICES_PER_REPEAT = 4  # each repeat alternates this many slices of env and ceiling
STATE_RESETS = 50
PIXEL_RESETS = 5

# The performance floors: (what is compared, configuration, bound, "min" or "max").
TARGETS: tuple[tuple[str, str, float, str], ...] = (
    ("steps_per_s", "state", 4000.0, "min"),
    ("steps_per_s", "front_only_640x480", 20.0, "min"),
    ("steps_per_s", "front_wrist_640x480", 10.0, "min"),
    ("steps_per_s", "front_wrist_224x224", 40.0, "min"),
    ("reset_ms", "state", 5.0, "max"),
    ("make_s", "state", 1.0, "max"),
)
RATIO_TARGET = 0.8  # every pixel configuration against its raw-renderer ceiling
VECTOR_SPEEDUP_TARGET = 1.7  # the native vector env over one env, state observations
BATCHED_SPEEDUP_TARGET = 1.8  # the batched vector env over one env, state observations
BATCHED_TARGET_MIN_ENVS = 64  # ... at this many environments (or the most measured)
VECTOR_CAMERA_SPEEDUP_TARGET = 1.8  # the same with cameras
VECTOR_TARGET_MIN_ENVS = 8  # the targets hold from this many environments
DEFAULT_IMAGE_SIZE = (96, 128)  # (height, width) of --vector-obs and --recording-cameras

_STATE_RATE_PATTERN = re.compile(r"^state_(\d+)hz$")
_CONFIG_PATTERN = re.compile(r"^(front_only|front_wrist|all)_(\d+)x(\d+)(?:_(fast|high))?$")


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """One measured configuration, named like ``state`` or ``front_wrist_640x480_high``."""

    name: str
    obs_type: str
    camera_config: str | None
    width: int
    height: int
    render_quality: str
    task: str = DEFAULT_TASK
    control_mode: str = DEFAULT_CONTROL_MODE
    env: tuple[tuple[str, Any], ...] = ()
    """Further ``gym.make`` keywords (``("dynamics", PATH)``, ...), as sorted pairs."""

    @classmethod
    def parse(
        cls,
        name: str,
        task: str = DEFAULT_TASK,
        control_mode: str = DEFAULT_CONTROL_MODE,
        env: Mapping[str, Any] | None = None,
    ) -> BenchConfig:
        """The configuration called ``name``, on ``task`` (a registered task), with the
        further ``gym.make`` keywords ``env`` (not those the name sets).

        Raises:
            ValueError: ``name`` is not ``state`` or ``{cameras}_{W}x{H}[_fast|_high]``,
                ``task`` is not registered, ``control_mode`` is unknown, or ``env`` has
                a bad or a reserved keyword.
        """
        config = cls._parse(name, task, control_mode)
        named = dict(config.env)  # what the name sets (state_30hz: control_hz)
        env = {k: v for k, v in dict(env or {}).items() if k not in named or named[k] != v}
        if not env:
            return config
        reserved = sorted(set(env) & {"task", "control_mode", *config.env_kwargs()})
        if reserved:
            raise ValueError(
                f"env keywords {reserved} are set by the configuration name, --task or "
                "--control-mode; leave them out of env."
            )
        from gym_soarm.envs.settings import EnvSettings

        EnvSettings.from_kwargs(task=config.task, **config.env_kwargs(), **env)  # checks
        return dataclasses.replace(config, env=tuple(sorted({**named, **env}.items())))

    @classmethod
    def _parse(cls, name: str, task: str, control_mode: str) -> BenchConfig:
        from gym_soarm.envs.control import CONTROL_MODES
        from gym_soarm.tasks import get_task
        from gym_soarm.validation import check_choice

        task = get_task(task).name
        check_choice("control_mode", control_mode, CONTROL_MODES)
        if name in ("state", "state_fast"):
            return cls(
                "state", "environment_state_agent_pos", None, 0, 0, "fast", task, control_mode
            )
        rate = _STATE_RATE_PATTERN.match(name)
        if rate is not None:  # state at another control rate: state_30hz
            from gym_soarm.sim.timing import check_control_hz

            hz = check_control_hz("the rate of " + name, int(rate.group(1)))
            return cls(
                name,
                "environment_state_agent_pos",
                None,
                0,
                0,
                "fast",
                task,
                control_mode,
                env=(("control_hz", hz),),
            )
        match = _CONFIG_PATTERN.match(name)
        if match is None:
            raise ValueError(
                f"unknown benchmark configuration {name!r}; expected 'state', 'state_{{HZ}}hz' or "
                "'{front_only|front_wrist|all}_{W}x{H}' with an optional '_fast' or '_high' "
                f"suffix, e.g. {', '.join(DEFAULT_CONFIGS)}."
            )
        cameras, width, height, quality = match.groups()
        return cls(
            name,
            "pixels_agent_pos",
            cameras,
            int(width),
            int(height),
            quality or "fast",
            task,
            control_mode,
        )

    @property
    def env_id(self) -> str:
        from gym_soarm.tasks import get_task

        return get_task(self.task).env_id

    @property
    def renders(self) -> bool:
        return self.camera_config is not None

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gym.make`` for this configuration."""
        kwargs: dict[str, Any] = {
            "obs_type": self.obs_type,
            "render_quality": self.render_quality,
            "control_mode": self.control_mode,
        }
        if self.renders:
            kwargs.update(
                camera_config=self.camera_config,
                observation_width=self.width,
                observation_height=self.height,
            )
        kwargs.update(self.env)
        return kwargs


def _peak_rss_mb() -> float | None:
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    # Linux reports kilobytes, macOS bytes.
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024


# --- workers (each runs in a process of its own) ------------------------------------------
# A worker prints "READY <json>" when set up, then answers each "run <seconds>" line on
# its stdin with "SLICE <json>" (steps taken and seconds spent in them) and "done" with
# "RESULT <json>" before exiting. The parent alternates short slices of a configuration
# and of its ceiling, so that both see the same machine load and their ratio holds even
# on a busy machine.


def _emit(tag: str, payload: dict) -> None:
    print(f"{tag} {json.dumps(payload)}", flush=True)


def _serve(ready: dict, run_slice: Callable[[float], dict], finish: Callable[[], dict]) -> None:
    _emit("READY", ready)
    for line in sys.stdin:
        command, _, argument = line.strip().partition(" ")
        if command == "run":
            _emit("SLICE", run_slice(float(argument)))
        elif command == "done":
            _emit("RESULT", finish())
            return


def _env_worker(config: BenchConfig, model_out: str) -> None:
    """Set one environment of ``config`` up and time its steps on request."""
    import gymnasium as gym
    import mujoco
    import numpy as np

    import gym_soarm
    from gym_soarm.render import backend, camera
    from gym_soarm.sim import cache
    from gym_soarm.sim import scene as model

    spec = gym_soarm.get_task(config.task)
    cache_file = cache.cached_path(
        model.model_cache_name(spec.scene, config.render_quality, spec.name)
    )
    model_cache_hit = cache_file is not None and cache_file.is_file()

    # Time spent inside the renderer, to split each step into physics and rendering.
    render_seconds = [0.0]
    original_render = camera.CameraRenderer.render

    def timed_render(self, *args: Any, **kwargs: Any):
        start = time.perf_counter()
        try:
            return original_render(self, *args, **kwargs)
        finally:
            render_seconds[0] += time.perf_counter() - start

    camera.CameraRenderer.render = timed_render

    t0 = time.perf_counter()
    env = gym.make(config.env_id, **config.env_kwargs())
    make_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    env.reset(seed=0)
    first_reset_ms = (time.perf_counter() - t0) * 1e3
    reset_times = []
    for _ in range(PIXEL_RESETS if config.renders else STATE_RESETS):
        t0 = time.perf_counter()
        env.reset()
        reset_times.append((time.perf_counter() - t0) * 1e3)

    rng = np.random.default_rng(ACTION_SEED)
    low, high = env.action_space.low, env.action_space.high
    actions = rng.uniform(low, high, size=(N_ACTIONS, len(low))).astype(np.float32)
    env.reset(seed=1)
    for i in range(3):  # warm up
        env.step(actions[i])
    counter = [0]

    def run_slice(seconds: float) -> dict:
        stepped = 0.0
        render_seconds[0] = 0.0
        n = 0
        i = counter[0]
        deadline = time.perf_counter() + seconds
        while True:
            t0 = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(actions[i % N_ACTIONS])
            t1 = time.perf_counter()
            stepped += t1 - t0
            n += 1
            i += 1
            if terminated or truncated:
                env.reset()
            if t1 >= deadline:
                break
        counter[0] = i
        return {"steps": n, "seconds": stepped, "render_seconds": render_seconds[0]}

    physics = env.unwrapped.physics
    mj_data = physics.data.ptr
    mujoco.mj_saveModel(physics.model.ptr, model_out, None)
    ready = {
        "make_s": make_s,
        "model_cache_hit": model_cache_hit,
        "first_reset_ms": first_reset_ms,
        "reset_ms": statistics.median(reset_times),
        "substeps": env.unwrapped.timing.substeps,
        "episode_steps": env.spec.max_episode_steps,
        "camera_ids": [physics.model.name2id(c, "camera") for c in env.unwrapped.cameras],
        "state": {
            "qpos": mj_data.qpos.tolist(),
            "qvel": mj_data.qvel.tolist(),
            "ctrl": mj_data.ctrl.tolist(),
        },
        "gl_backend": backend.gl_backend() if config.renders else None,
        "gym_soarm": gym_soarm.__version__,
        "mujoco": mujoco.__version__,
    }

    def finish() -> dict:
        env.close()
        return {"peak_rss_mb": _peak_rss_mb()}

    _serve(ready, run_slice, finish)


def _measure_vector(config: BenchConfig, seconds: float, repeats: int, processes: int) -> dict:
    """Aggregate steps/s of ``processes`` environments in an AsyncVectorEnv."""
    import gymnasium as gym
    import numpy as np

    import gym_soarm  # noqa: F401 - registers the environments

    t0 = time.perf_counter()
    envs = gym.make_vec(
        config.env_id, num_envs=processes, vectorization_mode="async", **config.env_kwargs()
    )
    make_s = time.perf_counter() - t0
    try:
        envs.reset(seed=0)
        rng = np.random.default_rng(ACTION_SEED)
        space = envs.single_action_space
        actions = rng.uniform(
            space.low, space.high, size=(N_ACTIONS, processes, space.shape[0])
        ).astype(np.float32)
        envs.step(actions[0])  # warm up
        rates = []
        i = 0
        for _ in range(repeats):
            n = 0
            t0 = time.perf_counter()
            deadline = t0 + seconds
            while time.perf_counter() < deadline or n == 0:
                envs.step(actions[i % N_ACTIONS])
                n += 1
                i += 1
            rates.append(n * processes / (time.perf_counter() - t0))
    finally:
        envs.close()
    return {"processes": processes, "make_s": make_s, "steps_per_s": spread(rates)}


def _measure_cold_make(visual: str, task: str = DEFAULT_TASK) -> dict:
    """``gym.make`` with an empty model cache: rebuild the meshes and compile."""
    with tempfile.TemporaryDirectory(prefix="gym_soarm_cold_cache_") as folder:
        os.environ["GYM_SOARM_CACHE_DIR"] = folder
        import gymnasium as gym

        import gym_soarm

        t0 = time.perf_counter()
        env = gym.make(
            gym_soarm.get_task(task).env_id,
            obs_type="environment_state_agent_pos",
            render_quality=visual,
        )
        cold = time.perf_counter() - t0
        env.close()
    return {"visual": visual, "make_s": cold}


# The ceiling runs in a process that never imports gym_soarm, so that mujoco.Renderer
# picks its GL backend from MUJOCO_GL like in any MuJoCo program. It speaks the same
# READY / run / REPEAT / done / RESULT protocol as the workers above.
_CEILING_SCRIPT = r"""
import json, sys, time
import mujoco
import numpy as np

def emit(tag, payload):
    print(tag + " " + json.dumps(payload), flush=True)

job = json.loads(sys.argv[1])
model = mujoco.MjModel.from_binary_path(job["model"])
data = mujoco.MjData(model)
state = job["state"]
data.qpos[:] = state["qpos"]
data.qvel[:] = state["qvel"]
data.ctrl[:] = state["ctrl"]
mujoco.mj_forward(model, data)
ready = {}
if job["mode"] == "step":
    rng = np.random.default_rng(job["seed"])
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    actions = rng.uniform(low, high, size=(1024, model.nu))
    nsub, episode = job["substeps"], job["episode_steps"]
    start = (data.qpos.copy(), data.qvel.copy())
    counter = [0]

    def run_slice(seconds):
        n, spent, i = 0, 0.0, counter[0]
        deadline = time.perf_counter() + seconds
        while True:
            data.ctrl[:] = actions[i % 1024]
            t0 = time.perf_counter()
            mujoco.mj_step(model, data, nsub)
            t1 = time.perf_counter()
            spent += t1 - t0
            n += 1
            i += 1
            if i % episode == 0:  # like the env's time limit: back to the episode start
                data.qpos[:], data.qvel[:] = start
                mujoco.mj_forward(model, data)
            if t1 >= deadline:
                break
        counter[0] = i
        return {"steps": n, "seconds": spent}
else:
    renderer = mujoco.Renderer(model, job["height"], job["width"])
    high = job["quality"] == "high"
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = high
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = high
    cameras = job["cameras"]
    for cam in cameras:
        renderer.update_scene(data, cam)
        renderer.render()
    try:
        from OpenGL import GL
        ready["gl_renderer"] = GL.glGetString(GL.GL_RENDERER).decode()
    except Exception as exc:
        ready["gl_renderer"] = "unknown (%s)" % type(exc).__name__

    def run_slice(seconds):
        n = 0
        t0 = time.perf_counter()
        deadline = t0 + seconds
        while True:
            for cam in cameras:
                renderer.update_scene(data, cam)
                renderer.render()
            n += 1
            if time.perf_counter() >= deadline:
                break
        return {"steps": n, "seconds": time.perf_counter() - t0}

emit("READY", ready)
for line in sys.stdin:
    command, _, argument = line.strip().partition(" ")
    if command == "run":
        emit("SLICE", run_slice(float(argument)))
    elif command == "done":
        if job["mode"] != "step":
            renderer.close()
        emit("RESULT", {})
        break
"""


# --- orchestration ----------------------------------------------------------------------------
class _Child:
    """A worker process spoken to line by line; killed if it outlives ``timeout``."""

    def __init__(self, args: list[str], env: dict[str, str], timeout: float) -> None:
        self._stderr = tempfile.TemporaryFile(mode="w+")  # noqa: SIM115 - closed in close()
        self._proc = subprocess.Popen(
            args,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
            bufsize=1,
        )
        self._watchdog = threading.Timer(timeout, self._proc.kill)
        self._watchdog.daemon = True
        self._watchdog.start()

    def expect(self, tag: str) -> dict:
        """The payload of the next ``tag`` line; RuntimeError if the process ends first."""
        assert self._proc.stdout is not None
        for line in self._proc.stdout:
            if line.startswith(tag + " "):
                return json.loads(line[len(tag) + 1 :])
        self._proc.wait()
        self._stderr.seek(0)
        tail = "\n".join(self._stderr.read().strip().splitlines()[-8:])
        raise RuntimeError(f"worker exited with code {self._proc.returncode}: {tail}")

    def ask(self, command: str, tag: str) -> dict:
        assert self._proc.stdin is not None
        self._proc.stdin.write(command + "\n")
        self._proc.stdin.flush()
        return self.expect(tag)

    def close(self) -> None:
        self._watchdog.cancel()
        if self._proc.poll() is None:
            self._proc.kill()
        self._proc.wait()
        for stream in (self._proc.stdin, self._proc.stdout):
            if stream is not None:
                stream.close()
        self._stderr.close()


def _worker_args(job: dict) -> list[str]:
    return [sys.executable, "-m", "gym_soarm.bench", "--worker", json.dumps(job)]


def _one_shot(job: dict, timeout: float) -> dict:
    child = _Child(_worker_args(job), dict(os.environ), timeout)
    try:
        return child.expect("RESULT")
    finally:
        child.close()


def measure_config(
    config: BenchConfig, seconds: float, repeats: int, processes: int, workdir: Path
) -> dict[str, Any]:
    """Every figure of one configuration and of its ceiling (each in a fresh process)."""
    timeout = 180 + 3 * seconds * repeats
    model_path = workdir / f"{config.name}.mjb"
    result: dict[str, Any] = {"name": config.name, **config.env_kwargs()}
    env_job = {
        "kind": "env",
        "config": config.name,
        "task": config.task,
        "control_mode": config.control_mode,
        "env": dict(config.env),
        "model_out": str(model_path),
    }
    env_child = _Child(_worker_args(env_job), dict(os.environ), timeout)
    ceiling_child = None
    try:
        ready = env_child.expect("READY")
        state = ready.pop("state")
        result.update(ready)
        ceiling_job = {
            "model": str(model_path),
            "state": state,
            "substeps": ready["substeps"],
            "episode_steps": ready["episode_steps"],
            "seed": ACTION_SEED,
            "mode": "render" if config.renders else "step",
            "cameras": ready["camera_ids"],
            "width": config.width,
            "height": config.height,
            "quality": config.render_quality,
        }
        ceiling_env = dict(os.environ, MUJOCO_GL=ready["gl_backend"] or "disable")
        ceiling_child = _Child(
            [sys.executable, "-c", _CEILING_SCRIPT, json.dumps(ceiling_job)], ceiling_env, timeout
        )
        ceiling_ready = ceiling_child.expect("READY")
        env_runs, ceiling_runs = [], []
        for _ in range(repeats):
            env_run = {"steps": 0, "seconds": 0.0, "render_seconds": 0.0}
            ceiling_run = {"steps": 0, "seconds": 0.0}
            for _ in range(SLICES_PER_REPEAT):  # alternate, so both see the same load
                for totals, child in ((env_run, env_child), (ceiling_run, ceiling_child)):
                    part = child.ask(f"run {seconds / SLICES_PER_REPEAT!r}", "SLICE")
                    for key in totals:
                        totals[key] += part[key]
            env_runs.append(env_run)
            ceiling_runs.append(ceiling_run)
        result.update(env_child.ask("done", "RESULT"))
        ceiling_child.ask("done", "RESULT")
    finally:
        env_child.close()
        if ceiling_child is not None:
            ceiling_child.close()
    env_rates = [r["steps"] / r["seconds"] for r in env_runs]
    step_ms = [r["seconds"] / r["steps"] * 1e3 for r in env_runs]
    render_ms = [r["render_seconds"] / r["steps"] * 1e3 for r in env_runs]
    result["steps_per_s"] = spread(env_rates)
    result["ms_per_step"] = {
        "total": statistics.median(step_ms),
        "render": statistics.median(render_ms),
        "physics": statistics.median([s - r for s, r in zip(step_ms, render_ms, strict=True)]),
    }
    ceiling_rates = [r["steps"] / r["seconds"] for r in ceiling_runs]
    result["ceiling"] = {
        "kind": (
            f"mujoco.Renderer, {len(ready['camera_ids'])} camera(s)"
            if config.renders
            else f"mujoco.mj_step x{ready['substeps']}"
        ),
        "steps_per_s": spread(ceiling_rates),
        "ms_per_step": 1e3 / statistics.median(ceiling_rates),
    }
    if "gl_renderer" in ceiling_ready:
        result["gl_renderer"] = ceiling_ready["gl_renderer"]
    # Median of the ratios of repeats whose slices alternated.
    result["ratio_to_ceiling"] = statistics.median(
        e / c for e, c in zip(env_rates, ceiling_rates, strict=True)
    )
    if processes > 1:
        vector_job = {
            "kind": "vector",
            "config": config.name,
            "task": config.task,
            "control_mode": config.control_mode,
            "env": dict(config.env),
            "seconds": seconds,
            "repeats": repeats,
            "processes": processes,
        }
        result["vector"] = _one_shot(vector_job, timeout + 120)
    return result


def measure_vector_scaling(
    counts: Sequence[int],
    obs: str,
    size: tuple[int, int],
    seconds: float,
    repeats: int,
    task: str = DEFAULT_TASK,
    modes: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Scaling of the vector envs with ``obs`` observations, in a fresh process.

    Returns :func:`gym_soarm.bench.bench_vector.measure`'s report, or ``{"obs": obs,
    "error": ...}`` when the process failed.
    """
    from gym_soarm.bench.bench_vector import VECTOR_MODES
    from gym_soarm.tasks import get_task

    modes = list(modes or VECTOR_MODES)
    if progress is not None:
        progress(f"measuring vector scaling ({obs}, num_envs {','.join(map(str, counts))}) ...")
    job = {
        "kind": "vector_scaling",
        "env_id": get_task(task).env_id,
        "counts": list(counts),
        "obs": obs,
        "size": list(size),
        "seconds": seconds,
        "repeats": repeats,
        "modes": modes,
    }
    timeout = 300 + len(counts) * (60 + (len(modes) + 1) * repeats * seconds * 3)
    try:
        return _one_shot(job, timeout)
    except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
        return {"obs": obs, "error": str(exc)}


def measure_recording(
    workers: int,
    ray: bool,
    episodes: int,
    cameras: Sequence[str],
    size: tuple[int, int],
    repeats: int,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Episodes per minute of 1 and ``workers`` recorders (and Ray), each in a fresh process.

    The repeats take every recorder in turn, so they see the same machine load; the
    median episodes per minute is reported with the speedup over one process (the
    median of the per-repeat ratios).
    """
    from gym_soarm.bench import bench_record

    variants = bench_record.variants(workers, ray)
    rows = []
    for camera_config in cameras:
        runs: dict[str, list[dict]] = {v["name"]: [] for v in variants}
        errors: dict[str, str] = {}
        for repeat in range(repeats):
            for variant in variants:
                if variant["name"] in errors:
                    continue
                if progress is not None:
                    progress(
                        f"recording {episodes} episodes ({camera_config}, {variant['name']}, "
                        f"repeat {repeat + 1}/{repeats}) ..."
                    )
                job = {
                    "kind": "recording",
                    "camera_config": camera_config,
                    "size": list(size),
                    "episodes": episodes,
                    "workers": variant["workers"],
                    "ray_address": variant["ray_address"],
                }
                try:
                    runs[variant["name"]].append(_one_shot(job, 600 + 60 * episodes))
                except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
                    errors[variant["name"]] = str(exc)
        base = runs[variants[0]["name"]]
        for variant in variants:
            name = variant["name"]
            row: dict[str, Any] = {
                "camera_config": camera_config,
                "recorder": name,
                "workers": variant["workers"],
                "ray": variant["ray_address"] is not None,
            }
            if name in errors:
                row["error"] = errors[name]
            else:
                got = runs[name]
                rates = [r["episodes_per_min"] for r in got]
                row.update(
                    episodes_per_min=spread(rates),
                    seconds=spread([r["seconds"] for r in got]),
                    episodes=[r["episodes"] for r in got],
                    dataset_episodes=[r["dataset_episodes"] for r in got],
                    frames=[r["frames"] for r in got],
                    dataset_frames=[r["dataset_frames"] for r in got],
                    bytes_on_disk=statistics.median(r["bytes_on_disk"] for r in got),
                )
                if len(base) == len(got):
                    row["speedup"] = statistics.median(
                        r["episodes_per_min"] / b["episodes_per_min"]
                        for r, b in zip(got, base, strict=True)
                    )
            rows.append(row)
    return {
        "task": bench_record.RECORD_TASK,
        "episodes": episodes,
        "size": list(size),
        "workers": workers,
        "ray": ray,
        "repeats": repeats,
        "rows": rows,
    }


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def check_targets(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The performance floors, each with the measured value and whether it is met."""
    by_name = {r["name"]: r for r in results if "error" not in r}
    checks = []
    for field, name, bound, kind in TARGETS:
        if name not in by_name:
            continue
        value = by_name[name][field]
        if isinstance(value, dict):
            value = value["median"]
        met = value >= bound if kind == "min" else value < bound
        checks.append({"config": name, "figure": field, "bound": bound, "kind": kind,
                       "value": value, "met": met})  # fmt: skip
    for name, r in by_name.items():
        if r.get("camera_config"):
            ratio = r["ratio_to_ceiling"]
            checks.append({"config": name, "figure": "ratio_to_ceiling", "bound": RATIO_TARGET,
                           "kind": "min", "value": ratio, "met": ratio >= RATIO_TARGET})  # fmt: skip
    return checks


def check_scaling_target(scaling: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The scaling targets: the native vector env's best speedup over one env at
    ``num_envs`` >= 8 (or the largest count measured, if smaller), with state
    observations and with cameras."""
    checks = []
    for report in scaling:
        native = [r for r in report.get("rows", []) if r["mode"] == "native"]
        if not native:
            continue
        least = min(VECTOR_TARGET_MIN_ENVS, max(r["num_envs"] for r in native))
        rows = [r for r in native if r["num_envs"] >= least]
        if not rows:
            continue
        state = report.get("obs") == "state"
        bound = VECTOR_SPEEDUP_TARGET if state else VECTOR_CAMERA_SPEEDUP_TARGET
        best = max(rows, key=lambda r: r["speedup"])
        name = f"native_vector_{report.get('obs')}_{best['num_envs']}"
        checks.append({"config": name, "figure": "speedup", "bound": bound, "kind": "min",
                       "value": best["speedup"], "met": best["speedup"] >= bound})  # fmt: skip
    for report in scaling:
        batched = [r for r in report.get("rows", []) if r["mode"] == "batched"]
        if not batched or report.get("obs") != "state":
            continue
        least = min(BATCHED_TARGET_MIN_ENVS, max(r["num_envs"] for r in batched))
        best = max((r for r in batched if r["num_envs"] >= least), key=lambda r: r["speedup"])
        bound = BATCHED_SPEEDUP_TARGET
        name = f"batched_vector_state_{best['num_envs']}"
        checks.append({"config": name, "figure": "speedup", "bound": bound, "kind": "min",
                       "value": best["speedup"], "met": best["speedup"] >= bound})  # fmt: skip
    return checks


def format_recording(report: dict[str, Any]) -> str:
    """The recording throughput as a Markdown table."""
    header = ["cameras", "recorder", "episodes/min median (min-max)", "speedup", "s per run"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in report["rows"]:
        cameras = r["camera_config"]
        if cameras != "none":
            cameras = f"{cameras} {report['size'][0]}x{report['size'][1]}"
        if "error" in r:
            lines.append(f"| {cameras} | {r['recorder']} | failed: {r['error']} | - | - |")
            continue
        rate = r["episodes_per_min"]
        speedup = f"{r['speedup']:.2f}x" if "speedup" in r else "-"
        lines.append(
            f"| {cameras} | {r['recorder']} | {_num(rate['median'])} ({_num(rate['min'])}-"
            f"{_num(rate['max'])}) | {speedup} | {r['seconds']['median']:.1f} |"
        )
    return "\n".join(lines)


def format_table(results: Sequence[dict[str, Any]]) -> str:
    """The results as a Markdown table."""
    vector = any("vector" in r for r in results)
    header = [
        "config",
        "steps/s median (min-max)",
        "ms/step physics + render",
        "ceiling steps/s",
        "ratio",
        "make s",
        "reset ms",
        "peak RSS MB",
    ]
    if vector:
        header.append("vector steps/s")
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in results:
        if "error" in r:
            lines.append(f"| {r['name']} | failed: {r['error']} |" + " |" * (len(header) - 2))
            continue
        sps, ms = r["steps_per_s"], r["ms_per_step"]
        rss = r.get("peak_rss_mb")
        row = [
            r["name"],
            f"{_num(sps['median'])} ({_num(sps['min'])}-{_num(sps['max'])})",
            f"{ms['physics']:.3f} + {ms['render']:.2f}",
            _num(r["ceiling"]["steps_per_s"]["median"]),
            f"{r['ratio_to_ceiling']:.2f}",
            f"{r['make_s']:.2f}",
            f"{r['reset_ms']:.2f}",
            "-" if rss is None else f"{rss:.0f}",
        ]
        if vector:
            v = r.get("vector")
            row.append(f"{_num(v['steps_per_s']['median'])} ({v['processes']} proc)" if v else "-")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def _num(x: float) -> str:
    if x >= 100:
        return f"{x:,.0f}"
    return f"{x:.1f}" if x >= 10 else f"{x:.2f}"


def run(
    configs: Sequence[str],
    seconds: float = DEFAULT_SECONDS,
    repeats: int = DEFAULT_REPEATS,
    processes: int = 1,
    progress: Callable[[str], None] | None = None,
    task: str = DEFAULT_TASK,
    control_mode: str = DEFAULT_CONTROL_MODE,
    vector_scaling: Sequence[int] = (),
    env: Mapping[str, Any] | None = None,
    vector_obs: Sequence[str] = ("state",),
    vector_modes: Sequence[str] | None = None,
    image_size: tuple[int, int] = DEFAULT_IMAGE_SIZE,
    recording: int = 0,
    recording_ray: bool = False,
    recording_episodes: int | None = None,
    recording_cameras: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Measure ``configs`` and return the whole report (what ``--json`` writes).

    Args:
        configs: configuration names (may be empty when ``vector_scaling`` or
            ``recording`` is asked for).
        vector_scaling: ``num_envs`` counts of the vector scaling (none: not measured).
        vector_obs: ``"state"`` or camera configs, each measured at every count.
        vector_modes: vector envs compared (default: native, async and sync).
        image_size: (height, width) of the camera configs of the scaling and recording.
        recording: worker count of the recording throughput (0: not measured).
        recording_ray: also record as Ray tasks on a local cluster.
        recording_episodes: episodes per recording.
        recording_cameras: ``"none"`` or camera configs, each recorded.
        env: further ``gym.make`` keywords of the measured configurations (``configs``
            only), e.g. ``{"dynamics": PATH}``.

    Raises:
        ValueError: a configuration name or the control mode is unknown, or
            seconds/repeats/processes or the scaling/recording options are out of range.
    """
    from gym_soarm.bench import bench_record, bench_vector

    parsed = [BenchConfig.parse(name, task, control_mode, env) for name in configs]
    vector_modes = tuple(vector_modes or bench_vector.VECTOR_MODES)
    recording_cameras = tuple(recording_cameras or bench_record.DEFAULT_CAMERAS)
    if recording_episodes is None:
        recording_episodes = bench_record.DEFAULT_EPISODES
    if not parsed and not vector_scaling and not recording:
        raise ValueError("configs must name at least one configuration")
    if vector_scaling and min(vector_scaling) < 1:
        raise ValueError(f"vector scaling counts must be at least 1; got {list(vector_scaling)}")
    unknown = [m for m in vector_modes if m not in bench_vector.VECTOR_MODES]
    if unknown:
        raise ValueError(
            f"vector modes must be among {', '.join(bench_vector.VECTOR_MODES)}; got {unknown}"
        )
    if not vector_obs:
        raise ValueError("vector obs must name 'state' or a camera config")
    if min(image_size) < 2 or any(v % 2 for v in image_size):
        raise ValueError(f"image size must be even and positive; got {image_size!r}")
    if recording < 0:
        raise ValueError(f"recording workers must be >= 0 (0: no recording); got {recording!r}")
    if recording_episodes < 1:
        raise ValueError(f"recording episodes must be at least 1; got {recording_episodes!r}")
    from gym_soarm import constants
    from gym_soarm.validation import resolve_camera_config

    for name, values, extra in (
        ("vector obs", vector_obs, "state"),
        ("recording cameras", recording_cameras, "none"),
    ):
        for value in values:  # checked now, not in a worker after other sections ran
            if value != extra:
                try:
                    resolve_camera_config(value)
                except ValueError:
                    raise ValueError(
                        f"{name} must be {extra!r} or a camera config "
                        f"({', '.join(constants.CAMERA_CONFIGS)}); got {value!r}"
                    ) from None
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number; got {seconds!r}")
    if repeats < 1:
        raise ValueError(f"repeats must be at least 1; got {repeats!r}")
    if processes < 1:
        raise ValueError(f"processes must be at least 1; got {processes!r}")
    from gym_soarm.tasks import get_task

    task_name = get_task(task).name
    say = progress or (lambda _message: None)
    load_start = os.getloadavg() if hasattr(os, "getloadavg") else None
    started = time.time()
    results: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="gym_soarm_bench_") as folder:
        for config in parsed:
            say(f"measuring {config.name} ...")
            try:
                results.append(measure_config(config, seconds, repeats, processes, Path(folder)))
            except (RuntimeError, subprocess.TimeoutExpired, OSError, ValueError) as exc:
                results.append({"name": config.name, "error": str(exc)})
        cold = []
        for visual in sorted({c.render_quality for c in parsed}):
            say(f"measuring a cold make ({visual} meshes, empty model cache) ...")
            try:
                job = {"kind": "cold_make", "visual": visual, "task": parsed[0].task}
                cold.append(_one_shot(job, 300))
            except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
                cold.append({"visual": visual, "error": str(exc)})
    scaling = [
        measure_vector_scaling(
            counts=vector_scaling,
            obs=obs,
            size=image_size,
            seconds=seconds,
            repeats=repeats,
            task=task,
            modes=vector_modes,
            progress=say,
        )
        for obs in (vector_obs if vector_scaling else ())
    ]
    recorded = (
        measure_recording(
            recording,
            recording_ray,
            recording_episodes,
            recording_cameras,
            image_size,
            repeats,
            progress=say,
        )
        if recording
        else None
    )
    first = next((r for r in results if "error" not in r), {})
    renderer = next((r["gl_renderer"] for r in results if r.get("gl_renderer")), None)
    return {
        "machine": {
            "cpu": _cpu_name(),
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
            "python": platform.python_version(),
            "gl_backend": next((r["gl_backend"] for r in results if r.get("gl_backend")), None),
            "gl_renderer": renderer,
            "load_average_start": load_start,
            "load_average_end": os.getloadavg() if hasattr(os, "getloadavg") else None,
        },
        "versions": {"gym_soarm": first.get("gym_soarm"), "mujoco": first.get("mujoco")},
        "settings": {
            "task": task_name,
            "control_mode": control_mode,
            "env": dict(env or {}),
            "seconds": seconds,
            "repeats": repeats,
            "processes": processes,
            "vector_scaling": list(vector_scaling),
            "recording_workers": recording,
            "started_unix": started,
            "duration_s": time.time() - started,
        },
        "configs": results,
        "cold_make": cold,
        "vector_scaling": scaling,
        "recording": recorded,
        "targets": (
            check_targets(results) + check_scaling_target(scaling)
            if control_mode == DEFAULT_CONTROL_MODE
            else []
        ),
    }


def serve_worker(job_text: str) -> None:
    """Run one measurement job (JSON from the parent) in this process and emit its result.

    The benchmark starts each job as ``python -m gym_soarm.bench --worker <json>``.
    """
    job = json.loads(job_text)
    kind = job["kind"]
    if kind == "env":
        config = BenchConfig.parse(job["config"], job["task"], job["control_mode"], job["env"])
        _env_worker(config, job["model_out"])
        return
    if kind == "vector":
        config = BenchConfig.parse(job["config"], job["task"], job["control_mode"], job["env"])
        out = _measure_vector(config, job["seconds"], job["repeats"], job["processes"])
    elif kind == "cold_make":
        out = _measure_cold_make(job["visual"], job["task"])
    elif kind == "vector_scaling":
        from gym_soarm.bench import bench_vector

        out = bench_vector.measure(
            job["env_id"],
            job["counts"],
            job["obs"],
            tuple(job["size"]),
            job["seconds"],
            job["repeats"],
            modes=job["modes"],
        )
    elif kind == "recording":
        from gym_soarm.bench import bench_record

        out = bench_record.record_once(
            job["camera_config"],
            tuple(job["size"]),
            job["episodes"],
            job["workers"],
            job["ray_address"],
        )
    else:
        raise ValueError(f"unknown worker job {kind!r}")
    _emit("RESULT", out)
