"""Ctrl-C in the middle of a program: start it, wait until it is busy, interrupt it."""

from __future__ import annotations

import signal
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Interrupted:
    """What an interrupted program left: its exit code and its whole output."""

    returncode: int
    stdout: str
    stderr: str


def interrupt_when(
    command: Sequence[str],
    ready: Callable[[subprocess.Popen], bool],
    *,
    within_s: float,
    then_s: float = 0.0,
    answer_s: float = 60.0,
    what: str = "the program to get busy",
) -> Interrupted:
    """Run ``command``; once ``ready(process)`` (polled) holds, wait ``then_s`` and send
    SIGINT (what Ctrl-C in a terminal sends), then collect the output within ``answer_s``.

    Fails the test, with the program's output, when it exits before it is ready or is
    not ready within ``within_s``; the program never outlives the call.
    """
    process = subprocess.Popen(
        list(command), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + within_s
        while not ready(process):
            if process.poll() is not None:
                out, err = process.communicate()
                raise AssertionError(f"the program exited before {what}:\n{out}\n{err}")
            if time.monotonic() > deadline:
                raise AssertionError(f"waited {within_s:g} s for {what}")
            time.sleep(0.05)
        time.sleep(then_s)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=answer_s)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    return Interrupted(process.returncode, out, err)
