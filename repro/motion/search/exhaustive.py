"""The exhaustive baseline: every startable pose of the semantics scored with the paper's ``d``.

No clusters, no boxes: the exact optimum of ``d = w_q d_qr + w_c d_cr`` (Pronost et al.,
Section 3.3), the reference the exact and pruned searches are measured against.  Ties (``d``
within :data:`~repro.motion.search.results.TIE_RTOL` of the minimum) go to the lowest pose index
(:func:`~repro.motion.search.results.select`).
"""

from __future__ import annotations

import numpy as np

from repro.errors import RetrievalError
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.query import Query
from repro.motion.search.results import RetrievalResult, build_result, select
from repro.motion.search.scoring import block_scores

__all__ = ["search_exhaustive", "select_all"]


def select_all(index: RetrievalIndex, q: Query, sem: str, c_r: np.ndarray) -> tuple:
    """The selection (:func:`~repro.motion.search.results.select`) among every startable pose of ``sem``:
    ``(row, d, d_qr, d_cr, n, transform)``."""
    b = index.sem_block[sem]
    s = block_scores(index, b, q, c_r)
    if s is None:
        raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
    d, _, _, n = s
    return select(index, q, b.rows, d, c_r, n)


def search_exhaustive(index: RetrievalIndex, q: Query, sem: str, c_r: np.ndarray, *,
                      method: str = "exhaustive") -> RetrievalResult:
    """Score every startable pose of ``sem`` (``c_r``: the clips' targets, Eq. 1 or not); the result says
    ``method`` (the exact search without Eq. 1 is this scan)."""
    best = select_all(index, q, sem, c_r)
    return build_result(index, q, best, c_r, None, cluster=-1, fallback="disabled", rank=-1, method=method)
