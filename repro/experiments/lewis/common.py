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

MOTION_LABEL = "vertex motion (model units; cm on the ICT face)"


#: The user's glTF faces added to every figure (see :func:`use_faces`): (path, sha256, model).
_FACES: list = []


def _load_face(path):
    from repro.errors import ModelError
    from repro.io import read_bytes

    if not isinstance(path, (str, os.PathLike)):
        raise ModelError(f"a face must be a .gltf/.glb path, got {path!r}")
    p = Path(path)
    if p.suffix.lower() not in (".gltf", ".glb"):
        raise ModelError(f"face {str(p)!r} is not a .gltf or .glb file")
    raw, _ = read_bytes(p, error=ModelError)
    return (str(p), hashlib.sha256(raw).hexdigest(), load_model(p))


@contextlib.contextmanager
def use_faces(paths):
    """Within the block, :func:`models` also returns the glTF faces at ``paths``.

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


def motion(d, d_ref=None):
    """Per-vertex motion of displacement ``d`` from ``d_ref``."""
    return per_vertex_motion(d, d_ref)


def zeros(model):
    return np.zeros(3 * model.n_vertices)
