"""Every figure and measurement, one module each; importing this registers them all.

Each public module of this package (not starting with ``_``) registers its
experiment with :func:`repro.experiments.registry.experiment` when imported; they
are discovered here, so adding a figure is adding a module.  See ``repro list``.
"""

import importlib
import pkgutil

from repro.experiments.registry import Result, experiment, get, registry, run

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
    if not _info.name.startswith("_") and _info.name != "registry":
        importlib.import_module(f"{__name__}.{_info.name}")

__all__ = ["Result", "experiment", "get", "registry", "run"]
