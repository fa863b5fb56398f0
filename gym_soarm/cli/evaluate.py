"""``python -m gym_soarm.evaluate`` (``gym-soarm-evaluate``): a policy's success on the protocol.

``--policy DIR`` (a ``python -m gym_soarm.train`` folder) or ``--policy expert`` (with
``--task``): episode ``k`` resets with seed ``--first-seed + k`` (default 1000, as
``lerobot-eval`` runs it). Prints the success rate; ``--json PATH`` writes
``success_rate`` (a fraction), ``episodes``, the seeds and each episode's success.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gym_soarm.cli.options import (
    add_override_arguments,
    int_at_least,
    settings_given,
    task_name,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.envs.settings import merge_keywords
from gym_soarm.tasks import get_task, task_names
from gym_soarm.tasks.suites import EVAL_SEED

EVALUATE_SETTINGS: tuple[str, ...] = (
    "reward_type",
    "visual_randomization",
    "physics_randomization",
    "servo_model",
    "object_placement",
    "distractors",
    "dynamics",
)
"""The environment settings ``--policy`` runs may change: the world, never what the
policy reads or sends (observation, units, control mode), which stay the policy's own."""


def env_kwargs(args: argparse.Namespace, base: dict[str, Any], task: str) -> dict[str, Any]:
    """The ``gym.make`` keywords of the evaluation: ``base`` (the policy's own, or state
    observations for the expert) with the flags given, checked."""
    return merge_keywords(base, task, settings_given(args))


DESCRIPTION = (
    "Score a trained policy (a python -m gym_soarm.train folder) or the "
    f"scripted expert on the benchmark's protocol: seeds {EVAL_SEED} + k."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("evaluate", DESCRIPTION)
    parser.add_argument(
        "--policy", required=True, help="a python -m gym_soarm.train --out folder, or 'expert'"
    )
    parser.add_argument(
        "--task",
        type=task_name,
        default=None,
        metavar="TASK",
        help=f"the task, by name, alias or gym id ({', '.join(task_names())}); required "
        "with --policy expert, else the policy's own (another is refused)",
    )
    parser.add_argument(
        "--episodes", type=int_at_least(1), default=50, help="episodes (default 50)"
    )
    parser.add_argument(
        "--first-seed", type=int, default=EVAL_SEED, help=f"seed of episode 0 (default {EVAL_SEED})"
    )
    parser.add_argument("--json", default=None, metavar="PATH", help="write the result as JSON")
    add_override_arguments(parser, EVALUATE_SETTINGS, "the policy", "the policy")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from gym_soarm.rl.evaluation import TrainedPolicy, score

    try:
        if args.json is not None and Path(args.json).is_dir():
            raise ValueError(f"--json must be a file path; {args.json!r} is a folder.")
        if args.policy == "expert":
            if args.task is None:
                raise ValueError("--policy expert needs --task, e.g. --task ReachTarget-v0.")
            task = get_task(args.task).name
            base: dict[str, Any] = {"obs_type": "state"}
            policy = None
        else:
            trained = TrainedPolicy(args.policy, args.task)
            task, base, policy = trained.task, trained.settings["env"], trained
        kwargs = env_kwargs(args, base, task)
        result = score(task, kwargs, policy, args.episodes, args.first_seed)
    except (ValueError, TypeError) as exc:  # refused input: argparse's usage error, exit 2
        parser.error(str(exc))
    except ImportError as exc:  # a missing extra
        raise SystemExit(f"python -m gym_soarm.evaluate: error: {exc}") from None
    result["policy"] = args.policy
    print(
        f"{task}: success {100 * result['success_rate']:.0f} % over {result['episodes']} "
        f"episode{'' if result['episodes'] == 1 else 's'} (seeds {result['seeds'][0]}-{result['seeds'][-1]}), mean return "
        f"{result['mean_return']:.2f}"
    )
    if args.json is not None:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result, indent=2) + "\n")
    return 0
