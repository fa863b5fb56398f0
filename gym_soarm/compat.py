"""The package's earlier module names and the programs' ``python -m`` names.

The package's folders follow its domains (``docs/architecture.md``). Two kinds of name
live on without a file of their own, answered by a finder that ``gym_soarm/__init__.py``
installs:

* **Programs**: ``python -m gym_soarm.train`` (and ``evaluate``, ``replay``, ``sysid``)
  runs :func:`gym_soarm.cli.train.main` as the console script ``gym-soarm-train`` does;
  importing ``gym_soarm.train`` runs nothing. (``record``, ``teleop``, ``expert`` and
  ``bench`` are folders of their domain, each with its ``__main__.py``.)
* **Moved modules**: ``import gym_soarm.env`` still gives the environment's module, now
  :mod:`gym_soarm.envs.env`, with a ``DeprecationWarning`` that names the new home.
  Pickles that name an old module (snapshots, settings) load too.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import CodeType, ModuleType

PROGRAMS: dict[str, str] = {
    "gym_soarm.train": "gym_soarm.cli.train",
    "gym_soarm.evaluate": "gym_soarm.cli.evaluate",
    "gym_soarm.replay": "gym_soarm.cli.replay",
    "gym_soarm.sysid": "gym_soarm.cli.sysid",
}
"""``python -m`` names of programs without a folder of their own: the module with ``main``."""

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
}
"""Earlier module names and their homes now."""


class _ProgramLoader(importlib.abc.InspectLoader):
    """Runs a program's ``main`` when executed as ``__main__`` (``python -m``), and
    nothing when imported (spawned worker processes import ``__main__`` again as
    ``__mp_main__``)."""

    def __init__(self, target: str) -> None:
        self.target = target

    def get_source(self, fullname: str) -> str:
        return (
            f'"""``python -m {fullname}``: runs :func:`{self.target}.main`."""\n'
            'if __name__ == "__main__":\n'
            "    import sys\n"
            f"    from {self.target} import main\n"
            "    sys.exit(main())\n"
        )

    def get_code(self, fullname: str) -> CodeType:
        return compile(self.get_source(fullname), f"<{fullname}>", "exec")

    def is_package(self, fullname: str) -> bool:
        return False

    def exec_module(self, module: ModuleType) -> None:
        exec(self.get_code(module.__name__), module.__dict__)


class _MovedLoader(importlib.abc.Loader):
    """Hands out the module's new home under its old name, with a warning."""

    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        warnings.warn(
            f"{module.__name__} moved to {self.target}; import it from there "
            f"(the old name goes in a later release).",
            DeprecationWarning,
            stacklevel=2,
        )
        # The import system hands out what sys.modules holds after this call.
        sys.modules[module.__name__] = importlib.import_module(self.target)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname in PROGRAMS:
            return importlib.machinery.ModuleSpec(fullname, _ProgramLoader(PROGRAMS[fullname]))
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, _MovedLoader(MOVED[fullname]))
        return None


def install() -> None:
    """Answer the old names (idempotent)."""
    if not any(isinstance(finder, _Finder) for finder in sys.meta_path):
        sys.meta_path.append(_Finder())


__all__ = ["MOVED", "PROGRAMS", "install"]
