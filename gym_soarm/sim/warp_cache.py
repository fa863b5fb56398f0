"""A warm kernel cache for ``vector_env="warp"`` on a GPU, built on a machine without one.

Warp compiles a module's CUDA kernels the first time a process loads it on a GPU; for
MuJoCo Warp's solver that takes minutes on a fresh cache. Warp's compiler targets a named
architecture without a GPU, so :func:`build_kernel_cache` does it beforehand:

1. each task's scene is stepped once on Warp's CPU device (``device="cpu"``), so that
   every module the step uses exists with the options a run gives it;
2. each of those modules is compiled ahead of time for the CUDA architectures asked
   (``arch=90``: H100 and H200) into the cache folder;
3. the CPU build's objects are removed (unless ``keep_cpu``), which leaves a folder of a
   few tens of MB, and a manifest (:data:`MANIFEST`) records the versions and
   architectures it was built for.

A GPU run points Warp at the folder (``WARP_CACHE_PATH=DIR``) and loads the cubins
instead of compiling them. The cache is keyed by each module's hash, which depends on
Warp's and MuJoCo Warp's versions: rebuild it when either changes.

The program: ``python -m gym_soarm.kernels --out DIR [--arch 90] [--task T ...]``
(``gym-soarm-kernels``).
"""

from __future__ import annotations

import json
import logging
import os
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

MANIFEST = "gym_soarm_kernels.json"
"""The manifest a built cache folder holds."""

CPU_SUFFIXES = (".o", ".cpp", ".obj")
"""Files of a module's CPU build, removed from the folder unless ``keep_cpu``."""


def check_archs(arch: Any) -> list[int]:
    """``arch`` (an int or ints, e.g. 90 for sm_90) as a list; a ValueError otherwise."""
    archs = [arch] if isinstance(arch, int) and not isinstance(arch, bool) else arch
    try:
        archs = list(archs)
    except TypeError:
        archs = [arch]
    if not archs or not all(
        isinstance(a, int) and not isinstance(a, bool) and 50 <= a <= 200 for a in archs
    ):
        raise ValueError(
            f"arch must be CUDA architectures as ints between 50 and 200 (90: H100/H200, "
            f"89: L4/RTX 4090, 80: A100); got {arch!r}."
        )
    return archs


def _warp_at(folder: Path) -> Any:
    """Warp, initialised with ``folder`` as its kernel cache (a ValueError if this process
    already initialised it elsewhere)."""
    from gym_soarm.sim.warp_backend import warp_available

    if not warp_available():
        raise ImportError(
            'building the kernel cache needs MuJoCo Warp: pip install "gym-soarm[warp]".'
        )
    import warp as wp

    current = wp.config.kernel_cache_dir
    if current is not None and Path(current).resolve() != folder.resolve():
        raise ValueError(
            f"Warp already uses the kernel cache {current!r} in this process; build the "
            f"cache for {str(folder)!r} in a fresh one (python -m gym_soarm.kernels)."
        )
    wp.config.kernel_cache_dir = str(folder)
    wp.config.quiet = True
    wp.init()
    return wp


def _load_modules(tasks: Sequence[str]) -> None:
    """Step each task's scene once on Warp's CPU device (every module it uses loaded)."""
    import gymnasium as gym

    for task in tasks:
        env = gym.make_vec(
            f"gym_soarm/{task}",
            num_envs=1,
            vectorization_mode="vector_entry_point",
            vector_env="warp",
            device="cpu",
            obs_type="state",
        )
        try:
            env.reset(seed=0)
            env.step(np.zeros(env.action_space.shape, np.float32))
        finally:
            env.close()


def build_kernel_cache(
    out: str | os.PathLike[str],
    arch: int | Sequence[int] = 90,
    tasks: Sequence[str] | None = None,
    limit: int | None = None,
    keep_cpu: bool = False,
) -> dict[str, Any]:
    """Compile Warp's and MuJoCo Warp's kernels of the tasks' step for ``arch`` into ``out``.

    Args:
        out: the cache folder (made; a GPU run sets ``WARP_CACHE_PATH`` to it).
        arch: the CUDA architecture or architectures (90: H100 and H200).
        tasks: the tasks whose scenes are stepped (names, aliases or ids; default: every
            registered task).
        limit: compile only the first ``limit`` modules (a quick check of the toolchain).
        keep_cpu: keep the CPU build's objects in the folder.

    Returns:
        The manifest written to ``out/gym_soarm_kernels.json``: versions, architectures,
        tasks, the modules compiled and skipped, seconds and the folder's bytes.

    Raises:
        ValueError: a bad architecture, task or ``limit``, or Warp already initialised in
            this process with another cache folder. Checked before anything is built.
        ImportError: MuJoCo Warp is not installed.
    """
    from gym_soarm import __version__
    from gym_soarm.tasks import BUILTIN_TASKS, get_task

    archs = check_archs(arch)
    names = list(BUILTIN_TASKS) if tasks is None else [get_task(t).name for t in tasks]
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
        raise ValueError(f"limit must be an int >= 1 or None; got {limit!r}.")
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"out must be a folder; {str(folder)!r} is a file. Pass a new folder.")
    folder.mkdir(parents=True, exist_ok=True)
    wp = _warp_at(folder)
    began = time.perf_counter()
    _load_modules(names)
    from warp._src.context import user_modules

    modules = list(user_modules.values())[:limit]
    compiled, skipped = _compile(wp, modules, archs)
    if not keep_cpu:
        for path in folder.rglob("*"):
            if path.is_file() and path.suffix in CPU_SUFFIXES:
                path.unlink()
    manifest = _manifest(wp, __version__, archs, names, compiled, skipped, began, folder)
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


def _compile(wp: Any, modules: list[Any], archs: list[int]) -> tuple[list[str], list[str]]:
    """Compile each module for ``archs``: the names compiled and those skipped (a module
    of generic kernels without overloads compiles nothing)."""
    compiled: list[str] = []
    skipped: list[str] = []
    for module in modules:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                paths = wp.compile_aot_module(module, arch=archs)
            except (RuntimeError, TypeError, ValueError) as exc:
                logger.warning("module %s not compiled: %s", module.name, exc)
                skipped.append(module.name)
                continue
        done = bool(paths) and not caught
        (compiled if done else skipped).append(module.name)
        logger.info("%s: %s", module.name, "compiled" if done else "skipped")
    return compiled, skipped


def _manifest(
    wp: Any,
    version: str,
    archs: list[int],
    tasks: list[str],
    compiled: list[str],
    skipped: list[str],
    began: float,
    folder: Path,
) -> dict[str, Any]:
    import importlib.metadata

    return {
        "gym_soarm": version,
        "warp": wp.__version__,
        "mujoco_warp": importlib.metadata.version("mujoco-warp"),
        "arch": archs,
        "tasks": tasks,
        "compiled": compiled,
        "skipped": skipped,
        "seconds": round(time.perf_counter() - began, 1),
        "bytes": sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()),
    }


__all__ = ["MANIFEST", "build_kernel_cache", "check_archs"]
