"""Scoring ``d_cr`` in the frame of the candidate's start pose (``scoring="start"``).

The methods of :class:`StartScoring` are those of
:class:`repro.motion.search.retrieval.MotionRetriever` (a mixin) that place a clip's hit trajectory
where it is played from a start pose (aligned on ``q_r`` as
:meth:`~repro.motion.search.retrieval.RetrievalResult.place` does) and measure its closest approach to
``c_r`` from the start frame on, plus the alignment-invariant region (distance range from the
pose's vertical centroid axis, height range) that bounds it for the exact search.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from repro.motion.database.annotation import SEMANTICS
from repro.motion.body.pose_frames import rotate_y

if TYPE_CHECKING:  # annotations only (retrieval imports this module)
    from repro.motion.search.retrieval import Query

__all__ = ["StartScoring"]


class StartScoring:
    """Start-frame scoring methods of :class:`~repro.motion.search.retrieval.MotionRetriever`."""

    def _start_geometry(self) -> dict:
        """Per pose: where its clip's hit trajectory lies when the clip is played from it.

        For a startable pose ``p`` (clip ``i``, frame ``f``): ``phi``, ``u`` with
        ``traj_f = R_y(phi) traj_0 + u`` (the trajectory from the root frame of the clip's
        first frame to the root frame of frame ``f``, actor metres), and over the played
        part ``t >= f`` of it, the range ``[rho_lo, rho_hi]`` of horizontal distances from
        the pose's weighted centroid and ``[y_lo, y_hi]`` of heights (units of the actor's
        size): an alignment-invariant region (the aligned placement rotates about the
        centroid), hence a bound of ``d_cr`` in the start frame.  Built on first use.
        """
        if self._start is not None:
            return self._start
        db = self.db
        N = db.n_poses
        phi = np.zeros(N)
        u = np.zeros((N, 3))
        rho = np.zeros((N, 2))
        yr = np.zeros((N, 2))
        cx, cz = np.zeros(N), np.zeros(N)
        st = np.flatnonzero(self.startable)
        cx[st], cz[st] = self.index.centroids_xz(st)
        for i in range(db.n_clips):
            F, hf = int(db.n_frames[i]), int(db.hit_frame[i])
            nf = min(hf, F)
            if nf <= 0:
                continue
            p0, t0 = int(db.pose_start[i]), int(db.traj_start[i])
            s = float(db.size_a[i])
            th = db.pose_heading[p0:p0 + nf]
            o = db.pose_origin[p0:p0 + nf]
            tr0 = db.traj[t0:t0 + F]
            ph = th[0] - th
            uu = rotate_y(o[0] - o, -th)
            phi[p0:p0 + nf] = ph
            u[p0:p0 + nf] = uu
            trf = rotate_y(tr0[None, :, :], ph[:, None]) + uu[:, None, :]  # (nf, F, 3)
            r = np.hypot(trf[..., 0] / s - cx[p0:p0 + nf, None], trf[..., 2] / s - cz[p0:p0 + nf, None])
            played = np.arange(F)[None, :] >= np.arange(nf)[:, None]
            rho[p0:p0 + nf, 0] = np.where(played, r, np.inf).min(axis=1)
            rho[p0:p0 + nf, 1] = np.where(played, r, -np.inf).max(axis=1)
            y = tr0[:, 1] / s
            yr[p0:p0 + nf, 0] = np.minimum.accumulate(y[::-1])[::-1][:nf]
            yr[p0:p0 + nf, 1] = np.maximum.accumulate(y[::-1])[::-1][:nf]
        exgroups = {}
        for sem in SEMANTICS:
            if self._ex.get(sem) is not None:
                ex = self._ex[sem]
                gs = ex["gstart"][:-1]
                rr, yy = rho[ex["rows"]], yr[ex["rows"]]
                exgroups[sem] = np.stack([np.minimum.reduceat(rr[:, 0], gs), np.maximum.reduceat(rr[:, 1], gs),
                                          np.minimum.reduceat(yy[:, 0], gs), np.maximum.reduceat(yy[:, 1], gs)], axis=1)
        self._start = {"exgroups": exgroups, "phi": phi, "u": u, "rho": rho, "y": yr}
        return self._start

    def _d_cr_start_per_actor(self, q: Query, rows: np.ndarray, alpha: np.ndarray, actor: np.ndarray,
                              c_hat: np.ndarray, cq) -> np.ndarray:
        """:meth:`_d_cr_start` for poses of several actors (each with its own ``q_r`` centroid ``cq[a]``)."""
        dcr = np.empty(rows.size)
        for a in q.q_n:
            sel = actor == a
            if np.any(sel):
                dcr[sel] = self._d_cr_start(rows[sel], alpha[sel], c_hat, cq[a])
        return dcr

    def _d_cr_start(self, rows: np.ndarray, alpha: np.ndarray, c_hat: np.ndarray, cq: np.ndarray,
                    chunk: int = 8192) -> np.ndarray:
        """Exact ``d_cr`` (actor metres) of poses ``rows`` scored in their start frame.

        The clip played from pose ``p`` (aligned on ``q_r`` by the rotation ``alpha`` about
        the vertical and the translation that matches the horizontal centroids) brings its
        hit point closest to ``c_r`` at ``min_{t >= f} |traj_0(t) - c_0|`` where ``c_0`` is
        the target taken back to the clip's first-frame root frame.
        """
        db = self.db
        g = self._start_geometry()
        clips = db.pose_clip[rows]
        s = db.size_a[clips]
        f = db.pose_frame[rows]
        # target in the pose's canonical frame (units of size), then actor metres, then frame 0
        v = c_hat[None, :] - np.array([cq[0], 0.0, cq[1]])[None, :]
        cf = rotate_y(v, -alpha)
        cx, cz = self.index.centroids_xz(rows)
        cf[:, 0] += cx
        cf[:, 2] += cz
        c0 = rotate_y(cf * s[:, None] - g["u"][rows], -g["phi"][rows])
        out = np.empty(rows.size)
        L = self.traj_padded.shape[1]
        t = np.arange(L)
        for a in range(0, rows.size, chunk):
            sl = slice(a, a + chunk)
            diff = self.traj_padded[clips[sl]] - c0[sl, None, :]
            d2 = np.einsum("ctk,ctk->ct", diff, diff)
            d2[t[None, :] < f[sl, None]] = np.inf
            out[sl] = np.sqrt(d2.min(axis=1))
        return out
