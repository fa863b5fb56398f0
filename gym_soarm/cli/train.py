"""``python -m gym_soarm.train`` (``gym-soarm-train``): train a state policy with
Stable-Baselines3, or imitate the task's expert from the state or from the cameras.

``--algo ppo|sac --task T --seed S [--steps N] --out DIR``: the package's recipe for the
algorithm and task (:mod:`gym_soarm.rl.hyperparams`), checkpoints, ``curve.csv`` and
``curve.png`` in ``DIR`` (:func:`gym_soarm.rl.training.train`). ``--algo bc|dagger``:
behaviour cloning (DART noise) or DAgger from the task's expert
(:func:`gym_soarm.rl.imitation.train_imitation`), the same files plus ``demos.npz``.
With ``--obs-type pixels_agent_pos`` (and ``--camera-config``, ``--observation-height``,
``--observation-width``) BC and DAgger train a pixel student
(:mod:`gym_soarm.rl.pixels`), on ``--device`` (default cpu).
``--algo ppo --init DIR``: PPO starting from the BC/DAgger policy in ``DIR``. Ctrl-C
stops the run and keeps its last checkpoint and curve.
"""

from __future__ import annotations

import argparse
import ast
import logging
import warnings
from collections.abc import Sequence
from typing import Any

from gym_soarm.cli.options import (
    IMAGE_SETTINGS,
    add_settings_arguments,
    int_at_least,
    settings_given,
    task_name,
)
from gym_soarm.cli.programs import program_parser
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.rl.hyperparams import IMITATION, TRAINERS, VEC_ENVS, VECTOR_ENVS
from gym_soarm.tasks import task_names


def _hyperparam(text: str) -> tuple[str, Any]:
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(
            f"expected KEY=VALUE (e.g. learning_rate=1e-4); got {text!r}"
        )
    try:
        return key, ast.literal_eval(value)
    except (ValueError, SyntaxError):
        raise argparse.ArgumentTypeError(
            f"the value of {key} must be a Python literal (a number, string, list ...); got {value!r}"
        ) from None


PIXEL_SETTINGS: tuple[str, ...] = (
    "obs_type",
    "camera_config",
    "observation_height",
    "observation_width",
    "render_quality",
)
"""What a pixel student sees (``--algo bc|dagger --obs-type pixels_agent_pos``); PPO and
SAC learn from the state and refuse them."""

TRAIN_EXCLUDES: tuple[str, ...] = (
    "task",  # --task
    *(name for name in IMAGE_SETTINGS if name not in PIXEL_SETTINGS),  # no window, RGB only
)
"""The environment settings the trainers set themselves."""


def env_changes(args: argparse.Namespace) -> dict[str, Any]:
    """The ``gym.make`` keywords the flags change over the recipe's environment."""
    return settings_given(args)


DESCRIPTION = (
    "Train PPO or SAC on a task's state observations with the package's "
    "recipe, or imitate the task's scripted expert (bc: behaviour cloning with DART "
    "noise, dagger: DAgger); writes model.zip, settings.json, curve.csv and curve.png "
    "to --out."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("train", DESCRIPTION)
    parser.add_argument("--algo", required=True, choices=TRAINERS, help="the algorithm")
    parser.add_argument(
        "--task",
        type=task_name,
        required=True,
        metavar="TASK",
        help=f"the task, by name, alias or gym id: {', '.join(task_names())}",
    )
    parser.add_argument("--seed", type=int_at_least(0), default=0, help="training seed (default 0)")
    parser.add_argument(
        "--steps",
        type=int_at_least(1),
        default=None,
        help="environment steps (default: the recipe's; ppo and sac only)",
    )
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument(
        "--eval-every",
        type=int_at_least(1),
        default=None,
        help="environment steps between evaluations on the protocol (default: the recipe's; "
        "ppo and sac only: bc and dagger evaluate after each round)",
    )
    parser.add_argument(
        "--eval-episodes",
        type=int_at_least(1),
        default=None,
        help="episodes per evaluation (default: the recipe's): the protocol's for ppo and sac, "
        "validation episodes (seeds 50000 + k) for bc and dagger",
    )
    parser.add_argument(
        "--hyperparams",
        nargs="+",
        type=_hyperparam,
        default=[],
        metavar="KEY=VALUE",
        help="replace recipe arguments of the algorithm, e.g. learning_rate=1e-4 "
        "learning_starts=100, or demos=50 rounds=3 for bc/dagger (Python literals)",
    )
    parser.add_argument(
        "--vector-env",
        choices=VECTOR_ENVS,
        default=None,
        help="the package's vector env the environments step in: PPO trains with RSL-RL on "
        "batched (the CPU) and warp (MuJoCo Warp, --device cuda), with Stable-Baselines3 on "
        "processes; SAC with Stable-Baselines3 on batched or processes; default: the "
        "recipe's (Stable-Baselines3 on the batched env for state observations)",
    )
    parser.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default=None,
        help="deprecated (use --vector-env): Stable-Baselines3's stepping, native (the "
        "package's vector env), dummy (this process) or subproc (one process each)",
    )
    parser.add_argument(
        "--init",
        default=None,
        metavar="DIR",
        help="--algo ppo only: start from the policy in DIR (a bc or dagger --out folder of "
        "the same task), with a behaviour-cloning term on its demonstrations",
    )
    parser.add_argument(
        "--device",
        default="cpu",
        help="where a pixel student trains (bc and dagger with --obs-type "
        "pixels_agent_pos), or PPO on RSL-RL's tensors live (--vector-env warp): cpu "
        "(default), cuda or cuda:N",
    )
    parser.add_argument(
        "--no-progress", action="store_true", help="no progress bar (e.g. in log files)"
    )
    add_settings_arguments(
        parser,
        exclude=TRAIN_EXCLUDES,
        defaults=dict.fromkeys(EnvSettings.names()),
        description="gym.make keywords over the recipe's environment (see docs/keywords.md); "
        "stored in settings.json, where gym_soarm.evaluate reads them",
        default_text="default: the recipe's",
    )
    return parser


