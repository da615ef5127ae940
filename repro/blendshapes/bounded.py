"""Bounded attenuation: Eq. (2) of Lewis et al. 2005 with the sliders kept in their range.

Eq. (3) minimises Eq. (2), ``alpha ||S w2||^2 + ||Sbar (w2 - w1)||^2``, without
constraints, so the attenuated weights can leave the slider range: on the ICT
face, with six vertices under the left eye selected and ``eyeSquint_L/R``,
``noseSneer_L/R`` at 0.7, Eq. (3) puts ``eyeSquint_L`` below zero (and other
shapes further).  A rig clamps such values silently, which undoes part of the
attenuation.  :func:`bounded_attenuate` and :func:`bounded_edit` minimise
Eq. (2) subject to ``lo <= w <= hi`` instead.

In the Gram form of :class:`~repro.blendshapes.attenuation.Attenuator`, Eq. (2)
is the m-dimensional box-constrained quadratic program

    min_u  1/2 u^T A u - u^T g,   lo <= u <= hi,   A = P + alpha Q,  g = P w1,

solved by :func:`solve_box_qp`: when the unconstrained solution ``M w1`` of
Eq. (3) is inside the box it is returned as is (one extra comparison per slider
move); otherwise a primal active-set method starts from its clamped value and
solves one free-set linear system per step (each step fixes or frees one shape).
``scipy.optimize.lsq_linear`` on a factor of ``A`` gives the same minimiser but
costs milliseconds per call (its set-up dominates at m = 57); the active set is
used for speed and ``lsq_linear`` as the fallback for a singular ``A`` (a
rank-deficient ``D``) and as the reference in the tests (``method="lsq_linear"``).
Speed per slider move, as ratios against Eq. (3)'s mat-vec in the same process:
:func:`repro.bench.attenuation.bench_bounded`.

Bounds
------
``lo`` and ``hi`` are numbers or length-m arrays (per-slider ranges), ``-inf``
/ ``inf`` allowed for one-sided ranges; ``lo > hi``, NaN, ``lo = inf`` or ``hi =
-inf`` raise :class:`~repro.errors.AttenuationError`.  The *requested* weights
(``w1``, ``w_base``, ``w_target``) may lie outside the range: the request is
only the right-hand side of Eq. (2), and the result is always inside the range
(the problem is feasible for every ``lo <= hi``).  In :func:`bounded_edit` the
bound is on the final weights ``w_base + u``, as a rig applies it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import lapack

from repro.blendshapes.attenuation import Attenuator, check_w_max
from repro.checks import abs_max, as_bool, as_choice, as_int, as_real_array, check_alloc, describe
from repro.errors import AttenuationError

__all__ = [
    "BoxQPResult",
    "bounded_attenuate",
    "bounded_edit",
    "check_bounds",
    "check_psd",
    "clamped_edit",
    "solve_box_qp",
]


class BoxQPResult(NamedTuple):
    """Solution of :func:`solve_box_qp`."""

    x: np.ndarray
    iterations: int  #: active-set steps (0: the unconstrained solution was inside the box)
    method: str  #: "unconstrained", "active-set" or "lsq_linear"
    n_at_bounds: int  #: coordinates of x at a bound


def check_bounds(lo, hi, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``lo`` and ``hi`` as float arrays of length ``m`` with ``lo <= hi``, or an AttenuationError."""
    m = as_int(m, "m (number of shapes)", lo=0, error=AttenuationError)
    check_alloc(16 * m, "the bounds lo and hi", error=AttenuationError)
    out = []
    for name, b in (("lo", lo), ("hi", hi)):
        a = as_real_array(b, name, error=AttenuationError, finite=False)
        if a.ndim == 0:
            a = np.full(m, float(a))
        if a.shape != (m,):
            raise AttenuationError(f"{name} must be a number or have shape ({m},) (one per shape), got {a.shape}")
        if np.isnan(a).any():
            raise AttenuationError(f"{name} has NaN at shapes {np.flatnonzero(np.isnan(a))[:10].tolist()}")
        out.append(a)
    lo, hi = out
    if (lo == np.inf).any() or (hi == -np.inf).any():
        raise AttenuationError("lo must be < inf and hi > -inf: the slider range would be empty")
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        i = int(bad[0])
        raise AttenuationError(f"lo > hi at shapes {bad[:10].tolist()} (e.g. lo {lo[i]} > hi {hi[i]}): empty slider range")
    return lo, hi


