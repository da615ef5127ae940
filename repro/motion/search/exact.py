"""Exact retrieval: branch and bound over the clusters and clip runs of a retrieval index.

:class:`ExactSearch` returns the exhaustive optimum of ``d = w_q d_qr + w_c d_cr`` (Pronost et
al., Section 3.3) without scoring every pose, over the clusters, boxes and clip runs of a
:class:`~repro.motion.search.index.RetrievalIndex`.  Bounds (issue 13, item 1):

* Kovar et al.'s aligned distance ``D`` minimises over an isometry group (rotations about
  the vertical, horizontal translations) under a weighted Euclidean seminorm: a
  pseudometric, so ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of a set of centroid
  ``m`` and radius ``r`` (largest ``D(m, p)``);
* ``d_cr >= dist(c_r, box)`` (the clip's hit-trajectory box).

Every bound has :data:`BOUND_SLACK` subtracted (rounding of the closed form).  The search is
a cascade over the *groups* (the poses of one clip inside one cluster), cheapest bound first,
compiled, in one call (:mod:`repro.motion.search.kernel`, which says why); the steps are in
:meth:`ExactSearch.search`.

Scoring ``d_cr`` in the frame of the start pose (``scoring="start"``: the closest approach of the
hit trajectory as played from the start frame on) was measured to cut the kick miss from 0.49 to
0.34 m (a possible future figure); it was removed in issue 24 because nothing used it, and commit
f839872 has it.  Item 5 of issue 13 (a second, alignment-invariant bound of ``D``: the Euclidean
distance between per-point heights and distances from the vertical centroid axis) is valid and tight
(about 0.8 of ``D`` at the median on the synthetic database) but, measured, did not pay after the
cluster and exact-``d_cr`` bounds (0.2 % of the poses left at the median, 1 % at p90): removed in
issue 24 with ``features=True``, which nothing used; commit f839872 has it too.
"""

from __future__ import annotations

import numpy as np

from repro.checks import abs_max, as_int, as_real_array, check_alloc
from repro.errors import RetrievalError
from repro.motion.core.kinematics import MAX_COORDINATE as MAX_COORD
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.index import RetrievalIndex, index_dtype
from repro.motion.search.query import Query
from repro.motion.search.results import RetrievalResult, finish, near_terms, near_threshold

__all__ = ["BOUND_SLACK", "ExactSearch", "sample_grid", "trajectory_samples"]

#: Slack (units of the actor's size) subtracted from the lower bounds of the exact search, above the
#: rounding error of the closed-form aligned distance (about 1e-8 near 0).
BOUND_SLACK: float = 1e-6
#: Trajectory samples nearest the target whose clips seed the first best ``d``.
NEAR_SAMPLES: int = 64
#: Trajectory samples per segment box of the compiled search (:func:`repro.motion.search.kernel._clip_dcr`).
SEGMENT: int = 8


