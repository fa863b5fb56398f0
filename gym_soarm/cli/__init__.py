"""Command-line programs of gym_soarm; each also runs as ``python -m gym_soarm.<name>``."""
