"""Selected motion attenuation, Lewis et al. 2005, Section 4, Eqs. (2)-(3).

The animator tags coordinates ``S`` (rows of ``D``) that should stay put.  A
slider change ``w1`` is replaced by the ``w2`` minimising Eq. (2),

    alpha * ||S w2||^2 + ||Sbar (w2 - w1)||^2,

whose solution is Eq. (3):

    w2 = (P + alpha Q)^-1 P w1,   P = Sbar^T Sbar,   Q = S^T S.

The default ``alpha`` is "the ratio of the number of unselected and selected
vertices" (Section 5); on rows that is ``#unselected rows / #selected rows``,
which equals the vertex ratio when whole vertices are selected.

Two implementations:

- :func:`attenuate` is Eq. (3) as the paper describes it: slice ``S`` and
  ``Sbar`` out of ``D``, form ``P`` and ``Q``, solve.  O(n m^2) per call.
- :class:`Attenuator` precomputes the Gram matrix ``G = D^T D`` once, so that a
  new selection costs O(k m^2) for ``k`` selected rows (``Q = S^T S``,
  ``P = G - Q``, ``P + alpha Q = G + (alpha - 1) Q``), caches
  ``M = (P + alpha Q)^-1 P`` per (selection, alpha), and turns a slider move
  into one m x m mat-vec.

Selections are 1-D arrays of row indices of ``D`` (row ``3*v + axis``); the
helpers :func:`select_vertices` and :func:`select_pairs` build them from vertex
ids and axis names.

Degenerate cases
----------------
``P + alpha Q`` is positive definite for every ``alpha > 0`` exactly when ``D``
has full column rank (``x^T (P + alpha Q) x = ||Sbar x||^2 + alpha ||S x||^2``).
When it does not (a zero shape, or shapes that are linear combinations of
others), Eq. (3) has many solutions that all give the same face ``D w2``; both
implementations then return the minimum-norm least-squares solution (via the
pseudo-inverse), and :attr:`Attenuator.rank` tells the rank.  ``P`` alone may be
singular (shapes with no support outside the selection): that is legitimate,
the solution is still unique, and such shapes are strongly suppressed; but then
the ``alpha -> 0`` limit is not ``w1`` for those components (Section 5's limit
assumes ``P`` invertible).  A selection of *every* coordinate leaves nothing
that may move (``P = 0``) and is refused.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable

import numpy as np
import scipy.linalg

from repro.blendshapes.model import AXES, BlendshapeModel
from repro.errors import AttenuationError, SelectionError

__all__ = [
    "attenuate",
    "Attenuator",
    "default_alpha",
    "check_selection",
    "select_vertices",
    "select_pairs",
    "select_axis",
]


# ---------------------------------------------------------------- selections
def _axis_index(axis) -> int:
    if isinstance(axis, str):
        a = axis.strip().lower()
        if a in AXES:
            return AXES.index(a)
        raise SelectionError(f"unknown axis {axis!r}; expected one of 'x', 'y', 'z' (or 0, 1, 2)")
    if isinstance(axis, (int, np.integer)) and 0 <= int(axis) < 3:
        return int(axis)
    raise SelectionError(f"unknown axis {axis!r}; expected one of 'x', 'y', 'z' (or 0, 1, 2)")


def _axes(axes) -> list[int]:
    if isinstance(axes, str):
        axes = list(axes)
    idx = [_axis_index(a) for a in axes]
    if not idx:
        raise SelectionError("no axis given; expected some of 'x', 'y', 'z'")
    if len(set(idx)) != len(idx):
        raise SelectionError(f"axis repeated in {axes!r}")
    return sorted(idx)


def _vertex_ids(vertices, n_vertices: int | None) -> np.ndarray:
    v = np.asarray(vertices)
    if v.ndim == 0:
        v = v.reshape(1)
    if v.ndim != 1 or (v.size and not np.issubdtype(v.dtype, np.integer)):
        raise SelectionError(f"vertex ids must be a 1-D integer array, got {v.dtype} of shape {v.shape}")
    if v.size == 0:
        raise SelectionError("the selection is empty: select at least one vertex")
    vals, counts = np.unique(v, return_counts=True)
    if (counts > 1).any():
        raise SelectionError(f"vertex ids repeated in the selection: {vals[counts > 1][:10].tolist()}")
    if v.min() < 0 or (n_vertices is not None and v.max() >= n_vertices):
        hi = "n-1" if n_vertices is None else str(n_vertices - 1)
        raise SelectionError(f"vertex ids {v.min()}..{v.max()} outside 0..{hi}")
    return v.astype(np.int64)


def select_vertices(vertices, axes="xyz", n_vertices: int | None = None) -> np.ndarray:
    """Rows of ``D`` for whole vertices, or for some of their axes.

    ``select_vertices([12, 40])`` selects all three coordinates of two vertices
    (Fig. 3's "two vertices ... in effect 6 coordinates"); ``axes="y"`` selects
    only their y coordinates (Fig. 4).
    """
    v = _vertex_ids(vertices, n_vertices)
    a = np.asarray(_axes(axes))
    return np.sort((3 * v[:, None] + a[None, :]).ravel())


def select_pairs(pairs: Iterable[tuple[int, int | str]], n_vertices: int | None = None) -> np.ndarray:
    """Rows of ``D`` from ``(vertex, axis)`` pairs, e.g. ``[(12, "y"), (40, "x")]``."""
    rows = []
    for p in pairs:
        try:
            v, axis = p
        except (TypeError, ValueError):
            raise SelectionError(f"expected (vertex, axis) pairs, got {p!r}") from None
        if not isinstance(v, (int, np.integer)) or v < 0 or (n_vertices is not None and v >= n_vertices):
            raise SelectionError(f"vertex {v!r} in pair {p!r} is not a valid vertex id")
        rows.append(3 * int(v) + _axis_index(axis))
    if not rows:
        raise SelectionError("the selection is empty: give at least one (vertex, axis) pair")
    rows = np.asarray(rows, dtype=np.int64)
    if np.unique(rows).size != rows.size:
        raise SelectionError("a (vertex, axis) pair is repeated in the selection")
    return np.sort(rows)


def select_axis(axis, n_vertices: int) -> np.ndarray:
    """Rows of ``D`` for one axis of every vertex (e.g. all ``"y"`` coordinates)."""
    return np.arange(_axis_index(axis), 3 * int(n_vertices), 3, dtype=np.int64)


def check_selection(selected, n_rows: int) -> np.ndarray:
    """``selected`` as a sorted int64 array of distinct rows in ``0..n_rows-1``.

    Raises :class:`~repro.errors.SelectionError` for an empty, repeated,
    out-of-range, non-integer or multi-dimensional selection, and for one that
    selects every row (then nothing may move and ``P = 0``).
    """
    s = np.asarray(selected)
    if s.ndim != 1:
        raise SelectionError(f"selected must be a 1-D array of row indices of D, got shape {s.shape}")
    if s.size == 0:
        raise SelectionError("the selection is empty: select at least one coordinate")
    if s.dtype == bool:
        raise SelectionError(
            "selected must hold row indices of D, not a boolean mask (use np.flatnonzero(mask))"
        )
    if not np.issubdtype(s.dtype, np.integer):
        raise SelectionError(f"selected must hold integer row indices of D, got dtype {s.dtype}")
    s = s.astype(np.int64)
    if s.min() < 0 or s.max() >= n_rows:
        raise SelectionError(
            f"selected rows {s.min()}..{s.max()} are outside 0..{n_rows - 1} (D has {n_rows} rows)"
        )
    u = np.unique(s)
    if u.size != s.size:
        vals, counts = np.unique(s, return_counts=True)
        raise SelectionError(f"selected rows repeated: {vals[counts > 1][:10].tolist()}")
    if u.size == n_rows:
        raise SelectionError(
            "every coordinate is selected: nothing is left free to move (P = 0 in Eq. 3)"
        )
    return u


def default_alpha(n_selected: int, n_rows: int) -> float:
    """Section 5's default: ``#unselected / #selected`` (rows; = vertices for whole vertices)."""
    if n_selected <= 0 or n_selected >= n_rows:
        raise SelectionError(f"cannot form the default alpha with {n_selected} of {n_rows} rows selected")
    return (n_rows - n_selected) / n_selected


def _check_alpha(alpha, n_selected: int, n_rows: int) -> float:
    if alpha is None:
        return default_alpha(n_selected, n_rows)
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise AttenuationError(f"alpha must be a positive number, got {alpha!r}") from None
    if not np.isfinite(a) or a <= 0:
        raise AttenuationError(f"alpha must be a finite number > 0 (Eq. 2), got {alpha!r}")
    return a


def _check_D(D) -> np.ndarray:
    D = np.asarray(D, dtype=np.float64)
    if D.ndim != 2 or D.shape[0] == 0 or D.shape[1] == 0:
        raise AttenuationError(f"D must be a non-empty 3n x m matrix, got shape {D.shape}")
    if D.shape[0] % 3:
        raise AttenuationError(
            f"D must have 3n rows (xyz per vertex, row 3*v + axis), got {D.shape[0]} rows"
        )
    if not np.isfinite(D).all():
        raise AttenuationError(f"D has {np.count_nonzero(~np.isfinite(D))} NaN/inf entries")
    return D


def _check_w(w1, m: int) -> np.ndarray:
    w = np.asarray(w1, dtype=np.float64)
    if w.shape != (m,):
        raise AttenuationError(f"w1 must have shape ({m},) for D with {m} shapes, got {w.shape}")
    if not np.isfinite(w).all():
        raise AttenuationError(f"w1 has NaN/inf at shapes {np.flatnonzero(~np.isfinite(w)).tolist()}")
    return w


def _solve_matrix(A: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, int]:
    """``A^-1 P`` by Cholesky, or the pseudo-inverse when ``A`` is singular; and rank(A)."""
    m = A.shape[0]
    scale = np.abs(np.diag(A)).max(initial=0.0)
    if scale > 0:
        try:
            c = scipy.linalg.cho_factor(A, check_finite=False)
            # a factor that exists can still be numerically singular: check conditioning
            d = np.abs(np.diag(c[0]))
            if d.min() > np.sqrt(m * np.finfo(float).eps) * d.max():
                return scipy.linalg.cho_solve(c, P, check_finite=False), m
        except np.linalg.LinAlgError:
            pass
    # rank-deficient D: all solutions of Eq. (3) give the same face; take the minimum-norm one
    pinv, rank = scipy.linalg.pinvh(A, return_rank=True, check_finite=False)
    return pinv @ P, int(rank)


def attenuate(D, w1, selected, alpha=None) -> np.ndarray:
    """Eq. (3) as the paper states it: ``w2 = (P + alpha Q)^-1 P w1``.

    Parameters
    ----------
    D : (3n, m) array
        Delta blendshape basis, row ``3*v + axis``.
    w1 : (m,) array
        The slider values (or slider change) the animator asked for.
    selected : 1-D int array
        Rows of ``D`` (coordinates) to keep still; see :func:`select_vertices`.
    alpha : float > 0, optional
        Weight of the selected term in Eq. (2).  Default ``#unselected /
        #selected`` rows (Section 5).

    Returns
    -------
    w2 : (m,) array

    This slices ``S`` and ``Sbar`` from ``D`` on every call (O(n m^2)); use
    :class:`Attenuator` for interactive use.
    """
    D = _check_D(D)
    n_rows, m = D.shape
    w1 = _check_w(w1, m)
    sel = check_selection(selected, n_rows)
    a = _check_alpha(alpha, sel.size, n_rows)
    mask = np.zeros(n_rows, dtype=bool)
    mask[sel] = True
    S, Sbar = D[mask], D[~mask]
    P = Sbar.T @ Sbar
    Q = S.T @ S
    M, _ = _solve_matrix(P + a * Q, P)
    return M @ w1


class Attenuator:
    """Eq. (3) at interactive speed: Gram precompute and per-selection caches.

    Parameters
    ----------
    model_or_D : BlendshapeModel or (3n, m) array
    cache_size : int
        How many (selection, alpha) solutions to keep.

    Examples
    --------
    >>> from repro.blendshapes import load_model, Attenuator, select_vertices
    >>> model = load_model("procedural")
    >>> att = Attenuator(model)
    >>> sel = select_vertices(model.regions["brow_middle"])
    >>> w2 = att.attenuate(model.weights(JawOpen=0.5), sel)      # doctest: +SKIP

    Cost: ``G = D^T D`` once, O(n m^2).  A new selection: ``Q = S^T S`` for its
    ``k`` rows, O(k m^2), then an m x m Cholesky solve.  A new alpha on a known
    selection: one m x m solve.  A slider move: ``M @ w1``, O(m^2).
    """

    def __init__(self, model_or_D, *, cache_size: int = 64):
        if isinstance(model_or_D, BlendshapeModel):
            self.model: BlendshapeModel | None = model_or_D
            D = model_or_D.D
        else:
            self.model = None
            D = _check_D(model_or_D)
        self.D = D
        self.n_rows, self.m = D.shape
        self.G = D.T @ D
        self.G.flags.writeable = False
        self._q: OrderedDict[bytes, np.ndarray] = OrderedDict()
        self._M: OrderedDict[tuple[bytes, float], tuple[np.ndarray, int]] = OrderedDict()
        self._cache_size = int(cache_size)
        self.rank: int | None = None  #: rank of ``P + alpha Q`` for the last solve (m = full)

    def __repr__(self) -> str:
        return f"Attenuator({self.n_rows // 3} vertices, {self.m} shapes, {len(self._M)} cached solves)"

    @staticmethod
    def _remember(cache: OrderedDict, key, value, size: int):
        cache[key] = value
        cache.move_to_end(key)
        while len(cache) > size:
            cache.popitem(last=False)
        return value

    def _selection(self, selected) -> tuple[np.ndarray, bytes]:
        sel = check_selection(selected, self.n_rows)
        return sel, sel.tobytes()

    def _Q(self, sel: np.ndarray, key: bytes) -> np.ndarray:
        Q = self._q.get(key)
        if Q is None:
            S = self.D[sel]
            Q = self._remember(self._q, key, S.T @ S, self._cache_size)
        else:
            self._q.move_to_end(key)
        return Q

    def default_alpha(self, selected) -> float:
        """Section 5's default alpha for this selection."""
        sel = check_selection(selected, self.n_rows)
        return default_alpha(sel.size, self.n_rows)

    def matrix(self, selected, alpha=None) -> np.ndarray:
        """``M = (P + alpha Q)^-1 P`` (m x m), so that ``w2 = M w1`` (Eq. 3); cached."""
        sel, key = self._selection(selected)
        a = _check_alpha(alpha, sel.size, self.n_rows)
        hit = self._M.get((key, a))
        if hit is not None:
            self._M.move_to_end((key, a))
            self.rank = hit[1]
            return hit[0]
        Q = self._Q(sel, key)
        if 2 * sel.size <= self.n_rows:
            P = self.G - Q  # O(m^2): the point of precomputing G
        else:  # most rows selected: the unselected slice is the smaller (and avoids cancellation)
            Sbar = np.delete(self.D, sel, axis=0)
            P = Sbar.T @ Sbar
        M, rank = _solve_matrix(P + a * Q, P)
        M.flags.writeable = False
        self._remember(self._M, (key, a), (M, rank), self._cache_size)
        self.rank = rank
        return M

    def attenuate(self, w1, selected, alpha=None) -> np.ndarray:
        """``w2`` for slider values (or a slider change) ``w1``: Eq. (3)."""
        M = self.matrix(selected, alpha)
        return M @ _check_w(w1, self.m)

    __call__ = attenuate

    def edit(self, w_base, w_target, selected, alpha=None) -> np.ndarray:
        """Final weights when the sliders move from ``w_base`` to ``w_target`` with attenuation on.

        The selection is made at ``w_base`` (the pose the animator wants to
        keep); the change ``w_target - w_base`` is attenuated (Section 5's
        workflow: select, adjust sliders, release): ``w_base + M (w_target - w_base)``.
        """
        w_base = _check_w(w_base, self.m)
        return w_base + self.attenuate(_check_w(w_target, self.m) - w_base, selected, alpha)

    def displacement(self, w) -> np.ndarray:
        """``D w`` as a flat (3n,) vector."""
        return self.D @ _check_w(w, self.m)

    def pose(self, w) -> np.ndarray:
        """Posed vertices ``f0 + D w`` (needs a model)."""
        if self.model is None:
            raise AttenuationError("pose() needs an Attenuator built from a BlendshapeModel")
        return self.model.f0 + self.displacement(w).reshape(-1, 3)

