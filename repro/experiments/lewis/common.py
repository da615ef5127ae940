"""Shared pieces of the Lewis et al. 2005 figures: which models to run, how to draw a face row."""

from __future__ import annotations

import numpy as np

from repro import data
from repro.blendshapes import Attenuator, load_model
from repro.blendshapes.metrics import per_vertex_motion

MOTION_LABEL = "vertex motion (model units; cm on the ICT face)"


def models():
    """The embedded face always; the real ICT face (face area) when its data is present."""
    out = [load_model("procedural")]
    if data.missing_reason("ict") is None:
        out.append(load_model("ict"))
    return out


def attenuators():
    """(model, Attenuator) pairs for :func:`models`."""
    return [(m, Attenuator(m)) for m in models()]


def motion(d, d_ref=None):
    """Per-vertex motion of displacement ``d`` from ``d_ref``."""
    return per_vertex_motion(d, d_ref)


def zeros(model):
    return np.zeros(3 * model.n_vertices)
