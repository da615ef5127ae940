"""The result of a retrieval (Pronost et al., Section 3.3, step 6) and the selection among scored poses.

"The motion associated with the lowest distance d is then rotated and translated to fit the initial
pose q_r": :class:`RetrievalResult` holds that rotation about the vertical axis and translation
(Kovar et al.'s closed form), with the numbers of ``d``.  :func:`select` is the rule the exact and
exhaustive searches share (the near-best candidates re-scored one by one, ties to the lowest pose
index), so that both return the same pose with the same numbers; :func:`build_result` makes the result
of the selected pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from repro.checks import as_real
from repro.errors import RetrievalError
from repro.motion.body.pose_frames import rotate_y
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.query import Query
from repro.motion.search.scoring import d_cr

__all__ = ["FALLBACKS", "MAX_NEAR", "NEAR_ATOL", "NEAR_RTOL", "TIE_ATOL", "TIE_RTOL", "QueryMatrices",
           "RetrievalResult", "build_result", "canonical", "finish", "near_terms", "near_threshold", "select",
           "tie_threshold"]

#: Values of :attr:`RetrievalResult.fallback`.
FALLBACKS: tuple[str, ...] = ("none", "neighbour_clusters", "no_box", "disabled")
#: Ties: candidates whose ``d`` is within ``TIE_RTOL * d + TIE_ATOL`` of the best are tied, and the
#: lowest pose index wins (shared by the exact and exhaustive searches, so that both return the same
#: pose even when two evaluations of ``d`` differ in the last bits).
TIE_RTOL: float = 1e-12
TIE_ATOL: float = 1e-15
#: Candidates within ``NEAR_RTOL * d + NEAR_ATOL * w_q * size_a`` of the best are re-scored one by one
#: before the tie rule (the closed-form aligned distance loses about 1e-8 of the actor's size near 0, and
#: its last bits depend on the batch a pose is scored in); at most ``MAX_NEAR`` of them.
NEAR_RTOL: float = 1e-9
NEAR_ATOL: float = 1e-7
MAX_NEAR: int = 64


@dataclass(frozen=True, eq=False)
class RetrievalResult:
    """The selected motion, where to start it, how to place it, and why.

    Attributes
    ----------
    clip : int
        Clip index in the database; ``name``, ``semantics``, ``hit_role`` describe it.
    start_frame : int
        The selected pose's frame: the motion is played from there.
    hit_frame : int
        The clip's hit frame (the hit comes ``hit_frame - start_frame`` frames later).
    pose : int
        Index of the selected pose in the database.
    d, d_qr, d_cr : float
        ``d = w_q d_qr + w_c d_cr`` (metres); ``d_qr`` aligned pose distance to ``q_r``,
        ``d_cr`` distance from the clip's hit trajectory to ``c_r``.
    w_q, w_c : float
    c_r : (3,) array
        The target for this clip's actor (Eq. 1), in the actor's root frame (metres).
    size_a, size_c : float
        Actor and character sizes (metres).
    cluster : int
        Selected cluster (-1 for the baselines).
    n_candidates : int
        Number of poses scored.
    fallback : str
        One of :data:`FALLBACKS`: ``"none"`` (the paper's algorithm found candidates in
        the nearest cluster), ``"neighbour_clusters"`` (found in the ``cluster_rank``-th
        nearest cluster), ``"no_box"`` (no clip of the semantics contains ``c_r``: every
        startable pose of the semantics scored), ``"disabled"`` (pruning off, or a
        baseline).
    cluster_rank : int
    method : str
        ``"pruned"``, ``"exhaustive"`` or ``"kdtree"``.
    rotation_y : float
        Rotation (radians, about +y) of the alignment ``A`` taking the clip's world
        coordinates (metres of the actor) to the root frame of ``q_r``:
        ``A(p) = rotate_y(p, rotation_y) + translation``.
    translation : (3,) array
        Its translation (y = 0).
    heading, origin : float, (3,) array
        Root frame of the current pose in the character's world.
    """

    clip: int
    name: str
    semantics: str
    hit_role: str
    start_frame: int
    hit_frame: int
    pose: int
    d: float
    d_qr: float
    d_cr: float
    w_q: float
    w_c: float
    c_r: np.ndarray
    size_a: float
    size_c: float
    cluster: int
    n_candidates: int
    fallback: str
    cluster_rank: int
    method: str
    rotation_y: float
    translation: np.ndarray
    heading: float = 0.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def align(self, points) -> np.ndarray:
        """Clip-world points (actor metres) -> root frame of ``q_r`` (actor metres)."""
        return rotate_y(points, self.rotation_y) + self.translation  # (rotate_y checks the points)

    def place(self, points, scale: float | None = None) -> np.ndarray:
        """Clip-world points -> the character's world.

        ``R_y(heading) (scale * align(p)) + origin``: the aligned clip, scaled from the
        actor to the character (default ``scale = size_c / size_a``, a uniform
        approximation of retargeting; exact when the character is the actor, where the
        start pose lands on the current pose up to ``d_qr``) and put in the current
        pose's root frame.
        """
        k = self.size_c / self.size_a if scale is None else as_real(scale, "scale", lo=0.0, lo_open=True,
                                                                      error=RetrievalError)
        return rotate_y(k * self.align(points), self.heading) + self.origin

    @property
    def lead_frames(self) -> int:
        """Frames from the start pose to the hit."""
        return self.hit_frame - self.start_frame


class QueryMatrices:
    """The query matrices of ``q_r`` (:meth:`~repro.motion.search.distance.AlignedPoseIndex.query_matrix`, one
    per actor), computed once per query: those of the last query asked for are kept."""

    def __init__(self, index: RetrievalIndex):
        self._index = index.index
        self._last = None

    def of(self, q: Query, actor: int):
        """The query matrix of ``q_r`` on ``actor``."""
        key = id(q)
        hit = self._last
        if hit is None or hit[0] != key or hit[1] is not q:
            self._last = hit = (key, q, {})
        got = hit[2]
        if actor not in got:
            got[actor] = self._index.query_matrix(q.q_n[actor])
        return got[actor]


def tie_threshold(best: float) -> float:
    """Candidates whose ``d`` is below this are tied with ``best`` (:data:`TIE_RTOL`, :data:`TIE_ATOL`)."""
    return best + TIE_RTOL * abs(best) + TIE_ATOL


def near_terms(index: RetrievalIndex) -> tuple[float, float]:
    """``(rtol, atol)`` of :func:`near_threshold`: ``best + rtol |best| + atol``."""
    return NEAR_RTOL, NEAR_ATOL * index.w_q * index.size_max


def near_threshold(index: RetrievalIndex, best: float) -> float:
    """Candidates whose ``d`` is below this are re-scored one by one (:func:`select`)."""
    rtol, atol = near_terms(index)
    return best + rtol * abs(best) + atol


def canonical(index: RetrievalIndex, q: Query, row: int, c_r: np.ndarray) -> tuple:
    """``(d, d_qr, d_cr, (theta, x0, z0))`` of one pose, always by the same one-row evaluation (so that
    every search reports the same numbers for the same pose, whatever batch it was first scored in),
    and its transform onto ``q_r``."""
    db = index.db
    i = int(db.pose_clip[row])
    qn = q.q_n[int(db.actor[i])]
    # the pose distance summed directly: the closed form cancels to ~1e-8 near a match
    D, alpha, x0, z0 = index.index.direct_distance(qn, row)
    dcr = float(d_cr(index, np.array([i]), c_r)[0])
    dqr = D * float(index.pose_size[row])
    return index.w_q * dqr + index.w_c * dcr, dqr, dcr, (alpha, x0, z0)


def select(index: RetrievalIndex, q: Query, rows: np.ndarray, d: np.ndarray, c_r: np.ndarray, n: int) -> tuple:
    """The selection among scored poses: ``(row, d, d_qr, d_cr, n, (theta, x0, z0))``.

    The poses within :func:`near_threshold` of the lowest ``d`` (above the rounding of
    the closed form, which differs in the last bits between batches) are re-scored by
    :func:`canonical`; the lowest of those wins, ties (:data:`TIE_RTOL`) to the lowest
    pose index.  The exact and exhaustive searches share it.
    """
    m = float(np.min(d))
    near = np.flatnonzero(d <= near_threshold(index, m))
    near = near[np.argsort(rows[near], kind="stable")]
    if near.size > MAX_NEAR:  # degenerate databases (many copies of one pose): the lowest indices
        near = np.concatenate([near[:MAX_NEAR], [int(np.argmin(d))]])
    scored = [(canonical(index, q, int(rows[j]), c_r), int(rows[j])) for j in near]
    m2 = min(v[0][0] for v in scored)
    (dd, dqr, dcr, tf), row = min((v for v in scored if v[0][0] <= tie_threshold(m2)), key=lambda v: v[1])
    return row, float(dd), float(dqr), float(dcr), int(n), tf


def build_result(index: RetrievalIndex, q: Query, best, c_r, matrices: QueryMatrices | None, *, cluster, fallback,
                 rank, method) -> RetrievalResult:
    """The result of ``best = (row, d, d_qr, d_cr, n[, (theta, x0, z0)])`` (the transform onto
    ``q_r`` when already known, as :func:`select` gives it; else computed with ``matrices``)."""
    row, d, dqr, dcr, n = best[:5]
    if not np.isfinite(d):
        raise RetrievalError(f"the weighted distance d is not finite (d = {d}) for clip "
                             f"{int(index.db.pose_clip[row])}: target or weights too large")
    db = index.db
    i = int(db.pose_clip[row])
    a = int(db.actor[i])
    if len(best) > 5:
        alpha, x0, z0 = best[5]
    else:
        _, alpha, x0, z0 = (float(v[0]) for v in index.index.distances(
            q.q_n[a], np.array([row]), return_transform=True, prepared=matrices.of(q, a)))
    s = float(db.size_a[i])
    th_i, o_i = float(db.pose_heading[row]), db.pose_origin[row]
    rot = alpha - th_i
    t = -rotate_y(o_i, rot) + s * np.array([x0, 0.0, z0])
    return RetrievalResult(
        clip=i, name=str(db.names[i]), semantics=str(db.semantics[i]), hit_role=str(db.hit_roles[i]),
        start_frame=int(db.pose_frame[row]), hit_frame=int(db.hit_frame[i]), pose=int(row), d=d, d_qr=dqr,
        d_cr=dcr, w_q=index.w_q, w_c=index.w_c, c_r=np.array(c_r[i]), size_a=s, size_c=q.size_c,
        cluster=cluster, n_candidates=int(n), fallback=fallback, cluster_rank=rank, method=method,
        rotation_y=rot, translation=t, heading=q.heading, origin=np.array(q.origin))


def finish(index: RetrievalIndex, q: Query, parts: list, c_r: np.ndarray, *, method: str, n: int) -> RetrievalResult:
    """The result of the selection (:func:`select`) among the scored ``parts`` (``(rows, d)`` pairs), by a
    search that has no cluster (the exact search, the exhaustive scan)."""
    if not parts:
        raise RetrievalError("no clip of an actor compatible with the character for this semantics")
    rows = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    best = select(index, q, rows, d, c_r, n)
    return build_result(index, q, best, c_r, None, cluster=-1, fallback="disabled", rank=-1, method=method)
