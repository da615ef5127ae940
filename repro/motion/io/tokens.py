"""Strict number tokens of the motion-capture text formats (BVH, ASF/AMC).

``float()`` accepts more than a number written in a file: ``1_0``, digits of other
scripts, ``inf`` and ``nan``.  The readers refuse those with the same
:class:`~repro.errors.BVHError` messages, from here.
"""

from __future__ import annotations

import math
import re

from repro.errors import BVHError

__all__ = ["INTEGER", "finite_float"]

#: A decimal integer token of a BVH file (a CHANNELS or Frames count).
INTEGER = re.compile(r"[+-]?[0-9]+")


def finite_float(tok: str, label: str) -> float:
    """``tok`` as a finite float written in ASCII without ``_``, else :class:`~repro.errors.BVHError`.

    The message is ``"{label} {tok!r} is not a number"`` (not parseable) or ``"... is not
    a finite number"`` (NaN, inf, ``_`` or non-ASCII digits); ``label`` names the place,
    e.g. ``"line 12: joint 'Hips' (OFFSET):"``.
    """
    try:
        v = float(tok)
    except ValueError:
        raise BVHError(f"{label} {tok!r} is not a number") from None
    if not math.isfinite(v) or "_" in tok or not tok.isascii():
        raise BVHError(f"{label} {tok!r} is not a finite number")
    return v
