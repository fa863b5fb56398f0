"""``python -m gym_soarm.bench`` (``gym-soarm-bench``): the speed benchmark.

Parses the command line, runs :func:`gym_soarm.bench.bench.run` and prints its tables,
checked targets and the JSON file it wrote. ``--worker`` (hidden) is how the benchmark
starts each measurement in a fresh process of its own
(:func:`gym_soarm.bench.jobs.serve_worker`).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from gym_soarm.bench import bench, bench_vector
from gym_soarm.cli.options import add_settings_arguments, settings_given, task_name
from gym_soarm.cli.programs import program_parser
from gym_soarm.envs.settings import EnvSettings
from gym_soarm.tasks import DEFAULT_TASK


def _print_scale(report: dict[str, Any]) -> None:
    for scaling in report["vector_scaling"]:
        if "error" in scaling:
            print(f"\nvector scaling ({scaling['obs']}): failed: {scaling['error']}")
            continue
        print(f"\nvector scaling, {bench_vector.title(scaling)}")
        print(bench_vector.format_table(scaling))
    recording = report["recording"]
    if recording is not None:
        print(
            f"\nrecording {recording['episodes']} {recording['task']} episodes "
            f"(whole record() call, start-up included; medians of {recording['repeats']})"
        )
        print(bench.format_recording(recording))


def _print_report(report: dict[str, Any]) -> None:
    """The report's tables and checked targets, as the program prints them."""
    machine = report["machine"]
    gl = (
        f", GL: {machine['gl_backend']} ({machine['gl_renderer']})" if machine["gl_backend"] else ""
    )
    print(
        f"\n{machine['cpu']} ({machine['cpu_count']} cores){gl}, load average "
        f"{machine['load_average_start']}, control mode {report['settings']['control_mode']}"
    )
    if report["configs"]:
        print(bench.format_table(report["configs"]))
    for cold in report["cold_make"]:
        if "error" in cold:
            print(f"cold make ({cold['visual']}): failed: {cold['error']}")
        else:
            print(f"cold make ({cold['visual']} meshes, empty cache): {cold['make_s']:.2f} s")
    _print_scale(report)
    for check in report["targets"]:
        sign = ">=" if check["kind"] == "min" else "<"
        status = "met" if check["met"] else "NOT met"
        print(
            f"target {check['config']} {check['figure']} {sign} {check['bound']:g}: "
            f"{check['value']:.4g} ({status})"
        )


BENCH_EXCLUDES: tuple[str, ...] = (
    "task",  # --task
    "obs_type",  # --configs names the observation, cameras, size and render quality
    "camera_config",
    "observation_height",
    "observation_width",
    "render_quality",
    "render_mode",  # nothing is shown
    "control_mode",  # --control-mode (kept as it was: its own default and help)
)
"""The environment settings the benchmark sets itself."""


def env_changes(args: argparse.Namespace) -> dict[str, Any]:
    """The further ``gym.make`` keywords of the measured configurations: the flags given
    (each flag's default is None: gym.make's own)."""
    return settings_given(args)


def _add_measurement_arguments(parser: argparse.ArgumentParser) -> None:
    """What one env's measurements run: configurations, durations, task and control mode."""
    parser.add_argument(
        "--configs",
        default=",".join(bench.DEFAULT_CONFIGS),
        help="comma-separated configurations: 'state' or '{front_only|front_wrist|all}_{W}x{H}'"
        " with an optional '_fast'/'_high' suffix (default: %(default)s)",
    )
    parser.add_argument(
        "--seconds",
        type=float,
        default=bench.DEFAULT_SECONDS,
        help="duration of each repeat (default: %(default)s)",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=bench.DEFAULT_REPEATS,
        help="timed repeats per measurement; medians are reported (default: %(default)s)",
    )
    parser.add_argument(
        "--processes",
        type=int,
        default=1,
        help="also step N environments in an AsyncVectorEnv and report aggregate steps/s",
    )
    parser.add_argument(
        "--json",
        default=bench.DEFAULT_JSON,
        help="where to write the results (default: %(default)s)",
    )
    parser.add_argument(
        "--task",
        type=task_name,
        default=DEFAULT_TASK,
        metavar="TASK",
        help="the registered task to measure, by name, alias or gym id (default: "
        "%(default)s, the scene of SoArm-v0)",
    )
    parser.add_argument(
        "--control-mode",
        default=bench.DEFAULT_CONTROL_MODE,
        help="the control mode to measure, with random actions of its own action space: "
        "joint_pos, joint_delta, ee_delta or ee_pose (default: %(default)s)",
    )


