"""The two approaches Lewis et al. 2005 reject in Section 3, made measurable.

1. **Zeroing rows of D.**  "find all rows in the blendshape matrix D that
   correspond to vertices that have recently been moved and set those rows to
   zero".  Selected coordinates are then guaranteed not to move, but the face
   leaves the subspace spanned by D: a frozen vertex is torn from a neighbour
   that a shape still moves ("disrupting the smoothness of the surface").
2. **Orthogonal locking.**  "select a set of one or more blendshapes to be
   'locked' ... the effect of the remaining blendshape vectors would be altered
   by projecting them onto a space orthogonal to the locked vectors".
   Orthogonality of whole-face vectors "does not sufficiently constrain the
   movement of particular vertices".

Both change the face in ways that cannot be written as ``D w`` for the original
``D``, so the functions here return displacements (flat 3n vectors, xyz packing)
that the metrics of :mod:`repro.blendshapes.metrics` compare with attenuation's
``D (w_base + w2)``.  The common scenario: the animator has reached ``w_base``
(e.g. Furrow = 0.4), then moves the sliders to ``w_target``.
"""

from __future__ import annotations

import numpy as np

from repro.blendshapes.attenuation import (
    check_D,
    check_w,
    finite_result,
    scale_exponent,
    scaled,
    check_selection,
)
from repro.checks import as_real_array
from repro.errors import AttenuationError

__all__ = ["zero_rows", "edit_zeroed", "orthogonal_lock", "edit_orthogonal"]


def zero_rows(D, selected) -> np.ndarray:
    """``D`` with the selected rows set to zero (Section 3, first rejected idea)."""
    D = check_D(D)
    sel = check_selection(selected, D.shape[0])
    Dz = D.copy()
    Dz[sel] = 0.0
    return Dz


def edit_zeroed(D, w_base, w_target, selected) -> np.ndarray:
    """Displacement after moving sliders ``w_base -> w_target`` with the selected rows of ``D`` zeroed.

    The pose reached so far is kept (``D w_base``); the further change acts
    through the zeroed basis: ``D w_base + D_0 (w_target - w_base)``.
    """
    D = check_D(D)
    w_base = check_w(w_base, D.shape[1], "w_base")
    w_target = check_w(w_target, D.shape[1], "w_target")
    with np.errstate(over="ignore", invalid="ignore"):
        dw = finite_result(w_target - w_base, "w_target - w_base")
    with np.errstate(over="ignore", invalid="ignore"):
        d = D @ w_base + zero_rows(D, selected) @ dw
    return finite_result(d, "the displacement")


def _locked_columns(locked, m: int) -> np.ndarray:
    L = as_real_array(locked, "locked (shape indices)", error=AttenuationError, integer=True)
    if L.ndim != 1 or L.size == 0:
        raise AttenuationError(f"locked must be a non-empty 1-D array of shape (column) indices, got {locked!r}")
    if L.min() < 0 or L.max() >= m or np.unique(L).size != L.size:
        raise AttenuationError(f"locked shape indices must be distinct and in 0..{m - 1}, got {L.tolist()}")
    if L.size == m:
        raise AttenuationError("every shape is locked: no slider is left to move")
    return np.sort(L.astype(np.int64))


def orthogonal_lock(D, locked) -> np.ndarray:
    """``D`` with every unlocked column projected orthogonal to span(locked columns).

    Section 3's second rejected idea.  Locked columns are kept as they are.  The
    projection uses an orthonormal basis of the locked columns from a QR
    factorisation (numerically stable Gram-Schmidt) of the locked columns, scaled by a
    power of two when ``D`` is very large or very small (the projection does not
    depend on the scale of ``D``).
    """
    D = check_D(D)
    L = _locked_columns(locked, D.shape[1])
    try:
        Ql, R = np.linalg.qr(scaled(D[:, L], scale_exponent(D)))
    except np.linalg.LinAlgError as e:  # pragma: no cover - QR of a finite matrix does not fail
        raise AttenuationError(f"QR factorisation of the locked shapes failed: {e}") from None
    keep = np.abs(np.diag(R)) > 1e-12 * max(np.abs(np.diag(R)).max(initial=0.0), 1e-300)
    Ql = Ql[:, keep]  # drop directions of locked shapes that are zero or dependent
    free = np.setdiff1d(np.arange(D.shape[1]), L)
    Do = D.copy()
    Do[:, free] -= Ql @ (Ql.T @ D[:, free])
    return finite_result(Do, "the projected basis")


def edit_orthogonal(D, w_base, w_target, locked) -> np.ndarray:
    """Displacement after moving the unlocked sliders ``w_base -> w_target`` with ``locked`` shapes locked.

    Locked sliders keep their ``w_base`` values (they are locked); the change
    of the others acts through the projected basis:
    ``D w_base + D_perp (w_target - w_base)`` restricted to unlocked columns.
    """
    D = check_D(D)
    m = D.shape[1]
    L = _locked_columns(locked, m)
    w_base = check_w(w_base, m, "w_base")
    w_target = check_w(w_target, m, "w_target")
    with np.errstate(over="ignore", invalid="ignore"):
        dw = finite_result(w_target - w_base, "w_target - w_base")
    dw[L] = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        d = D @ w_base + orthogonal_lock(D, L) @ dw
    return finite_result(d, "the displacement")
