"""Benchmarks that print ratios against a baseline measured in the same process.

These machines are noisy, so no absolute time is asserted anywhere: each benchmark
times a baseline and the method side by side, interleaved, and reports medians and
their ratio.  One module per benchmark, each the home of one ``repro bench`` command:

- :mod:`repro.bench.attenuation` -- Lewis et al. 2005, Section 5 (``repro bench attenuation``);
- :mod:`repro.bench.retrieval` -- Pronost et al., Sections 3.3 and 4 (``repro bench retrieval``);
- :mod:`repro.bench.adaptation` -- Pronost et al., Sections 3.4 and 4 (``repro bench adaptation``);
- :mod:`repro.bench.index_build` -- Pronost et al., Section 3.2.2, the scaled databases and index
  (``repro bench index``);
- :mod:`repro.bench.prepare` -- Pronost et al., Section 3.3, preparing a query (``repro bench prepare``).

This module holds only what they share (the machine line and the median timer).  The
paper's published numbers are in :mod:`repro.motion.runtime.paper`, never here.  The
benchmark functions are also reachable as ``repro.bench.<name>`` (loaded on first use)
so that ``from repro.bench import bench_retrieval`` keeps working.
"""

from __future__ import annotations

import importlib
import os
import platform
import time

import numpy as np

__all__ = ["machine", "median_time"]

#: the benchmark functions, by the module that holds them (``repro.bench.<name>`` forwards)
_HOMES = {
    "bench_attenuation": "attenuation", "bench_attenuation_scaling": "attenuation", "format_attenuation": "attenuation",
    "bench_bounded": "attenuation",
    "bench_retrieval": "retrieval", "retrieval_summary": "retrieval", "format_retrieval": "retrieval",
    "bench_adaptation": "adaptation", "format_adaptation": "adaptation",
    "bench_index_build": "index_build", "format_index_build": "index_build",
    "bench_prepare": "prepare", "format_prepare": "prepare",
    "bench_order": "order", "format_order": "order",
}


def machine() -> str:
    """A one-line description of this machine, for benchmark output."""
    return (f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores, "
            f"{platform.python_implementation()} {platform.python_version()}, numpy {np.__version__}").replace("  ", " ")


def median_time(fn, args_list) -> float:
    """Median seconds per call of ``fn(*args)`` over ``args_list`` (after one untimed warm-up call)."""
    fn(*args_list[0])
    times = []
    for args in args_list:
        t0 = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def __getattr__(name: str):
    if name in _HOMES:
        return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
