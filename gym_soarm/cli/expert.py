"""``python -m gym_soarm.expert``: the scripted expert's success rate per task.

Runs :func:`gym_soarm.expert.evaluate` (every grid cell x the four seed yaws x the
seeds, state observations) and prints one line per task.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import gymnasium as gym

from gym_soarm.expert import EVALUATION_SEEDS, TASK_ENV_IDS, evaluate


def main(argv: Sequence[str] | None = None) -> None:
    """Print the expert's success rate per task over the evaluation episodes."""
    parser = argparse.ArgumentParser(
        description="Measure the scripted expert's success rate over 9 cells x 4 yaws x 3 seeds."
    )
    parser.add_argument("--task", choices=[*TASK_ENV_IDS, "all"], default="all")
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=list(EVALUATION_SEEDS),
        help="reset seeds (default: %(default)s)",
    )
    parser.add_argument("--verbose", action="store_true", help="print every failed episode")
    args = parser.parse_args(argv)
    tasks = list(TASK_ENV_IDS) if args.task == "all" else [args.task]
    for task in tasks:
        started = time.perf_counter()
        results = evaluate(task, args.seeds)
        elapsed = time.perf_counter() - started
        wins = sum(r.success for r in results)
        steps = sorted(r.steps for r in results if r.success)
        limit = gym.spec(TASK_ENV_IDS[task]).max_episode_steps
        spread = f"steps to success {steps[0]}-{steps[-1]} of {limit}" if steps else "no success"
        print(
            f"{task}: {wins}/{len(results)} = {100.0 * wins / len(results):.1f} % success, "
            f"{spread} ({elapsed:.1f} s)"
        )
        if args.verbose:
            for r in results:
                if not r.success:
                    print(
                        f"  failed: cell {r.cell} yaw {r.yaw_deg:g} seed {r.seed} ({r.steps} steps)"
                    )


if __name__ == "__main__":
    main()
