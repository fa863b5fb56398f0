"""Command-line programs of gym_soarm: each is one module here, with its ``main``.

One way into a program, three spellings: the console script ``gym-soarm-<name>``, ``python
-m gym_soarm <name>`` (:mod:`gym_soarm.cli.programs` lists them) and ``python -m
gym_soarm.<name>`` (a plain module, ``gym_soarm/<name>.py``, or the ``__main__.py`` of the
program's domain folder, that only calls this ``main``). The developers' programs run
from here: ``python -m gym_soarm.cli.docs``, ``.episode_hashes`` and ``.settings_table``.
Library modules hold no ``__main__`` block; ``tests/test_architecture.py`` checks it.
"""
