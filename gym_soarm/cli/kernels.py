"""Build the kernel cache of ``vector_env="warp"`` for a GPU, on a machine without one
(:mod:`gym_soarm.sim.warp_cache`)::

    python -m gym_soarm.kernels --out kcache --arch 90
    WARP_CACHE_PATH=$PWD/kcache python my_gpu_run.py   # loads the cubins, compiles nothing
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Sequence

from gym_soarm.cli.options import int_at_least, task_name
from gym_soarm.cli.programs import program_parser

DESCRIPTION = (
    "Compile Warp's and MuJoCo Warp's CUDA kernels of the tasks' step for a "
    "named GPU architecture into a cache folder, without a GPU: each task's scene is "
    "stepped once on Warp's CPU device, then each module is compiled ahead of time. A GPU "
    "run with WARP_CACHE_PATH=DIR loads them instead of compiling."
)
"""What ``--help`` says the program does."""


def build_parser() -> argparse.ArgumentParser:
    parser = program_parser("kernels", DESCRIPTION)
    parser.add_argument("--out", required=True, metavar="DIR", help="the cache folder")
    parser.add_argument(
        "--arch",
        type=int,
        nargs="+",
        default=[90],
        help="CUDA architectures (default 90: H100 and H200; 89: L4/RTX 4090; 80: A100)",
    )
    parser.add_argument(
        "--task",
        type=task_name,
        action="append",
        default=None,
        help="a task whose scene is stepped (repeatable; default: every task)",
    )
    parser.add_argument(
        "--limit",
        type=int_at_least(1),
        default=None,
        help="compile only the first N modules (a quick check of the toolchain)",
    )
    parser.add_argument(
        "--keep-cpu", action="store_true", help="keep the CPU build's objects in the folder"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", force=True)
    from gym_soarm.sim.warp_cache import build_kernel_cache

    try:
        manifest = build_kernel_cache(
            args.out, args.arch, args.task, limit=args.limit, keep_cpu=args.keep_cpu
        )
    except ValueError as exc:
        parser.error(str(exc))
    except ImportError as exc:
        raise SystemExit(f"python -m gym_soarm.kernels: error: {exc}") from None
    summary = {k: v for k, v in manifest.items() if k not in ("compiled", "skipped")}
    summary.update(compiled=len(manifest["compiled"]), skipped=len(manifest["skipped"]))
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
