"""``python -m gym_soarm <program> [args]``: every program of the package by its name.

Each program is one module of ``gym_soarm/cli/`` with its ``main``; the console script
``gym-soarm-<program>`` and ``python -m gym_soarm.<program>`` run the same ``main``.
``python -m gym_soarm`` (or ``--help``) lists them; an unknown name is refused with the
list and argparse's usage code, 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from collections.abc import Iterator, Sequence
from typing import Any, NamedTuple

PROG = "python -m gym_soarm"


class Program(NamedTuple):
    module: str
    """The module whose ``main(argv)`` runs the program."""
    summary: str
    """What it does, in a line."""


PROGRAMS: dict[str, Program] = {
    "train": Program(
        "gym_soarm.cli.train", "train a policy on a task (RL, or imitating the expert)"
    ),
    "evaluate": Program("gym_soarm.cli.evaluate", "score a trained policy or the expert"),
    "record": Program("gym_soarm.cli.record", "record expert demonstrations as a LeRobotDataset"),
    "teleop": Program("gym_soarm.cli.teleop", "drive the arm from the keyboard or a gamepad"),
    "expert": Program("gym_soarm.cli.expert", "each task's scripted expert success rate"),
    "replay": Program("gym_soarm.cli.replay", "replay a LeRobot SO-101 dataset's actions"),
    "sysid": Program("gym_soarm.cli.sysid", "fit the simulated servos to a LeRobot dataset"),
    "bench": Program("gym_soarm.cli.bench", "the speed benchmark"),
    "kernels": Program("gym_soarm.cli.kernels", "build Warp's CUDA kernels for a GPU, without one"),
}
"""Every program (each a console script ``gym-soarm-<name>``) and its module."""

_dispatched: list[str] = []  # the program python -m gym_soarm is running, if any


def program_name(name: str) -> str:
    """The usage line's name of program ``name``, as the user started it:
    ``python -m gym_soarm <name>``, the console script ``gym-soarm-<name>``, or else
    ``python -m gym_soarm.<name>``."""
    if _dispatched and _dispatched[-1] == name:
        return f"{PROG} {name}"
    script = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    if script == f"gym-soarm-{name}":
        return script
    return f"python -m gym_soarm.{name}"


def program_parser(name: str, description: str, **kwargs: Any) -> argparse.ArgumentParser:
    """The command line parser of program ``name``: its usage line names the program as
    the user started it (:func:`program_name`); ``kwargs`` go to ``ArgumentParser``."""
    return argparse.ArgumentParser(prog=program_name(name), description=description, **kwargs)


@contextlib.contextmanager
def _running(name: str) -> Iterator[None]:
    _dispatched.append(name)
    try:
        yield
    finally:
        _dispatched.pop()


def usage() -> str:
    """The list of programs that ``python -m gym_soarm --help`` prints."""
    width = max(map(len, PROGRAMS))
    lines = [
        f"usage: {PROG} <program> [args]   ({PROG} <program> --help: its options)",
        "",
        "programs (each also a console script, gym-soarm-<program>):",
    ]
    lines += [f"  {name:<{width}}  {program.summary}" for name, program in PROGRAMS.items()]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int | None:
    """Run the program named by ``argv[0]`` with the rest; return its exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        print(usage(), file=sys.stderr)
        print(f"{PROG}: error: name a program", file=sys.stderr)
        return 2
    name, rest = args[0], args[1:]
    if name in ("-h", "--help", "help"):
        print(usage())
        return 0
    if name == "--version":
        from gym_soarm import __version__

        print(f"gym_soarm {__version__}")
        return 0
    if name not in PROGRAMS:
        print(f"usage: {PROG} <program> [args]", file=sys.stderr)
        print(
            f"{PROG}: error: unknown program {name!r}; choose from {', '.join(PROGRAMS)}",
            file=sys.stderr,
        )
        return 2
    program = importlib.import_module(PROGRAMS[name].module)
    with _running(name):
        return program.main(rest)