class ExactSearch:
    """The exact search over an index: the compiled kernel's arrays, made once per semantics.

    ``arrays[semantics]``: the index's groups (:attr:`RetrievalIndex.groups`) with the hit-trajectory
    samples of their clips (:func:`trajectory_samples`) and the closed-form terms of their poses
    (:meth:`~repro.motion.search.distance.AlignedPoseIndex.terms`), C-contiguous; None for a semantics
    without candidates.
    """

    def __init__(self, index: RetrievalIndex):
        self.index = index
        self.arrays = {}
        for sem in SEMANTICS:
            g = index.groups[sem]
            self.arrays[sem] = None if g is None else {**g, **trajectory_samples(index.db, g["uclip"]),
                                                       **_index_terms(g["index"])}
        self._cterms = tuple(np.ascontiguousarray(t) for t in index.centroid_index.terms()[:5])
        self._slots: dict = {}  # (semantics, query actors) -> the query slot of each group's and clip's actor

    def _slots_of(self, sem: str, slots: tuple) -> tuple:
        """The query slot of each group's and each clip's actor (-1: an actor the character cannot use)."""
        key = (sem, slots)
        got = self._slots.get(key)
        if got is None:
            ex = self.arrays[sem]
            amap = np.full(int(self.index.db.actor.max()) + 1, -1, dtype=np.intp)
            amap[list(slots)] = np.arange(len(slots))
            got = self._slots[key] = (amap[ex["gactor"]], amap[ex["uactor"]])
        return got

    def search(self, q: Query, sem: str, c_r: np.ndarray, c_hat: np.ndarray, *, stats: dict | None = None,
               batch: int = 32) -> RetrievalResult:
        """The exhaustive optimum of ``d`` over the poses of ``sem``, by a cascade over the clip runs (groups),
        cheapest bound first, in one compiled call (:func:`repro.motion.search.kernel.search_first`, which
        says why); ``c_r`` the clips' targets (Eq. 1), ``c_hat = c / size_c``.

        1. per cluster and actor: ``max(D(q_r, m) - r, 0)`` with ``m, r`` its centroid and radius;
           a group's bound is ``s (w_q max(D(q_r, m) - r, 0) + w_c lc)`` with ``lc`` its clip's
           box gap (units of size), computed only for the groups looked at; 2. a first best ``d``:
           the ``batch`` groups of lowest bound among those of the clusters nearest ``q_r`` and of
           the clips passing nearest ``c_r`` (the nearest trajectory samples), scored exactly;
           3. the groups whose bound can beat it: those of the clips with a trajectory sample
           within ``best / (w_c smin)`` of ``c_hat`` (``d >= w_c d_cr >= w_c smin d_cr / s``), by
           their exact ``d_cr``; 4. the poses still below the best ``d`` scored exactly, lowest
           bound first (a run of more than one pose first bounded by its own centroid and radius),
           until the next bound exceeds the best.  Every bound has :data:`BOUND_SLACK` subtracted.
           Candidates within rounding of the best are re-scored one by one and ties go to the lowest
           pose index, as in the exhaustive scan (:func:`~repro.motion.search.results.select`): both
           return the same pose with the same numbers.  ``stats`` (a dict), when given, receives
           ``clusters_visited``, ``groups_scored`` and ``poses_scored``.
        """
        from repro.motion.search.kernel import search_first  # numba: imported on first use

        ex = self.arrays[sem]
        index = self.index
        slots = tuple(q.q_n)
        gslot, uslot = self._slots_of(sem, slots)
        qpts = np.array([q.q_n[a].T for a in slots], dtype=float)
        rtol, atol = near_terms(index)
        pos, d, n_groups, n_clusters = search_first(
            c_hat, qpts, index.weights, *self._cterms, index.radius[sem], gslot, ex["gcluster"],
            ex["gsize"], ex["gstart"], ex["gu"], ex["ugroups"], ex["ustart"], ex["ucl"], uslot, ex["ulo"], ex["uhi"],
            ex["usize"], ex["tpts"], ex["tstart"], ex["tlen"], ex["sbox"], ex["useg"], SEGMENT, ex["M"], ex["perm"],
            ex["X"], ex["Z"], ex["H"], ex["Y2"], ex["size"], ex["gcent"], ex["gci"], ex["gradius"], index.w_q,
            index.w_c, rtol, atol, BOUND_SLACK, ex["clstart"], *ex["grid"], ex["tclip"], NEAR_SAMPLES, batch)
        if pos.size == 0:
            raise RetrievalError("no clip of an actor compatible with the character for this semantics")
        if stats is not None:
            stats.update(clusters_visited=int(n_clusters), groups_scored=int(n_groups), poses_scored=int(pos.size))
        keep = d <= near_threshold(index, float(d.min()))
        return finish(index, q, [(ex["rows"][pos[keep]], d[keep])], c_r, method="exact", n=pos.size)


