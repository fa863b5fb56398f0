"""The processes the benchmark measures in: started, spoken to line by line (the protocol
of :mod:`gym_soarm.bench.ceiling`) and killed if they outlive their time.

Every measurement runs in a fresh process of its own, so that the peak memory and GL
contexts of one never touch another: ``python -m gym_soarm.bench --worker JOB``
(:func:`worker_command`, :func:`gym_soarm.bench.jobs.serve_worker`) or the ceiling's
program.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading


class Child:
    """A worker process spoken to line by line; killed if it outlives ``timeout``."""

    def __init__(self, args: list[str], env: dict[str, str], timeout: float) -> None:
        self._stderr = tempfile.TemporaryFile(mode="w+")  # noqa: SIM115 - closed in close()
        self._proc = subprocess.Popen(
            args,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
            bufsize=1,
        )
        self._watchdog = threading.Timer(timeout, self._proc.kill)
        self._watchdog.daemon = True
        self._watchdog.start()

    def expect(self, tag: str) -> dict:
        """The payload of the next ``tag`` line; RuntimeError if the process ends first."""
        assert self._proc.stdout is not None
        for line in self._proc.stdout:
            if line.startswith(tag + " "):
                return json.loads(line[len(tag) + 1 :])
        self._proc.wait()
        self._stderr.seek(0)
        tail = "\n".join(self._stderr.read().strip().splitlines()[-8:])
        raise RuntimeError(f"worker exited with code {self._proc.returncode}: {tail}")

    def ask(self, command: str, tag: str) -> dict:
        """Send ``command`` (a protocol line) and return the payload of its ``tag`` reply."""
        assert self._proc.stdin is not None
        self._proc.stdin.write(command + "\n")
        self._proc.stdin.flush()
        return self.expect(tag)

    def close(self) -> None:
        self._watchdog.cancel()
        if self._proc.poll() is None:
            self._proc.kill()
        self._proc.wait()
        for stream in (self._proc.stdin, self._proc.stdout):
            if stream is not None:
                stream.close()
        self._stderr.close()


def worker_command(job: dict) -> list[str]:
    """The command line of a worker process that runs ``job`` (:mod:`gym_soarm.bench.jobs`)."""
    return [sys.executable, "-m", "gym_soarm.bench", "--worker", json.dumps(job)]


def one_shot(job: dict, timeout: float) -> dict:
    """Run ``job`` in a fresh worker process and return its result."""
    child = Child(worker_command(job), dict(os.environ), timeout)
    try:
        return child.expect("RESULT")
    finally:
        child.close()
