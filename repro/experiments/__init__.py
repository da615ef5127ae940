"""Every figure and measurement, one module each, by paper: ``lewis/`` and ``pronost/``.

Each figure module registers its experiment with
:func:`repro.experiments.registry.experiment` when imported; importing this package
discovers and imports them all (:func:`repro.experiments.registry.discover`), so adding
a figure is adding a module.  See ``repro list``.
"""

from repro.experiments.registry import Result, discover, experiment, get, registry, run

discover()

__all__ = ["Result", "experiment", "get", "registry", "run"]
