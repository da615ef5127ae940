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
that may move (``P = 0``) and is refused.  A system that cannot be solved at
all raises :class:`~repro.errors.AttenuationError`, never numpy's ``LinAlgError``.

Scale
-----
Eq. (3) does not depend on the scale of ``D``: for ``D -> s D``, ``P`` and ``Q``
scale by ``s^2`` and ``M = (P + alpha Q)^-1 P`` does not change.  The
arithmetic does: ``P`` overflows for ``|D| ~ 1e155`` and underflows for ``|D| ~
1e-160``.  Both implementations therefore scale ``D`` by a power of two (exact)
to ``max |D|`` in [0.5, 1) before forming ``P`` and ``Q`` whenever ``max |D|``
is outside ``2^-100 .. 2^100`` (so a face in millimetres, metres or light years
gives the same ``w2``, to about 1e-14, from 1e-300 to 1e300; any sensibly
scaled ``D`` is used as it is).  ``Attenuator.G`` is then the Gram matrix of the
scaled ``D`` (``Attenuator.scale_exponent`` tells the power of two).

Arguments are checked (:func:`repro.blendshapes.model.as_real_array`):
strings, ``None``, objects, booleans, complex or non-finite values, floats where
indices are meant and wrong shapes raise :class:`~repro.errors.AttenuationError`
or :class:`~repro.errors.SelectionError` naming the argument.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable

import math

import numpy as np
import scipy.linalg

from repro.checks import abs_max, as_int, as_real, as_real_array, describe
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
    if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool) and 0 <= int(axis) < 3:
        return int(axis)
    raise SelectionError(f"unknown axis {axis!r}; expected one of 'x', 'y', 'z' (or 0, 1, 2)")


def _axes(axes) -> list[int]:
    if isinstance(axes, str):
        axes = list(axes)
    elif not isinstance(axes, (list, tuple, np.ndarray, range)) or (isinstance(axes, np.ndarray) and axes.ndim != 1):
        raise SelectionError(f"axes must be a string like 'xy' or a list of axes, got {describe(axes)}")
    idx = [_axis_index(a) for a in axes]
    if not idx:
        raise SelectionError("no axis given; expected some of 'x', 'y', 'z'")
    if len(set(idx)) != len(idx):
        raise SelectionError(f"axis repeated in {axes!r}")
    return sorted(idx)


#: Largest vertex count a selection helper accepts (3 x 10^8 rows of D, far above any face model).
MAX_VERTICES = 100_000_000


def _n_vertices(n_vertices, *, optional: bool = True) -> int | None:
    if n_vertices is None and optional:
        return None
    return as_int(n_vertices, "n_vertices", error=SelectionError, lo=1, hi=MAX_VERTICES)


def _vertex_ids(vertices, n_vertices: int | None) -> np.ndarray:
    n_vertices = _n_vertices(n_vertices)
    v = as_real_array(vertices, "vertex ids", error=SelectionError, integer=True)
    if v.ndim == 0:
        v = v.reshape(1)
    if v.ndim != 1:
        raise SelectionError(f"vertex ids must be a 1-D integer array, got shape {v.shape}")
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
    n_vertices = _n_vertices(n_vertices)
    if isinstance(pairs, (str, bytes)) or not isinstance(pairs, Iterable) or (
        isinstance(pairs, np.ndarray) and pairs.ndim == 0  # iterable by type, not by value
    ):
        raise SelectionError(f"expected an iterable of (vertex, axis) pairs, got {describe(pairs)}")
    rows = []
    for p in pairs:
        try:
            v, axis = p
        except (TypeError, ValueError):
            raise SelectionError(f"expected (vertex, axis) pairs, got {p!r}") from None
        if (
            not isinstance(v, (int, np.integer))
            or isinstance(v, (bool, np.bool_))
            or v < 0
            or v >= (MAX_VERTICES if n_vertices is None else n_vertices)
        ):
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
    return np.arange(_axis_index(axis), 3 * _n_vertices(n_vertices, optional=False), 3, dtype=np.int64)


def check_selection(selected, n_rows: int) -> np.ndarray:
    """``selected`` as a sorted int64 array of distinct rows in ``0..n_rows-1``.

    Raises :class:`~repro.errors.SelectionError` for an empty, repeated,
    out-of-range, non-integer or multi-dimensional selection, and for one that
    selects every row (then nothing may move and ``P = 0``).
    """
    n_rows = as_int(n_rows, "n_rows", error=SelectionError, lo=1)
    s = as_real_array(selected, "selected (row indices of D)", error=SelectionError, integer=True)
    if s.ndim != 1:
        raise SelectionError(f"selected must be a 1-D array of row indices of D, got shape {s.shape}")
    if s.size == 0:
        raise SelectionError("the selection is empty: select at least one coordinate")
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
    n_selected = as_int(n_selected, "n_selected", error=SelectionError)
    n_rows = as_int(n_rows, "n_rows", error=SelectionError)
    if n_selected <= 0 or n_selected >= n_rows:
        raise SelectionError(f"cannot form the default alpha with {n_selected} of {n_rows} rows selected")
    return (n_rows - n_selected) / n_selected


