"""Argument checks of the whole blendshape package (model, attenuation, alternatives, metrics, scenarios).

Numbers must be real numbers (not strings, ``None``, objects, booleans or complex
values), integers must be integers (numpy integers accepted; bools, floats and
strings refused) in range, and the error is the caller's ReproError subclass
naming the argument.
"""

from __future__ import annotations

import math
import numbers
import operator
import reprlib

import numpy as np

from repro.errors import ModelError

__all__ = ["describe", "as_real_array", "abs_max", "as_int", "as_real", "as_str"]

_INT64_MAX = np.iinfo(np.int64).max


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60


def describe(x) -> str:
    """A short repr of a bad argument and its type, for error messages (bounded for big inputs)."""
    return f"{_REPR.repr(x)} ({type(x).__name__})"


def as_real_array(
    x,
    name: str,
    *,
    error: type[Exception] = ModelError,
    integer: bool = False,
    ndim: int | None = None,
    shape: tuple[int | None, ...] | None = None,
    finite: bool = True,
) -> np.ndarray:
    """``x`` as a float64 (or, with ``integer=True``, int64) array, or ``error`` naming ``name``.

    Refused: strings, ``None`` and other objects, ragged nesting, booleans,
    complex values (their imaginary part is never silently dropped), floats
    where integers are meant (an empty array of any numeric dtype is accepted
    as an empty integer array), integers beyond int64, and, when ``finite``,
    NaN/inf (and values that overflow float64, e.g. large ``longdouble``s).
    ``ndim`` / ``shape`` (``None`` entries match any length) check the result.
    """
    what = "integer indices" if integer else "real numbers"
    if isinstance(x, (str, bytes)):
        raise error(f"{name} must be an array of {what}, got the string {describe(x)}")
    try:
        a = np.asarray(x)
    except (ValueError, TypeError, OverflowError) as e:
        raise error(f"{name} must be an array of {what}, got {describe(x)} ({e})") from None
    kind = a.dtype.kind
    if kind == "b":
        hint = "; for a boolean mask use np.flatnonzero(mask)" if integer else ""
        raise error(f"{name} must hold {what}, not booleans{hint}")
    if kind == "c":
        raise error(f"{name} must hold {what}, got complex values (dtype {a.dtype})")
    if kind not in "iuf":
        got = "None" if x is None else f"dtype {a.dtype} from {describe(x)}"
        raise error(f"{name} must be an array of {what}, got {got}")
    if ndim is not None and a.ndim != ndim:
        raise error(f"{name} must be a {ndim}-D array, got shape {a.shape}")
    if shape is not None and (
        a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape))
    ):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise error(f"{name} must have shape {want}, got {a.shape}")
    if integer:
        if kind == "f":
            if a.size:
                raise error(f"{name} must hold integer indices, got dtype {a.dtype}")
            return np.zeros(a.shape, dtype=np.int64)
        if kind == "u" and a.size and a.max() > _INT64_MAX:
            raise error(f"{name} holds integers too large for an index (max {a.max()})")
        return a.astype(np.int64, copy=False)
    if a.dtype != np.float64:
        with np.errstate(over="ignore"):
            a = a.astype(np.float64)
    if finite and not np.isfinite(a).all():
        raise error(f"{name} has {np.count_nonzero(~np.isfinite(a))} NaN/inf values (or values beyond float64)")
    return a


def abs_max(X: np.ndarray) -> float:
    """``max |X|`` of a finite float array without an |X|-sized temporary (0 for an empty one)."""
    if X.size == 0:
        return 0.0
    return float(max(X.max(), -X.min()))


def as_int(
    x, name: str, *, error: type[Exception] = ModelError, lo: int | None = None, hi: int | None = None
) -> int:
    """``x`` as a Python int (numpy integers accepted; bools, floats, strings refused) in ``lo..hi``."""
    if isinstance(x, (bool, np.bool_)):
        raise error(f"{name} must be an integer, got the bool {x!r}")
    try:
        v = operator.index(x)
    except TypeError:
        raise error(f"{name} must be an integer, got {describe(x)}") from None
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        lo_s = "-inf" if lo is None else str(lo)
        hi_s = "inf" if hi is None else str(hi)
        raise error(f"{name} must be an integer in {lo_s}..{hi_s}, got {v}")
    return v


def as_real(x, name: str, *, error: type[Exception] = ModelError, finite: bool = True) -> float:
    """``x`` as a finite Python float: an int/float/numpy number or a 0-d real array.

    Strings (even ``"5"``), ``None``, booleans, complex numbers and objects are refused.
    """
    if isinstance(x, (bool, np.bool_, str, bytes)) or x is None:
        raise error(f"{name} must be a real number, got {describe(x)}")
    if isinstance(x, numbers.Real):
        try:
            v = float(x)
        except (OverflowError, ValueError, TypeError):
            raise error(f"{name} must be a real number within float64 range, got {describe(x)}") from None
    elif isinstance(x, np.ndarray) and x.ndim == 0 and x.dtype.kind in "iuf":
        v = float(x)
    else:
        raise error(f"{name} must be a real number, got {describe(x)}")
    if finite and not math.isfinite(v):
        raise error(f"{name} must be finite, got {v}")
    return v


def as_str(x, name: str, *, error: type[Exception] = ModelError) -> str:
    if not isinstance(x, str):
        raise error(f"{name} must be a string, got {describe(x)}")
    return x
