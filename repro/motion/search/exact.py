"""Exact retrieval: branch and bound over the clusters and clip runs of :class:`MotionRetriever`.

The methods of :class:`ExactSearch` are those of :class:`repro.motion.search.retrieval.MotionRetriever`
(a mixin: they read its database, clusters and per-pose arrays) that return the exhaustive
optimum of ``d = w_q d_qr + w_c d_cr`` without scoring every pose.  Bounds (issue 13, item 1):

* Kovar et al.'s aligned distance ``D`` minimises over an isometry group (rotations about
  the vertical, horizontal translations) under a weighted Euclidean seminorm: a
  pseudometric, so ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of a set of centroid
  ``m`` and radius ``r`` (largest ``D(m, p)``);
* ``d_cr >= dist(c_r, box)`` (the clip's hit-trajectory box).

Every bound has :data:`BOUND_SLACK` subtracted (rounding of the closed form).  The search is
a cascade over the *groups* (the poses of one clip inside one cluster), cheapest bound first,
compiled, in one call (:mod:`repro.motion.search.kernel`, which says why).

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

from typing import TYPE_CHECKING

import numpy as np

from repro.checks import abs_max, as_int, as_real_array, check_alloc
from repro.errors import RetrievalError
from repro.motion.database.annotation import SEMANTICS
from repro.motion.core.kinematics import MAX_COORDINATE as MAX_COORD
from repro.motion.search.distance import aligned_distance

if TYPE_CHECKING:  # annotations only (retrieval imports this module)
    from repro.motion.search.retrieval import Query, RetrievalResult

__all__ = ["BOUND_SLACK", "ExactSearch", "sample_grid"]

#: Slack (units of the actor's size) subtracted from the lower bounds of the exact search, above the
#: rounding error of the closed-form aligned distance (about 1e-8 near 0).
BOUND_SLACK: float = 1e-6
#: Trajectory samples nearest the target whose clips seed the first best ``d``.
NEAR_SAMPLES: int = 64
#: Trajectory samples per segment box of the compiled search (:func:`repro.motion.search.kernel._clip_dcr`).
SEGMENT: int = 8


class ExactSearch:
    """Branch-and-bound methods of :class:`~repro.motion.search.retrieval.MotionRetriever` (see the module docstring)."""

    def _bounds_setup(self) -> None:
        """Per (cluster, semantics) block: its radius, and the clips' boxes in units of their actor's size.

        Radius: the largest aligned distance (units of the actor's size) from the centroid
        to a pose of the block, so that ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of
        it (triangle inequality of the pseudometric ``D``).
        """
        db = self.db
        s = db.size_a
        self._nbox_lo = db.box_min / s[:, None]
        self._nbox_hi = db.box_max / s[:, None]
        k = self.clusters.k
        self._bb = {}
        for sem in SEMANTICS:
            rad = np.full(k, np.inf)
            for cl in range(k):
                b = self.cluster_block[cl][sem]
                if b is None:
                    continue
                self._groups(b)
                rad[cl] = float(b.index.distances(self.clusters.centroids[cl]).max())
            self._bb[sem] = {"radius": rad}

    def _groups(self, b) -> None:
        """Split a block into its clips' runs of poses: offsets, radius and centroid of each (exact search).

        The radius is the largest aligned distance from the run's centroid
        (:meth:`_group_centroids`, rounded to float32 and kept, for the runs of more than one
        pose, as ``b.gcent`` until :meth:`_exact_setup` gathers them) to its poses, so that
        ``D(q, p) >= D(q, m) - r`` for each pose ``p`` of the run (the compiled search's bound
        of a run, before its poses are scored).  The radius is measured from the rounded centroid, which keeps the bound exact
        (any centre will do), in half the memory (at 1,000x the float64 terms of the centroids
        took the build's traced peak from 3.4 to 4.3 GB, measured).
        """
        G = b.uclips.size
        gstart = np.concatenate([[0], np.flatnonzero(np.diff(b.inv)) + 1, [b.rows.size]])
        if gstart.size != G + 1:  # rows sorted, so each clip's poses are contiguous
            raise AssertionError("block rows are not grouped by clip")
        b.gstart = gstart
        pts = self.db.pose_points[b.rows]
        cent = self._group_centroids(b, pts).astype(np.float32)
        r = aligned_distance(cent[b.inv].astype(float), pts, self.weights)
        b.gradius = np.maximum.reduceat(r, gstart[:-1])
        b.gcent = cent[np.diff(gstart) > 1]  # a run of one pose is bounded by scoring it

    def _group_centroids(self, b, pts: np.ndarray | None = None) -> np.ndarray:
        """(G, P, 3) float64: the mean cloud of each clip run of block ``b`` (after :meth:`_groups`)."""
        if pts is None:
            pts = self.db.pose_points[b.rows]
        cnt = np.diff(b.gstart).astype(float)
        return np.add.reduceat(pts, b.gstart[:-1], axis=0) / cnt[:, None, None]


    def _prepared(self, q: Query, actor: int | None = None):
        """The query matrices of ``q_r`` (one per actor; that of ``actor`` alone when given), computed
        once per query."""
        key = id(q)
        hit = self._qm_cache
        if hit is None or hit[0] != key or hit[1] is not q:
            self._qm_cache = hit = (key, q, {})
        got = hit[2]
        for a in (q.q_n if actor is None else (actor,)):
            if a not in got:
                got[a] = self.index.query_matrix(q.q_n[a])
        return got if actor is None else got[actor]

    def _exact_setup(self) -> None:
        """Flat arrays of the groups (clip runs inside clusters) of each semantics, cluster by cluster."""
        db = self.db
        self._ex = {}
        for sem in SEMANTICS:
            blocks = [b for b in (self.cluster_block[cl][sem] for cl in range(self.clusters.k)) if b is not None]
            gcent = np.empty((sum(b.gcent.shape[0] for b in blocks), self.weights.size, 3), dtype=np.float32)
            nc = 0
            rows, gstart, gcl, rad, clstart = [], [0], [], [], [0]
            for cl in range(self.clusters.k):
                b = self.cluster_block[cl][sem]
                if b is not None:
                    rows.append(b.rows)
                    gstart.extend((b.gstart[1:] + gstart[-1] - 0).tolist())
                    gcl.append(np.full(b.uclips.size, cl))
                    rad.append(b.gradius)
                    gcent[nc:nc + b.gcent.shape[0]] = b.gcent  # filled in place (memory)
                    nc += b.gcent.shape[0]
                    b.gcent = None
                clstart.append(clstart[-1] + (0 if b is None else b.uclips.size))
            if not rows:
                self._ex[sem] = None
                continue
            span = self._sem_span[sem]  # the blocks' rows, concatenated: views of the gathered candidates
            rows, psize, pactor, pclip = (self._cand[n][span] for n in ("rows", "size", "actor", "clip"))
            gstart = np.asarray(gstart, dtype=np.intp)
            gclip = db.pose_clip[rows[gstart[:-1]]]
            uclip, gu = np.unique(gclip, return_inverse=True)
            index = self.index.subset(rows)
            self._ex[sem] = {
                "rows": rows, "index": index, "gstart": gstart, "glen": np.diff(gstart),
                "gclip": gclip, "gsize": db.size_a[gclip], "gactor": db.actor[gclip], "gcluster": np.concatenate(gcl),
                "gradius": np.concatenate(rad),
                "clstart": np.asarray(clstart, dtype=np.intp), "glen_cl": np.diff(clstart), "size": psize,
                "actor": pactor, "clip": pclip, "sem": sem,
                "uclip": uclip, "gu": gu, "ulo": self._nbox_lo[uclip], "uhi": self._nbox_hi[uclip],
                "pu": np.repeat(gu, np.diff(gstart)), "ugroups": np.argsort(gu, kind="stable"),
                "ustart": np.searchsorted(np.sort(gu), np.arange(uclip.size + 1)), "usize": db.size_a[uclip], "smin": float(db.size_a[uclip].min()),
                **self._trajectory_samples(uclip), **_index_terms(index),
            }
            ex = self._ex[sem]
            ex["gcent"] = gcent  # the centroids (float32) of the runs of more than one pose, in order
            multi = ex["glen"] > 1
            ex["gci"] = np.where(multi, np.cumsum(multi) - 1, -1).astype(_index_dtype(multi.size))  # row in gcent, or -1
            ex["ucl"] = ex["gcluster"][ex["ugroups"]]  # the cluster of each clip's groups, clip by clip
            ex["uactor"] = db.actor[uclip]  # a clip's groups are of its actor (gactor == uactor[gu])

    def _trajectory_samples(self, uclip: np.ndarray) -> dict:
        """The hit-trajectory samples of clips ``uclip`` in units of their actor's size, and the position in
        ``uclip`` of each sample's clip (the compiled search's labels of the samples)."""
        db = self.db
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

    def _search_exact(self, c, q: Query, sem: str, scale_target: bool = True, stats: dict | None = None,
                      batch: int = 32) -> RetrievalResult:
        """The exact search of ``sem``: the compiled cascade (:meth:`_search_exact_compiled`)."""
        c_r = self._c_r(c, q.size_c, scale_target)
        if not scale_target:  # the normalised target differs per actor size: score everything (exact)
            return self._search_exhaustive(c, q, sem, scale_target, method="exact")
        return self._search_exact_compiled(self._ex[sem], c_r, c / q.size_c, q, stats, batch)

    def _search_exact_compiled(self, ex: dict, c_r: np.ndarray, c_hat: np.ndarray, q: Query,
                               stats: dict | None, batch: int) -> RetrievalResult:
        """The cascade in one compiled call
        (:func:`repro.motion.search.kernel.search_first`, which says why)."""
        from repro.motion.search.kernel import search_first  # numba: imported on first use

        slots = tuple(q.q_n)
        gslot = ex.setdefault("gslot", {}).get(slots)
        if gslot is None:  # the query slot of each group's actor (-1: an actor the character cannot use)
            amap = np.full(int(self.db.actor.max()) + 1, -1, dtype=np.intp)
            amap[list(slots)] = np.arange(len(slots))
            gslot = ex["gslot"][slots] = amap[ex["gactor"]]
            ex.setdefault("uslot", {})[slots] = amap[ex["uactor"]]
        qpts = np.array([q.q_n[a].T for a in slots], dtype=float)
        rtol, atol = self._near_terms()
        if self._cterms is None:
            self._cterms = tuple(np.ascontiguousarray(t) for t in self.centroid_index.terms()[:5])
        pos, d, n_groups, n_clusters = search_first(
            c_hat, qpts, self.weights, *self._cterms, self._bb[ex["sem"]]["radius"], gslot, ex["gcluster"],
            ex["gsize"], ex["gstart"], ex["gu"], ex["ugroups"], ex["ustart"], ex["ucl"], ex["uslot"][slots], ex["ulo"], ex["uhi"], ex["usize"],
            ex["tpts"], ex["tstart"], ex["tlen"], ex["sbox"], ex["useg"], SEGMENT, ex["M"], ex["perm"], ex["X"], ex["Z"], ex["H"], ex["Y2"],
            ex["size"], ex["gcent"], ex["gci"], ex["gradius"], self.w_q, self.w_c, rtol, atol, BOUND_SLACK, ex["clstart"], *ex["grid"], ex["tclip"],
            NEAR_SAMPLES, batch)
        if pos.size == 0:
            raise RetrievalError("no clip of an actor compatible with the character for this semantics")
        if stats is not None:
            stats.update(clusters_visited=int(n_clusters), groups_scored=int(n_groups), poses_scored=int(pos.size))
        keep = d <= self._near_threshold(float(d.min()))
        return self._finish(q, [(ex["rows"][pos[keep]], d[keep])], c_r, method="exact", n=pos.size)


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
    return lo, h, dims, start, order.astype(_index_dtype(order.size))


def _index_dtype(n: int):
    """int32 for indices below ``n`` when they fit (half the memory of intp at 1,000x), else int64."""
    return np.int32 if n < 2 ** 31 else np.int64


def _index_terms(index) -> dict:
    """The terms of an :class:`~repro.motion.search.distance.AlignedPoseIndex` subset the compiled search reads
    (:meth:`~repro.motion.search.distance.AlignedPoseIndex.terms`), C-contiguous (views when they are)."""
    return dict(zip(("M", "X", "Z", "H", "Y2", "perm"), (np.ascontiguousarray(t) for t in index.terms())))