def check_alpha(alpha, n_selected: int, n_rows: int) -> float:
    if alpha is None:
        return default_alpha(n_selected, n_rows)
    try:
        a = as_real(alpha, "alpha", error=AttenuationError, finite=False)
    except AttenuationError:
        a = float("nan")
    if not math.isfinite(a) or a <= 0:
        raise AttenuationError(f"alpha must be a finite number > 0 (Eq. 2), got {describe(alpha)}")
    return a


def check_D(D) -> np.ndarray:
    D = as_real_array(D, "D", error=AttenuationError, finite=False)
    if D.ndim != 2 or D.shape[0] == 0 or D.shape[1] == 0:
        raise AttenuationError(f"D must be a non-empty 3n x m matrix, got shape {D.shape}")
    if D.shape[0] % 3:
        raise AttenuationError(
            f"D must have 3n rows (xyz per vertex, row 3*v + axis), got {D.shape[0]} rows"
        )
    if not np.isfinite(D).all():
        raise AttenuationError(f"D has {np.count_nonzero(~np.isfinite(D))} NaN/inf entries")
    return D


def check_w_max(w1, m: int, name: str = "w1") -> tuple[np.ndarray, float]:
    """``w1`` as a finite float vector of length ``m``, and ``max |w1|`` (one reduction checks both)."""
    if type(w1) is np.ndarray and w1.dtype == np.float64:  # the slider-move hot path
        w = w1
    else:
        w = as_real_array(w1, name, error=AttenuationError, finite=False)
    if w.shape != (m,):
        raise AttenuationError(f"{name} must have shape ({m},) for D with {m} shapes, got {w.shape}")
    wmax = float(np.abs(w).max(initial=0.0))
    if not wmax <= _FMAX:  # NaN or inf somewhere
        raise AttenuationError(f"{name} has NaN/inf at shapes {np.flatnonzero(~np.isfinite(w)).tolist()}")
    return w, wmax


def check_w(w1, m: int, name: str = "w1") -> np.ndarray:
    return check_w_max(w1, m, name)[0]


_FMAX = float(np.finfo(np.float64).max)


def _matvec(A: np.ndarray, amax: float, x: np.ndarray, xmax: float, what: str) -> np.ndarray:
    """``A @ x``; when the bound ``max|A| max|x| n`` allows overflow, refuse a non-finite result."""
    if amax * xmax * x.size < 1e300:  # cannot overflow: the hot path, no errstate needed
        return A @ x
    with np.errstate(over="ignore", invalid="ignore"):
        y = A @ x
    return finite_result(y, what)


def finite_result(x: np.ndarray, what: str) -> np.ndarray:
    if not np.isfinite(x).all():
        raise AttenuationError(f"{what} overflows float64 (the weights or D are too large)")
    return x


# Eq. (3) is invariant under D -> s D (P and Q scale by s^2, M = (P + alpha Q)^-1 P does not), but
# P and Q overflow for |D| ~ 1e155 and underflow for |D| ~ 1e-160.  D is therefore scaled by a power
# of two (exact, no rounding) to max |D| in [0.5, 1) before the Gram matrices are formed, unless max
# |D| is already within 2^-_SAFE_EXP .. 2^_SAFE_EXP, where nothing overflows or loses precision.
_SAFE_EXP = 100
_GRAM_BLOCK = 1 << 16  # rows per block when a scaled Gram matrix is accumulated (bounded extra memory)


def scale_exponent(D: np.ndarray, top: float | None = None) -> int:
    """``e`` such that ``D * 2**-e`` is well scaled for Eq. (3): 0 when ``D`` already is (``top`` = max |D|)."""
    top = abs_max(D) if top is None else top
    if top == 0.0:
        return 0
    e = int(np.frexp(top)[1])
    return 0 if -_SAFE_EXP <= e <= _SAFE_EXP else e


def scaled(X: np.ndarray, e: int) -> np.ndarray:
    return X if e == 0 else np.ldexp(X, -e)


