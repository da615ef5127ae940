"""The aligned pose distance of Kovar et al., for one pair and for many candidates (Pronost et al., Section 3.2.2).

"A solution that we use, proposed by Kovar et al. [10] consists of minimizing the distance
between the two poses by tuning the alignment parameters of the two motions."

Kovar, Gleicher and Pighin, "Motion Graphs", SIGGRAPH 2002, Sec. 3.1
-------------------------------------------------------------------
For point clouds ``a_i`` and ``b_i`` (i = 1..P) with weights ``w_i`` (normalised here to
sum to 1), the distance is

    ``D(a, b)^2 = min over theta, x0, z0 of  sum_i w_i |a_i - T(b_i)|^2``,

where ``T`` rotates about the vertical axis by ``theta`` and translates by
``(x0, 0, z0)``: ``T(x, y, z) = (c x + s z + x0, y, -s x + c z + z0)`` with
``c = cos theta``, ``s = sin theta`` (the right-handed rotation about +y).  Derivation:
for fixed ``theta`` the optimal translation matches the weighted centroids,
``x0 = X - (c X' + s Z')``, ``z0 = Z - (-s X' + c Z')`` with ``X = sum w x``,
``X' = sum w x'`` and so on (``sum w = 1``).  With centred clouds the cost becomes
``sum w (y - y')^2 + H_a + H_b - 2 (c A + s B)`` where

    ``A = sum w (x x' + z z') - (X X' + Z Z')``,
    ``B = sum w (x z' - z x') - (X Z' - Z X')``,
    ``H_a = sum w (x^2 + z^2) - (X^2 + Z^2)``   (likewise ``H_b``),

which is minimal for ``(c, s)`` proportional to ``(A, B)``: ``theta = atan2(B, A)``
(Kovar et al.'s formula), and the minimum is

    ``D^2 = sum w (y - y')^2 + H_a + H_b - 2 sqrt(A^2 + B^2)``.

This closed form needs only dot products between the query and each candidate, so
:class:`AlignedPoseIndex` evaluates it for many candidate poses with one matrix product
(the per-candidate sums are precomputed).  ``D`` is the weighted root-mean-square
distance between the aligned clouds (metres for clouds in metres).  It is symmetric,
zero for identical poses, and invariant to rotating either pose about y and translating
it on the floor (checked by the tests).

:func:`aligned_distance` is the closed form for pose clouds broadcast against each other;
:class:`AlignedPoseIndex` holds the query-independent terms of many candidates, the form the
retrieval (:mod:`repro.motion.search.retrieval`) and the compiled search
(:mod:`repro.motion.search.kernel`) evaluate.  Pose clouds are those of
:mod:`repro.motion.body.pose_frames`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from repro.checks import as_bool, as_int, as_real_array, describe
from repro.errors import MotionError
from repro.motion.body.pose_frames import CHUNK, check_magnitude, float_poses, pose_weights

__all__ = ["aligned_distance", "AlignedPoseIndex"]


def _moments(p: np.ndarray, w: np.ndarray):
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    X, Z = x @ w, z @ w
    H = (x * x + z * z) @ w - (X * X + Z * Z)
    return x, y, z, X, Z, H


def aligned_distance(a, b, weights=None, *, return_transform: bool = False):
    """Kovar et al.'s aligned pose distance (weighted RMS, see the module docstring).

    Parameters
    ----------
    a, b : (..., P, 3) arrays
        Point clouds, broadcast against each other.
    weights : (P,) array, optional
        Non-negative point weights (normalised to sum 1); default uniform.
    return_transform : bool, default False
        Also return the transformation ``T`` applied to ``b``.

    Returns
    -------
    d : (...) array
        ``sqrt(min sum w |a - T(b)|^2)``.
    theta, x0, z0 : (...) arrays, only with ``return_transform``
        ``T(p) = rotate_y(p, theta) + (x0, 0, z0)`` maps ``b`` onto ``a``.
    """
    return_transform = as_bool(return_transform, "return_transform", error=MotionError)
    a = as_real_array(a, "pose cloud a", error=MotionError, finite=False)
    b = as_real_array(b, "pose cloud b", error=MotionError, finite=False)
    try:
        np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    except ValueError:
        raise MotionError(f"pose clouds a {a.shape} and b {b.shape} do not broadcast together") from None
    if a.ndim < 2 or b.ndim < 2 or a.shape[-1] != 3 or b.shape[-1] != 3 or a.shape[-2] != b.shape[-2]:
        raise MotionError(f"pose clouds must be (..., P, 3) with equal P, got {a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise MotionError("pose clouds contain NaN or inf")
    check_magnitude(a, "pose cloud a")
    check_magnitude(b, "pose cloud b")
    w = pose_weights(a.shape[-2], weights)
    xa, ya, za, Xa, Za, Ha = _moments(a, w)
    xb, yb, zb, Xb, Zb, Hb = _moments(b, w)
    A = (xa * xb + za * zb) @ w - (Xa * Xb + Za * Zb)
    B = (xa * zb - za * xb) @ w - (Xa * Zb - Za * Xb)
    dy = ((ya - yb) ** 2) @ w
    d2 = np.maximum(dy + Ha + Hb - 2.0 * np.hypot(A, B), 0.0)
    d = np.sqrt(d2)
    if not return_transform:
        return d
    theta = np.arctan2(B, A)
    c, s = np.cos(theta), np.sin(theta)
    x0 = Xa - (c * Xb + s * Zb)
    z0 = Za - (-s * Xb + c * Zb)
    return d, theta, x0, z0


@dataclass(eq=False)
class AlignedPoseIndex:
    """Many candidate poses, ready for one-query-to-all aligned distances.

    Precomputes everything of the closed form that does not depend on the query, so
    that :meth:`distances` costs one ``(N, 3P) @ (3P, 3)`` matrix product plus O(N)
    element-wise work.

    Parameters
    ----------
    points : (N, P, 3) array
        Candidate clouds, float32 or float64 (kept as :attr:`points`, not copied; None in a
        :meth:`subset`).  The closed-form terms are float64 whatever their dtype.
    weights : (P,) array, optional
        Point weights (normalised); default uniform.
    order : (n,) int array, optional
        Store the matrix terms of the poses ``order`` only, in that order (default: every
        pose, in order).  A :meth:`subset` whose rows are a run of consecutive entries of
        ``order`` is then a view, not a copy: the retriever orders the startable poses by
        (semantics, cluster, pose) (:func:`repro.motion.search.index_build.block_order`) so that its
        per-cluster and per-semantics candidate blocks share one array instead of one copy
        each (the 1,000x database: 4.6 M poses).  The terms of a pose outside ``order`` are
        recomputed from :attr:`points` when asked for (same values).
    """

    points: np.ndarray | None
    weights: np.ndarray | None = None
    order: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = float_poses(self.points, "candidate poses", allow_empty=True)
        self.points = p
        N, P, _ = p.shape
        self._P = P
        w = pose_weights(P, self.weights)
        self.weights = w
        self._N = N
        self._perm = None  # (a subset's) row -> stored row, when not the identity
        if self.order is None:
            self._pos = None
            stored = None
        else:
            if hasattr(self.order, "__len__") and not isinstance(self.order, np.ndarray) and len(self.order) > N:
                raise MotionError(f"order must be distinct pose indices in [0, {N}), got {len(self.order)} of them")
            stored = np.asarray(self.order)
            if stored.ndim != 1 or stored.dtype.kind not in "iu" or (stored.size and (
                    stored.min() < 0 or stored.max() >= N)) or np.unique(stored).size != stored.size:
                raise MotionError(f"order must be distinct pose indices in [0, {N}), got {describe(self.order)}")
            self.order = stored = stored.astype(np.intp)
            self._pos = np.full(N, -1, dtype=np.intp)
            self._pos[stored] = np.arange(stored.size)
        n = N if stored is None else stored.size
        # the stored poses' scalar terms X, Z, H, Y2 (4, n) and matrix terms, both in stored order (a subset
        # that is a run of ``order`` is a view of them); columns of M: [w x', w z', w y'] ->
        # M @ [[xa, -za, 0], [za, xa, 0], [0, 0, ya]].  Filled by chunks (float32 points are never copied
        # whole to float64); M is element-wise in each pose, the scalar terms are sums (chunks in pose order).
        self._T = np.empty((4, n))
        for a in range(0, N, CHUNK):  # the scalar terms by chunks of poses in pose order (see _pose_terms)
            t = np.stack(self._terms(p[a:a + CHUNK], want_m=False)[1:])
            if stored is None:
                self._T[:, a:a + CHUNK] = t
            else:
                at = self._pos[a:a + CHUNK]
                self._T[:, at[at >= 0]] = t[:, at >= 0]
        self._X, self._Z, self._H, self._Y2 = self._T
        self._M = np.empty((n, 3 * P))
        for a in range(0, n, CHUNK):
            self._M[a:a + CHUNK] = self._terms(p[a:a + CHUNK] if stored is None else p[stored[a:a + CHUNK]])[0]

    def _pose_terms(self, rows: np.ndarray) -> np.ndarray:
        """(4, r): ``X, Z, H, Y2`` of poses ``rows`` recomputed from :attr:`points` on the same chunks of
        poses as in the constructor (the sums go through BLAS, whose rounding may depend on the rows
        computed together: the same chunks give the same values as stored)."""
        out = np.empty((4, rows.size))
        ch = rows // CHUNK
        for c in np.unique(ch):
            a, sel = int(c) * CHUNK, ch == c
            out[:, sel] = np.stack(self._terms(self.points[a:a + CHUNK], want_m=False)[1:])[:, rows[sel] - a]
        return out

    def _terms(self, pts: np.ndarray, want_m: bool = True):
        """``(M rows or None, X, Z, H, Y2)`` of the clouds ``pts`` (n, P, 3), in float64."""
        w = self.weights
        x, y, z, X, Z, H = _moments(pts.astype(float, copy=False), w)
        M = None
        if want_m:
            P = self._P
            M = np.empty((x.shape[0], 3 * P))
            M[:, :P], M[:, P:2 * P], M[:, 2 * P:] = x * w, z * w, y * w
        return M, X, Z, H, (y * y) @ w

    def _rows_t(self, rows: np.ndarray) -> tuple:
        """``X, Z, H, Y2`` of poses ``rows`` (copies), from the stored ones (in stored order) or recomputed."""
        if self._pos is None:
            at = rows if self._perm is None else self._perm[rows]
            return self._X[at], self._Z[at], self._H[at], self._Y2[at]
        at = self._pos[rows]
        ok = at >= 0
        if ok.all():
            return tuple(self._T[:, at])
        out = np.empty((4, rows.size))
        out[:, ok] = self._T[:, at[ok]]
        out[:, ~ok] = self._pose_terms(rows[~ok])
        return tuple(out)

    def centroids_xz(self, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """``X, Z``: the weighted horizontal centroid of the candidates ``rows`` (default all), in the
        clouds' units (the translation part of the closed form, see the module docstring)."""
        rows = self._check_rows(rows)
        X, Z, _, _ = self._rows_t(rows)
        return X, Z

    def _check_rows(self, rows, name: str = "rows") -> np.ndarray:
        """Candidate rows: ``None`` (all), a boolean mask of length n or indices in ``0..n-1`` (intp), else
        :class:`MotionError` (a float, a string or an index out of range raised numpy's errors)."""
        n = self.n
        if rows is None:
            return np.arange(n)
        if isinstance(rows, np.ndarray) and rows.dtype.kind in "iu" and rows.ndim == 1:
            r = rows  # the retrieval's own gathers: no copy, only the range
        else:
            if isinstance(rows, range) and len(rows) > n:  # range(10**12) is not copied to be refused
                raise MotionError(f"{name} must be candidate indices in 0..{n - 1}, got {describe(rows)}")
            try:
                a = np.asarray(rows) if not isinstance(rows, (str, bytes)) else None
            except (TypeError, ValueError):
                a = None
            if a is None or a.ndim != 1:
                raise MotionError(f"{name} must be a 1-D array of candidate indices or a mask, got {describe(rows)}")
            if a.dtype.kind == "b":
                if a.size != n:
                    raise MotionError(f"{name}: a boolean mask of length {a.size}, not {n}")
                return np.flatnonzero(a)
            r = as_real_array(a, name, error=MotionError, integer=True, ndim=1)
        if r.size and (r.min() < 0 or r.max() >= n):
            raise MotionError(f"{name} must be candidate indices in 0..{n - 1}, got {int(r.min())}..{int(r.max())}")
        return r.astype(np.intp, copy=False)

    def _rows_m(self, rows: np.ndarray) -> np.ndarray:
        """The matrix terms of poses ``rows`` (a copy), from the stored ones or recomputed."""
        if self._pos is None:
            return self._M[rows] if self._perm is None else self._M[self._perm[rows]]
        at = self._pos[rows]
        ok = at >= 0
        if ok.all():
            return self._M[at]
        out = np.empty((rows.size, self._M.shape[1]))
        out[ok] = self._M[at[ok]]
        out[~ok] = self._terms(self.points[rows[~ok]])[0]
        return out

    def subset(self, rows) -> AlignedPoseIndex:
        """An index of the candidates ``rows`` only (``points`` is None).

        A view of the stored terms when ``rows`` are consecutive entries of ``order``
        (see the class), in any order (the subset then keeps the permutation to its rows:
        its distances are in the order of ``rows``); else contiguous copies.
        """
        if rows is None:
            raise MotionError("rows must be candidate indices or a mask, got None")
        rows = self._check_rows(rows)
        out = object.__new__(AlignedPoseIndex)
        out.points = None
        out.order = None
        out._pos = None
        out._perm = None
        out.weights = self.weights
        out._P = self._P
        out._T = None
        out._N = int(rows.size)
        at = None if self._pos is None or rows.size == 0 else self._pos[rows]
        lo = None if at is None else int(at.min())
        if (at is not None and lo >= 0 and int(at.max()) - lo == rows.size - 1
                and np.bincount(at - lo, minlength=rows.size).max() == 1):  # a run of ``order``, permuted
            sl = slice(lo, lo + rows.size)
            out._M = self._M[sl]
            out._X, out._Z, out._H, out._Y2 = self._T[0, sl], self._T[1, sl], self._T[2, sl], self._T[3, sl]
            if np.any(np.diff(at) != 1):
                out._perm = at - lo
        else:
            out._M = np.ascontiguousarray(self._rows_m(rows))
            out._X, out._Z, out._H, out._Y2 = self._rows_t(rows)
        return out

    @property
    def n(self) -> int:
        """Number of candidate poses N."""
        return self._N

    @property
    def n_points(self) -> int:
        """Number of points P' of a pose cloud (a query is a ``(P', 3)`` array)."""
        return self._P

    def terms(self) -> tuple[np.ndarray, ...]:
        """``(M, X, Z, H, Y2, perm)``: the closed form's stored terms (views) and the stored entry of each
        candidate (``perm[i]``), for a compiled reader of :meth:`distances` (the exact retrieval's)."""
        if self._pos is not None:
            raise MotionError("terms() needs an index stored in candidate order (a subset, or one built without order)")
        perm = np.arange(self._N, dtype=np.intp) if self._perm is None else self._perm.astype(np.intp, copy=False)
        return self._M, self._X, self._Z, self._H, self._Y2, perm

    def query_matrix(self, q: np.ndarray) -> tuple[np.ndarray, float, float, float, float]:
        """The query-dependent parts: ``(3P, 3)`` matrix and ``X, Z, H, sum w y^2`` of the query."""
        q = self._query(q)
        P = self._P
        w = self.weights
        xa, ya, za = q[:, 0], q[:, 1], q[:, 2]
        Q = np.zeros((3 * P, 3))
        Q[:P, 0], Q[P:2 * P, 0] = xa, za
        Q[:P, 1], Q[P:2 * P, 1] = -za, xa
        Q[2 * P:, 2] = ya
        Xa, Za = float(xa @ w), float(za @ w)
        Ha = float((xa * xa + za * za) @ w) - (Xa * Xa + Za * Za)
        return Q, Xa, Za, Ha, float((ya * ya) @ w)

    def _query(self, q) -> np.ndarray:
        """A query pose: a finite float (P, 3) array, else :class:`MotionError`."""
        q = as_real_array(q, "query pose", error=MotionError, finite=False)
        if q.shape != (self._P, 3):
            raise MotionError(f"query pose must be ({self._P}, 3), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise MotionError("query pose contains NaN or inf")
        return check_magnitude(q, "query pose")

    def distances(self, q: np.ndarray, rows: np.ndarray | None = None, *, return_transform: bool = False,
                  prepared=None):
        """Aligned distances from query ``q`` (P, 3) to the candidates ``rows`` (default all).

        Parameters
        ----------
        q : (P, 3) array
        rows : int array, optional
            Candidate subset (gathered: prefer a :meth:`subset` for repeated use).
        return_transform : bool
            Also return ``theta, x0, z0`` (n,) of the transformation mapping each
            candidate onto ``q`` (as in :func:`aligned_distance` with ``a = q``).
        prepared : tuple, optional
            :meth:`query_matrix` of ``q`` when already computed.
        """
        Q, Xa, Za, Ha, Ya2 = self.query_matrix(q) if prepared is None else prepared
        return_transform = as_bool(return_transform, "return_transform", error=MotionError)
        perm = None
        if rows is None and self._pos is None:
            # every candidate, in stored order (a permuted subset's results are permuted at the end:
            # element-wise, so the same values as permuting the terms first)
            X, Z, H, Y2 = self._X, self._Z, self._H, self._Y2
            R = self._M @ Q
            perm = self._perm
        else:
            rows = self._check_rows(rows)
            M = self._rows_m(rows)
            X, Z, H, Y2 = self._rows_t(rows)
            R = M @ Q
        A = R[:, 0] - (Xa * X + Za * Z)
        B = R[:, 1] - (Xa * Z - Za * X)
        d2 = Ya2 - 2.0 * R[:, 2] + Y2 + Ha + H - 2.0 * np.hypot(A, B)
        d = np.sqrt(np.maximum(d2, 0.0))
        if not return_transform:
            return d if perm is None else d[perm]
        theta = np.arctan2(B, A)
        c, s = np.cos(theta), np.sin(theta)
        out = d, theta, Xa - (c * X + s * Z), Za - (-s * X + c * Z)
        return out if perm is None else tuple(o[perm] for o in out)

    def direct_distance(self, q: np.ndarray, row: int) -> tuple[float, float, float, float]:
        """``(d, theta, x0, z0)`` of query ``q`` (P, 3) to stored pose ``row``, ``d`` summed directly.

        The transform is the closed form's (the terms of :meth:`query_matrix` and of the stored
        pose, for this one pair); ``d = sqrt(sum w |q - T(p)|^2)`` is then summed over the
        points instead of expanded, so it keeps full precision where the closed form cancels
        (``d2`` of two near-equal poses is the difference of terms ~``H``: ``d`` off by ~1e-8
        sqrt(H)).  Needs :attr:`points` (not a :meth:`subset`).
        """
        if self.points is None:
            raise MotionError("direct_distance needs the candidate clouds (this index is a subset)")
        # one pair, in plain dot products: :meth:`distances` on one row costs ~5x more (its matrix
        # product and per-array steps, measured ~115 us against ~25 us); the same terms, rounded in
        # another order (a few ulps of theta)
        row = as_int(row, "row (candidate index)", 0, self.n - 1, error=MotionError)
        q = self._query(q)
        p = self.points[row].astype(float)
        w = self.weights
        pw = p * w[:, None]
        S = q.T @ pw  # S[a, b] = sum w q_a p_b
        Xa, _, Za = (w @ q).tolist()
        X, _, Z = pw.sum(axis=0).tolist()
        A = (S[0, 0] + S[2, 2]).item() - (Xa * X + Za * Z)
        B = (S[0, 2] - S[2, 0]).item() - (Xa * Z - Za * X)
        theta = math.atan2(B, A)
        c, s = math.cos(theta), math.sin(theta)
        x0, z0 = Xa - (c * X + s * Z), Za - (-s * X + c * Z)
        # q - T(p), T(p) = rotate_y(p, theta) + (x0, 0, z0) as a row-vector product
        diff = q - (p @ np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]) + [x0, 0.0, z0])
        return float(np.sqrt(np.einsum("pk,pk,p->", diff, diff, w))), theta, x0, z0