def trajectory_samples(db: MotionDatabase, uclip: np.ndarray) -> dict:
    """The hit-trajectory samples of clips ``uclip`` in units of their actor's size, and the position in
    ``uclip`` of each sample's clip (the compiled search's labels of the samples)."""
    n = db.n_frames[uclip]
    st = db.traj_start[uclip]
    idx = np.repeat(st - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(int(n.sum()))
    tclip = np.repeat(np.arange(uclip.size), n)
    tpts = db.traj[idx] / db.size_a[uclip][tclip, None]
    tstart = np.concatenate([[0], np.cumsum(n)[:-1]]).astype(np.intp)
    # segments of SEGMENT samples (the compiled search's boxes): they tile each clip's samples in order
    nseg = -(-n // SEGMENT)
    useg = np.concatenate([[0], np.cumsum(nseg)]).astype(np.intp)
    seg_start = np.repeat(tstart - SEGMENT * useg[:-1], nseg) + SEGMENT * np.arange(int(useg[-1]))
    sbox = np.concatenate([np.minimum.reduceat(tpts, seg_start), np.maximum.reduceat(tpts, seg_start)], axis=1)
    return {"tpts": tpts, "tclip": tclip, "tlen": n.astype(np.intp), "tstart": tstart,
            "sbox": np.ascontiguousarray(sbox), "useg": useg, "grid": sample_grid(tpts)}


def sample_grid(pts: np.ndarray, per_cell: int = 8, max_cells: int = 1 << 21) -> tuple:
    """A uniform grid of the points ``pts`` (n, 3) for :func:`repro.motion.search.kernel._nearest_samples`:
    ``(lo, h, dims, cell_start, order)``, ``order`` (int32 when it fits) the points by cell (x fastest; an index, not
    a sorted copy of the points: 4 bytes a point, not 32, which counts at 1,000x),
    about ``per_cell`` points per cell of the bounding box and at most ``max_cells`` cells (a point beyond
    the last cell of an axis goes to it: edge cells extend to infinity, which the search allows for)."""
    pts = as_real_array(pts, "pts (trajectory samples)", error=RetrievalError, shape=(None, 3))
    if pts.size and abs_max(pts) > MAX_COORD:  # the extent would overflow to inf
        raise RetrievalError(f"pts (trajectory samples) beyond {MAX_COORD:g} in magnitude")
    per_cell = as_int(per_cell, "per_cell", 1, None, error=RetrievalError)
    max_cells = as_int(max_cells, "max_cells", 1, None, error=RetrievalError)
    check_alloc(8 * min(max_cells, 1 << 30), f"max_cells={max_cells} (the sample grid's cells)", error=RetrievalError)
    lo = pts.min(axis=0) if pts.size else np.zeros(3)
    ext = np.maximum((pts.max(axis=0) if pts.size else np.zeros(3)) - lo, 1e-9)
    h = float((np.prod(ext) * per_cell / max(pts.shape[0], 1)) ** (1.0 / 3.0))
    while True:  # an axis of small extent gets one cell; the others about ``per_cell`` points each
        h = max(h, float(ext.max()) / 1024.0)
        dims = np.maximum(np.ceil(ext / h), 1).astype(np.intp)
        if int(np.prod(dims)) <= max_cells:
            break
        h *= 1.25
    cell3 = np.minimum(((pts - lo) / h).astype(np.intp), dims - 1)
    cell = (cell3[:, 2] * dims[1] + cell3[:, 1]) * dims[0] + cell3[:, 0]
    order = np.argsort(cell, kind="stable")
    start = np.concatenate([[0], np.cumsum(np.bincount(cell, minlength=int(np.prod(dims))))]).astype(np.intp)
    return lo, h, dims, start, order.astype(index_dtype(order.size))


def _index_terms(index) -> dict:
    """The terms of an :class:`~repro.motion.search.distance.AlignedPoseIndex` subset the compiled search reads
    (:meth:`~repro.motion.search.distance.AlignedPoseIndex.terms`), C-contiguous (views when they are)."""
    return dict(zip(("M", "X", "Z", "H", "Y2", "perm"), (np.ascontiguousarray(t) for t in index.terms())))
