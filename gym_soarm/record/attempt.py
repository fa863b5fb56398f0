"""One recording attempt: what it needs, the loop that plays it, where its origin goes.

The recorder (:mod:`gym_soarm.record.record`) and its runners in this process
(:func:`record_here`), in worker processes (:mod:`gym_soarm.record.parallel`) and in Ray
tasks (:mod:`gym_soarm.record.ray_tasks`) all play attempts through
:func:`record_attempt` from an :class:`AttemptPlan`.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gym_soarm import constants
from gym_soarm.data.writer import LeRobotDatasetWriter
from gym_soarm.tasks.base import TaskSpec

VARIATION_PATH = "meta/variation.jsonl"
"""Each kept episode's index, task, reset seed and what its reset drew (JSON lines)."""
FPS = constants.RENDER_FPS
"""Frames per second of a recording at the default control rate (a recording's frames
are its environment's control steps: ``AttemptPlan.fps``)."""


@dataclasses.dataclass(frozen=True)
class AttemptPlan:
    """Everything an attempt needs besides its index (picklable, for worker processes)."""

    spec: TaskSpec
    env_kwargs: dict[str, Any]
    features: dict[str, dict[str, Any]]
    robot_type: str
    seed: int
    dart_noise: float
    keep: str
    units: str
    wrist_roll_offset_deg: float
    cameras: tuple[str, ...]
    state_only: bool

    @property
    def fps(self) -> int:
        """Frames per second: the environment's control rate (``control_hz``)."""
        return int(self.env_kwargs.get("control_hz", FPS))


def record_attempt(
    env: gym.Env, expert: Any, writer: LeRobotDatasetWriter, plan: AttemptPlan, attempt: int
) -> tuple[bool, dict[str, Any] | None]:
    """Play attempt ``attempt`` (reset with ``plan.seed + attempt``) into ``writer``'s buffer.

    Returns:
        Whether the expert succeeded, and what the reset drew (``info["variation"]``, or
        None). The frames stay in the writer's episode buffer: the caller saves, exports
        or clears them.
    """
    base = env.unwrapped
    noise = np.random.default_rng([plan.seed, attempt])
    obs, info = env.reset(seed=plan.seed + attempt)
    drawn = info.get("variation")
    expert.reset()
    done = False
    while not done:
        action_rad = expert.next_targets_radians()  # radians, whatever the units
        current_rad = base.commanded_targets
        action = base.control.action_for_targets(action_rad, current_rad)
        executed = action
        if plan.dart_noise > 0:
            noisy_rad = action_rad + noise.normal(0.0, plan.dart_noise, action_rad.shape)
            executed = base.control.action_for_targets(noisy_rad, current_rad)
        frame: dict[str, Any] = {
            "observation.state": obs["agent_pos"].astype(np.float32),
            "action": action,
            "task": env.unwrapped.task_description,
        }
        if plan.state_only:
            frame["observation.environment_state"] = obs["environment_state"].astype(np.float32)
        else:
            for camera in plan.cameras:
                frame[f"observation.images.{camera}"] = obs["pixels"][camera]
        obs, reward, terminated, truncated, info = env.step(executed)
        done = terminated or truncated
        frame["next.reward"] = np.array([reward], np.float32)
        frame["next.success"] = np.array([info["is_success"]])
        frame["next.done"] = np.array([done])
        writer.add_frame(frame)
    return bool(info["is_success"]), drawn


def write_variation(
    root: str | os.PathLike[str],
    episode_index: int,
    seed: int,
    drawn: Mapping[str, Any] | None,
    task: str,
) -> None:
    """Append a kept episode's origin to ``meta/variation.jsonl``: its index, task and reset
    seed, and what its reset drew (``info["variation"]``) when the scene is varied."""
    line = {"episode_index": episode_index, "task": task, "seed": seed, **(drawn or {})}
    with open(Path(root) / VARIATION_PATH, "a", encoding="utf-8") as out:
        out.write(json.dumps(line) + "\n")


def record_here(
    root: str | os.PathLike[str],
    writer: LeRobotDatasetWriter,
    plan: AttemptPlan,
    episodes: int,
    max_attempts: int,
    bar: Any,
) -> tuple[int, int, bool]:
    """Record one task's attempts in this process into ``writer`` until ``episodes`` are
    kept or ``max_attempts`` made: (attempts, successes, interrupted by Ctrl-C)."""
    from gym_soarm.expert import make_expert

    kept = attempts = successes = 0
    env = gym.make(plan.spec.env_id, **plan.env_kwargs)
    try:
        expert = make_expert(env)
        while kept < episodes and attempts < max_attempts:
            success, drawn = record_attempt(env, expert, writer, plan, attempts)
            attempts += 1
            successes += success
            if success or plan.keep == "all":
                index = writer.save_episode()
                write_variation(root, index, plan.seed + attempts - 1, drawn, plan.spec.name)
                kept += 1
                if bar is not None:
                    bar.update(1)
            else:
                writer.clear_episode_buffer()
            if bar is not None:
                bar.set_postfix(success=f"{successes}/{attempts}", frames=writer.num_frames)
    except KeyboardInterrupt:
        return attempts, successes, True
    finally:
        env.close()
    return attempts, successes, False
