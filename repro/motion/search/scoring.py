"""Scoring poses with the paper's weighted distance ``d = w_q d_qr + w_c d_cr`` (Pronost et al., Section 3.3).

Step 1 (Eq. 1, ``c_r = c * size_a / size_c`` for every clip's actor: :class:`ClipTargets`) and
step 5: ``d_qr`` is the aligned distance between a pose and ``q_r`` (Kovar et al.; weighted RMS
over the pose points, metres of the actor, :func:`d_qr`) and ``d_cr`` the minimum distance between
its clip's hit-point trajectory, in the root frame of the clip's first frame, and ``c_r``
(metres, :func:`d_cr`).  The paper's pruned search, the baselines and the result building score
with these functions over a :class:`~repro.motion.search.index.RetrievalIndex`.
"""

from __future__ import annotations

import numpy as np

from repro.errors import RetrievalError
from repro.motion.body.skeleton import rescale_constraint
from repro.motion.search.arguments import MAX_TARGET_M
from repro.motion.search.index import Block, RetrievalIndex
from repro.motion.search.query import Query

__all__ = ["ClipTargets", "allowed", "block_scores", "best_of_block", "d_cr", "d_qr", "score_rows"]


class ClipTargets:
    """Eq. 1 for every clip of an index: ``c_r`` of each clip's actor, the ratios kept while the
    character's size is the same."""

    def __init__(self, index: RetrievalIndex):
        self._size_a = index.db.size_a
        self._n_clips = index.db.n_clips
        self._ratio_cache = None

    def c_r(self, c: np.ndarray, size_c: float, scale_target: bool) -> np.ndarray:
        """(C, 3) target of every clip's actor: Eq. 1 (or c itself without scaling)."""
        if not scale_target:
            return np.broadcast_to(c, (self._n_clips, 3))
        # Eq. 1, c * size_a / size_c (rescale_constraint), for every clip's size_a at once
        rescale_constraint(c, 1.0, size_c)  # validates c and size_c
        hit = self._ratio_cache  # size_a / size_c per clip, kept while the character's size is the same
        if hit is None or hit[0] != size_c:
            ratio = self._size_a / size_c
            self._ratio_cache = hit = (size_c, ratio, float(ratio.max()))
        _, ratio, rmax = hit
        # |c_k ratio_i| is largest at the largest ratio (rounding is monotone): one check for every clip
        if not np.all(np.abs(c * rmax) <= MAX_TARGET_M * 1e3):
            raise RetrievalError(f"target {c.tolist()} rescaled from the character's size {size_c:g} m to the "
                                 f"actors' (Eq. 1) is beyond {MAX_TARGET_M * 1e3:g} m")
        # the same products as c[None, :] * ratio[:, None], formed along the clips (a (C, 3) broadcast
        # over a length-3 inner axis costs ~5x more, measured at 7,200 clips): a transposed view
        return (c[:, None] * ratio[None, :]).T


def allowed(index: RetrievalIndex, rows: np.ndarray, q: Query) -> np.ndarray:
    """The poses ``rows`` of actors the query reaches."""
    if len(q.actors) == len(index.actors_present):
        return rows
    return rows[np.isin(index.db.actor[index.db.pose_clip[rows]], q.actors)]


def d_qr(index: RetrievalIndex, rows: np.ndarray, q: Query) -> np.ndarray:
    """Aligned distances (metres of each pose's actor) from q_r to poses ``rows`` (gathered)."""
    out = np.empty(rows.size)
    act = index.db.actor[index.db.pose_clip[rows]]
    for a, qn in q.q_n.items():
        sel = act == a
        if np.any(sel):
            out[sel] = index.index.distances(qn, rows[sel])
    return index.pose_size[rows] * out


def d_cr(index: RetrievalIndex, clips: np.ndarray, c_r: np.ndarray) -> np.ndarray:
    """Min distance from each clip's hit trajectory to its c_r."""
    diff = index.traj_padded[clips] - c_r[clips][:, None, :]
    return np.sqrt(np.min(np.einsum("ctk,ctk->ct", diff, diff), axis=1))


def score_rows(index: RetrievalIndex, rows: np.ndarray, q: Query, c_r: np.ndarray) -> tuple:
    """Best of an arbitrary set of poses, ``(row, d, d_qr, d_cr, n)`` (gathering path, for the k-d tree's
    neighbours)."""
    clips_of_rows = index.db.pose_clip[rows]
    uc, inv = np.unique(clips_of_rows, return_inverse=True)
    dcr = d_cr(index, uc, c_r)[inv]
    dqr = d_qr(index, rows, q)
    d = index.w_q * dqr + index.w_c * dcr
    j = int(np.argmin(d))
    return int(rows[j]), float(d[j]), float(dqr[j]), float(dcr[j]), rows.size


def block_scores(index: RetrievalIndex, b: Block | None, q: Query, c_r: np.ndarray,
                 inside: np.ndarray | None = None) -> tuple | None:
    """Every pose of a block scored: ``(d, d_qr, d_cr of each clip of the block, n_scored)``, or None if
    none qualifies.

    ``inside`` (C,) bool: the box test; poses of other clips (and of actors the query does not
    reach) are not candidates: their ``d`` is inf.
    """
    if b is None:
        return None
    valid_u = np.ones(b.uclips.size, dtype=bool) if inside is None else inside[b.uclips]
    if len(q.q_n) != len(index.actors_present):
        valid_u &= np.isin(index.db.actor[b.uclips], q.actors)
    if not valid_u.any():
        return None
    dcr_u = np.zeros(b.uclips.size)
    dcr_u[valid_u] = d_cr(index, b.uclips[valid_u], c_r)
    if b.single_actor is not None:
        dq = b.index.distances(q.q_n[b.single_actor])
    else:
        dq = np.zeros(b.rows.size)
        for a, qn in q.q_n.items():
            sel = np.flatnonzero(b.actor == a)
            if sel.size:
                dq[sel] = b.index.distances(qn, sel)
    dq *= b.size
    valid = valid_u[b.inv]
    d = index.w_q * dq + index.w_c * dcr_u[b.inv]
    n = int(valid.sum())
    if n < valid.size:
        d[~valid] = np.inf
    return d, dq, dcr_u, n


def best_of_block(index: RetrievalIndex, b: Block | None, q: Query, c_r: np.ndarray,
                  inside: np.ndarray | None = None) -> tuple | None:
    """Best pose of a block (:func:`block_scores`): ``(row, d, d_qr, d_cr, n_scored)``, or None."""
    s = block_scores(index, b, q, c_r, inside)
    if s is None:
        return None
    d, dq, dcr_u, n = s
    j = int(np.argmin(d))
    return int(b.rows[j]), float(d[j]), float(dq[j]), float(dcr_u[b.inv[j]]), n
