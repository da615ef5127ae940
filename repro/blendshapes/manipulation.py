"""Direct manipulation of blendshapes (Lewis and Anjyo 2010) on the Gram machinery of the Attenuator.

Lewis and Anjyo, "Direct Manipulation Blendshapes" (IEEE CG&A 30(4), 2010), the
sequel to Lewis et al. 2005: the animator drags a few vertices to target
positions and the system finds slider weights, regularised towards the current
weights.  With the 2005 pin available at the same time (drag the mouth corner
while the eye stays put), the change ``u = w - w_current`` minimises

    ||B u - r||^2 + mu_abs ||u||^2 + alpha ||S D u||^2,

where ``B`` are the rows of ``D`` of the dragged coordinates, ``r = target -
(f0 + D w_current)`` at those coordinates (how far the drag asks them to go),
and ``S`` selects the pinned coordinates (a selection of rows, as for
attenuation).  The normal equations are m x m:

    (B^T B + mu_abs I + alpha Q) u = B^T r,    Q = S^T S,

with ``B^T B`` and ``Q`` the :meth:`~repro.blendshapes.attenuation.Attenuator.selection_gram`
of the dragged and pinned rows (cached by the Attenuator).  :meth:`DirectManipulator.prepare`
forms and factors that matrix once per (drag selection, pin, mu, alpha); a
target move then costs two k x m mat-vecs and one m x m Cholesky solve.  With
bounds (``lo``/``hi``, e.g. the slider range [0, 1]) the same quadratic goes
through :func:`repro.blendshapes.bounded.solve_box_qp`.

Parameters and units
--------------------
``mu`` is relative: ``mu_abs = mu * trace(B^T B) / m``, the mean squared motion
a unit weight gives the dragged coordinates, so ``mu`` is independent of the
model's units and of how many vertices are dragged (default ``1e-3``; must be
> 0: a few dragged vertices do not determine m weights).  ``alpha`` weighs the
pinned coordinates' squared motion against the dragged coordinates' squared
error (both lengths in model units; default 100).  As for Eq. (3), ``D`` is
used scaled by the Attenuator's power of two, which changes nothing.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg

from repro.blendshapes.attenuation import (
    Attenuator,
    check_cache_size,
    check_selection,
    check_w,
    scaled,
    select_vertices,
)
from repro.blendshapes.bounded import check_bounds, solve_box_qp
from repro.checks import as_bool, as_real, as_real_array, describe
from repro.blendshapes.model import BlendshapeModel
from repro.errors import AttenuationError, SelectionError

__all__ = ["DEFAULT_MU", "DEFAULT_PIN_ALPHA", "DirectManipulator", "Drag", "DragResult"]

DEFAULT_MU = 1e-3
DEFAULT_PIN_ALPHA = 100.0


class DragResult(NamedTuple):
    """What :meth:`DirectManipulator.solve` found, with ``info=True``."""

    w: np.ndarray  #: the new weights
    dragged_error: float  #: largest distance of a dragged vertex from its target
    pinned_motion: float  #: largest motion of a pinned vertex (0 without a pin)
    n_sliders_moved: int  #: shapes whose weight changed by more than 1e-3
    method: str  #: "cholesky", or the box solver's method with bounds


@dataclass(frozen=True)
class Drag:
    """A prepared drag: the dragged vertices, the pin, and the factored normal matrix."""

    vertices: np.ndarray  #: dragged vertex ids
    rows: np.ndarray  #: their rows of D (3 per vertex)
    pinned: np.ndarray | None  #: pinned rows of D
    mu: float
    alpha: float
    B: np.ndarray  #: scaled rows of D for the dragged coordinates (3k x m)
    A: np.ndarray  #: B^T B + mu_abs I + alpha Q (scaled), m x m
    factor: tuple  #: Cholesky factor of A


def _positive(x, name, default) -> float:
    if x is None:
        return default
    v = as_real(x, name, error=AttenuationError)
    if not v > 0:
        raise AttenuationError(f"{name} must be a finite number > 0, got {describe(x)}")
    return v


class DirectManipulator:
    """Drag vertices to targets; solve for weights near the current ones (Lewis and Anjyo 2010).

    Parameters
    ----------
    model_or_attenuator : BlendshapeModel or Attenuator built from one
        An Attenuator is shared (its Gram matrix and selection caches).
    cache_size : int
        How many prepared drags to keep, ``0..MAX_CACHE_SIZE`` (as the Attenuator's).

    Examples
    --------
    >>> from repro.blendshapes import load_model
    >>> model = load_model("procedural")
    >>> dm = DirectManipulator(model)
    >>> v = model.regions["mouth_corners"][:1]
    >>> target = model.pose(model.weights(SmirkLeft=0.7))[v]
    >>> w = dm.solve(model.weights(), v, target)            # doctest: +SKIP
    """

    def __init__(self, model_or_attenuator, *, cache_size: int = 32):
        if isinstance(model_or_attenuator, Attenuator):
            att = model_or_attenuator
        elif isinstance(model_or_attenuator, BlendshapeModel):
            att = Attenuator(model_or_attenuator)
        else:
            raise AttenuationError(f"expected a BlendshapeModel or an Attenuator, got {describe(model_or_attenuator)}")
        if att.model is None:
            raise AttenuationError("direct manipulation needs the neutral face: build the Attenuator from a BlendshapeModel")
        self.attenuator = att
        self.model: BlendshapeModel = att.model
        self.m = att.m
        self._cache_size = check_cache_size(cache_size)  # before anything is built: -1 broke the cache
        self._drags: OrderedDict = OrderedDict()

    def __repr__(self) -> str:
        return f"DirectManipulator({self.model.n_vertices} vertices, {self.m} shapes, {len(self._drags)} prepared drags)"

    def prepare(self, dragged, pinned=None, *, mu=None, alpha=None) -> Drag:
        """The factored normal matrix for dragging ``dragged`` vertex ids with ``pinned`` rows kept (cached)."""
        n = self.model.n_vertices
        select_vertices(dragged, "xyz", n)  # checks the ids: integers, distinct, in range
        verts = np.atleast_1d(np.asarray(dragged)).astype(np.int64)  # the caller's order: targets follow it
        rows = (3 * verts[:, None] + np.arange(3)[None, :]).ravel()
        mu = _positive(mu, "mu", DEFAULT_MU)
        alpha = _positive(alpha, "alpha", DEFAULT_PIN_ALPHA)
        pin = None
        if pinned is not None:
            pin = check_selection(pinned, 3 * n)
            both = np.intersect1d(pin, rows)
            if both.size:
                raise SelectionError(f"vertices {np.unique(both // 3)[:10].tolist()} are both dragged and pinned")
        key = (rows.tobytes(), None if pin is None else pin.tobytes(), mu, alpha)
        hit = self._drags.get(key)
        if hit is not None:
            self._drags.move_to_end(key)
            return hit
        att = self.attenuator
        H = np.array(att.selection_gram(rows))
        tr = float(np.trace(H))
        if not tr > 0:
            raise SelectionError(f"no shape moves the dragged vertices {verts[:10].tolist()}: they cannot be dragged")
        A = H + (mu * tr / self.m) * np.eye(self.m)
        if pin is not None:
            A += alpha * att.selection_gram(pin)
        try:
            factor = scipy.linalg.cho_factor(A, lower=True, check_finite=False)
        except np.linalg.LinAlgError:  # cannot happen for mu > 0 short of overflow
            raise AttenuationError("the direct-manipulation system is not positive definite (D or alpha out of range)") from None
        B = scaled(self.model.D[rows], att.scale_exponent)
        for a in (B, A):
            a.flags.writeable = False
        drag = Drag(verts, rows, pin, mu, alpha, B, A, factor)
        self._drags[key] = drag
        while len(self._drags) > self._cache_size:
            self._drags.popitem(last=False)
        return drag

    def solve(self, w_current, dragged, targets, pinned=None, *, mu=None, alpha=None, lo=None, hi=None,
              info: bool = False):
        """New weights moving ``dragged`` vertex ids towards ``targets`` ((k, 3) positions).

        ``pinned``: rows of D to keep (:func:`~repro.blendshapes.select_vertices`);
        ``lo``/``hi``: optional slider range (both or neither; numbers or per
        shape).  ``dragged`` may be a prepared :class:`Drag` (then ``pinned``,
        ``mu``, ``alpha`` are its own).  ``info=True`` returns a :class:`DragResult`.
        """
        info = as_bool(info, "info", error=AttenuationError)
        drag = dragged if isinstance(dragged, Drag) else self.prepare(dragged, pinned, mu=mu, alpha=alpha)
        w = check_w(w_current, self.m, "w_current")
        k = drag.vertices.size
        t = as_real_array(targets, "targets", error=AttenuationError, finite=False)
        if t.shape == (3,) and k == 1:
            t = t.reshape(1, 3)
        if t.shape != (k, 3):
            raise AttenuationError(f"targets must have shape ({k}, 3) for {k} dragged vertices, got {t.shape}")
        if not np.isfinite(t).all():
            raise AttenuationError(f"targets have {np.count_nonzero(~np.isfinite(t))} NaN/inf values")
        e = self.attenuator.scale_exponent
        D_rows = self.model.D[drag.rows]
        with np.errstate(over="ignore", invalid="ignore"):
            r = t.reshape(-1) - self.model.f0[drag.vertices].reshape(-1) - D_rows @ w
            g = drag.B.T @ scaled(r, e)
        if not np.isfinite(g).all():
            raise AttenuationError("the drag overflows float64 (targets or weights too large)")
        u = scipy.linalg.cho_solve(drag.factor, g, check_finite=False)
        method = "cholesky"
        if (lo is None) != (hi is None):
            raise AttenuationError("give both lo and hi (the slider range), or neither")
        if lo is not None:
            lo_, hi_ = check_bounds(lo, hi, self.m)
            with np.errstate(over="ignore", invalid="ignore"):
                lo_u, hi_u = lo_ - w, hi_ - w
            res = solve_box_qp(drag.A, g, lo_u, hi_u, u)
            u, method = res.x, res.method
            w_new = np.clip(w + u, lo_, hi_)
        else:
            w_new = w + u
        if not np.isfinite(w_new).all():
            raise AttenuationError("the drag overflows float64 (targets or weights too large)")
        if not info:
            return w_new
        with np.errstate(over="ignore", invalid="ignore"):
            reached = self.model.f0[drag.vertices] + (D_rows @ w_new).reshape(-1, 3)
            dragged_error = float(np.hypot.reduce(reached - t, axis=1).max())
            pinned_motion = 0.0
            if drag.pinned is not None:
                du = (self.model.D[drag.pinned] @ (w_new - w))
                pv = drag.pinned // 3
                per_vertex = np.zeros(self.model.n_vertices)
                np.add.at(per_vertex, pv, du**2)
                pinned_motion = float(np.sqrt(per_vertex.max()))
        if not (np.isfinite(dragged_error) and np.isfinite(pinned_motion)):
            raise AttenuationError("the drag's distances overflow float64 (targets too far from the face)")
        return DragResult(w_new, dragged_error, pinned_motion,
                          int(np.count_nonzero(np.abs(w_new - w) > 1e-3)), method)

    def positions(self, w, vertices) -> np.ndarray:
        """Posed positions (k, 3) of ``vertices`` at weights ``w`` (``f0 + D w`` at those rows only)."""
        select_vertices(vertices, "xyz", self.model.n_vertices)
        v = np.atleast_1d(np.asarray(vertices)).astype(np.int64)
        rows = (3 * v[:, None] + np.arange(3)[None, :]).ravel()
        w = check_w(w, self.m, "w")
        return self.model.f0[v] + (self.model.D[rows] @ w).reshape(-1, 3)
