"""``python -m gym_soarm.expert`` (``gym-soarm-expert``): each task's expert success rate.

Runs :func:`gym_soarm.expert.evaluate` on every registered task (or the tasks and suites
named), with state observations, and prints one line per task: success, steps to success
and the time taken. ``--control-mode`` makes the expert answer in another control mode.
``--protocol N`` measures it on the benchmark's protocol instead
(:func:`gym_soarm.expert.evaluate_protocol`: episode ``k`` resets with seed
``EVAL_SEED + k``, as ``lerobot-eval`` runs it), the reference row of a suite's scores.
``--perturbed [N]`` measures it from perturbed states instead
(:mod:`gym_soarm.expert.perturbed`: random actions, a push, a dropped object, half-closed
jaws; N episodes of each).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from typing import Any

from gym_soarm.cli.options import (
    IMAGE_SETTINGS,
    add_settings_arguments,
    settings_from_args,
    task_selection,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.expert import EXPERT_KINDS, EpisodeResult, evaluate, evaluate_protocol
from gym_soarm.expert.perturbed import PERTURBATIONS, PerturbedResult, evaluate_perturbed
from gym_soarm.tasks import get_task, task_names
from gym_soarm.tasks.suites import (
    EVAL_SEED,
    SUITE_NAMES,
    SelectedTask,
    distinct_tasks,
    resolve_selection,
)

EXPERT_EXCLUDES: tuple[str, ...] = (
    "task",  # --task: tasks, suites or all
    "obs_type",  # the expert reads the state: environment_state_agent_pos
    *IMAGE_SETTINGS,  # nothing is rendered
)
"""The environment settings the expert's measurement sets itself."""
EXPERT_OBS_TYPE = "environment_state_agent_pos"


def env_settings(args: argparse.Namespace, item: SelectedTask) -> EnvSettings:
    """The environment settings of ``item``'s measurement: the flags, then the suite's
    own variation."""
    return settings_from_args(args, task=item.task, obs_type=EXPERT_OBS_TYPE, **item.variation)


def env_kwargs(settings: EnvSettings) -> dict[str, Any]:
    """The keywords the evaluation functions pass on to ``gym.make`` (they set the task
    and the observation type themselves)."""
    kwargs = settings.to_kwargs()
    del kwargs["task"], kwargs["obs_type"]
    return kwargs


def _selection(text: str) -> str:
    return text if text == "all" else task_selection(text)


DESCRIPTION = (
    "Measure the expert's success rate on each task: grid tasks "
    "over 9 cells x 4 yaws x 3 seeds, the others over seeds 0-99 (or, with --protocol, "
    f"on the benchmark's seeds {EVAL_SEED} + k)."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    """The program's command line."""
    parser = program_parser("expert", DESCRIPTION)
    parser.add_argument(
        "--task",
        nargs="+",
        type=_selection,
        default=["all"],
        metavar="TASK",
        help=f"tasks to measure: {', '.join(task_names())}, suites "
        f"({', '.join(SUITE_NAMES)}), or all (default)",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=None,
        help="seeds per grid cell and yaw for grid tasks (default 3), episodes for the "
        "others (default 100)",
    )
    parser.add_argument(
        "--protocol",
        type=int,
        default=None,
        metavar="N",
        help=f"instead: N episodes per task on the benchmark's protocol (seeds {EVAL_SEED} + k, "
        "a suite's own randomisation), as lerobot-eval runs them",
    )
    parser.add_argument(
        "--perturbed",
        type=int,
        nargs="?",
        const=20,
        default=None,
        metavar="N",
        help="instead: the success from perturbed states (random actions, a push, a dropped "
        "object, half-closed jaws, a shove of random joint targets mid-episode), N episodes "
        "of each per task (default 20)",
    )
    parser.add_argument(
        "--kind",
        choices=EXPERT_KINDS,
        default="state",
        help="state: the expert that acts from the state (default); scripted: the timed script",
    )
    parser.add_argument("--verbose", action="store_true", help="print every failed episode")
    add_settings_arguments(
        parser,
        exclude=EXPERT_EXCLUDES,
        helps={
            "control_mode": "the environment's control mode, in which the expert answers "
            "(default joint_pos)"
        },
        description="gym.make keywords of every measured environment (see docs/keywords.md); "
        "a suite's own variation wins",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    """Print the expert's success rate per task over its evaluation episodes."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.perturbed is not None:
        if args.perturbed < 1:
            parser.error(f"--perturbed must be >= 1; got {args.perturbed}")
        if args.seeds is not None or args.protocol is not None:
            parser.error("--perturbed runs its own episodes; drop --seeds and --protocol")
    if args.seeds is not None and args.seeds < 1:
        parser.error(f"--seeds must be >= 1; got {args.seeds}")
    if args.protocol is not None and args.protocol < 1:
        parser.error(f"--protocol must be >= 1; got {args.protocol}")
    if args.seeds is not None and args.protocol is not None:
        parser.error("--seeds and --protocol choose the episodes two ways; give one of them")
    names = [",".join(task_names()) if name == "all" else name for name in args.task]
    for item in distinct_tasks(resolve_selection(",".join(names))):
        started = time.perf_counter()
        try:
            kwargs = env_kwargs(env_settings(args, item))
        except ValueError as exc:  # also TypeError: ArgumentTypeError is both
            parser.error(str(exc))
        if args.perturbed is not None:
            results = evaluate_perturbed(item.task, args.perturbed, kind=args.kind, **kwargs)
            _report_perturbed(item.task, results)
            continue
        if args.protocol is not None:
            results = evaluate_protocol(item.task, args.protocol, kind=args.kind, **kwargs)
        else:
            results = evaluate(item.task, args.seeds, kind=args.kind, **kwargs)
        label = item.task if not item.variation else f"{item.group}/{item.task}"
        _report(label, get_task(item.task).max_episode_steps, results, started, args.verbose)


def _report_perturbed(label: str, results: list[PerturbedResult]) -> None:
    # A shove that left an object off the table or out of reach does not count.
    results = [r for r in results if r.applied or r.perturbation != "shove"]
    parts = []
    for perturbation in PERTURBATIONS:
        rows = [r for r in results if r.perturbation == perturbation]
        if rows:
            wins = sum(r.success for r in rows)
            parts.append(f"{perturbation} {wins}/{len(rows)}")
    wins = sum(r.success for r in results)
    print(
        f"{label}: {wins}/{len(results)} = {100.0 * wins / len(results):.1f} % success from "
        f"perturbed states ({', '.join(parts)})",
        flush=True,
    )


def _report(
    label: str, limit: int, results: list[EpisodeResult], started: float, verbose: bool
) -> None:
    elapsed = time.perf_counter() - started
    wins = sum(r.success for r in results)
    steps = sorted(r.steps for r in results if r.success)
    spread = (
        f"steps to success {steps[0]}-{steps[-1]} (median {steps[len(steps) // 2]}) of {limit}"
        if steps
        else "no success"
    )
    print(
        f"{label}: {wins}/{len(results)} = {100.0 * wins / len(results):.1f} % success, "
        f"{spread} ({elapsed:.1f} s)",
        flush=True,
    )
    if verbose:
        for r in results:
            if not r.success:
                print(f"  failed: seed {r.seed} options {r.options} ({r.steps} steps)")


if __name__ == "__main__":
    main()
