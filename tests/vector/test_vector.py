"""Vector environments with pixel observations, under every multiprocessing start method.

Each asynchronous run happens in a subprocess (``tests/vector_probe.py``) with a
timeout: a worker that hangs, e.g. on a GL display inherited through ``fork``, fails
its test instead of blocking the suite.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest
import vector_probe
from paths import TESTS

pytestmark = pytest.mark.gl

PROBE = TESTS / "vector_probe.py"
# Generous: spawn and forkserver workers import the package afresh on a loaded machine.
STARTUP_TIMEOUT_S = 300
# A fork worker that hangs on the parent's display would block forever; this bounds it.
FORK_TIMEOUT_S = 120


def clean_environ() -> dict[str, str]:
    """This process's environment without its GL choice (PyOpenGL's platform is set once
    EGL is in use here), so that each probe picks its own backend."""
    return {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}


def run_probe(*args: str, timeout: float, env: dict[str, str] | None = None):
    """Run the probe script; return (returncode, report or None, stderr)."""
    proc = subprocess.Popen(
        [sys.executable, str(PROBE), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its workers share the session and are killed with it
        env={**clean_environ(), **(env or {})},
    )
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(
            f"vector_probe.py {' '.join(args)} did not finish within {timeout} s "
            f"(a worker hangs). stderr:\n{err[-3000:]}"
        )
    lines = out.strip().splitlines()
    report = json.loads(lines[-1]) if proc.returncode == 0 and lines else None
    return proc.returncode, report, err


def check_vector_report(report: dict) -> None:
    vector = report["vector"]
    n = vector_probe.NUM_ENVS
    height, width = (
        vector_probe.KWARGS["observation_height"],
        vector_probe.KWARGS["observation_width"],
    )
    assert vector["shape"] == [n, height, width, 3]
    assert vector["dtype"] == "uint8"
    assert all(vector["contained"]), "an observation fell outside the vector observation space"
    assert min(vector["frame_std"]) > 5.0, "a worker returned a blank frame"
    workers, serial = vector["workers"], report["serial"]
    # Seeds SEED and SEED + 1 give different episodes: different start and different frames.
    assert (workers[0]["cell"], workers[0]["yaw"]) != (workers[1]["cell"], workers[1]["yaw"])
    # The same actions move both arms alike; the cube, hence every frame, differs.
    assert all(a != b for a, b in zip(workers[0]["frames"], workers[1]["frames"], strict=True))
    # Each worker plays exactly the episode of a plain environment with its seed.
    for worker, reference in zip(workers, serial, strict=True):
        assert (worker["cell"], worker["yaw"]) == (reference["cell"], reference["yaw"])
        assert worker["frames"] == reference["frames"]
        assert worker["agent_pos"] == reference["agent_pos"]


@pytest.mark.subprocess
@pytest.mark.parametrize("context", ["fork", "forkserver", "spawn"])
def test_async_vector_env_renders_pixels_in_its_workers(context):
    code, report, err = run_probe(
        "--mode", "async", "--context", context, timeout=STARTUP_TIMEOUT_S
    )
    assert code == 0, err[-3000:]
    check_vector_report(report)
    assert report["parent_rendered_before"] is False
    # The workers rendered every frame; the parent never opened a GL display.
    assert report["parent_rendered_after_vector"] is False


@pytest.mark.subprocess
def test_fork_workers_render_after_the_parent_rendered():
    code, report, err = run_probe(
        "--mode", "async", "--context", "fork", "--render-first", timeout=FORK_TIMEOUT_S
    )
    assert code == 0, err[-3000:]
    assert report["backend"] == "egl"
    assert report["parent_rendered_before"] is True
    check_vector_report(report)


@pytest.mark.subprocess
def test_fork_after_osmesa_rendering_raises_a_clear_error_instead_of_hanging():
    """Mesa's OSMesa cannot be given a fresh display in a forked child: we say so."""
    code, report, err = run_probe(
        "--mode",
        "async",
        "--context",
        "fork",
        "--render-first",
        timeout=FORK_TIMEOUT_S,
        env={"MUJOCO_GL": "osmesa"},
    )
    assert code != 0 and report is None
    assert "GLBackendError" in err
    assert "forked after its parent rendered with OSMesa" in err
    assert "vector_kwargs={'context': 'forkserver'}" in err


def test_sync_vector_env_matches_serial_environments():
    report = {
        "vector": vector_probe.run_vector("sync", None),
        "serial": vector_probe.run_serial(),
    }
    check_vector_report(report)
