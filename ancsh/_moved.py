"""Old module names kept importable for one release (0.1 -> 0.2), with a ``DeprecationWarning``.

The package was re-laid out (``docs/ARCHITECTURE.md``): studies moved to :mod:`ancsh.studies`, commands to
:mod:`ancsh.cli`, and :mod:`ancsh.learned` was split into ``network/``, ``training/`` and ``inference/``.
``import ancsh.learned.predict`` (or ``from ancsh.learned.provider import LearnedProvider``) still works: a finder
appended to ``sys.meta_path`` answers an old name with the module at its new place -- the same module object, so
monkeypatching through the old name patches the new module -- and warns once per old name. A module that was
split (its library part and its study part) answers with a read-only view of its new modules, looked up in order.
Names that left a module which stayed answer from it through :func:`moved_names` (:data:`MOVED_NAMES`).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

# old module name -> new module name, or the new modules of a module that was split
MOVED = {
    "ancsh.benchcli": "ancsh.cli.bench",
    "ancsh.demo": "ancsh.cli.demo",
    "ancsh.data.cli": ("ancsh.cli.data", "ancsh.cli.bench.render", "ancsh.studies.render", "ancsh.cli._args"),
    "ancsh.learned.cli": "ancsh.cli.training",
    "ancsh.learned.app_cli": "ancsh.cli.learned",
    "ancsh.solvers.icp.cli": "ancsh.cli.cad",
    "ancsh.tracking.cli": "ancsh.cli.track",
    "ancsh.solvers.bench": ("ancsh.studies.fit", "ancsh.studies.fit.measure", "ancsh.studies.fit.report",
                            "ancsh.cli.bench.fit"),
    "ancsh.learned.bench": ("ancsh.studies.learned_cost", "ancsh.studies.ablation", "ancsh.studies.equivariance",
                            "ancsh.cli.bench.learned"),
    "ancsh.learned.gap_bench": ("ancsh.studies.train_test_gap", "ancsh.cli.bench.train_test_gap"),
    "ancsh.learned.refine_bench": ("ancsh.studies.refinement", "ancsh.cli.bench.refinement"),
    "ancsh.learned.gpu_check": ("ancsh.studies.gpu_check", "ancsh.cli.bench.gpu_check"),
    "ancsh.learned.evaluate": ("ancsh.studies.table1", "ancsh.studies.table1.measure",
                               "ancsh.studies.table1.statistics", "ancsh.studies.table1.report"),
    "ancsh.learned.equivariance": "ancsh.studies.equivariance",
    "ancsh.learned.targets": "ancsh.studies.targets",
    "ancsh.uncertainty_calibration": ("ancsh.studies.uncertainty_calibration",
                                      "ancsh.studies.uncertainty_calibration.measure",
                                      "ancsh.studies.uncertainty_calibration.statistics",
                                      "ancsh.studies.uncertainty_calibration.report", "ancsh.cli.bench.uncertainty"),
    "ancsh.scaling": ("ancsh.studies.scaling", "ancsh.cli.bench.scaling"),
    "ancsh.tracking.bench": ("ancsh.studies.tracking", "ancsh.studies.tracking.measure",
                             "ancsh.studies.tracking.statistics", "ancsh.studies.tracking.report",
                             "ancsh.cli.bench.tracking"),
    "ancsh.solvers.icp.evaluate": ("ancsh.studies.cad", "ancsh.studies.cad.measure", "ancsh.studies.cad.report"),
    "ancsh.learned.pointnet2": "ancsh.learned.network.pointnet2",
    "ancsh.learned.config": "ancsh.learned.network.config",
    "ancsh.learned.weights": "ancsh.learned.network.weights",
    "ancsh.learned.losses": "ancsh.learned.training.losses",
    "ancsh.learned.compiled": "ancsh.learned.training.compiled",
    "ancsh.learned.data": "ancsh.learned.training.data",
    "ancsh.learned.train": "ancsh.learned.training.train",
    "ancsh.learned.select": "ancsh.learned.training.select",
    "ancsh.learned.voting": "ancsh.learned.inference.voting",
    "ancsh.learned.provider": "ancsh.learned.inference.provider",
    "ancsh.learned.predict": "ancsh.learned.inference.predict",
    "ancsh.learned.confidence": ("ancsh.learned.inference.confidence", "ancsh.studies.confidence_calibration"),
}

# module -> {name: the module it moved to}: names that left a module which itself stayed
MOVED_NAMES = {
    "ancsh.data.catalog": {"ranges_report": "ancsh.studies.catalog_reports",
                           "write_import_report": "ancsh.studies.catalog_reports"},
    "ancsh.data.measure": {"ranges_table": "ancsh.studies.catalog_reports"},
}

REMOVED_IN = "0.2"


class MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names of :data:`MOVED` and loads them as their new modules."""

    def __init__(self):
        self._specs = {}

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = MOVED[spec.name]
        where = new if isinstance(new, str) else " and ".join(new)
        warnings.warn(f"{spec.name} moved to {where}; the old name stops working in ancsh {REMOVED_IN}",
                      DeprecationWarning, stacklevel=2)  # warnings skips the import machinery's frames
        if not isinstance(new, str):
            return _split_view(spec.name, [importlib.import_module(name) for name in new])
        module = importlib.import_module(new)
        self._specs[spec.name] = module.__spec__  # the import system sets the alias's spec; exec_module restores it
        return module

    def exec_module(self, module):
        if module.__spec__.name in self._specs:
            module.__spec__ = self._specs.pop(module.__spec__.name)


def _split_view(name: str, modules: list) -> types.ModuleType:
    """A module named ``name`` whose attributes are those of ``modules`` (the first that has it)."""
    view = types.ModuleType(name, f"Deprecated: moved to {', '.join(m.__name__ for m in modules)}.")

    def __getattr__(attr: str):
        for module in modules:
            if hasattr(module, attr):
                return getattr(module, attr)
        raise AttributeError(f"module {name!r} has no attribute {attr!r}")

    view.__getattr__ = __getattr__
    return view


def moved_names(module: str):
    """A module ``__getattr__`` answering the names of :data:`MOVED_NAMES` that left ``module``, with a warning."""
    moved = MOVED_NAMES.get(module, {})

    def __getattr__(name: str):
        if name not in moved:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} moved to {moved[name]}; the old name stops working in ancsh {REMOVED_IN}",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(moved[name]), name)

    return __getattr__


def install() -> None:
    """Append the finder to ``sys.meta_path`` once (after the real finders: only missing names reach it)."""
    if not any(isinstance(f, MovedModuleFinder) for f in sys.meta_path):
        sys.meta_path.append(MovedModuleFinder())
