"""The scripted expert's success on every task under variation.

python scripts/expert_randomized.py --physics light --servo sts3215 --grid-seeds 1 --episodes 20
python scripts/expert_randomized.py --physics none --servo ideal --distractors 4
python scripts/expert_randomized.py --physics none --servo ideal --placement uniform --tasks LiftCube-v0
"""

from __future__ import annotations

import argparse

from gym_soarm.expert import evaluate
from gym_soarm.tasks import get_task, task_names


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--physics", default="light", help="physics_randomization")
    parser.add_argument("--visual", default="none", help="visual_randomization")
    parser.add_argument("--servo", default="sts3215", help="servo_model")
    parser.add_argument("--grid-seeds", type=int, default=1, help="seeds per grid cell and yaw")
    parser.add_argument("--episodes", type=int, default=20, help="seeds of the other tasks")
    parser.add_argument("--distractors", type=int, default=0, help="distractors (0-4)")
    parser.add_argument("--placement", default=None, help="object_placement (task default)")
    parser.add_argument("--tasks", nargs="+", default=None, help="tasks (default: all)")
    args = parser.parse_args()
    kwargs = {
        "physics_randomization": args.physics,
        "visual_randomization": args.visual,
        "servo_model": args.servo,
        "distractors": args.distractors,
        "object_placement": args.placement,
    }
    print("| task | episodes | expert success |\n|---|---|---|")
    for task in args.tasks or task_names():
        grid = get_task(task).make_task(args.placement).placement == "grid"
        results = evaluate(task, args.grid_seeds if grid else args.episodes, **kwargs)
        wins = sum(result.success for result in results)
        print(
            f"| `{task}` | {len(results)} | {wins}/{len(results)} "
            f"({100 * wins / len(results):.0f} %) |"
        )


if __name__ == "__main__":
    main()