def _gram(X: np.ndarray, e: int) -> np.ndarray:
    """``(X 2^-e)^T (X 2^-e)``, in row blocks when scaling is needed (no full copy of ``X``)."""
    if e == 0:
        return X.T @ X
    G = np.zeros((X.shape[1], X.shape[1]))
    for i in range(0, X.shape[0], _GRAM_BLOCK):
        B = np.ldexp(X[i : i + _GRAM_BLOCK], -e)
        G += B.T @ B
    return G


def _solve_matrix(A: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, int]:
    """``A^-1 P`` by Cholesky, or the pseudo-inverse when ``A`` is singular; and rank(A).

    Never lets numpy/scipy's ``LinAlgError`` out: a system that cannot be solved
    at all (non-finite entries, an SVD that does not converge) is an
    :class:`~repro.errors.AttenuationError`.
    """
    m = A.shape[0]
    if not (np.isfinite(A).all() and np.isfinite(P).all()):
        raise AttenuationError("P + alpha Q of Eq. (3) has NaN/inf entries: D or alpha is out of range")
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
    try:
        pinv, rank = scipy.linalg.pinvh(A, return_rank=True, check_finite=False)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise AttenuationError(f"Eq. (3) cannot be solved: P + alpha Q is singular and its pseudo-inverse failed ({e})") from None
    M = pinv @ P
    if not np.isfinite(M).all():
        raise AttenuationError("Eq. (3) cannot be solved: the solution of the singular system is not finite")
    return M, int(rank)


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
    D = check_D(D)
    n_rows, m = D.shape
    w1 = check_w(w1, m)
    sel = check_selection(selected, n_rows)
    a = check_alpha(alpha, sel.size, n_rows)
    mask = np.zeros(n_rows, dtype=bool)
    mask[sel] = True
    e = scale_exponent(D)  # Eq. (3) does not depend on the scale of D; the arithmetic does
    S, Sbar = scaled(D[mask], e), scaled(D[~mask], e)
    P = Sbar.T @ Sbar
    Q = S.T @ S
    with np.errstate(over="ignore", invalid="ignore"):
        A = P + a * Q  # an inf here (alpha ~ 1e300) is refused by _solve_matrix
    M, _ = _solve_matrix(A, P)
    return _matvec(M, float(np.abs(M).max()), w1, float(np.abs(w1).max()), "w2 = M w1")


#: Largest ``cache_size`` an :class:`Attenuator` (or a DirectManipulator) accepts (each entry holds an m x m matrix).
MAX_CACHE_SIZE = 100_000


def check_cache_size(cache_size) -> int:
    """``cache_size`` of the caches here: an integer in ``0..MAX_CACHE_SIZE`` (0 keeps nothing)."""
    return as_int(cache_size, "cache_size", error=AttenuationError, lo=0, hi=MAX_CACHE_SIZE)


