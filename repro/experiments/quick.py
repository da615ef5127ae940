"""The quick figures, each computed once: in a process, and across the processes of one run.

:func:`quick_result` is figure ``name`` in quick mode (``call_experiment(get(name), quick=True)``),
computed at most once per process; :func:`quick_png` its picture as the gallery of notebook 00 shows it
(PNG, :data:`GALLERY_DPI`).  Notebook 00 and the claims ledger read both.

When the environment variable :data:`SHARED` names a folder, the results are shared across the
processes that see it: a process that computes a figure writes its tables and its picture there,
and another reads them instead of computing again.  The test session sets it for itself and every
process it starts (the notebooks' kernels, the runs beside the tests) and removes the folder when it
ends, so that one run computes each quick figure once per kind of data, however many notebooks show it
(issue 27, the faster loop).  Nothing else sets it: a user's notebook computes its figures as always.

An entry's key is the sha256 of the figure's name, the data folder and what the manifest records a
figure's outputs depend on (:func:`~repro.experiments.registry.input_key`: the package's source, the data
the figure can use as this process sees it, the library versions, a user's faces), so a code change,
``DATA = "embedded"`` or a folder without data gets entries of its own.  An entry is
written atomically with the sha256 of its payload beside it, and read only from a folder that is the
user's own and writable by no one else; an entry that does not verify is computed again.  The payload
is a pickle of pandas tables (a result's ``draw`` is a closure, which pickle cannot carry): a result
read from the folder draws its stored picture.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import pickle
import stat
from pathlib import Path

#: the environment variable naming the folder shared by the processes of one run (unset: nothing shared)
SHARED = "REPRO_QUICK_RESULTS"
#: the dots per inch of the gallery's pictures (each figure at its own size)
GALLERY_DPI = 100

_results: dict = {}  # key -> Result, this process's
_pngs: dict = {}  # key -> PNG bytes, this process's


def shared_folder() -> Path | None:
    """The folder :data:`SHARED` names when it can be trusted (a folder of this user's, writable by no one else)."""
    name = os.environ.get(SHARED)
    if not name:
        return None
    try:
        st = os.lstat(name)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return None
    return Path(name)


def key(name: str) -> str:
    """The sha256 naming figure ``name``'s quick result: its name, the package's source, the data it can use."""
    from repro import data
    from repro.experiments import get
    from repro.experiments.registry import input_key
    from repro.experiments.shared import code_fingerprint

    what = {"name": name, "data_dir": str(data.data_dir()),
            **input_key(get(name), quick=True, code=code_fingerprint())}
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()


def quick_result(name: str):
    """Figure ``name`` in quick mode: computed once per process, or read from the run's shared folder.

    Raises what :func:`repro.experiments.get` raises for an unknown name.
    """
    k = key(name)
    if k not in _results:
        stored = _read(k)
        if stored is not None:
            _results[k], _pngs[k] = stored
        else:
            from repro.experiments import get
            from repro.experiments.registry import call_experiment

            _results[k] = call_experiment(get(name), quick=True)
            if shared_folder() is not None:
                share(name, _results[k])
    return _results[k]


def quick_png(name: str) -> bytes:
    """The picture of :func:`quick_result` ``(name)``, as PNG bytes at :data:`GALLERY_DPI` (drawn once)."""
    result = quick_result(name)
    k = key(name)
    if k not in _pngs:
        _pngs[k] = _png(result)
    return _pngs[k]


def share(name: str, result) -> None:
    """Write ``result`` (figure ``name``'s quick result) and its picture into the shared folder, if there is one."""
    from repro.io import atomic_path

    folder = shared_folder()
    if folder is None:
        return
    k = key(name)
    png = _pngs.get(k) or _png(result)
    _pngs[k] = png
    payload = pickle.dumps({"table": result.table, "extra_tables": result.extra_tables, "png": png},
                           protocol=pickle.HIGHEST_PROTOCOL)
    with atomic_path(folder / f"{k}.pickle", mode=0o600) as tmp:
        tmp.write_bytes(payload)
    with atomic_path(folder / f"{k}.sha256", mode=0o600) as tmp:
        tmp.write_text(hashlib.sha256(payload).hexdigest())


def _read(k: str):
    """(Result, PNG bytes) of entry ``k`` of the shared folder, or None (no folder, no entry, or it does not verify)."""
    from repro.errors import ReproError
    from repro.experiments.registry import Result
    from repro.io import read_bytes

    folder = shared_folder()
    if folder is None:
        return None
    try:
        payload = read_bytes(folder / f"{k}.pickle")[0]
        digest = read_bytes(folder / f"{k}.sha256")[0].decode().strip()
    except (ReproError, UnicodeDecodeError):
        return None
    if hashlib.sha256(payload).hexdigest() != digest:
        return None
    entry = pickle.loads(payload)  # verified, from a folder of this user's that no one else can write
    png = entry["png"]
    return Result(entry["table"], draw=lambda: _picture(png), extra_tables=entry["extra_tables"]), png


def _png(result) -> bytes:
    import matplotlib.pyplot as plt

    fig = result.draw()
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=GALLERY_DPI, metadata={"Software": None})
    finally:
        plt.close(fig)
    return buf.getvalue()


def _picture(png: bytes):
    """A figure showing the stored picture pixel for pixel when saved at :data:`GALLERY_DPI`."""
    import matplotlib.image as mpimg
    from matplotlib.figure import Figure

    pixels = mpimg.imread(io.BytesIO(png), format="png")
    fig = Figure(figsize=(pixels.shape[1] / GALLERY_DPI, pixels.shape[0] / GALLERY_DPI), dpi=GALLERY_DPI)
    fig.figimage(pixels, origin="upper")
    return fig
