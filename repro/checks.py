"""Argument checks: the one set of validators every public function of both papers uses at its entry.

Numbers must be real numbers (not strings, ``None``, objects, booleans or complex
values), integers must be integers (numpy integers accepted; bools, floats and
strings refused) in range, flags must be booleans, choices one of their names, and
the error is the caller's :class:`~repro.errors.ReproError` subclass naming the
argument (default :class:`~repro.errors.ArgumentError`).  :func:`check_alloc`
checks what an argument will make the library allocate against a stated budget
(:data:`MEMORY_BUDGET`) before anything is allocated.

This module belongs to the shared ground (with errors, io and data): it imports
nothing of either paper.
"""

from __future__ import annotations

import math
import numbers
import operator
import reprlib

import numpy as np

import os

from repro.errors import ArgumentError

__all__ = [
    "read_only",
    "describe",
    "as_real_array",
    "abs_max",
    "as_int",
    "as_real",
    "as_str",
    "as_bool",
    "as_choice",
    "as_names",
    "as_path",
    "check_alloc",
    "MEMORY_BUDGET",
]

_INT64_MAX = np.iinfo(np.int64).max


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60


def read_only(a, dtype=None) -> np.ndarray:
    """A private copy of ``a`` that cannot be written: how the immutable types of both papers
    (``Motion``, ``Skeleton``, ``BlendshapeModel``) keep the arrays they were given."""
    a = np.array(a, dtype=dtype, copy=True)
    a.flags.writeable = False
    return a


def describe(x) -> str:
    """A short repr of a bad argument and its type, for error messages (bounded for big inputs)."""
    return f"{_REPR.repr(x)} ({type(x).__name__})"


def as_real_array(
    x,
    name: str,
    *,
    error: type[Exception] = ArgumentError,
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
    if isinstance(x, range):  # a few bytes that np.asarray expands to len(x) int64s
        try:
            n = len(x)
        except OverflowError:  # longer than sys.maxsize
            n = 1 << 63
        check_alloc(8 * n, name, error=error)
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
    x, name: str, lo: int | None = None, hi: int | None = None, *, error: type[Exception] = ArgumentError
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
        raise error(f"{name} must be an integer in {lo_s}..{hi_s}, got {v} (out of range)")
    return v


def as_real(
    x,
    name: str,
    *,
    error: type[Exception] = ArgumentError,
    finite: bool = True,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """``x`` as a finite Python float: an int/float/numpy number or a 0-d real array.

    Strings (even ``"5"``), ``None``, booleans, complex numbers and objects are refused.
    ``lo`` / ``hi`` bound it (closed, or open with ``lo_open`` / ``hi_open``); NaN is
    never in range.
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
    if lo is not None or hi is not None:
        below = lo is not None and (v <= lo if lo_open else v < lo)
        above = hi is not None and (v >= hi if hi_open else v > hi)
        if below or above or math.isnan(v):
            left = "-inf" if lo is None else f"{lo:g}"
            right = "inf" if hi is None else f"{hi:g}"
            span = f"{'(' if lo_open or lo is None else '['}{left}, {right}{')' if hi_open or hi is None else ']'}"
            raise error(f"{name} must be in {span}, got {v}")
    return v


def as_str(x, name: str, *, error: type[Exception] = ArgumentError) -> str:
    """``x`` itself if it is a ``str``, else ``error`` naming ``name``."""
    if not isinstance(x, str):
        raise error(f"{name} must be a string, got {describe(x)}")
    return x


def as_bool(x, name: str, *, error: type[Exception] = ArgumentError) -> bool:
    """``x`` as a bool: ``True``/``False`` or a numpy bool only (not ``1``, ``"yes"`` or ``None``)."""
    if not isinstance(x, (bool, np.bool_)):
        raise error(f"{name} must be True or False, got {describe(x)}")
    return bool(x)


def as_choice(x, name: str, choices, *, error: type[Exception] = ArgumentError):
    """``x`` if it is one of ``choices`` (compared by equality, hashable values only), else ``error`` listing them."""
    choices = tuple(choices)
    try:
        ok = any(type(x) is type(c) and x == c for c in choices) or (
            isinstance(x, str) and x in [c for c in choices if isinstance(c, str)]
        )
    except (TypeError, ValueError):  # e.g. an array compared with a string
        ok = False
    if not ok:
        raise error(f"{name} must be one of {', '.join(repr(c) for c in choices)}; got {describe(x)}")
    return x


def as_names(
    x, name: str, *, error: type[Exception] = ArgumentError, nonempty: bool = True, one: bool = False, item: str = "a name"
) -> tuple[str, ...]:
    """``x`` as a tuple of strings (role, shape, dataset names ...), or ``error`` naming ``name``.

    A lone string is refused (``"pelvis"`` is not the sequence ``("p", "e", ...)``), unless
    ``one=True``, which takes it as a sequence of one; so are non-iterables and non-string
    items; ``nonempty`` refuses an empty sequence; ``item`` names an entry in messages.
    """
    if isinstance(x, str):
        if one:
            return (x,)
        raise error(f"{name} must be a sequence of names, got the string {x!r}")
    try:
        names = tuple(x)
    except TypeError:
        raise error(f"{name} must be a sequence of names, got {describe(x)}") from None
    for entry in names:
        as_str(entry, f"{item} in {name}", error=error)
    if nonempty and not names:
        raise error(f"{name} must name at least one")
    return names


def as_path(x, name: str, *, error: type[Exception] = ArgumentError):
    """``x`` (a ``str`` or ``os.PathLike``) as a :class:`pathlib.Path`, or ``error``: other types, NUL characters."""
    from pathlib import Path

    try:
        p = Path(x)
    except TypeError:
        raise error(f"{name} must be a path, got {describe(x)}") from None
    if "\x00" in str(p):
        raise error(f"{name} {str(p)[:60]!r}: a path cannot hold a NUL character")
    return p


def _budget_from_env() -> int:
    raw = os.environ.get("REPRO_MEMORY_BUDGET", "")
    try:
        v = int(float(raw)) if raw else 0
    except ValueError:
        v = 0
    return v if v > 0 else 8 << 30


#: Largest allocation (bytes) one argument may ask of the library: 8 GiB, or ``REPRO_MEMORY_BUDGET``
#: (bytes) when that is set to a positive number.  The 1,000x retrieval build, the largest thing the
#: project makes on purpose, peaks at about 3.6 GB; a request beyond the budget is refused before
#: anything is allocated, with a message naming the argument and what it would take.
MEMORY_BUDGET: int = _budget_from_env()


def check_alloc(nbytes, what: str, *, error: type[Exception] = ArgumentError, budget: int | None = None) -> int:
    """Refuse (``error``) an allocation of ``nbytes`` above ``budget`` (default :data:`MEMORY_BUDGET`).

    ``nbytes`` is computed by the caller from the arguments (a Python int, so it cannot
    overflow); ``what`` says which argument asks for it, e.g. ``"factors=10**9 (the
    augmented database)"``.  Returns ``nbytes``.
    """
    budget = MEMORY_BUDGET if budget is None else budget
    n = int(nbytes)
    if n > budget:
        raise error(
            f"{what} would need about {_gib(n)} of memory, more than the budget of {_gib(budget)} "
            f"(REPRO_MEMORY_BUDGET, bytes, raises it)"
        )
    return n


def _gib(n: int) -> str:
    return f"{n / (1 << 30):.3g} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.3g} MiB"
