"""Where things are, for tests in any folder of ``tests/``."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
"""The ``tests`` folder (its helper modules, ``data/formats``, ``vector_probe.py``)."""
ROOT = TESTS.parent
"""The repository (README, docs, examples, scripts)."""
