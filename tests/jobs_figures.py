"""Tiny figures for the ``--jobs`` tests, in a module of their own so that spawned workers can import them.

Importing registers them; :func:`unregister` removes them again (tests/test_jobs.py).
"""

from __future__ import annotations

import os
import sys

import pandas as pd

from repro.errors import ModelError
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

NAMES = ("zz_jobs_a", "zz_jobs_b", "zz_jobs_faces", "zz_jobs_fails", "zz_jobs_dies", "zz_jobs_speed", "zz_jobs_slow_a",
         "zz_jobs_slow_b", "zz_jobs_orphan_a", "zz_jobs_orphan_b")


def _table(i, quick):
    return pd.DataFrame({"i": [i], "x": [i / 7.0], "quick": [bool(quick)]})


@experiment("zz_jobs_a", "jobs test figure a", paper="lewis2005", data=())
def zz_jobs_a(quick=False):
    return Result(_table(1, quick), extra_tables={"more": _table(11, quick)})


@experiment("zz_jobs_b", "jobs test figure b", paper="lewis2005", data=())
def zz_jobs_b(quick=False, progress=False):
    return Result(_table(2, quick))


@experiment("zz_jobs_faces", "jobs test: the faces in use and the process", paper="lewis2005", data=())
def zz_jobs_faces(quick=False):
    return Result(pd.DataFrame({"faces": [len(common.face_inputs())], "pid": [os.getpid()]}))


@experiment("zz_jobs_fails", "jobs test: fails with one of repro's errors", paper="lewis2005", data=())
def zz_jobs_fails(quick=False):
    raise ModelError("zz_jobs_fails cannot be computed (on purpose)")


@experiment("zz_jobs_dies", "jobs test: its process dies", paper="lewis2005", data=())
def zz_jobs_dies(quick=False):
    from pathlib import Path

    if os.environ.get("ZZ_JOBS_DIE_IN"):  # leave a temporary file as a killed writer would, then die
        Path(os.environ["ZZ_JOBS_DIE_IN"], ".zz_jobs_dies.csv.abc123.tmp").write_text("half")
    sys.stdout.flush()
    os._exit(3)


@experiment("zz_jobs_speed", "jobs test: a timing figure (pid of the process it ran in)", paper="lewis2005",
            data=(), timing=True)
def zz_jobs_speed(quick=False):
    return Result(pd.DataFrame({"pid": [os.getpid()]}))


def _slow(tag):
    """Half-write the CSV (a temporary file beside it), say so, and wait to be interrupted."""
    import time
    from pathlib import Path

    from repro.io import atomic_path

    out = Path(os.environ["ZZ_JOBS_SLOW_IN"])
    with atomic_path(out / f"zz_jobs_slow_{tag}.csv") as tmp:
        tmp.write_text("half")
        (out.parent / f"started-{os.getpid()}").write_text("")
        time.sleep(120)
    return Result(pd.DataFrame({"i": [0]}))


@experiment("zz_jobs_slow_a", "jobs test: slow, to be interrupted", paper="lewis2005", data=())
def zz_jobs_slow_a(quick=False):
    return _slow("a")


@experiment("zz_jobs_slow_b", "jobs test: slow, to be interrupted", paper="lewis2005", data=())
def zz_jobs_slow_b(quick=False):
    return _slow("b")


def _outlive_parent(tmp=None):
    """Say so, wait for this worker's parent to die, and outlive it (bounded: 120 s), as a figure still
    computing when its run is killed; a half-written ``tmp`` is then finished."""
    import time
    from pathlib import Path

    parent, deadline = os.getppid(), time.monotonic() + 120
    if tmp is not None:
        tmp.write_text("half")
    Path(os.environ["ZZ_JOBS_ORPHAN_IN"], f"started-{os.getpid()}").write_text("")
    while os.getppid() == parent and time.monotonic() < deadline:
        time.sleep(0.02)
    if tmp is not None:
        tmp.write_text("i\n0\n")


@experiment("zz_jobs_orphan_a", "jobs test: half-writes its CSV, then outlives its run", paper="lewis2005", data=())
def zz_jobs_orphan_a(quick=False):
    from pathlib import Path

    from repro.io import atomic_path

    if not os.environ.get("ZZ_JOBS_ORPHAN_IN"):
        return Result(pd.DataFrame({"i": [0]}))
    with atomic_path(Path(os.environ["ZZ_JOBS_ORPHAN_OUT"]) / "zz_jobs_orphan_a.csv") as tmp:
        _outlive_parent(tmp)  # (then published here, by atomic_path, unless stopped)
    return Result(pd.DataFrame({"i": [0]}))


@experiment("zz_jobs_orphan_b", "jobs test: outlives its run, then returns its table", paper="lewis2005", data=())
def zz_jobs_orphan_b(quick=False):
    if os.environ.get("ZZ_JOBS_ORPHAN_IN"):
        _outlive_parent()  # (then written by run, unless stopped)
    return Result(pd.DataFrame({"i": [1]}))


def unregister() -> None:
    """Remove these figures from the registry (and this module, so that importing it registers them again)."""
    import importlib

    reg = importlib.import_module("repro.experiments.registry")  # (``repro.experiments.registry`` is the function)
    for name in NAMES:
        reg._REGISTRY.pop(name, None)
    sys.modules.pop(__name__, None)
