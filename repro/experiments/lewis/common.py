"""Shared pieces of the Lewis et al. 2005 figures: which models to run, how to draw a face row."""

from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path

import numpy as np

from repro import data
from repro.blendshapes import Attenuator, load_model
from repro.blendshapes.metrics import per_vertex_motion

MOTION_LABEL = "vertex motion\n(model units; cm on ICT)"


#: The user's glTF faces added to every figure (see :func:`use_faces`): (path, sha256, model).
_FACES: list = []


#: The files a user's face may be (what :func:`repro.blendshapes.load_model` reads as a path).
FACE_SUFFIXES = (".gltf", ".glb", ".vrm")


def _load_face(path):
    from repro.errors import ModelError
    from repro.io import read_bytes

    if not isinstance(path, (str, os.PathLike)):
        raise ModelError(f"a face must be a .gltf/.glb/.vrm path, got {path!r}")
    p = Path(path)
    if p.suffix.lower() not in FACE_SUFFIXES:
        raise ModelError(f"face {str(p)!r} is not a .gltf, .glb or .vrm file")
    raw, _ = read_bytes(p, error=ModelError)
    return (str(p), hashlib.sha256(raw).hexdigest(), load_model(p))


@contextlib.contextmanager
def use_faces(paths):
    """Within the block, :func:`models` also returns the glTF/VRM faces at ``paths``.

    Every file is read (and checked) on entry, so a missing or invalid one is a
    :class:`~repro.errors.ModelError` before any figure runs.
    """
    loaded = [_load_face(p) for p in (paths or ())]
    saved = list(_FACES)
    _FACES[:] = saved + loaded
    try:
        yield [m for _, _, m in loaded]
    finally:
        _FACES[:] = saved


def face_inputs() -> list[dict]:
    """The user's faces in use, as ``{"file", "sha256"}`` (the run cache keys on their content)."""
    return [{"file": Path(p).name, "sha256": h} for p, h, _ in _FACES]


def models():
    """The embedded face always; the real ICT face (face area) when its data is present;
    then the user's faces given with :func:`use_faces` (``repro run --face``)."""
    out = [load_model("procedural")]
    if data.missing_reason("ict") is None:
        out.append(load_model("ict"))
    out += [m for _, _, m in _FACES]
    return out


def attenuators():
    """(model, Attenuator) pairs for :func:`models`."""
    return [(m, Attenuator(m)) for m in models()]


#: The columns of a figure's ``skipped`` table (:func:`applicable`, :func:`applicable_sessions`).
SKIPPED_COLUMNS = ["model", "scenario", "reason"]


def _face(item):
    return item[0] if isinstance(item, tuple) else item


def applicable(items, keys):
    """The faces (models, or ``(model, ...)`` pairs) on which every session in ``keys`` runs, and a table
    (:data:`SKIPPED_COLUMNS`) of why each other face is left out of the figure, in the words of
    :meth:`~repro.blendshapes.scenarios.Scenario.not_applicable` (e.g. a user's face without the sliders
    a session of Lewis et al. 2005, Figs. 1-5, moves)."""
    import pandas as pd

    from repro.blendshapes import scenarios as S

    kept, rows = [], []
    for item in items:
        why = [(k, S.scenario(k).not_applicable(_face(item))) for k in keys]
        rows += [{"model": _face(item).name, "scenario": k, "reason": w} for k, w in why if w is not None]
        if all(w is None for _, w in why):
            kept.append(item)
    return kept, pd.DataFrame(rows, columns=SKIPPED_COLUMNS)


def applicable_sessions(items, keys):
    """``(item, key)`` for every face and session in ``keys`` that runs on it, and the ``skipped`` table of
    the rest (a face is left out only of the sessions that do not apply to it)."""
    import pandas as pd

    runs, skipped = [], []
    for item in items:
        for k in keys:
            ok, why = applicable([item], [k])
            runs += [(item, k)] if ok else []
            skipped.append(why)
    return runs, pd.concat(skipped, ignore_index=True) if skipped else pd.DataFrame(columns=SKIPPED_COLUMNS)


def skipped_tables(skipped) -> dict:
    """``{"skipped": table}`` for a Result's ``extra_tables`` when a face was left out (``repro run`` writes
    it as ``<name>-skipped.csv``), else nothing: the figures on the built-in faces are unchanged."""
    return {"skipped": skipped} if len(skipped) else {}


def motion(d, d_ref=None):
    """Per-vertex motion of displacement ``d`` from ``d_ref``."""
    return per_vertex_motion(d, d_ref)


def zeros(model):
    return np.zeros(3 * model.n_vertices)
