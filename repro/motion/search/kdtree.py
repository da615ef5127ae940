"""The k-d tree baseline: nearest neighbours of a feature vector, rescored with the paper's ``d``.

Feature of a pose: ``w_q sqrt(w) * cloud`` (its canonical-frame cloud, in units of the actor's
size, flattened) and ``w_c * hit_position / size_a``; the query uses ``q_r``'s cloud and
``c / size_c`` (= ``c_r / size_a`` by Eq. 1).  Euclidean distance between these vectors ignores
the alignment (an upper bound of ``d_qr``) and replaces ``d_cr`` by the distance to the hit
position; the ``kd_neighbours`` nearest are rescored with the exact ``d``
(:func:`~repro.motion.search.scoring.score_rows`).  No box pruning.  A
:class:`scipy.spatial.cKDTree` per semantics, built on first use (:class:`KdTrees`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from repro.errors import RetrievalError
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.query import Query
from repro.motion.search.results import QueryMatrices, RetrievalResult, build_result
from repro.motion.search.scoring import allowed, score_rows

__all__ = ["KdTrees", "search_kdtree"]


class KdTrees:
    """The feature k-d tree of each semantics of an index, built on first use (the first search of a
    semantics includes the build)."""

    def __init__(self, index: RetrievalIndex):
        self._index = index
        self._trees: dict = {}

    def of(self, sem: str) -> tuple:
        """``(tree, rows)``: the k-d tree of the startable poses ``rows`` of ``sem``."""
        if sem not in self._trees:
            index = self._index
            rows = index.sem_rows[sem]
            db = index.db
            sw = np.sqrt(index.weights)[None, :, None]
            pose = (db.pose_points[rows] * sw).reshape(rows.size, -1) * index.w_q
            clips = db.pose_clip[rows]
            hit = db.hit_position[clips] / db.size_a[clips, None] * index.w_c
            self._trees[sem] = (cKDTree(np.concatenate([pose, hit], axis=1)), rows)
        return self._trees[sem]


def search_kdtree(index: RetrievalIndex, trees: KdTrees, c: np.ndarray, q: Query, sem: str, c_r: np.ndarray,
                  matrices: QueryMatrices, *, kd_neighbours: int) -> RetrievalResult:
    """The ``kd_neighbours`` nearest poses of ``sem`` to the query's feature (per actor of the query), the
    best of them by ``d`` (``c``: the target, ``c_r``: the clips' targets by Eq. 1)."""
    tree, rows_all = trees.of(sem)
    sw = np.sqrt(index.weights)[:, None]
    best = None
    for a, qn in q.q_n.items():
        v = np.concatenate([(qn * sw).reshape(-1) * index.w_q, c / q.size_c * index.w_c])
        kk = min(kd_neighbours, rows_all.size)
        dist, nb = tree.query(v, k=kk)
        nb = np.atleast_1d(nb)[np.isfinite(np.atleast_1d(dist))]  # cKDTree marks missing ones with n
        rows = allowed(index, rows_all[nb], q)
        if rows.size == 0:
            continue
        cand = score_rows(index, rows, q, c_r)
        if best is None or cand[1] < best[1]:
            best = cand
    if best is None:
        raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
    return build_result(index, q, best, c_r, matrices, cluster=-1, fallback="disabled", rank=-1, method="kdtree")
