"""The package's earlier module names, answered by a finder that ``gym_soarm/__init__.py``
installs.

``import gym_soarm.env`` still gives the environment's module, now
:mod:`gym_soarm.envs.env`, with a ``DeprecationWarning`` that names the new home: the
loader imports the new module and hands it out under the old name (the same module
object, so pickles that name an old module, snapshots and settings, load too). Nothing
is compiled or executed here; ``python -m`` with an old name runs the new module's own
file (its ``get_code``), so ``python -m gym_soarm.tools.docs`` still prints the table.

The programs' ``python -m`` names are plain modules: ``gym_soarm/train.py`` (and
``evaluate``, ``replay``, ``sysid``), the ``__main__.py`` of ``gym_soarm/record/``,
``teleop/``, ``expert/`` and ``bench/``, and ``python -m gym_soarm <program>``
(``gym_soarm/__main__.py``).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from types import CodeType, ModuleType

MOVED: dict[str, str] = {
    "gym_soarm.env": "gym_soarm.envs.env",
    "gym_soarm.settings": "gym_soarm.envs.settings",
    "gym_soarm.control": "gym_soarm.envs.control",
    "gym_soarm.infos": "gym_soarm.envs.infos",
    "gym_soarm.snapshot": "gym_soarm.envs.snapshot",
    "gym_soarm.batched": "gym_soarm.vector.batched",
    "gym_soarm.processes": "gym_soarm.vector.workers",
    "gym_soarm.calibration": "gym_soarm.real.calibration",
    "gym_soarm.dynamics": "gym_soarm.real.dynamics",
    "gym_soarm.units": "gym_soarm.real.units",
    "gym_soarm.unit_maps": "gym_soarm.real.unit_maps",
    "gym_soarm.data.replay": "gym_soarm.real.replay",
    "gym_soarm.data.sysid": "gym_soarm.real.sysid",
    "gym_soarm.data.record": "gym_soarm.record.record",
    "gym_soarm.data.parallel": "gym_soarm.record.parallel",
    "gym_soarm.data.ray_tasks": "gym_soarm.record.ray_tasks",
    "gym_soarm.data.attempt": "gym_soarm.record.attempt",
    "gym_soarm.tools.bench": "gym_soarm.bench.bench",
    "gym_soarm.tools.bench_record": "gym_soarm.bench.bench_record",
    "gym_soarm.tools.bench_vector": "gym_soarm.bench.bench_vector",
    "gym_soarm.tools.timings": "gym_soarm.bench.timings",
    "gym_soarm.tools.docs": "gym_soarm.cli.docs",
    "gym_soarm.tools.episode_hashes": "gym_soarm.cli.episode_hashes",
}
"""Earlier module names and their homes now."""

FOLDED: dict[str, str] = {
    "gym_soarm.tools": "its modules moved to gym_soarm.bench and gym_soarm.cli",
}
"""Earlier packages without a home of their own: an empty package, so that the moved
names under them (``gym_soarm.tools.docs``) still import."""


_LATER = "import it from there (the old name goes in a later release)."


def _importer_level() -> int:
    """The ``stacklevel`` of the code that imported the old name, for a warning raised
    here: the first frame outside this module and the import machinery (so that Python
    shows it by default when that code is ``__main__``)."""
    frame, level = sys._getframe(1), 1
    while frame is not None:
        name = frame.f_code.co_filename
        if "importlib" in name and "_bootstrap" in name:
            frame = frame.f_back  # warnings.warn skips these frames itself
        elif name in (__file__, importlib.__file__):
            frame, level = frame.f_back, level + 1
        else:
            break
    return level


def _warn(message: str) -> None:
    warnings.warn(message, DeprecationWarning, stacklevel=_importer_level())


class _MovedLoader(importlib.abc.Loader):
    """Hands out the module's new home under its old name, with a warning.

    ``create_module`` returns None (a placeholder module); ``exec_module`` imports the new
    module and puts it in ``sys.modules`` under the old name, and the import system hands
    out what ``sys.modules`` holds after that call (the import system's documented
    contract). The new module's own ``__spec__`` and ``__name__`` stay untouched: a
    ``create_module`` that returned the new module would see its ``__spec__`` replaced
    by the old name's.
    """

    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        _warn(f"{module.__name__} moved to {self.target}; {_LATER}")
        sys.modules[module.__name__] = importlib.import_module(self.target)

    def get_code(self, fullname: str) -> CodeType | None:
        """The new module's code, from its own file: what ``python -m <old name>`` runs."""
        _warn(f"{fullname} moved to {self.target}; {_LATER}")
        spec = importlib.util.find_spec(self.target)
        loader = spec.loader if spec is not None else None
        if not isinstance(loader, importlib.abc.InspectLoader):
            raise ImportError(f"{self.target} has no code to run", name=fullname)
        return loader.get_code(self.target)


class _FoldedLoader(importlib.abc.Loader):
    """An empty package in place of a folder that was folded into others."""

    def __init__(self, note: str) -> None:
        self.note = note

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        _warn(f"{module.__name__} is gone: {self.note} (see gym_soarm.compat.MOVED).")


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, _MovedLoader(MOVED[fullname]))
        if fullname in FOLDED:
            return importlib.machinery.ModuleSpec(
                fullname, _FoldedLoader(FOLDED[fullname]), is_package=True
            )
        return None


def install() -> None:
    """Answer the old names (idempotent)."""
    if not any(isinstance(finder, _Finder) for finder in sys.meta_path):
        sys.meta_path.append(_Finder())


__all__ = ["FOLDED", "MOVED", "install"]