IMITATION_REFUSED: dict[str, str] = {
    "--steps": "its size is the recipe's demos, rounds and episodes_per_round; set them with "
    "--hyperparams demos=N",
    "--eval-every": "it evaluates after each round",
    "--vec-env": "it runs the recipe's n_envs episodes side by side in this process",
    "--vector-env": "it runs the recipe's n_envs episodes side by side in this process",
    "--init": "it starts from the expert's demonstrations, while --init starts PPO from a "
    "trained policy (--algo ppo --init DIR)",
}
"""The PPO and SAC flags an imitation run refuses, and why."""


def _run_imitation(args: argparse.Namespace) -> Any:
    """``--algo bc`` or ``dagger``, refusing the flags of the RL trainers."""
    for flag, value in (
        ("--steps", args.steps),
        ("--eval-every", args.eval_every),
        ("--vec-env", args.vec_env),
        ("--vector-env", args.vector_env),
        ("--init", args.init),
    ):
        if value is not None:
            raise ValueError(
                f"{flag} does not apply to --algo {args.algo}: "
                f"{IMITATION_REFUSED[flag]}. Drop {flag}."
            )
    from gym_soarm.rl.imitation import train_imitation

    return train_imitation(args.algo, args.task, args.out, **_run_keywords(args))


def _run_rl(args: argparse.Namespace) -> Any:
    """``--algo ppo`` or ``sac`` (from the state vector), refusing the pixel flags."""
    pixel_flags = sorted(set(env_changes(args)) & set(PIXEL_SETTINGS))
    if pixel_flags or (args.device != "cpu" and args.vector_env is None):
        given = pixel_flags or ["device"]
        raise ValueError(
            f"--algo {args.algo} learns from the state vector; "
            f"{', '.join('--' + name.replace('_', '-') for name in given)} "
            "apply to pixel students (--algo bc or dagger with --obs-type "
            "pixels_agent_pos). Drop them."
        )
    from gym_soarm.rl.training import train

    return train(
        args.algo,
        args.task,
        args.out,
        steps=args.steps,
        eval_every=args.eval_every,
        progress_bar=not args.no_progress,
        vec_env=args.vec_env,
        init=args.init,
        vector_env=args.vector_env,
        **_run_keywords(args),
    )


def _run_keywords(args: argparse.Namespace) -> dict[str, Any]:
    """What every trainer takes from the flags: seed, evaluation, recipe, env and device."""
    return {
        "seed": args.seed,
        "eval_episodes": args.eval_episodes,
        "hyperparams": dict(args.hyperparams),
        "env": env_changes(args),
        "device": args.device,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Train; 0 when the run finished, 130 when Ctrl-C stopped it (checkpoint kept)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", force=True)
    if args.vec_env is not None:
        warnings.warn(
            "--vec-env is deprecated; pass --vector-env batched or processes (the package's "
            "vector envs). --vec-env native, dummy and subproc still train as before.",
            FutureWarning,
            stacklevel=1,
        )
    try:
        result = _run_imitation(args) if args.algo in IMITATION else _run_rl(args)
    except (ValueError, TypeError) as exc:  # refused input: argparse's usage error, exit 2
        parser.error(str(exc))
    except ImportError as exc:  # a missing extra
        raise SystemExit(f"python -m gym_soarm.train: error: {exc}") from None
    rate = "n/a" if result.success_rate is None else f"{100 * result.success_rate:.0f} %"
    state = "interrupted" if result.interrupted else "done"
    # Imitation runs choose their best round on validation episodes, not the protocol's.
    scored = "the validation episodes" if args.algo in IMITATION else "the protocol"
    print(
        f"{state}: {result.env_steps} steps in {result.wall_s:.0f} s; success on "
        f"{scored} {rate}; checkpoint and curve in {result.out}"
    )
    return 130 if result.interrupted else 0