def _add_vector_arguments(parser: argparse.ArgumentParser) -> None:
    """The vector envs' scaling: how many environments, which observations and envs."""
    parser.add_argument(
        "--vector-scaling",
        default="",
        metavar="COUNTS",
        help="also measure vector envs (batched, native processes, AsyncVectorEnv, "
        "SyncVectorEnv) at "
        "these comma-separated num_envs, e.g. 1,2,4,8,16, against one env",
    )
    parser.add_argument(
        "--vector-obs",
        default="state",
        help="observations of --vector-scaling: comma-separated 'state' and camera configs, "
        "e.g. state,front_wrist (default: %(default)s)",
    )
    parser.add_argument(
        "--vector-modes",
        default="batched,processes,async,sync",
        help="vector envs of --vector-scaling (default: %(default)s)",
    )
    parser.add_argument(
        "--image-size",
        default="96x128",
        metavar="HxW",
        help="image size of the cameras of --vector-obs and --recording-cameras "
        "(default: %(default)s)",
    )


def _add_recording_arguments(parser: argparse.ArgumentParser) -> None:
    """The recording's throughput: workers, Ray, episodes and cameras."""
    parser.add_argument(
        "--recording",
        type=int,
        default=0,
        metavar="WORKERS",
        help="also measure recording throughput (episodes/min) with 1 and WORKERS processes",
    )
    parser.add_argument(
        "--recording-ray",
        action="store_true",
        help="with --recording, also record as Ray tasks on a local cluster (needs ray)",
    )
    parser.add_argument(
        "--recording-episodes",
        type=int,
        default=6,
        help="LiftCube-v0 episodes per recording (default: %(default)s)",
    )
    parser.add_argument(
        "--recording-cameras",
        default="none,front_wrist",
        help="camera configs recorded, 'none' for state only (default: %(default)s)",
    )


DESCRIPTION = (
    "Measure env steps/s, make/reset time and memory against MuJoCo's own "
    "ceiling (bare mj_step, bare mujoco.Renderer) on this machine."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    """The program's command line."""
    parser = program_parser("bench", DESCRIPTION)
    _add_measurement_arguments(parser)
    _add_vector_arguments(parser)
    _add_recording_arguments(parser)
    add_settings_arguments(
        parser,
        exclude=BENCH_EXCLUDES,
        defaults=dict.fromkeys(EnvSettings.names()),
        description="further gym.make keywords of the --configs measurements (see "
        "docs/keywords.md)",
        default_text="default: gym.make's",
    )
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.worker:
        bench.serve_worker(args.worker)
        return 0
    configs = [c.strip() for c in args.configs.split(",") if c.strip()]
    try:
        counts = [int(c) for c in args.vector_scaling.split(",") if c.strip()]
        height, width = (int(v) for v in args.image_size.lower().split("x"))
    except ValueError:
        parser.error(
            "--vector-scaling must be comma-separated integers and --image-size HEIGHTxWIDTH; "
            f"got {args.vector_scaling!r} and {args.image_size!r}"
        )
    try:
        report = bench.run(
            configs,
            args.seconds,
            args.repeats,
            args.processes,
            progress=lambda m: print(m, file=sys.stderr, flush=True),
            task=args.task,
            control_mode=args.control_mode,
            vector_scaling=counts,
            env=env_changes(args),
            vector_obs=[o.strip() for o in args.vector_obs.split(",") if o.strip()],
            vector_modes=[m.strip() for m in args.vector_modes.split(",") if m.strip()],
            image_size=(height, width),
            recording=args.recording,
            recording_ray=args.recording_ray,
            recording_episodes=args.recording_episodes,
            recording_cameras=[c.strip() for c in args.recording_cameras.split(",") if c.strip()],
        )
    except ValueError as exc:
        parser.error(str(exc))
    _print_report(report)
    Path(args.json).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")
    failed = any("error" in r for r in report["configs"] + report["vector_scaling"])
    if report["recording"] is not None:
        failed = failed or any("error" in r for r in report["recording"]["rows"])
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
