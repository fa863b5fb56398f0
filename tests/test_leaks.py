"""Making, stepping and closing environments again and again leaks nothing.

Training jobs rebuild environments for hours; each cycle here opens a GL context,
renders pixel observations and closes, and the process must come back to where it was.
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym
import numpy as np
from conftest import SMALL

CYCLES = 60
WARMUP_CYCLES = 2  # the first GL context loads Mesa and compiles its shaders once
RSS_GROWTH_LIMIT_MB = 150
# A steady leak of a few MB per cycle could stay under the limit above; the typical
# growth per cycle catches it, while the allocator's one-off jumps (tens of MB, once)
# do not count.
TYPICAL_RSS_GROWTH_PER_CYCLE_LIMIT_MB = 0.5


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def threads() -> int:
    return len(os.listdir("/proc/self/task"))


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("/proc/self/status has no VmRSS line")


def make_step_close(cycle: int) -> None:
    env = gym.make("SoArm-v0", obs_type="pixels_agent_pos", camera_config="front_wrist", **SMALL)
    obs, _ = env.reset(seed=cycle)
    assert obs["pixels"]["front_camera"].std() > 5.0  # the context really rendered
    for _ in range(2):
        obs, *_ = env.step(env.action_space.sample())
    env.close()


def test_make_step_close_cycles_leak_no_fds_threads_or_memory():
    for cycle in range(WARMUP_CYCLES):
        make_step_close(cycle)
    fds, tasks, rss = open_fds(), threads(), rss_mb()
    rss_after = []
    for cycle in range(CYCLES):
        make_step_close(WARMUP_CYCLES + cycle)
        rss_after.append(rss_mb())
        assert open_fds() == fds, f"cycle {cycle}: {open_fds() - fds:+d} open file descriptors"
    assert threads() == tasks, f"{threads() - tasks:+d} threads after {CYCLES} cycles"
    growth = rss_after[-1] - rss
    assert growth < RSS_GROWTH_LIMIT_MB, f"RSS grew {growth:.1f} MB over {CYCLES} cycles"
    typical = float(np.median(np.diff(rss_after)))
    assert typical < TYPICAL_RSS_GROWTH_PER_CYCLE_LIMIT_MB, (
        f"RSS grows {typical:.2f} MB in a typical cycle: {np.round(rss_after, 1).tolist()}"
    )


def test_close_frees_every_renderer_and_is_safe_twice():
    from gym_soarm.render import camera as rendering

    env = gym.make("SoArm-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    env.render()
    env.unwrapped.render_camera_image("wrist_camera", height=32, width=32)  # a second size
    renderers = list(env.unwrapped._observer.renderers.values())
    assert len(renderers) == 2 and all(r in rendering._live_renderers for r in renderers)
    env.close()
    assert not any(r in rendering._live_renderers for r in renderers)
    assert env.unwrapped._observer.renderers == {}
    env.close()
