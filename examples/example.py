"""Record SO-101 episodes to one MP4 file per camera.

    python examples/example.py

runs one pick-and-place episode (SoArm-v0) with the scripted expert and writes

    videos/front_camera_YYYYmmdd_HHMMSS.mp4
    videos/wrist_camera_YYYYmmdd_HHMMSS.mp4

(H.264, yuv420p, at the control rate, 50 fps by default: they play in a browser). The first
run renders with the ``fast`` quality and takes about 10 s on two CPU cores without a GPU (plus about a
second to build the meshes on a new machine); ``--quality high`` adds shadows and
multisampling and takes about a minute and a half there. ``--task`` records any
registered task (``--task StackCube-v0``). An episode ends half a second after
the task succeeds, when --steps steps have run, or at the environment's step limit.
With several episodes the files get an _epNN suffix. On a desktop with the GUI build of
OpenCV the run is also shown in a window (--viewer auto); on a server it runs headless.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import gym_soarm
from gym_soarm import constants
from gym_soarm.cli.options import task_name
from gym_soarm.render.display import DisplayUnavailableError, window_support_problem
from gym_soarm.render.video import save_frames_to_mp4
from gym_soarm.tasks import DEFAULT_TASK, placement, task_names
from gym_soarm.validation import check_image_size

TAIL_STEPS = 25  # keep recording 0.5 s after success: the release and retreat
Policy = Callable[[Any, dict[str, Any]], np.ndarray]


class RandomPolicy:
    """Uniform random joint targets from the action space, seeded."""

    def __init__(self, env: gym.Env, seed: int) -> None:
        self.action_space = env.action_space
        self.action_space.seed(seed)

    def reset(self) -> None:
        """Nothing to reset: every action is an independent draw."""

    def __call__(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        return self.action_space.sample()


def make_policy(name: str, env: gym.Env, seed: int) -> tuple[Any, str]:
    """The policy called ``name`` for ``env`` and a description of what it is."""
    if name == "random":
        return RandomPolicy(env, seed), "random actions"
    return gym_soarm.make_expert(env), "the scripted expert"


def resolve_viewer(choice: str) -> bool:
    """Whether to open the window: ``auto`` opens it only when windows work here."""
    if choice == "off":
        return False
    problem = window_support_problem()
    if choice == "on" and problem is not None:
        raise DisplayUnavailableError(problem)
    return problem is None


def run_episode(
    env: gym.Env,
    policy: Any,
    max_steps: int,
    seed: int | None,
    options: dict[str, Any],
    description: str,
) -> tuple[dict[str, list[np.ndarray]], int | None]:
    """Run one episode and collect every camera frame.

    Returns:
        The frames of each camera (the reset frame first) and the step at which the
        task succeeded, or None.
    """
    obs, info = env.reset(seed=seed, options=options)
    policy.reset()
    frames = {name: [frame] for name, frame in obs["pixels"].items()}
    success_step = None
    with tqdm(total=max_steps, desc=description, unit="step", leave=True) as progress:
        for step in range(1, max_steps + 1):
            obs, _reward, _terminated, truncated, info = env.step(policy(obs, info))
            for name, frame in obs["pixels"].items():
                frames[name].append(frame)
            progress.update()
            if success_step is None and info["is_success"]:
                success_step = step
            if truncated or (success_step is not None and step - success_step >= TAIL_STEPS):
                break
    return frames, success_step


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--task",
        type=task_name,
        default=DEFAULT_TASK,
        metavar="TASK",
        help=f"the task, by name, alias or gym id: {', '.join(task_names())} "
        f"(default: {DEFAULT_TASK})",
    )
    parser.add_argument("--episodes", type=int, default=1, help="episodes to record (default: 1)")
    parser.add_argument(
        "--steps",
        type=int,
        default=None,
        help="at most this many steps per episode (default: the task's limit)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the first reset (default: 0)")
    parser.add_argument(
        "--grid-cell",
        type=int,
        choices=range(placement.NUM_GRID_CELLS),
        default=None,
        metavar="0-8",
        help="cube start cell of the grid tasks (default: a random cell from the seed)",
    )
    parser.add_argument(
        "--camera-config",
        choices=tuple(constants.CAMERA_CONFIGS),
        default=constants.DEFAULT_CAMERA_CONFIG,
        help=f"cameras to record (default: {constants.DEFAULT_CAMERA_CONFIG})",
    )
    parser.add_argument(
        "--output-dir", type=Path, default=Path("videos"), help="folder (default: videos)"
    )
    parser.add_argument(
        "--quality",
        choices=("fast", "high"),
        default="fast",
        help="fast (default): about 10 s for an episode on two cores; high: shadows and "
        "multisampling, about ten times slower without a GPU",
    )
    parser.add_argument("--height", type=int, default=480, help="frame height (default: 480)")
    parser.add_argument("--width", type=int, default=640, help="frame width (default: 640)")
    parser.add_argument(
        "--viewer",
        choices=("auto", "on", "off"),
        default="auto",
        help="show the run in a window: auto opens one when a display and GUI OpenCV exist",
    )
    parser.add_argument(
        "--policy",
        choices=("expert", "random"),
        default="expert",
        help="the scripted expert (default) or uniform random joint targets",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1; got {args.episodes}")
    if args.steps is not None and args.steps < 1:
        parser.error(f"--steps must be at least 1; got {args.steps}")
    for flag in ("height", "width"):
        try:
            check_image_size(f"--{flag}", getattr(args, flag))
        except ValueError as error:
            parser.error(str(error))
    if args.grid_cell is not None and gym_soarm.get_task(args.task).default_placement != "grid":
        parser.error(f"--grid-cell applies to the grid tasks; {args.task} places objects anywhere")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        show_window = resolve_viewer(args.viewer)
    except DisplayUnavailableError as error:
        print(f"--viewer on: {error}", file=sys.stderr)
        return 1
    env_id = gym_soarm.get_task(args.task).env_id
    env = gym.make(
        env_id,
        obs_type="pixels_agent_pos",
        camera_config=args.camera_config,
        observation_height=args.height,
        observation_width=args.width,
        render_quality=args.quality,
        render_mode="human" if show_window else None,
    )
    policy, policy_name = make_policy(args.policy, env, args.seed)
    max_steps = env.spec.max_episode_steps if args.steps is None else args.steps
    print(
        f"{env_id} (gym_soarm {gym_soarm.__version__}): {policy_name}, cameras "
        f"{', '.join(env.unwrapped.cameras)}, {args.width}x{args.height}, {args.quality} quality"
        f"{', window open' if show_window else ''}"
    )
    stamp = time.strftime("%Y%m%d_%H%M%S")
    successes = 0
    try:
        for episode in range(args.episodes):
            frames, success_step = run_episode(
                env,
                policy,
                max_steps,
                seed=args.seed if episode == 0 else None,
                options=None if args.grid_cell is None else {"cube_grid_position": args.grid_cell},
                description=f"episode {episode + 1}/{args.episodes}",
            )
            suffix = f"_ep{episode + 1:02d}" if args.episodes > 1 else ""
            for name, camera_frames in frames.items():
                path = args.output_dir / f"{name}_{stamp}{suffix}.mp4"
                save_frames_to_mp4(camera_frames, path, fps=env.metadata["render_fps"])
                print(f"wrote {path} ({len(camera_frames)} frames)")
            if success_step is None:
                print(f"episode {episode + 1}: not successful")
            else:
                successes += 1
                print(
                    f"episode {episode + 1}: success at step {success_step} "
                    f"({success_step * env.unwrapped.dt:.2f} s)"
                )
    finally:
        env.close()
    print(f"{successes}/{args.episodes} episodes succeeded")
    return 0


if __name__ == "__main__":
    sys.exit(main())
