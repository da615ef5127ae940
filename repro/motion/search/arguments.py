"""The checked arguments of the retrieval (Pronost et al., Section 3.3): target, weights, flags, method.

Arguments are checked, never silently cut or coerced (a :class:`~repro.errors.RetrievalError`
names the value and what is allowed); the limits are stated in
:mod:`repro.motion.search.retrieval`'s docstring.
"""

from __future__ import annotations

import numpy as np

from repro.errors import RetrievalError
from repro.motion.core.motion import finite_vector3

__all__ = ["MAX_TARGET_M", "MAX_WEIGHT", "METHODS", "check_flag", "check_method", "check_target", "check_weight"]

#: Largest |coordinate| (metres) of a target accepted by the searches (see the module docstring).
MAX_TARGET_M: float = 1e6
#: Largest accepted ``w_q`` / ``w_c`` (only their ratio matters).
MAX_WEIGHT: float = 1e6
#: The search methods (``method=`` of :meth:`repro.motion.search.retrieval.MotionRetriever.search`).
METHODS: tuple[str, ...] = ("pruned", "exact", "exhaustive", "kdtree")


def check_target(target) -> np.ndarray:
    """The target ``c``: a finite 3-vector of real numbers, each coordinate within :data:`MAX_TARGET_M`."""
    if isinstance(target, (str, bytes)):
        raise RetrievalError(f"target must be a 3-vector of numbers (metres), got {target!r}")
    try:
        a = np.asarray(target)
    except (TypeError, ValueError):
        a = None
    if a is None or a.dtype.kind not in "biuf" and a.dtype.kind != "O":
        raise RetrievalError(f"target must be a 3-vector of real numbers (metres), got {target!r}")
    c = finite_vector3(target, "target (x, y, z) in the character's root frame", RetrievalError)
    if np.abs(c).max() > MAX_TARGET_M:
        raise RetrievalError(f"target {c.tolist()} is more than {MAX_TARGET_M:g} m from the character; "
                             "expected metres in the character's root frame")
    return c


def check_weight(name: str, w) -> float:
    """A weight of ``d = w_q d_qr + w_c d_cr``: a positive finite real number, at most :data:`MAX_WEIGHT`."""
    if isinstance(w, (bool, np.bool_)) or not isinstance(w, (int, float, np.integer, np.floating)):
        raise RetrievalError(f"{name} must be a positive real number in (0, {MAX_WEIGHT:g}], got {w!r}")
    w = float(w)
    if not (np.isfinite(w) and 0.0 < w <= MAX_WEIGHT):
        raise RetrievalError(f"{name} must be positive, finite and at most {MAX_WEIGHT:g}, got {w!r}")
    return w


def check_flag(name: str, v) -> bool:
    """A boolean flag (``prune``, ``scale_target``, ``across_trees``): True or False, nothing else."""
    if not isinstance(v, (bool, np.bool_)):
        raise RetrievalError(f"{name} must be True or False, got {v!r}")
    return bool(v)


def check_method(method) -> str:
    """``method`` checked: one of :data:`METHODS`."""
    if not isinstance(method, str) or method not in METHODS:
        raise RetrievalError(f"unknown method {method!r}; expected one of {list(METHODS)}")
    return method
