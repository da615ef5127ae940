"""The paper's retrieval (Pronost et al., Section 3.3): nearest cluster, box pruning, weighted distance.

Steps 3 to 5 of :mod:`repro.motion.search.retrieval`'s docstring: the cluster whose centroid is
nearest to ``q_r`` (aligned distance) is selected; clips whose hit-trajectory box does not
contain ``c_r`` are eliminated (the paper's "does not contain q_r" is a typo for ``c_r``: see
Figure 4), and so are poses of clips of another semantics; the remaining poses are scored with
``d = w_q d_qr + w_c d_cr``.  Fallbacks when pruning leaves nothing (the paper does not say):
the next clusters in order of centroid distance (``"neighbour_clusters"``), then, if no clip of
the semantics has a box containing ``c_r``, every startable pose of the semantics (``"no_box"``).
"""

from __future__ import annotations

import numpy as np

from repro.errors import RetrievalError
from repro.motion.search.exhaustive import select_all
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.query import Query
from repro.motion.search.results import QueryMatrices, RetrievalResult, build_result
from repro.motion.search.scoring import best_of_block

__all__ = ["search_pruned"]


def search_pruned(index: RetrievalIndex, q: Query, sem: str, c_r: np.ndarray, matrices: QueryMatrices, *,
                  prune: bool = True) -> RetrievalResult:
    """The paper's search of ``sem`` for the query ``q`` and the clips' targets ``c_r`` (Eq. 1 or not).

    ``prune=False`` disables both the cluster selection and the box test: every startable pose
    of the semantics is scored (the exhaustive optimum, ties to the lowest pose index).
    """
    if not prune:
        best = select_all(index, q, sem, c_r)
        return build_result(index, q, best, c_r, matrices, cluster=-1, fallback="disabled", rank=-1, method="pruned")
    # 3. the cluster nearest to q_r (aligned distance to the centroids)
    if len(q.q_n) == 1:
        (qn,) = q.q_n.values()
        dc = index.centroid_index.distances(qn)
    else:
        dc = np.min([index.centroid_index.distances(v) for v in q.q_n.values()], axis=0)
    order = np.argsort(dc, kind="stable")
    # 4. box pruning (clip level, all clips at once), 5. scoring of what remains
    db = index.db
    inside = np.all((db.box_min <= c_r) & (c_r <= db.box_max), axis=1)
    any_inside = bool(np.any(inside[index.sem_block[sem].uclips]))
    for rank, cl in enumerate(order.tolist() if any_inside else ()):
        best = best_of_block(index, index.cluster_block[cl][sem], q, c_r, inside)
        if best is not None:
            return build_result(index, q, best, c_r, matrices, cluster=int(cl),
                                fallback="none" if rank == 0 else "neighbour_clusters", rank=rank, method="pruned")
    # no clip of this semantics has a box containing c_r: score them all
    best = best_of_block(index, index.sem_block[sem], q, c_r)
    if best is None:
        raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
    return build_result(index, q, best, c_r, matrices, cluster=int(order[0]), fallback="no_box", rank=-1,
                        method="pruned")