def _lsq_linear(A: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The box QP through ``scipy.optimize.lsq_linear`` on a factor of ``A`` (any PSD ``A``)."""
    from scipy.optimize import lsq_linear

    lam, V = np.linalg.eigh(A)
    keep = lam > max(lam.max(initial=0.0), 0.0) * A.shape[0] * np.finfo(float).eps
    if not keep.any():
        return np.clip(np.zeros_like(g), lo, hi)
    s = np.sqrt(lam[keep])
    R = s[:, None] * V[:, keep].T  # R^T R = A (on its range)
    c = (V[:, keep].T @ g) / s  # R^T c = g, since g lies in the range of A
    x = lsq_linear(R, c, bounds=(lo, hi), method="bvls", tol=1e-13, lsq_solver="exact").x
    return np.clip(x, lo, hi)


def _free_solve(A, g, x, F, W):
    """Solve ``A_FF y = g_F - A_FW x_W`` by Cholesky (LAPACK ``dposv``); None when not positive definite."""
    f = np.flatnonzero(F)
    Af = A[f]
    rhs = g[f] - Af[:, W] @ x[W] if W.any() else g[f]
    _, y, info = lapack.dposv(Af[:, f], rhs, lower=1, overwrite_a=1, overwrite_b=0)
    if info != 0 or not np.isfinite(y).all():
        return None
    return y


def _pdas(A, g, lo, hi, x, c, max_iter):
    """Primal-dual active set (Hintermueller, Ito and Kunisch 2003): a few free-set solves."""
    m = g.shape[0]
    L = x <= lo
    U = (x >= hi) & ~L
    for it in range(1, max_iter + 1):
        W = L | U
        F = ~W
        x = np.where(L, lo, np.where(U, hi, x))
        if F.any():
            y = _free_solve(A, g, x, F, W)
            if y is None:
                return None, it
            x[F] = y
        lam = g - A @ x  # minus the gradient; 0 on the free set up to rounding
        lam[F] = 0.0
        z = x + lam / c
        L_new = z < lo
        U_new = (z > hi) & ~L_new
        if (L_new == L).all() and (U_new == U).all():
            return x, it
        L, U = L_new, U_new
    return None, max_iter if m else 0


def _primal_active_set(A, g, lo, hi, x, at_lo, at_hi, gtol, xtol, max_iter):
    """Primal active set from a feasible ``x``: one bound fixed or freed per free-set solve."""
    m = g.shape[0]
    fixed_for_good = lo == hi
    for it in range(1, max_iter + 1):
        W = at_lo | at_hi
        F = ~W
        if F.any():
            y = _free_solve(A, g, x, F, W)
            if y is None:
                return None, it
            lf, hf, xf = lo[F], hi[F], x[F]
            inside = (y >= lf - xtol[F]) & (y <= hf + xtol[F])
        else:
            inside = np.ones(0, dtype=bool)
        if inside.all():
            if F.any():
                x[F] = np.clip(y, lo[F], hi[F])
            grad = A @ x - g  # multipliers of the fixed coordinates
            wrong = np.where(at_lo & ~fixed_for_good, -grad, 0.0) + np.where(at_hi & ~fixed_for_good, grad, 0.0)
            j = int(np.argmax(wrong)) if m else 0
            if m == 0 or wrong[j] <= gtol:
                return x, it
            at_lo[j] = at_hi[j] = False
            continue
        # step from x towards y until the first free coordinate meets a bound; fix it there
        d = y - xf
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d < 0, (lf - xf) / d, np.where(d > 0, (hf - xf) / d, np.inf))
        t = np.maximum(t, 0.0)
        k = int(np.argmin(t))
        step = min(1.0, float(t[k]))
        xf = xf + step * d
        idx = np.flatnonzero(F)
        hit = (~inside) & (t <= step * (1 + 1e-12))
        hit[k] = True
        low_hit, high_hit = hit & (d < 0), hit & (d > 0)
        xf[low_hit] = lf[low_hit]
        xf[high_hit] = hf[high_hit]
        x[F] = xf
        at_lo[idx[low_hit]] = True
        at_hi[idx[high_hit]] = True
    return None, max_iter


def solve_box_qp(A, g, lo, hi, x0=None, *, max_iter: int | None = None, method: str = "auto") -> BoxQPResult:
    """``min 1/2 x^T A x - g^T x`` subject to ``lo <= x <= hi``, for a symmetric PSD ``A``.

    ``x0``: the unconstrained minimiser when known (Eq. 3's ``M w1``; solved here
    when None); returned as is when inside the box.  Otherwise, from
    ``clip(x0)``: the primal-dual active-set method (Hintermueller, Ito and
    Kunisch, SIAM J. Optim. 13(3), 2003; typically a handful of free-set solves),
    then, should it not settle within ``max_iter`` steps (default ``2 m + 10``),
    a primal active-set method (monotone: one bound fixed or freed per solve),
    and last ``scipy.optimize.lsq_linear`` on a factor of ``A``.  A singular or
    near-singular ``A`` (a rank-deficient ``D``) gets a ridge of ``1e-12 max
    diag(A)``: among the minimisers (all giving the same face) it picks one of
    small norm.  ``method="lsq_linear"`` skips the active sets (the reference).
    An empty problem (m = 0) returns an empty ``x``.  Raises
    :class:`~repro.errors.AttenuationError` when ``A`` is not symmetric positive
    semi-definite (:func:`check_psd`): the methods here find the minimum of a
    convex quadratic only, and return a mere stationary point otherwise.
    """
    g = as_real_array(g, "g", error=AttenuationError, ndim=1)
    m = g.shape[0]
    A = as_real_array(A, "A", error=AttenuationError, shape=(m, m))
    lo, hi = check_bounds(lo, hi, m)
    if x0 is not None:
        x0 = as_real_array(x0, "x0", error=AttenuationError, shape=(m,))
    as_choice(method, "method", ("auto", "lsq_linear"), error=AttenuationError)
    if max_iter is not None:
        max_iter = as_int(max_iter, "max_iter", error=AttenuationError, lo=1, hi=MAX_ITER)
    if m == 0:  # nothing to solve (LAPACK refuses an empty matrix)
        return BoxQPResult(np.zeros(0), 0, "unconstrained", 0)
    check_psd(A)
    return _box_qp(A, g, lo, hi, x0, max_iter=max_iter, method=method)


#: Largest ``max_iter`` :func:`solve_box_qp` accepts (each step is an m x m solve).
MAX_ITER = 1_000_000


def check_psd(A: np.ndarray, name: str = "A") -> None:
    """Refuse a matrix that is not symmetric positive semi-definite (within rounding).

    The active sets and ``lsq_linear`` on a factor of ``A`` minimise a convex
    quadratic; for an indefinite ``A`` they return a stationary point, not the
    minimum (``-I`` on [0, 1]^3 gave x = 0, objective 0, where x = 1 gives -4.5).
    ``A`` is scaled by its largest entry first, so that the eigenvalues of a
    matrix near the float64 limit do not overflow.
    """
    s = abs_max(A)
    if s == 0.0:
        return
    As = A / s
    asym = abs_max(As - As.T)
    if asym > 1e-10:
        raise AttenuationError(f"{name} must be symmetric (a Gram matrix); max |{name} - {name}^T| is "
                               f"{asym:.3g} of its largest entry")
    try:
        lam = np.linalg.eigvalsh(As)
    except np.linalg.LinAlgError as e:  # pragma: no cover - eigvalsh of a finite symmetric matrix converges
        raise AttenuationError(f"the eigenvalues of {name} could not be computed ({e})") from None
    tol = 1e-10 * max(float(np.abs(lam).max()), 1.0) * A.shape[0]
    if lam[0] < -tol:
        raise AttenuationError(f"{name} must be positive semi-definite (the box QP is convex only then); its "
                               f"smallest eigenvalue is {lam[0] * s:.6g} (largest {lam[-1] * s:.6g})")


def _box_qp(A, g, lo, hi, x0=None, *, max_iter=None, method="auto") -> BoxQPResult:
    """:func:`solve_box_qp` on checked arguments (the per-slider-move path)."""
    m = g.shape[0]
    if method == "lsq_linear":
        x = _lsq_linear(A, g, lo, hi)
        return BoxQPResult(x, 0, "lsq_linear", int(np.count_nonzero((x <= lo) | (x >= hi))))
    scale = float(np.abs(np.diag(A)).max(initial=0.0))
    if x0 is None:
        _, x0, info = lapack.dposv(A, g, lower=1)
        if info != 0 or not np.isfinite(x0).all():  # singular: the ridge below, from the ridged solution
            try:
                x0 = np.linalg.solve(A + 1e-12 * scale * np.eye(m), g)
            except np.linalg.LinAlgError:
                return _box_qp(A, g, lo, hi, method="lsq_linear")
    if ((x0 >= lo) & (x0 <= hi)).all():
        return BoxQPResult(np.array(x0, dtype=np.float64), 0, "unconstrained", 0)
    if scale == 0.0:
        x = np.clip(np.zeros(m), lo, hi)
        return BoxQPResult(x, 0, "active-set", int(np.count_nonzero((x <= lo) | (x >= hi))))
    Ar = A + 1e-12 * scale * np.eye(m)  # harmless for a well-conditioned A, decisive for a singular one
    max_iter = 2 * m + 10 if max_iter is None else max_iter
    x_start = np.clip(x0, lo, hi)
    x, it = _pdas(Ar, g, lo, hi, x_start.copy(), scale, max_iter)
    steps = it
    if x is None:
        gtol = 1e-11 * (scale * (1.0 + float(np.abs(x_start).max(initial=0.0))) + float(np.abs(g).max(initial=0.0)))
        xtol = 1e-13 * (1.0 + np.abs(np.where(np.isfinite(lo), lo, 0.0)) + np.abs(np.where(np.isfinite(hi), hi, 0.0)))
        at_lo = x0 <= lo
        at_hi = (x0 >= hi) & ~at_lo
        x, it = _primal_active_set(Ar, g, lo, hi, x_start.copy(), at_lo, at_hi, gtol, xtol, 10 * m)
        steps += it
    if x is None:
        return _box_qp(A, g, lo, hi, method="lsq_linear")
    x = np.clip(x, lo, hi)
    return BoxQPResult(x, steps, "active-set", int(np.count_nonzero((x <= lo) | (x >= hi))))


def _checked(att, name="attenuator") -> Attenuator:
    if not isinstance(att, Attenuator):
        raise AttenuationError(f"{name} must be an Attenuator, got {describe(att)}")
    return att


def _solve(att: Attenuator, w1, selected, alpha, lo, hi, offset=None) -> BoxQPResult:
    """Eq. (2) in ``u`` for request ``w1`` with ``lo - offset <= u <= hi - offset`` (bounds checked)."""
    A, P, M = att.system(selected, alpha)
    w, _ = check_w_max(w1, att.m, "w1")
    if offset is not None:
        lo, hi = lo - offset, hi - offset
    with np.errstate(over="ignore", invalid="ignore"):
        u0 = M @ w
        g = P @ w
    if not (np.isfinite(u0).all() and np.isfinite(g).all()):
        raise AttenuationError("the bounded solve overflows float64 (the weights or D are too large)")
    return _box_qp(A, g, lo, hi, u0)


def bounded_attenuate(att: Attenuator, w1, selected, alpha=None, lo=0.0, hi=1.0, *, info: bool = False):
    """``w2`` minimising Eq. (2) subject to ``lo <= w2 <= hi`` (default the slider range [0, 1]).

    Equals :meth:`Attenuator.attenuate` (Eq. 3) whenever that is inside the
    range.  ``info=True`` returns the :class:`BoxQPResult` (iterations, method).
    """
    att = _checked(att)
    info = as_bool(info, "info", error=AttenuationError)
    r = _solve(att, w1, selected, alpha, *check_bounds(lo, hi, att.m))
    return r if info else r.x


def bounded_edit(att: Attenuator, w_base, w_target, selected, alpha=None, lo=0.0, hi=1.0, *, info: bool = False):
    """:meth:`Attenuator.edit` with the final weights kept in ``lo..hi``.

    The change ``u`` minimises Eq. (2) for ``w1 = w_target - w_base`` subject to
    ``lo <= w_base + u <= hi``; returns ``w_base + u`` (or the
    :class:`BoxQPResult` of ``u`` with ``info=True``).
    """
    att = _checked(att)
    info = as_bool(info, "info", error=AttenuationError)
    w_base, _ = check_w_max(w_base, att.m, "w_base")
    w_target, _ = check_w_max(w_target, att.m, "w_target")
    with np.errstate(over="ignore", invalid="ignore"):
        w1 = w_target - w_base
    if not np.isfinite(w1).all():
        raise AttenuationError("w_target - w_base overflows float64")
    lo, hi = check_bounds(lo, hi, att.m)
    r = _solve(att, w1, selected, alpha, lo, hi, offset=w_base)
    w = np.clip(w_base + r.x, lo, hi)  # rounding of the offset only
    return r._replace(x=w) if info else w


def clamped_edit(att: Attenuator, w_base, w_target, selected, alpha=None, lo=0.0, hi=1.0) -> np.ndarray:
    """What a rig does with Eq. (3)'s result: :meth:`Attenuator.edit`, then clamped to ``lo..hi``."""
    att = _checked(att)
    lo, hi = check_bounds(lo, hi, att.m)
    return np.clip(att.edit(w_base, w_target, selected, alpha), lo, hi)