class Attenuator:
    """Eq. (3) at interactive speed: Gram precompute and per-selection caches.

    Parameters
    ----------
    model_or_D : BlendshapeModel or (3n, m) array
    cache_size : int
        How many (selection, alpha) solutions to keep, ``0..MAX_CACHE_SIZE``
        (0 keeps none: every call solves).  Each holds three m x m matrices: ``M`` and, for
        the bounded solve (:meth:`system`), ``A = P + alpha Q`` and ``P``.

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
        self._cache_size = check_cache_size(cache_size)
        if isinstance(model_or_D, BlendshapeModel):
            self.model: BlendshapeModel | None = model_or_D
            D = model_or_D.D
        else:
            self.model = None
            D = check_D(model_or_D)
        self.D = D
        self.n_rows, self.m = D.shape
        self.abs_max = model_or_D.abs_max[0] if self.model is not None else abs_max(D)
        #: ``D`` is used as ``D * 2**-scale_exponent`` in the Gram matrices (0 for any sensibly scaled D)
        self.scale_exponent = scale_exponent(D, self.abs_max)
        self.G = _gram(D, self.scale_exponent)  #: ``(D 2^-e)^T (D 2^-e)``; = ``D^T D`` when ``e = 0``
        self.G.flags.writeable = False
        self._q: OrderedDict[bytes, np.ndarray] = OrderedDict()
        # (selection, alpha) -> (M, rank, max |M|, A = P + alpha Q, P)
        self._M: OrderedDict[tuple[bytes, float], tuple] = OrderedDict()
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
            S = scaled(self.D[sel], self.scale_exponent)
            Q = self._remember(self._q, key, S.T @ S, self._cache_size)
        else:
            self._q.move_to_end(key)
        return Q

    def selection_gram(self, selected) -> np.ndarray:
        """``Q = S^T S`` (m x m, of the scaled ``D``) for a selection of rows; cached, read-only.

        With :attr:`G` it gives the Gram form of any quadratic in ``S D w``
        (:mod:`repro.blendshapes.bounded`, :mod:`repro.blendshapes.manipulation`).
        """
        sel, key = self._selection(selected)
        Q = self._Q(sel, key)
        Q.flags.writeable = False
        return Q

    def system(self, selected, alpha=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, P, M)`` of Eq. (3): ``A = P + alpha Q``, ``P = Sbar^T Sbar`` (scaled ``D``), ``M = A^-1 P``; cached.

        Eq. (2) is ``u^T A u - 2 u^T P w1 + const`` in ``u = w2``: the Gram form
        the bounded solve (:func:`repro.blendshapes.bounded.bounded_attenuate`) minimises.
        """
        hit = self._matrix(selected, alpha)
        return hit[3], hit[4], hit[0]

    def default_alpha(self, selected) -> float:
        """Section 5's default alpha for this selection."""
        sel = check_selection(selected, self.n_rows)
        return default_alpha(sel.size, self.n_rows)

    def matrix(self, selected, alpha=None) -> np.ndarray:
        """``M = (P + alpha Q)^-1 P`` (m x m), so that ``w2 = M w1`` (Eq. 3); cached."""
        return self._matrix(selected, alpha)[0]

    def _matrix(self, selected, alpha) -> tuple:
        """``(M, rank, max |M|, A, P)`` for a selection and alpha, from the cache or solved."""
        sel, key = self._selection(selected)
        a = check_alpha(alpha, sel.size, self.n_rows)
        hit = self._M.get((key, a))
        if hit is not None:
            self._M.move_to_end((key, a))
            self.rank = hit[1]
            return hit
        Q = self._Q(sel, key)
        if 2 * sel.size <= self.n_rows:
            P = self.G - Q  # O(m^2): the point of precomputing G
        else:  # most rows selected: the unselected slice is the smaller (and avoids cancellation)
            Sbar = scaled(np.delete(self.D, sel, axis=0), self.scale_exponent)
            P = Sbar.T @ Sbar
        with np.errstate(over="ignore", invalid="ignore"):
            A = P + a * Q  # an inf here (alpha ~ 1e300) is refused by _solve_matrix
        M, rank = _solve_matrix(A, P)
        M.flags.writeable = False
        A.flags.writeable = False
        P.flags.writeable = False
        hit = (M, rank, float(np.abs(M).max(initial=0.0)), A, P)
        self._remember(self._M, (key, a), hit, self._cache_size)
        self.rank = rank
        return hit

    def attenuate(self, w1, selected, alpha=None) -> np.ndarray:
        """``w2`` for slider values (or a slider change) ``w1``: Eq. (3)."""
        M, _, mmax = self._matrix(selected, alpha)[:3]
        w, wmax = check_w_max(w1, self.m)
        return _matvec(M, mmax, w, wmax, "w2 = M w1")

    __call__ = attenuate

    def edit(self, w_base, w_target, selected, alpha=None) -> np.ndarray:
        """Final weights when the sliders move from ``w_base`` to ``w_target`` with attenuation on.

        The selection is made at ``w_base`` (the pose the animator wants to
        keep); the change ``w_target - w_base`` is attenuated (Section 5's
        workflow: select, adjust sliders, release): ``w_base + M (w_target - w_base)``.
        """
        w_base, bmax = check_w_max(w_base, self.m, "w_base")
        w_target, tmax = check_w_max(w_target, self.m, "w_target")
        M, _, mmax = self._matrix(selected, alpha)[:3]
        dmax = bmax + tmax  # bounds max |w_target - w_base|
        if dmax < 1e300 and mmax * dmax * self.m + bmax < 1e300:  # nothing can overflow: the hot path
            return w_base + M @ (w_target - w_base)
        with np.errstate(over="ignore", invalid="ignore"):
            dw = finite_result(w_target - w_base, "w_target - w_base")
            return finite_result(w_base + M @ dw, "w_base + w2")

    def displacement(self, w) -> np.ndarray:
        """``D w`` as a flat (3n,) vector."""
        w, wmax = check_w_max(w, self.m, "w")
        return _matvec(self.D, self.abs_max, w, wmax, "the displacement D w")

    def pose(self, w) -> np.ndarray:
        """Posed vertices ``f0 + D w`` (needs a model)."""
        if self.model is None:
            raise AttenuationError("pose() needs an Attenuator built from a BlendshapeModel")
        d = self.displacement(w).reshape(-1, 3)
        with np.errstate(over="ignore", invalid="ignore"):
            f = self.model.f0 + d
        return finite_result(f, "the pose f0 + D w")

