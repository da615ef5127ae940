"""Every figure and measurement, one module each; importing this registers them all.

See :mod:`repro.experiments.registry` for the registry and ``repro list``.
"""

from repro.experiments import (  # noqa: F401  (each module registers its experiment)
    alpha_sweep,
    attenuation_speed,
    fig2_interference,
    fig3_attenuation,
    fig4_axis_selection,
    fig5_alpha,
    rejected_alternatives,
)
from repro.experiments.registry import Result, experiment, get, registry, run

__all__ = ["Result", "experiment", "get", "registry", "run"]
