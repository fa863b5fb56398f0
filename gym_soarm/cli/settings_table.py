"""``python -m gym_soarm.cli.settings_table``: write (or check) ``docs/keywords.md``.

The page is :func:`gym_soarm.cli.docs.keywords_page`, generated from the fields of
:class:`gym_soarm.envs.settings.EnvSettings`; a test keeps the committed page current.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from gym_soarm.cli.docs import KEYWORDS_PATH, keywords_page


def main(argv: Sequence[str] | None = None) -> int:
    """Write the keyword page; with ``--check``, exit 1 when the file differs."""
    parser = argparse.ArgumentParser(
        prog="python -m gym_soarm.cli.settings_table",
        description="Write docs/keywords.md, the table of gym.make keywords generated from "
        "gym_soarm.envs.settings.EnvSettings.",
    )
    parser.add_argument(
        "--out", default=KEYWORDS_PATH, metavar="PATH", help=f"the page (default {KEYWORDS_PATH})"
    )
    parser.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 when the page is not current"
    )
    args = parser.parse_args(argv)
    page = keywords_page()
    path = Path(args.out)
    if args.check:
        current = path.is_file() and path.read_text(encoding="utf-8") == page
        if not current:
            print(
                f"{path} is not current: run python -m gym_soarm.cli.settings_table",
                file=sys.stderr,
            )
        return 0 if current else 1
    path.write_text(page, encoding="utf-8")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
