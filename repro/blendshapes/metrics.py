"""Measurements for Lewis et al. 2005: how still the selection stays, how much
of the intended motion the rest keeps, and how smooth the surface remains.

Displacements are flat (3n,) vectors in the xyz packing of ``D`` (row
``3*v + axis``) or (n, 3) arrays; both are accepted.  Selections are rows of
``D`` as built by :func:`repro.blendshapes.select_vertices`.

- :func:`selected_motion`: ``||S (d - d_ref)||``, the quantity Eq. (2)'s first
  term penalises (Figs. 3-5: "the selected vertices maintain their positions").
- :func:`unselected_fidelity`: ``1 - ||Sbar (d - d_int)|| / ||Sbar (d_int - d_ref)||``,
  1 when the unselected coordinates move exactly as the sliders intend, 0 when
  their error is as large as the intended motion (Fig. 5e: "not moving
  unselected vertices either").
- :func:`roughness`: the largest uniform-Laplacian magnitude of the
  displacement field, ``max_i ||d_i - mean_{j~i} d_j||``; a frozen vertex whose
  neighbour keeps moving (Section 3's argument against zeroing rows) shows up
  as a spike.  :func:`roughness_near` looks only at a selection and its
  neighbours, where that tear happens.  :func:`edge_strain` gives the per-edge relative length change.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from repro.blendshapes.attenuation import check_selection
from repro.checks import as_real_array
from repro.blendshapes.model import BlendshapeModel
from repro.errors import ModelError

__all__ = [
    "per_vertex_motion",
    "selected_motion",
    "unselected_error",
    "unselected_fidelity",
    "laplacian_magnitude",
    "roughness",
    "roughness_near",
    "edge_strain",
]


def _flat(d, name: str = "displacement") -> np.ndarray:
    d = as_real_array(d, name, finite=False, error=ModelError)
    if d.ndim == 2 and d.shape[1] == 3:
        d = d.reshape(-1)
    if d.ndim != 1 or d.size % 3:
        raise ModelError(f"{name} must be a flat 3n vector or an (n, 3) array, got shape {d.shape}")
    if not np.isfinite(d).all():
        raise ModelError(f"{name} has NaN/inf values")
    return d


def _norm(x: np.ndarray) -> float:
    """Euclidean norm of a vector; BLAS ``nrm2`` neither overflows (|x| ~ 1e200) nor underflows (~ 1e-200)."""
    r = float(scipy.linalg.norm(x, check_finite=False)) if x.size else 0.0
    if not math.isfinite(r):
        raise ModelError("a displacement norm overflows float64")
    return r


def _row_norms(x: np.ndarray) -> np.ndarray:
    """Norms of the rows of an (n, 3) array, without overflow or underflow (``hypot``)."""
    with np.errstate(over="ignore"):
        r = np.hypot(np.hypot(x[:, 0], x[:, 1]), x[:, 2])
    if not np.isfinite(r).all():
        raise ModelError("a per-vertex displacement norm overflows float64")
    return r


def _diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        out = a - b
    if not np.isfinite(out).all():
        raise ModelError("the difference of two displacements overflows float64")
    return out


def _pair(d, d_ref, name="reference", *, required: bool = False):
    d = _flat(d)
    if d_ref is None and required:
        raise ModelError(f"the {name} is required (a displacement like d), got None")
    if d_ref is None:
        return d, np.zeros_like(d)
    r = _flat(d_ref, name)
    if r.shape != d.shape:
        raise ModelError(f"{name} has {r.size} coordinates, displacement has {d.size}")
    return d, r


def per_vertex_motion(d, d_ref=None) -> np.ndarray:
    """Euclidean motion of every vertex, ``||d_v - d_ref_v||`` (n,), e.g. for heat maps."""
    d, r = _pair(d, d_ref)
    return _row_norms(_diff(d, r).reshape(-1, 3))


def selected_motion(d, selected, d_ref=None) -> float:
    """``||S (d - d_ref)||``: how far the selected coordinates moved from ``d_ref`` (default: neutral)."""
    d, r = _pair(d, d_ref)
    sel = check_selection(selected, d.size)
    return _norm(_diff(d[sel], r[sel]))


def _unselected(n: int, selected) -> np.ndarray:
    mask = np.ones(n, dtype=bool)
    mask[check_selection(selected, n)] = False
    return mask


def unselected_error(d, d_intended, selected) -> float:
    """``||Sbar (d - d_intended)||``: how far the unselected coordinates are from where the sliders meant them."""
    d, t = _pair(d, d_intended, "intended displacement", required=True)
    m = _unselected(d.size, selected)
    return _norm(_diff(d[m], t[m]))


def unselected_fidelity(d, d_intended, selected, d_ref=None) -> float:
    """``1 - ||Sbar (d - d_int)|| / ||Sbar (d_int - d_ref)||`` (1 = exactly as intended).

    ``d_ref`` is the displacement before the moves (default: neutral).  NaN
    when the sliders intend no motion of the unselected coordinates.
    """
    d, t = _pair(d, d_intended, "intended displacement", required=True)
    _, r = _pair(d, d_ref)
    m = _unselected(d.size, selected)
    intended = _norm(_diff(t[m], r[m]))
    if intended == 0:
        return float("nan")
    return float(1.0 - _norm(_diff(d[m], t[m])) / intended)


def _model(model) -> BlendshapeModel:
    if not isinstance(model, BlendshapeModel):
        raise ModelError(f"expected a BlendshapeModel, got {type(model).__name__}")
    if not len(model.faces):
        raise ModelError(f"model {model.name!r} has no faces: smoothness needs mesh connectivity")
    return model


def laplacian_magnitude(model: BlendshapeModel, d) -> np.ndarray:
    """Per-vertex ``||d_i - mean_{j~i} d_j||`` (n,): the uniform-Laplacian roughness of a displacement."""
    model = _model(model)
    d = _flat(d)
    if d.size != 3 * model.n_vertices:
        raise ModelError(f"displacement has {d.size // 3} vertices, model has {model.n_vertices}")
    with np.errstate(over="ignore", invalid="ignore"):
        lap = model.laplacian @ d.reshape(-1, 3)
    if not np.isfinite(lap).all():
        raise ModelError("the Laplacian of the displacement overflows float64")
    return _row_norms(lap)


def roughness(model: BlendshapeModel, d) -> float:
    """Largest :func:`laplacian_magnitude` over the mesh (model units)."""
    return float(laplacian_magnitude(model, d).max())


def roughness_near(model: BlendshapeModel, d, vertices) -> float:
    """Largest :func:`laplacian_magnitude` over ``vertices`` and their mesh neighbours.

    Where a selection is frozen (zeroed rows of D) while a shape still moves
    its neighbours, the tear shows here, whatever happens elsewhere on the face.
    """
    model = _model(model)
    v = np.unique(as_real_array(vertices, "vertices", integer=True, error=ModelError))
    if v.size == 0 or v.min() < 0 or v.max() >= model.n_vertices:
        raise ModelError(f"vertices must be ids in 0..{model.n_vertices - 1}")
    e = model.edges
    inside = np.isin(e, v)
    ring = np.union1d(v, e[inside.any(axis=1)].ravel())
    return float(laplacian_magnitude(model, d)[ring].max())


def edge_strain(model: BlendshapeModel, d) -> np.ndarray:
    """Per-edge relative length change ``| ||e + de|| - ||e|| | / ||e||`` for displacement ``d``."""
    model = _model(model)
    d = _flat(d).reshape(-1, 3)
    if d.shape[0] != model.n_vertices:
        raise ModelError(f"displacement has {d.shape[0]} vertices, model has {model.n_vertices}")
    e = model.edges
    with np.errstate(over="ignore", invalid="ignore"):
        rest = model.f0[e[:, 1]] - model.f0[e[:, 0]]
        moved = rest + d[e[:, 1]] - d[e[:, 0]]
    L0 = _row_norms(rest)
    with np.errstate(over="ignore"):  # a displacement near the float64 limit over an edge of length ~1
        strain = np.abs(_row_norms(moved) - L0) / np.where(L0 > 0, L0, 1.0)
    if not np.isfinite(strain).all():
        raise ModelError("the edge strain overflows float64 (the displacement is too large)")
    return strain
