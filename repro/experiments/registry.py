"""One registry for every figure and measurement: ``repro list / run / all``.

An experiment is a pure function of its inputs (and a seed) registered with
:func:`experiment`; it returns a :class:`Result` holding its numbers as a pandas
DataFrame and a small function that draws them.  :func:`run` writes
``NAME.csv`` first and then ``NAME.png``, both atomically, so the numbers exist
even where drawing fails (e.g. no OpenGL for a 3D panel: the figure then fails
with :class:`~repro.errors.RenderUnavailableError`, the CSV stays).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from repro.errors import UnknownFigureError

__all__ = ["Experiment", "Result", "experiment", "registry", "get", "run"]


@dataclass
class Result:
    """What an experiment returns: its numbers, and how to draw them."""

    table: "object"  # pandas.DataFrame
    draw: "Callable[[], object] | None" = None  # () -> matplotlib Figure
    extra_tables: dict = field(default_factory=dict)  # suffix -> DataFrame, written NAME-suffix.csv


@dataclass(frozen=True)
class Experiment:
    name: str
    caption: str
    func: Callable[..., Result]
    module: str
    paper: str  # "lewis2005" | "pronost2008"


_REGISTRY: dict[str, Experiment] = {}


def experiment(name: str, caption: str, *, paper: str):
    """Register ``func(quick: bool = False) -> Result`` as figure/measurement ``name``."""

    def deco(func):
        if name in _REGISTRY:
            raise ValueError(f"experiment {name!r} registered twice")
        if "quick" not in inspect.signature(func).parameters:
            raise TypeError(f"experiment {name!r} must accept quick=")
        _REGISTRY[name] = Experiment(name, caption, func, func.__module__, paper)
        return func

    return deco


def registry() -> dict[str, Experiment]:
    """All registered experiments, by name (importing the experiment modules)."""
    import repro.experiments  # noqa: F401  (registers)

    return dict(sorted(_REGISTRY.items()))


def get(name: str) -> Experiment:
    reg = registry()
    if name not in reg:
        raise UnknownFigureError(f"unknown figure or measurement {name!r}; known: {', '.join(reg) or 'none'}")
    return reg[name]


def run(name: str, outdir="figures", *, quick: bool = False) -> list[Path]:
    """Run experiment ``name`` and write its CSV (and PNG) into ``outdir``; the paths written."""
    from repro.io import save_figure, write_csv

    exp = get(name)
    result = exp.func(quick=quick)
    out = Path(outdir)
    written = [write_csv(out / f"{name}.csv", result.table)]
    for suffix, table in result.extra_tables.items():
        written.append(write_csv(out / f"{name}-{suffix}.csv", table))
    if result.draw is not None:
        import matplotlib.pyplot as plt

        figure = result.draw()
        try:
            written.append(save_figure(out / f"{name}.png", figure))
        finally:
            plt.close(figure)
    return written
