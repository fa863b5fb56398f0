"""Runs a small vector environment the way a training script would and prints a JSON report.

``tests/vector/test_vector.py`` starts this file in a subprocess with a timeout, so that a worker
that hangs fails its test instead of blocking the suite::

    python tests/vector_probe.py --mode async --context fork --render-first

The report holds, per worker, the start cell and yaw, a digest of every frame and the
agent positions, and the same figures from plain serial environments with the same seeds.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import gymnasium as gym
import numpy as np

import gym_soarm
from gym_soarm.render import backend as rendering

ENV_ID = "SoArm-v0"
NUM_ENVS = 2
STEPS = 3
SEED = 11
KWARGS = {
    "obs_type": "pixels_agent_pos",
    "camera_config": "front_only",
    "observation_height": 48,
    "observation_width": 64,
}
CAMERA = "front_camera"


def _digest(frame: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(frame).tobytes()).hexdigest()


def _actions(space: gym.spaces.Box) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.uniform(space.low, space.high).astype(np.float32) for _ in range(STEPS)]


def _egl_display_open() -> bool:
    egl_module = sys.modules.get("mujoco.egl")
    return egl_module is not None and getattr(egl_module, "EGL_DISPLAY", None) is not None


def run_vector(mode: str, context: str | None) -> dict:
    vector_kwargs = {"context": context} if mode == "async" and context else {}
    envs = gym.make_vec(
        ENV_ID,
        num_envs=NUM_ENVS,
        vectorization_mode=mode,
        vector_kwargs=vector_kwargs,
        **KWARGS,
    )
    try:
        obs, info = envs.reset(seed=SEED)
        frames = [obs["pixels"][CAMERA]]
        agent_pos = [obs["agent_pos"]]
        contained = [bool(envs.observation_space.contains(obs))]
        for action in _actions(envs.single_action_space):
            obs, _reward, _terminated, _truncated, _info = envs.step(np.stack([action] * NUM_ENVS))
            frames.append(obs["pixels"][CAMERA])
            agent_pos.append(obs["agent_pos"])
            contained.append(bool(envs.observation_space.contains(obs)))
        return {
            "shape": list(frames[0].shape),
            "dtype": str(frames[0].dtype),
            "contained": contained,
            "frame_std": [float(np.std(f)) for f in frames[0]],
            "workers": [
                {
                    "cell": int(info["cube_grid_position"][i]),
                    "yaw": float(info["cube_rotation_deg"][i]),
                    "frames": [_digest(f[i]) for f in frames],
                    "agent_pos": [p[i].tolist() for p in agent_pos],
                }
                for i in range(NUM_ENVS)
            ],
        }
    finally:
        envs.close()


def run_serial() -> list[dict]:
    """The same episodes from one environment per seed, in this process."""
    results = []
    for i in range(NUM_ENVS):
        env = gym.make(ENV_ID, **KWARGS)
        try:
            obs, info = env.reset(seed=SEED + i)
            frames, agent_pos = [obs["pixels"][CAMERA]], [obs["agent_pos"]]
            for action in _actions(env.action_space):
                obs, *_ = env.step(action)
                frames.append(obs["pixels"][CAMERA])
                agent_pos.append(obs["agent_pos"])
            results.append(
                {
                    "cell": int(info["cube_grid_position"]),
                    "yaw": float(info["cube_rotation_deg"]),
                    "frames": [_digest(f) for f in frames],
                    "agent_pos": [p.tolist() for p in agent_pos],
                }
            )
        finally:
            env.close()
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--mode", choices=("async", "sync"), required=True)
    parser.add_argument("--context", choices=("fork", "forkserver", "spawn"))
    parser.add_argument(
        "--render-first",
        action="store_true",
        help="render a frame in this process before the vector environment starts",
    )
    args = parser.parse_args()
    report: dict = {"pid": os.getpid(), "backend": None}
    parent_env = None
    if args.render_first:
        # Kept open while the workers run: its GL context is alive when they fork.
        parent_env = gym.make(ENV_ID, **KWARGS)
        parent_env.reset(seed=0)
        report["backend"] = rendering.gl_backend()
    report["parent_rendered_before"] = _egl_display_open()
    report["vector"] = run_vector(args.mode, args.context)
    if parent_env is not None:
        parent_env.step(parent_env.action_space.sample())  # the parent still renders
        parent_env.close()
    # Async workers render in their own processes: the parent must not have needed GL.
    report["parent_rendered_after_vector"] = _egl_display_open()
    report["serial"] = run_serial()
    print(json.dumps(report))


if __name__ == "__main__":
    assert gym_soarm.ENV_IDS  # the import registers the environment ids
    main()
