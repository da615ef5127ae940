"""Every figure and measurement, one module each; importing this registers them all.

See :mod:`repro.experiments.registry` for the registry and ``repro list``.
"""

from repro.experiments import attenuation_speed  # noqa: F401
from repro.experiments.registry import Result, experiment, get, registry, run

__all__ = ["Result", "experiment", "get", "registry", "run"]
