"""The documentation the tests read: the README and every page of docs/.

A snippet, a command or a figure that a test checks is looked up in all of them, so a
section can move from the README to a page (or between pages) and keep its test.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"


def documentation_files() -> list[Path]:
    """The README, then the pages of docs/ in name order."""
    return [README, *sorted(DOCS.glob("*.md"))]


def file_with(text: str) -> Path:
    """The one documentation file that contains ``text``."""
    found = [path for path in documentation_files() if text in path.read_text()]
    names = [str(path.relative_to(ROOT)) for path in found]
    assert len(found) == 1, f"{text!r} should be in exactly one documentation file; found {names}"
    return found[0]


def code_after(heading: str, language: str = "python") -> str:
    """The first ``language`` code block after ``heading``, in whichever file holds it."""
    text = file_with(heading).read_text()
    start = text.index(heading)
    match = re.compile(rf"```{language}\n(.*?)```", re.DOTALL).search(text, start)
    assert match, f"no {language} block after {heading!r}"
    return match.group(1)
