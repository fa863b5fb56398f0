"""``python -m gym_soarm.cli.episode_hashes record|check|print [FILE]``: every task's
episode hashes on this machine (:mod:`gym_soarm.tools.episode_hashes`), to guard a
refactor: record before the change, check after it, on the same machine."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from gym_soarm.tools.episode_hashes import check, episode_hashes, record


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
