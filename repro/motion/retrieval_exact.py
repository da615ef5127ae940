"""Exact retrieval: branch and bound over the clusters and clip runs of :class:`MotionRetriever`.

The methods of :class:`ExactSearch` are those of :class:`repro.motion.retrieval.MotionRetriever`
(a mixin: they read its database, clusters and per-pose arrays) that return the exhaustive
optimum of ``d = w_q d_qr + w_c d_cr`` without scoring every pose.  Bounds (issue 13, item 1):

* Kovar et al.'s aligned distance ``D`` minimises over an isometry group (rotations about
  the vertical, horizontal translations) under a weighted Euclidean seminorm: a
  pseudometric, so ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of a set of centroid
  ``m`` and radius ``r`` (largest ``D(m, p)``);
* ``scoring="first"``: ``d_cr >= dist(c_r, box)`` (the clip's hit-trajectory box);
  ``scoring="start"``: the alignment-invariant region of :mod:`repro.motion.retrieval_start`.

Every bound has :data:`BOUND_SLACK` subtracted (rounding of the closed form).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from repro.motion.annotation import SEMANTICS
from repro.motion.clustering import AlignedPoseIndex, aligned_distance

if TYPE_CHECKING:  # annotations only (retrieval imports this module)
    from repro.motion.retrieval import Query, RetrievalResult

__all__ = ["BOUND_SLACK", "ExactSearch"]

#: Slack (units of the actor's size) subtracted from the lower bounds of the exact search, above the
#: rounding error of the closed-form aligned distance (about 1e-8 near 0).
BOUND_SLACK: float = 1e-6


class ExactSearch:
    """Branch-and-bound methods of :class:`~repro.motion.retrieval.MotionRetriever` (see the module docstring)."""

    def _bounds_setup(self) -> None:
        """Per (cluster, semantics) block: radius, smallest actor size, union box of its clips.

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
            smin = np.full(k, np.inf)
            lo = np.full((k, 3), np.inf)
            hi = np.full((k, 3), -np.inf)
            for cl in range(k):
                b = self.cluster_block[cl][sem]
                if b is None:
                    continue
                self._groups(b)
                rad[cl] = float(b.index.distances(self.clusters.centroids[cl]).max())
                smin[cl] = float(b.size.min())
                lo[cl] = self._nbox_lo[b.uclips].min(axis=0)
                hi[cl] = self._nbox_hi[b.uclips].max(axis=0)
            self._bb[sem] = {"radius": rad, "s_min": smin, "box_lo": lo, "box_hi": hi,
                             "empty": ~np.isfinite(smin)}

    def _groups(self, b) -> None:
        """Split a block into its clips' runs of poses: centroid and radius of each (exact search)."""
        G = b.uclips.size
        gstart = np.concatenate([[0], np.flatnonzero(np.diff(b.inv)) + 1, [b.rows.size]])
        if gstart.size != G + 1:  # rows sorted, so each clip's poses are contiguous
            raise AssertionError("block rows are not grouped by clip")
        pts = self.db.pose_points[b.rows]
        cnt = np.diff(gstart).astype(float)
        cent = np.add.reduceat(pts, gstart[:-1], axis=0) / cnt[:, None, None]
        r = aligned_distance(cent[b.inv], pts, self.weights)
        b.gstart = gstart
        b.gcent = cent
        b.gindex = None
        b.gradius = np.maximum.reduceat(r, gstart[:-1])


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


    def _prepared(self, q: Query) -> dict:
        """The query matrices of ``q_r`` (one per actor), computed once per query."""
        key = id(q)
        hit = self._qm_cache
        if hit is None or hit[0] != key or hit[1] is not q:
            self._qm_cache = hit = (key, q, {a: self.index.query_matrix(qn) for a, qn in q.q_n.items()})
        return hit[2]

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
            rows, gstart, gcl, cent, rad, clstart = [], [0], [], [], [], [0]
            for cl in range(self.clusters.k):
                b = self.cluster_block[cl][sem]
                if b is not None:
                    rows.append(b.rows)
                    gstart.extend((b.gstart[1:] + gstart[-1] - 0).tolist())
                    gcl.append(np.full(b.uclips.size, cl))
                    cent.append(b.gcent)
                    rad.append(b.gradius)
                clstart.append(clstart[-1] + (0 if b is None else b.uclips.size))
            if not rows:
                self._ex[sem] = None
                continue
            rows = np.concatenate(rows)
            gstart = np.asarray(gstart, dtype=np.intp)
            gclip = db.pose_clip[rows[gstart[:-1]]]
            uclip, gu = np.unique(gclip, return_inverse=True)
            self._ex[sem] = {
                "rows": rows, "index": self.index.subset(rows), "gstart": gstart, "glen": np.diff(gstart),
                "gclip": gclip, "gsize": db.size_a[gclip], "gactor": db.actor[gclip], "gcluster": np.concatenate(gcl),
                "gindex": AlignedPoseIndex(np.concatenate(cent), self.weights), "gradius": np.concatenate(rad),
                "clstart": np.asarray(clstart, dtype=np.intp), "size": self.pose_size[rows],
                "actor": db.actor[db.pose_clip[rows]], "clip": db.pose_clip[rows], "sem": sem,
                "uclip": uclip, "gu": gu,
            }

    def _group_lb(self, ex: dict, gids: np.ndarray, q: Query, scoring: str, c_hat, cq, prep, c_r,
                  lc: np.ndarray | None = None) -> np.ndarray:
        """Lower bound of ``d`` (metres) on every pose of the groups ``gids``.

        ``lc`` (metres): a bound of ``d_cr`` per group when already known.
        """
        lb = np.full(gids.size, np.inf)
        gact = ex["gactor"][gids]
        for a, qn in q.q_n.items():
            sel = np.flatnonzero(gact == a) if len(self.actors_present) > 1 else slice(None)
            sub = gids[sel]
            if sub.size == 0:
                continue
            dg = ex["gindex"].distances(qn, sub, prepared=prep[a])
            lq = np.maximum(dg - ex["gradius"][sub] - BOUND_SLACK, 0.0)
            if lc is not None:
                lcs = lc[sel]
            elif scoring == "first":  # d_cr is per clip: exact (one trajectory per clip, cheap)
                uc, inv = np.unique(ex["gclip"][sub], return_inverse=True)
                lcs = self._d_cr(uc, c_r)[inv]
            else:
                lcs = ex["gsize"][sub] * self._lb_cr("start", c_hat, cq[a],
                                                     reg=self._start_geometry()["exgroups"][ex["sem"]][sub])
            lb[sel] = ex["gsize"][sub] * self.w_q * lq + self.w_c * lcs
        return lb

    def _eval_groups(self, ex: dict, gids: np.ndarray, q: Query, c_r, scoring: str, c_hat, cq, prep, best: float):
        """Exact ``d`` of the poses of groups ``gids`` whose own bound can beat ``best``."""
        st, ln = ex["gstart"][gids], ex["glen"][gids]
        tot = int(ln.sum())
        pos = np.repeat(st - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln) + np.arange(tot)
        rows = ex["rows"][pos]
        actor, size, clip = ex["actor"][pos], ex["size"][pos], ex["clip"][pos]
        allowed = np.isin(actor, q.actors) if len(q.q_n) != len(self.actors_present) else None
        dq = np.full(tot, np.inf)
        alpha = np.zeros(tot) if scoring == "start" else None
        for a, qn in q.q_n.items():
            sel = np.flatnonzero(actor == a) if len(self.actors_present) > 1 else slice(None)
            sub = pos[sel]
            if sub.size == 0:
                continue
            if scoring == "start":
                out = ex["index"].distances(qn, sub, return_transform=True, prepared=prep[a])
                dq[sel], alpha[sel] = out[0], out[1]
            else:
                dq[sel] = ex["index"].distances(qn, sub, prepared=prep[a])
        dqr = dq * size
        if scoring == "first":
            lbc = self._lb_cr("first", c_hat, None, self._nbox_lo[clip], self._nbox_hi[clip])
            lb = self.w_q * dqr + self.w_c * lbc * size
        else:
            g = self._start_geometry()
            lb = np.full(tot, np.inf)
            for a in q.q_n:
                sel = np.flatnonzero(actor == a) if len(self.actors_present) > 1 else slice(None)
                reg = np.concatenate([g["rho"][rows[sel]], g["y"][rows[sel]]], axis=1)
                lb[sel] = self.w_q * dqr[sel] + self.w_c * size[sel] * self._lb_cr("start", c_hat, cq[a], reg=reg)
        if allowed is not None:
            lb[~allowed] = np.inf
        keep = np.flatnonzero(lb <= self._tie_threshold(best))
        if keep.size == 0:
            return None
        if scoring == "first":
            uc, inv = np.unique(clip[keep], return_inverse=True)
            dcr = self._d_cr(uc, c_r)[inv]
        else:
            dcr = self._d_cr_start_per_actor(q, rows[keep], alpha[keep], actor[keep], c_hat, cq)
        d = self.w_q * dqr[keep] + self.w_c * dcr
        return rows[keep], d, dqr[keep], dcr, keep.size

    def _search_exact(self, c, q: Query, sem: str, scoring: str, scale_target: bool = True,
                      stats: dict | None = None, batch: int = 48) -> RetrievalResult:
        c_r = self._c_r(c, q.size_c, scale_target)
        if not scale_target:  # the normalised target differs per actor size: score everything (exact)
            return self._search_exhaustive(c, q, sem, scoring, scale_target, method="exact")
        ex = self._ex[sem]
        c_hat = self._c_hat(c, q)
        cq = self._cq(q)
        prep = self._prepared(q)
        bb = self._bb[sem]
        geo = self._start_geometry() if scoring == "start" else None
        # 1. clusters: lower bound of d over each (cluster, semantics) block, per actor of the query
        lbs, lqs = [], []
        for a, qn in q.q_n.items():
            lq = np.maximum(self.centroid_index.distances(qn) - bb["radius"] - BOUND_SLACK, 0.0)
            lc = (self._lb_cr("first", c_hat, None, bb["box_lo"], bb["box_hi"]) if scoring == "first"
                  else self._lb_cr("start", c_hat, cq[a], reg=geo["blocks"][sem]))
            lbs.append(bb["s_min"] * (self.w_q * lq + self.w_c * lc))
            lqs.append(lq)
        lb_cl = np.min(lbs, axis=0)
        lb_cl[bb["empty"]] = np.inf
        lq_cl = np.min(lqs, axis=0)
        order = np.argsort(lb_cl, kind="stable")
        best, parts, n, n_groups = np.inf, [], 0, 0
        clst = ex["clstart"]

        def visit(gids, lbg):
            nonlocal best, n, n_groups
            o = np.argsort(lbg, kind="stable")
            gids, lbg = gids[o], lbg[o]
            for a in range(0, gids.size, batch):
                if not lbg[a] <= self._tie_threshold(best):
                    break
                sub = gids[a:a + batch][lbg[a:a + batch] <= self._tie_threshold(best)]
                n_groups += sub.size
                out = self._eval_groups(ex, sub, q, c_r, scoring, c_hat, cq, prep, best)
                if out is not None:
                    n += out[4]
                    parts.append(out)
                    best = min(best, float(out[1].min()))

        # 2. the most promising cluster first (its clip runs, best bound first): a first best d
        first = int(order[0])
        g0 = np.arange(clst[first], clst[first + 1])
        visit(g0, self._group_lb(ex, g0, q, scoring, c_hat, cq, prep, c_r))
        # 3. every other clip run (group) whose bound can beat it; bounds from cheap to tight
        thr = self._tie_threshold(best)
        gs = ex["gsize"]
        lq_g = lq_cl[ex["gcluster"]]
        if scoring == "first":
            uc = ex["uclip"]
            lc_u = self._lb_cr("first", c_hat, None, self._nbox_lo[uc], self._nbox_hi[uc]) * self.db.size_a[uc]
            lc = lc_u[ex["gu"]]
        else:
            lc = np.min([gs * self._lb_cr("start", c_hat, cq[a], reg=geo["exgroups"][sem]) for a in q.q_n], axis=0)
        lb0 = gs * self.w_q * lq_g + self.w_c * lc
        lb0[clst[first]:clst[first + 1]] = np.inf  # visited
        cand = np.flatnonzero(lb0 <= thr)
        if scoring == "first" and cand.size:
            # exact d_cr of the clips still in (one trajectory per clip)
            need = np.unique(ex["gu"][cand])
            dcr_u = np.full(uc.size, np.inf)
            dcr_u[need] = self._d_cr(uc[need], c_r)
            lc = dcr_u[ex["gu"][cand]]
            m = gs[cand] * self.w_q * lq_g[cand] + self.w_c * lc <= thr
            cand, lc = cand[m], lc[m]
        elif cand.size:
            lc = lc[cand]
        if cand.size:
            lbg = self._group_lb(ex, cand, q, scoring, c_hat, cq, prep, c_r, lc=lc)
            m = lbg <= thr
            visit(cand[m], lbg[m])
        if stats is not None:
            stats.update(clusters_visited=int(np.unique(ex["gcluster"][cand]).size + 1), groups_scored=int(n_groups),
                         poses_scored=int(n))
        thr = self._tie_threshold(best)
        parts = [(p[0][m], p[1][m], p[2][m], p[3][m]) for p in parts for m in [p[1] <= thr]]
        return self._finish(q, parts, c_r, method="exact", n=n)
