"""``python -m gym_soarm.expert`` (``gym-soarm-expert``): each task's expert success rate.

Runs :func:`gym_soarm.expert.evaluate` on every registered task (or the ones named),
with state observations, and prints one line per task: success, steps to success and
the time taken. ``--control-mode`` makes the expert answer in another control mode.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

from gym_soarm.control import CONTROL_MODES
from gym_soarm.expert import evaluate
from gym_soarm.tasks import get_task, task_names, task_spellings


def main(argv: Sequence[str] | None = None) -> None:
    """Print the expert's success rate per task over its evaluation episodes."""
    parser = argparse.ArgumentParser(
        prog="python -m gym_soarm.expert",
        description="Measure the scripted expert's success rate on each task: grid tasks "
        "over 9 cells x 4 yaws x 3 seeds, the others over seeds 0-99.",
    )
    parser.add_argument(
        "--task",
        nargs="+",
        choices=[*task_spellings(), "all"],
        default=["all"],
        metavar="TASK",
        help=f"tasks to measure: {', '.join(task_names())}, or all (default)",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=None,
        help="seeds per grid cell and yaw for grid tasks (default 3), episodes for the "
        "others (default 100)",
    )
    parser.add_argument(
        "--control-mode",
        choices=CONTROL_MODES,
        default="joint_pos",
        help="the environment's control mode, in which the expert answers (default joint_pos)",
    )
    parser.add_argument("--verbose", action="store_true", help="print every failed episode")
    args = parser.parse_args(argv)
    if args.seeds is not None and args.seeds < 1:
        parser.error(f"--seeds must be >= 1; got {args.seeds}")
    names = task_names() if "all" in args.task else [get_task(t).name for t in args.task]
    for name in dict.fromkeys(names):
        started = time.perf_counter()
        results = evaluate(name, args.seeds, control_mode=args.control_mode)
        elapsed = time.perf_counter() - started
        wins = sum(r.success for r in results)
        steps = sorted(r.steps for r in results if r.success)
        limit = get_task(name).max_episode_steps
        spread = (
            f"steps to success {steps[0]}-{steps[-1]} (median {steps[len(steps) // 2]}) of {limit}"
            if steps
            else "no success"
        )
        print(
            f"{name}: {wins}/{len(results)} = {100.0 * wins / len(results):.1f} % success, "
            f"{spread} ({elapsed:.1f} s)",
            flush=True,
        )
        if args.verbose:
            for r in results:
                if not r.success:
                    print(f"  failed: seed {r.seed} options {r.options} ({r.steps} steps)")


if __name__ == "__main__":
    main()
