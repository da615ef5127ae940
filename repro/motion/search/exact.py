"""Exact retrieval: branch and bound over the clusters and clip runs of :class:`MotionRetriever`.

The methods of :class:`ExactSearch` are those of :class:`repro.motion.search.retrieval.MotionRetriever`
(a mixin: they read its database, clusters and per-pose arrays) that return the exhaustive
optimum of ``d = w_q d_qr + w_c d_cr`` without scoring every pose.  Bounds (issue 13, item 1):

* Kovar et al.'s aligned distance ``D`` minimises over an isometry group (rotations about
  the vertical, horizontal translations) under a weighted Euclidean seminorm: a
  pseudometric, so ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of a set of centroid
  ``m`` and radius ``r`` (largest ``D(m, p)``);
* ``scoring="first"``: ``d_cr >= dist(c_r, box)`` (the clip's hit-trajectory box);
  ``scoring="start"``: the alignment-invariant region of :mod:`repro.motion.search.start`.

Every bound has :data:`BOUND_SLACK` subtracted (rounding of the closed form).  The search is
a cascade over the *groups* (the poses of one clip inside one cluster), cheapest bound first
(:meth:`ExactSearch._search_exact`).  With ``scoring="first"`` (the paper's frame, the default)
the cascade runs compiled, in one call (:mod:`repro.motion.search.kernel`, which says why);
the numpy cascade below serves ``scoring="start"`` and ``features=True``, and there the exact
``d_cr`` of the clips within reach of the best ``d`` comes from one k-d tree query over the
hit-trajectory samples (in units of the actor's size, so that one tree serves every actor).

Item 5 of issue 13 (a second, alignment-invariant bound): :func:`invariant_features` gives a
lower bound of ``D`` (the Euclidean distance between per-point heights and distances from the
vertical centroid axis).  It is valid and tight (about 0.8 of ``D`` at the median on the
synthetic database) but, measured, does not pay after the cluster and exact-``d_cr`` bounds
(0.2 % of the poses left at the median, 1 % at p90): ``features=False`` is the default.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from repro.checks import abs_max, as_int, as_real_array, check_alloc
from repro.errors import RetrievalError
from repro.motion.database.annotation import SEMANTICS
from repro.motion.core.kinematics import MAX_COORDINATE as MAX_COORD
from repro.motion.search.distance import aligned_distance

if TYPE_CHECKING:  # annotations only (retrieval imports this module)
    from repro.motion.search.retrieval import Query, RetrievalResult

__all__ = ["BOUND_SLACK", "FEATURE_RTOL", "ExactSearch", "invariant_features", "sample_grid"]

#: Slack (units of the actor's size) subtracted from the lower bounds of the exact search, above the
#: rounding error of the closed-form aligned distance (about 1e-8 near 0).
BOUND_SLACK: float = 1e-6
#: Relative slack of the feature bound, above the rounding of its float32 features (about 1e-7).
FEATURE_RTOL: float = 1e-5
#: Trajectory samples nearest the target whose clips seed the first best ``d`` (``scoring="first"``).
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


    def _lb_cr(self, scoring: str, c_hat: np.ndarray, cq: tuple, box_lo=None, box_hi=None, reg=None) -> np.ndarray:
        """Lower bound of ``d_cr`` / ``size_a`` from boxes (first frame) or start regions (see below)."""
        if scoring == "first":
            gap = np.maximum(np.maximum(box_lo - c_hat, c_hat - box_hi), 0.0)
            lc = np.sqrt(np.einsum("ck,ck->c", gap, gap))
        else:
            rc = float(np.hypot(c_hat[0] - cq[0], c_hat[2] - cq[1]))
            gr = np.maximum(np.maximum(reg[:, 0] - rc, rc - reg[:, 1]), 0.0)
            gy = np.maximum(np.maximum(reg[:, 2] - c_hat[1], c_hat[1] - reg[:, 3]), 0.0)
            lc = np.hypot(gr, gy)
        return np.maximum(lc - BOUND_SLACK, 0.0)


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

    def _c_hat(self, c: np.ndarray, q: Query) -> np.ndarray:
        return c / q.size_c

    def _cq(self, q: Query) -> dict:
        w = self.weights
        return {a: (float(qn[:, 0] @ w), float(qn[:, 2] @ w)) for a, qn in q.q_n.items()}


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
        ``uclip`` of each sample's clip (for :meth:`_ball_dcr`; the k-d tree is built on first use)."""
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

    def _search_exact(self, c, q: Query, sem: str, scoring: str, scale_target: bool = True,
                      stats: dict | None = None, batch: int = 32, features: bool = False) -> RetrievalResult:
        """Filter cascade over the clip runs (groups) of ``sem``, cheapest bound first.

        1. per cluster and actor: ``max(D(q_r, m) - r, 0)`` with ``m, r`` its centroid and
           radius; a group's bound is ``s (w_q max(D(q_r, m) - r, 0) + w_c lc)`` with ``lc``
           its clip's box gap (``"first"``) or its start region (``"start"``), computed only
           for the groups looked at; 2. a first best ``d``: the ``batch`` groups of lowest
           bound among those of the clusters nearest ``q_r`` and (``"first"``) of the clips
           passing nearest ``c_r``, scored exactly; 3. the groups whose bound can beat it:
           with ``"first"`` (``w_c > 0``) those of the clips with a trajectory sample within
           ``best / (w_c smin)`` of ``c_hat`` (the nearest samples of step 2 when they hold
           that ball, else one ball query), by their exact ``d_cr``; otherwise those of the
           clusters with ``smin w_q max(D - r, 0)`` below it, by their group bound; 4. per pose of what is
           left, the alignment-invariant feature bound of ``D`` (:func:`invariant_features`,
           ``features=False`` skips it, for measuring it); 5. the poses still below the best
           ``d`` scored exactly, lowest bound first, in chunks, until the next bound
           exceeds the best.  Ties as in the exhaustive scan.
        """
        c_r = self._c_r(c, q.size_c, scale_target)
        if not scale_target:  # the normalised target differs per actor size: score everything (exact)
            return self._search_exhaustive(c, q, sem, scoring, scale_target, method="exact")
        ex = self._ex[sem]
        c_hat = self._c_hat(c, q)
        first = scoring == "first"
        if first and not features:
            return self._search_exact_compiled(ex, c_r, c_hat, q, stats, batch)
        prep = self._prepared(q)
        cq = self._cq(q)
        geo = None if first else self._start_geometry()
        wq, wc = self.w_q, self.w_c
        G = ex["gsize"].size
        multi = len(self.actors_present) > 1
        radius = self._bb[sem]["radius"]
        gs, gcl, gu = ex["gsize"], ex["gcluster"], ex["gu"]
        # 1. cluster bounds (units of size), per actor of the query; clip box gaps ("first")
        dcl = {a: self.centroid_index.distances(qn, prepared=prep[a]) for a, qn in q.q_n.items()}
        lq_cl = {a: np.maximum(d - radius - BOUND_SLACK, 0.0) for a, d in dcl.items()}

        def lq_of(g):  # the cluster bound of groups g (inf for actors not in the query)
            if not multi:
                (lq,) = lq_cl.values()
                return lq[gcl[g]]
            out = np.full(g.size, np.inf)
            ga = ex["gactor"][g]
            for a, lq in lq_cl.items():
                sel = np.flatnonzero(ga == a)
                out[sel] = lq[gcl[g[sel]]]
            return out

        def lb_of(g, lq):  # the group bound of groups g (metres): s (w_q lq + w_c lc)
            if first:
                ug = gu[g]
                lc = self._lb_cr("first", c_hat, None, ex["ulo"][ug], ex["uhi"][ug])
            else:
                lc = np.full(g.size, np.inf)
                ga = ex["gactor"][g] if multi else None
                for a in q.q_n:
                    sel = np.flatnonzero(ga == a) if multi else slice(None)
                    lc[sel] = self._lb_cr("start", c_hat, cq[a], reg=geo["exgroups"][sem][g[sel]])
            return gs[g] * (wq * lq + wc * lc)

        # 2. a first best d from the most promising groups: those of the clusters nearest q_r
        # (centroid distance), and the best groups of the clips passing nearest to c_r
        B = min(batch, G)
        dmin = next(iter(dcl.values())) if len(dcl) == 1 else np.min(list(dcl.values()), axis=0)
        dcr_u = np.full(ex["uclip"].size, np.nan) if first else None  # exact d_cr per clip (metres), lazily
        near = None
        clstart = ex["clstart"]
        if G > B:
            ncl = ex["glen_cl"]
            order = np.argsort(np.where(ncl > 0, dmin, np.inf), kind="stable")
            take = order[:int(np.searchsorted(np.cumsum(ncl[order]), 8 * B)) + 1]
            gp = _ranges(clstart[take], ncl[take])
            lbp = lb_of(gp, lq_of(gp))
            probe = gp[np.argpartition(lbp, B - 1)[:B]] if gp.size > B else gp
            if first and wc > 0:
                near, near_dh, near_far = self._nearest_clips(ex, dcr_u, c_hat, NEAR_SAMPLES)
                gn = ex["ugroups"][_ranges(ex["ustart"][near], ex["ustart"][near + 1] - ex["ustart"][near])]
                lbn = gs[gn] * wq * lq_of(gn) + wc * dcr_u[gu[gn]]
                if gn.size > B:
                    gn = gn[np.argpartition(lbn, B - 1)[:B]]
                probe = np.union1d(probe, gn)
        else:
            probe = np.arange(G)
        if multi or not first:  # groups of actors not in the query (one actor, "first": all finite)
            probe = probe[np.isfinite(lb_of(probe, lq_of(probe)))]
        if probe.size == 0:
            raise RetrievalError("no clip of an actor compatible with the character for this semantics")
        parts = []
        pos = self._group_poses(ex, probe)
        out = self._exact_poses(ex, pos, q, scoring, c_r, c_hat, cq, prep, dcr_u, np.inf)
        best = float(out[1].min())
        parts.append(out)
        n, n_groups = out[4], probe.size
        thr = self._near_threshold(best)
        inprobe = np.zeros(G, dtype=bool)
        inprobe[probe] = True
        if first and wc > 0:
            # 3. every other group whose bound can beat it: only clips with a trajectory sample within
            # thr / (w_c smin) of c_hat can (d >= w_c d_cr >= w_c smin d_cr / s); their exact d_cr
            # from one k-d tree query, then the groups of those clips by their exact bound
            rad = thr / (wc * ex["smin"])
            if near is not None and near_far > _ball_radius(rad):  # the ball is inside the nearest samples
                uin = near[near_dh <= _ball_radius(rad)]
            else:
                uin = self._ball_dcr(ex, dcr_u, c_hat, rad)
            cand = ex["ugroups"][_ranges(ex["ustart"][uin], ex["ustart"][uin + 1] - ex["ustart"][uin])]
            cand = cand[~inprobe[cand]]
            lq_c = lq_of(cand)
            m = gs[cand] * wq * lq_c + wc * dcr_u[gu[cand]] <= thr
            o = np.argsort(cand[m], kind="stable")  # groups in their stored order, as the other branch
            cand, lq_c = cand[m][o], lq_c[m][o]
        else:
            # 3. every other group whose bound can beat it, in the clusters whose bound can
            # (s >= smin and lc >= 0: s (w_q lq + w_c lc) >= smin w_q lq)
            lq_min = next(iter(lq_cl.values())) if len(lq_cl) == 1 else np.min(list(lq_cl.values()), axis=0)
            keep_cl = np.flatnonzero((ex["smin"] * wq * lq_min <= thr) & (np.diff(clstart) > 0))
            cand = _ranges(clstart[keep_cl], clstart[keep_cl + 1] - clstart[keep_cl])
            cand = cand[~inprobe[cand]]
            lq_c = lq_of(cand)
            m = lb_of(cand, lq_c) <= thr
            cand, lq_c = cand[m], lq_c[m]
            if first and cand.size:
                self._fill_dcr(ex, dcr_u, gu[cand], c_r)
                lb_c = gs[cand] * wq * lq_c + wc * dcr_u[gu[cand]]
                m = lb_c <= thr
                cand, lq_c = cand[m], lq_c[m]
        n_groups += cand.size
        if cand.size:
            pos = self._group_poses(ex, cand)
            glen = ex["glen"][cand]
            s = ex["size"][pos]
            lq = np.repeat(lq_c, glen)
            if first:
                lcm = dcr_u[ex["pu"][pos]]  # metres, exact
            else:
                lcm = np.empty(pos.size)
                for a in q.q_n:
                    sel = np.flatnonzero(ex["actor"][pos] == a) if multi else slice(None)
                    rows = ex["rows"][pos[sel]]
                    reg = np.concatenate([geo["rho"][rows], geo["y"][rows]], axis=1)
                    lcm[sel] = s[sel] * self._lb_cr("start", c_hat, cq[a], reg=reg)
            lb = s * wq * lq + wc * lcm
            m = lb <= self._near_threshold(best)
            pos, lb, lcm, s = pos[m], lb[m], lcm[m], s[m]
            # 4. the alignment-invariant bound of D (item 5)
            if features and pos.size:
                if "feat" not in ex:  # built on first use (the bound is off by default)
                    ex["feat"] = invariant_features(self.db.pose_points[ex["rows"]], self.weights).astype(np.float32)
                lf = np.empty(pos.size)
                for a, qn in q.q_n.items():
                    sel = np.flatnonzero(ex["actor"][pos] == a) if multi else slice(None)
                    fq = invariant_features(qn[None], self.weights)[0].astype(np.float32)
                    diff = ex["feat"][pos[sel]] - fq
                    lf[sel] = np.sqrt(np.einsum("ij,ij->i", diff, diff, dtype=np.float64))
                lf = np.maximum(lf * (1.0 - FEATURE_RTOL) - BOUND_SLACK, 0.0)
                lb = np.maximum(lb, s * wq * lf + wc * lcm)
                m = lb <= self._near_threshold(best)
                pos, lb = pos[m], lb[m]
            # 5. exact d, lowest bound first
            o = np.argsort(lb, kind="stable")
            pos, lb = pos[o], lb[o]
            a, chunk = 0, 4 * batch
            while a < pos.size:  # chunks doubling in size: few calls when the bound stops late
                if not lb[a] <= self._near_threshold(best):
                    break
                sub = pos[a:a + chunk][lb[a:a + chunk] <= self._near_threshold(best)]
                a, chunk = a + chunk, 2 * chunk
                out = self._exact_poses(ex, sub, q, scoring, c_r, c_hat, cq, prep, dcr_u, best)
                if out is not None:
                    n += out[4]
                    parts.append(out)
                    best = min(best, float(out[1].min()))
        if stats is not None:
            stats.update(clusters_visited=int(np.unique(ex["gcluster"][np.concatenate([probe, cand])]).size),
                         groups_scored=int(n_groups), poses_scored=int(n))
        thr = self._near_threshold(best)
        parts = [(p[0][m], p[1][m]) for p in parts for m in [p[1] <= thr]]
        return self._finish(q, parts, c_r, method="exact", n=n, scoring=scoring, c_hat=c_hat, cq=cq)

    def _search_exact_compiled(self, ex: dict, c_r: np.ndarray, c_hat: np.ndarray, q: Query,
                               stats: dict | None, batch: int) -> RetrievalResult:
        """``scoring="first"``: the cascade of :meth:`_search_exact` in one compiled call
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
        return self._finish(q, [(ex["rows"][pos[keep]], d[keep])], c_r, method="exact", n=pos.size, scoring="first")

    @staticmethod
    def _group_poses(ex: dict, gids: np.ndarray) -> np.ndarray:
        """Positions (into the semantics' pose arrays) of the poses of groups ``gids``."""
        st, ln = ex["gstart"][gids], ex["glen"][gids]
        tot = int(ln.sum())
        return np.repeat(st - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln) + np.arange(tot)

    @staticmethod
    def _ball_dcr(ex: dict, dcr_u: np.ndarray, c_hat: np.ndarray, radius: float) -> None:
        """``d_cr`` (metres, paper's frame) of every clip of the semantics with a trajectory sample within
        ``radius`` (units of size) of ``c_hat``, from a k-d tree of the samples; the others get inf (their
        ``d_cr`` exceeds ``radius`` times their size).  Clips already known keep their value.  Returns the clips within
        ``radius`` (positions in the semantics' clips, ascending)."""
        if "tree" not in ex:
            ex["tree"] = cKDTree(ex["tpts"])
        rad = _ball_radius(radius)
        M = ex["tpts"].shape[0]
        idx = np.asarray(ex["tree"].query_ball_point(c_hat, rad), dtype=np.intp)
        dh = np.full(dcr_u.size, np.inf)
        if idx.size > M // 8:  # a large ball: every sample
            if "tcols" not in ex:  # the numpy path only (features=True): built on first use
                ex["tcols"] = np.ascontiguousarray(ex["tpts"].T)
            tx, ty, tz = ex["tcols"]  # contiguous coordinates: three 1-D passes, no (M, 3) temporaries
            d2 = np.square(tx - c_hat[0])
            d2 += np.square(ty - c_hat[1])
            d2 += np.square(tz - c_hat[2])
            dh = np.sqrt(np.minimum.reduceat(d2, ex["tstart"]))
            uin = np.flatnonzero(dh <= rad)
            dh[dh > rad] = np.inf  # as the ball (its clips only)
        elif idx.size:
            idx.sort()  # samples are stored clip by clip: the clips of a sorted ball come in runs
            diff = ex["tpts"][idx] - c_hat
            tc = ex["tclip"][idx]
            at = np.flatnonzero(np.concatenate([[True], tc[1:] != tc[:-1]]))
            uin = tc[at]
            dh[uin] = np.sqrt(np.minimum.reduceat(np.einsum("ij,ij->i", diff, diff), at))
        else:
            uin = np.zeros(0, dtype=np.intp)
        unknown = np.isnan(dcr_u)
        dcr_u[unknown] = dh[unknown] * ex["usize"][unknown]
        return uin

    @staticmethod
    def _nearest_clips(ex: dict, dcr_u: np.ndarray, c_hat: np.ndarray, k: int) -> tuple:
        """The clips (positions in the semantics' clips, ascending) of the ``k`` trajectory samples nearest
        ``c_hat``; their ``d_cr`` (metres, paper's frame) is filled in (the first sample of a clip is its
        nearest).  Returns ``(clips, their distance in units of size, the k-th distance)`` (inf for the
        last when the ``k`` samples are all of them): every sample nearer than the last is among them."""
        if "tree" not in ex:
            ex["tree"] = cKDTree(ex["tpts"])
        k = min(k, ex["tpts"].shape[0])
        dist, idx = ex["tree"].query(c_hat, k=k)
        u, first = np.unique(ex["tclip"][np.atleast_1d(idx)], return_index=True)
        unknown = np.isnan(dcr_u[u])
        dist = np.atleast_1d(dist)
        dcr_u[u[unknown]] = dist[first[unknown]] * ex["usize"][u[unknown]]
        return u, dist[first], (float(dist[-1]) if k < ex["tpts"].shape[0] else np.inf)

    def _fill_dcr(self, ex: dict, dcr_u: np.ndarray, u: np.ndarray, c_r: np.ndarray) -> None:
        """Exact ``d_cr`` (metres, the paper's frame) of the semantics' clips ``u`` not yet known."""
        need = np.zeros(dcr_u.size, dtype=bool)
        need[u] = True
        need &= np.isnan(dcr_u)
        k = np.flatnonzero(need)
        if k.size:
            dcr_u[k] = self._d_cr(ex["uclip"][k], c_r)

    def _exact_poses(self, ex: dict, pos: np.ndarray, q: Query, scoring: str, c_r, c_hat, cq, prep,
                     dcr_u, best: float):
        """Exact ``(rows, d, d_qr, d_cr, n)`` of the poses at ``pos`` whose bound can beat ``best`` (None if none)."""
        multi = len(self.actors_present) > 1
        actor, size = ex["actor"][pos], ex["size"][pos]
        dq = np.full(pos.size, np.inf)
        alpha = None if scoring == "first" else np.zeros(pos.size)
        for a, qn in q.q_n.items():
            sel = np.flatnonzero(actor == a) if multi else slice(None)
            sub = pos[sel]
            if sub.size == 0:
                continue
            if alpha is None:
                dq[sel] = ex["index"].distances(qn, sub, prepared=prep[a])
            else:
                out = ex["index"].distances(qn, sub, return_transform=True, prepared=prep[a])
                dq[sel], alpha[sel] = out[0], out[1]
        dqr = dq * size
        rows = ex["rows"][pos]
        if scoring == "first":
            u = ex["pu"][pos]
            self._fill_dcr(ex, dcr_u, u, c_r)
            dcr = dcr_u[u]
            d = self.w_q * dqr + self.w_c * dcr
            keep = np.flatnonzero(np.isfinite(d))
            if keep.size == 0:
                return None
            return rows[keep], d[keep], dqr[keep], dcr[keep], keep.size
        g = self._start_geometry()
        lb = np.full(pos.size, np.inf)
        for a in q.q_n:
            sel = np.flatnonzero(actor == a) if multi else slice(None)
            reg = np.concatenate([g["rho"][rows[sel]], g["y"][rows[sel]]], axis=1)
            lb[sel] = self.w_q * dqr[sel] + self.w_c * size[sel] * self._lb_cr("start", c_hat, cq[a], reg=reg)
        keep = np.flatnonzero(lb <= self._near_threshold(best))
        if keep.size == 0:
            return None
        dcr = self._d_cr_start_per_actor(q, rows[keep], alpha[keep], actor[keep], c_hat, cq)
        d = self.w_q * dqr[keep] + self.w_c * dcr
        return rows[keep], d, dqr[keep], dcr, keep.size


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


def _ball_radius(radius: float) -> float:
    """The radius (units of size) of the samples taken as within ``radius`` of ``c_hat`` (rounding slack)."""
    return radius * (1.0 + 1e-9) + BOUND_SLACK


def _ranges(start: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The concatenated ranges ``start[i] .. start[i] + length[i]`` (int arrays), in order."""
    tot = int(length.sum())
    return np.repeat(start - np.concatenate([[0], np.cumsum(length)[:-1]]), length) + np.arange(tot)


def invariant_features(points: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Alignment-invariant features of pose clouds, ``(..., 2P)``: ``sqrt(w) y`` and ``sqrt(w) rho``.

    ``rho`` is each point's horizontal distance from the vertical axis through the cloud's
    weighted centroid, ``y`` its height: both unchanged by a rotation about the vertical
    and a horizontal translation.  Since the aligned distance matches the horizontal
    centroids and ``|h_a - R h_b| >= | |h_a| - |h_b| |``, the Euclidean distance between
    the features of two clouds is a lower bound of Kovar et al.'s aligned distance
    (issue 13, item 5).
    """
    p = as_real_array(points, "points (pose clouds)", error=RetrievalError)
    if p.ndim < 2 or p.shape[-1] != 3:
        raise RetrievalError(f"points (pose clouds) must be (..., P, 3), got shape {p.shape}")
    weights = as_real_array(weights, "weights", error=RetrievalError, shape=(p.shape[-2],))
    if np.any(weights < 0) or (weights.size and abs_max(weights) > MAX_COORD) or (p.size and abs_max(p) > MAX_COORD):
        raise RetrievalError(f"weights must be >= 0, and weights and points at most {MAX_COORD:g} in magnitude")
    sw = np.sqrt(weights)
    X = p[..., 0] @ weights
    Z = p[..., 2] @ weights
    rho = np.hypot(p[..., 0] - X[..., None], p[..., 2] - Z[..., None])
    return np.concatenate([p[..., 1] * sw, rho * sw], axis=-1)
