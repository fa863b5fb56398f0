"""The ceiling of one configuration, and the line protocol of the benchmark's processes.

The benchmark runs this file by its path (``python .../gym_soarm/bench/ceiling.py JOB``,
:data:`PATH`), in a process that never imports gym_soarm, so that ``mujoco.Renderer``
picks its GL backend from ``MUJOCO_GL`` as in any MuJoCo program. ``JOB`` (JSON) names
a compiled model (``.mjb``), the state to start from and what to measure:

* ``"mode": "step"``: bare ``mujoco.mj_step`` with the environment's substeps and
  random servo targets, back to the start state every ``episode_steps`` steps;
* ``"mode": "render"``: a bare ``mujoco.Renderer`` of the same cameras, image size and
  quality (shadows, reflections).

Every measuring process of the benchmark speaks one protocol on its stdin and stdout:
it prints ``READY <json>`` when set up, answers each ``run <seconds>`` line with
``SLICE <json>`` (the steps taken and the seconds spent in them), and ``done`` with
``RESULT <json>`` before it exits (:func:`emit`, :func:`serve`). Importing this module
runs nothing; it imports only the standard library, MuJoCo and NumPy.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

PATH = Path(__file__).resolve()
"""This file: the program the benchmark runs by its path."""

N_ACTIONS = 1024  # random servo targets drawn up front and cycled


def emit(tag: str, payload: dict) -> None:
    """Print one protocol line, ``<tag> <json>``."""
    print(f"{tag} {json.dumps(payload)}", flush=True)


def serve(
    ready: dict, run_slice: Callable[[float], dict], finish: Callable[[], dict], lines: Any = None
) -> None:
    """Answer the protocol's commands from ``lines`` (default: stdin) until ``done``."""
    emit("READY", ready)
    for line in sys.stdin if lines is None else lines:
        command, _, argument = line.strip().partition(" ")
        if command == "run":
            emit("SLICE", run_slice(float(argument)))
        elif command == "done":
            emit("RESULT", finish())
            return


def _start(job: dict) -> tuple[Any, Any]:
    import mujoco

    model = mujoco.MjModel.from_binary_path(job["model"])
    data = mujoco.MjData(model)
    state = job["state"]
    data.qpos[:] = state["qpos"]
    data.qvel[:] = state["qvel"]
    data.ctrl[:] = state["ctrl"]
    mujoco.mj_forward(model, data)
    return model, data


def stepper(job: dict, model: Any, data: Any) -> Callable[[float], dict]:
    """``run_slice`` of bare physics: ``mj_step`` with the substeps of one control step."""
    import mujoco
    import numpy as np

    rng = np.random.default_rng(job["seed"])
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    actions = rng.uniform(low, high, size=(N_ACTIONS, model.nu))
    substeps, episode = job["substeps"], job["episode_steps"]
    start = (data.qpos.copy(), data.qvel.copy())
    counter = [0]

    def run_slice(seconds: float) -> dict:
        n, spent, i = 0, 0.0, counter[0]
        deadline = time.perf_counter() + seconds
        while True:
            data.ctrl[:] = actions[i % N_ACTIONS]
            t0 = time.perf_counter()
            mujoco.mj_step(model, data, substeps)
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

    return run_slice


def renderer(job: dict, model: Any, data: Any, ready: dict) -> tuple[Callable, Callable]:
    """``run_slice`` of bare rendering (every camera once a step) and the renderer's
    ``close``; ``ready`` gets the GL renderer's name."""
    import mujoco

    bare = mujoco.Renderer(model, job["height"], job["width"])
    high = job["quality"] == "high"
    bare.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = high
    bare.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = high
    cameras = job["cameras"]
    for cam in cameras:  # warm up (the GL context, the textures)
        bare.update_scene(data, cam)
        bare.render()
    try:
        from OpenGL import GL

        ready["gl_renderer"] = GL.glGetString(GL.GL_RENDERER).decode()
    except Exception as exc:  # any failure only loses the name
        ready["gl_renderer"] = f"unknown ({type(exc).__name__})"

    def run_slice(seconds: float) -> dict:
        n = 0
        t0 = time.perf_counter()
        deadline = t0 + seconds
        while True:
            for cam in cameras:
                bare.update_scene(data, cam)
                bare.render()
            n += 1
            if time.perf_counter() >= deadline:
                break
        return {"steps": n, "seconds": time.perf_counter() - t0}

    return run_slice, bare.close


def main(argv: list[str] | None = None) -> int:
    """Measure the ceiling that the JSON job ``argv[0]`` describes, as the protocol asks."""
    if sys.path and sys.path[0] and Path(sys.path[0]).resolve() == PATH.parent:
        del sys.path[0]  # run by its path: its neighbours are no top-level modules
    job = json.loads((sys.argv[1:] if argv is None else argv)[0])
    model, data = _start(job)
    ready: dict = {}
    close = None
    if job["mode"] == "step":
        run_slice = stepper(job, model, data)
    else:
        run_slice, close = renderer(job, model, data, ready)

    def finish() -> dict:
        if close is not None:
            close()
        return {}

    serve(ready, run_slice, finish)
    return 0


if __name__ == "__main__":
    sys.exit(main())
