"""``python -m gym_soarm.cli.episode_hashes record|check|print [FILE]``: a fingerprint of
every task's episodes, to guard behaviour on one machine.

For every registered task, with ``obs_type="environment_state_agent_pos"``: the expert's
episodes on seeds 0 and 1 (to their end) and 50 steps of seeded random actions from seed
2. Every observation, reward, terminated and truncated flag, and the info's
``is_success``, ``reward_terms`` and the task's own keys are fed into one sha256.

Floating point is reproducible on one machine with one set of library versions, not
across CPUs, so hashes are only ever compared with hashes made where the same key holds
(:func:`machine_key`: CPU, operating system, Python, NumPy and MuJoCo). To check that a
refactor keeps every episode, record before and check after, on the same machine::

    python -m gym_soarm.cli.episode_hashes record hashes.json   # before the change
    python -m gym_soarm.cli.episode_hashes check hashes.json    # after it

``check`` refuses a file recorded under another key rather than reporting differences
that only the machine explains.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import struct
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

import gym_soarm
from gym_soarm.expert import make_expert
from gym_soarm.tasks import BUILTIN_TASKS

EXPERT_SEEDS = (0, 1)
RANDOM_SEED = 2
RANDOM_STEPS = 50


def machine_key() -> dict[str, str]:
    """What bit-for-bit equality of episodes depends on: the CPU and the libraries."""
    return {
        "machine": platform.machine(),
        "processor": _cpu_model(),
        "system": platform.system(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
    }


def _cpu_model() -> str:
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor()


def _feed(digest: Any, value: Any) -> None:
    """Feed ``value`` into ``digest`` canonically: type, shape and the exact bytes."""
    if isinstance(value, np.ndarray):
        digest.update(f"a{value.dtype.str}{value.shape}".encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, dict):
        digest.update(b"{")
        for key in sorted(value):
            digest.update(repr(key).encode())
            _feed(digest, value[key])
        digest.update(b"}")
    elif isinstance(value, list | tuple):
        digest.update(b"[")
        for item in value:
            _feed(digest, item)
        digest.update(b"]")
    elif isinstance(value, bool | np.bool_):
        digest.update(b"T" if value else b"F")
    elif isinstance(value, float | np.floating):
        digest.update(b"f" + struct.pack("<d", float(value)))
    elif isinstance(value, int | np.integer):
        digest.update(b"i" + repr(int(value)).encode())
    elif isinstance(value, str) or value is None:
        digest.update(b"s" + repr(value).encode())
    else:
        raise TypeError(f"cannot hash {type(value).__name__} {value!r}; add it to _feed")


def _info_part(info: dict[str, Any], task_keys: set[str]) -> dict[str, Any]:
    keys = {"is_success", "reward_terms"} | task_keys
    return {key: info[key] for key in keys}


def episode_hash(task: str) -> str:
    """The sha256 of ``task``'s expert episodes and seeded random steps."""
    env = gym.make(gym_soarm.get_task(task).env_id, obs_type="environment_state_agent_pos")
    digest = hashlib.sha256()
    try:
        base = env.unwrapped
        expert = make_expert(env)
        task_keys: set[str] = set()
        for seed in EXPERT_SEEDS:
            obs, info = env.reset(seed=seed)
            task_keys = set(base.task_logic.episode_info(base.physics))
            expert.reset()
            _feed(digest, (obs, _info_part(info, task_keys)))
            while True:
                obs, reward, terminated, truncated, info = env.step(expert(obs, info))
                _feed(digest, (obs, reward, terminated, truncated, _info_part(info, task_keys)))
                if terminated or truncated:
                    break
        obs, info = env.reset(seed=RANDOM_SEED)
        env.action_space.seed(RANDOM_SEED)
        _feed(digest, (obs, _info_part(info, task_keys)))
        for _ in range(RANDOM_STEPS):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            _feed(digest, (obs, reward, terminated, truncated, _info_part(info, task_keys)))
            if terminated or truncated:
                break
    finally:
        env.close()
    return digest.hexdigest()


def episode_hashes(tasks: Sequence[str] | None = None) -> dict[str, str]:
    """``{task: hash}`` for ``tasks`` (default: the built-in tasks; a task registered by
    the caller, in a test say, is hashed only when named)."""
    return {task: episode_hash(task) for task in (tasks or BUILTIN_TASKS)}


def record(path: str | Path) -> dict[str, Any]:
    """Write this machine's key and every task's hash to ``path`` (JSON); return them."""
    table = {"key": machine_key(), "hashes": episode_hashes()}
    Path(path).write_text(json.dumps(table, indent=2) + "\n")
    return table


def check(path: str | Path) -> list[str]:
    """The tasks whose episodes differ from those recorded in ``path`` on this machine.

    Raises:
        ValueError: ``path`` was recorded under another machine key (CPU or library
            versions): its hashes say nothing about this machine.
    """
    table = json.loads(Path(path).read_text())
    if table.get("key") != machine_key():
        raise ValueError(
            f"{path} was recorded under {table.get('key')}, this machine is {machine_key()}: "
            "hashes only compare on one machine with one set of libraries. Record on this "
            "machine before the change (record) and check after it (check)."
        )
    now = episode_hashes(list(table["hashes"]))
    return [task for task, value in table["hashes"].items() if now[task] != value]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m gym_soarm.cli.episode_hashes",
        description="Record every task's episode hashes on this machine, or check them "
        "against a recording made on this machine (before and after a change).",
    )
    parser.add_argument("command", choices=["record", "check", "print"])
    parser.add_argument("path", nargs="?", default="episode_hashes.json")
    args = parser.parse_args(argv)
    if args.command == "print":
        json.dump(episode_hashes(), sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    if args.command == "record":
        record(args.path)
        sys.stdout.write(f"recorded {args.path}\n")
        return 0
    changed = check(args.path)
    if changed:
        sys.stdout.write(f"episodes changed: {', '.join(changed)}\n")
        return 1
    sys.stdout.write("every task's episodes are as recorded\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
