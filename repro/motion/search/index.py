"""The database organised for the retrieval (Pronost et al., Section 3.2.2): the retrieval index.

"We propose to organize the database into clusters in a precomputation process": everything
the searches read that does not depend on the query is computed here once, in
:class:`RetrievalIndex`, and only read afterwards: k-means clusters of all poses, the closed-form
terms of the aligned distance for every pose (:func:`repro.motion.search.index_build.build_pose_index`),
the candidate poses (those before their clip's hit) of every semantics and of every (cluster,
semantics) as :class:`Block` s, the clips' hit-trajectory boxes in units of their actor's size,
padded hit trajectories, and the bounds of the exact search (:mod:`repro.motion.search.exact`):
each block's radius about its centroid, and its clips' runs of poses (*groups*) with their radii,
gathered per semantics, cluster by cluster (:attr:`RetrievalIndex.groups`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.checks import as_int
from repro.errors import MotionError, RetrievalError
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.arguments import check_weight
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance
from repro.motion.search.index_build import block_order, build_pose_index

__all__ = ["Block", "RetrievalIndex", "group_centroids", "index_dtype"]


@dataclass(eq=False)
class Block:
    """Candidate poses with their precomputed, contiguous data."""

    rows: np.ndarray  # global pose indices
    index: AlignedPoseIndex  # their closed-form terms
    clips: np.ndarray  # clip of each pose
    size: np.ndarray  # size_a of each pose's actor
    actor: np.ndarray  # base actor of each pose
    uclips: np.ndarray  # distinct clips
    inv: np.ndarray  # clips == uclips[inv]
    single_actor: int | None
    # groups (the poses of one clip in the block, contiguous since rows are sorted), for the exact search
    gstart: np.ndarray | None = None  # (G+1,) offsets
    gradius: np.ndarray | None = None  # (G,) largest aligned distance centroid -> pose
    gcent: np.ndarray | None = None  # (G, P, 3) float32 centroids, until the index gathers them


class RetrievalIndex:
    """What the searches read of a database, built once (Section 3.2.2's precomputation).

    Parameters
    ----------
    db : MotionDatabase
    k : int, optional
        Number of clusters (default :func:`repro.motion.search.kmeans.default_k`).
    seed : int, default 0
        k-means seed.
    weights : (P',) array, optional
        Pose point weights (default uniform).
    w_q, w_c : float, default 1
        Weights of ``d = w_q d_qr + w_c d_cr``, in ``(0, MAX_WEIGHT]``.

    Attributes
    ----------
    db, index, clusters, weights, centroid_index, w_q, w_c
        The database, the poses' closed-form terms, the k-means clusters, the point weights, the
        centroids' terms, the weights of ``d``.
    pose_size, size_max, startable, actors_present
        Per pose the size of its actor, the largest size, whether it can start a motion; the
        actors of the database.
    sem_rows, sem_block, cluster_block
        The candidate poses of each semantics (rows, :class:`Block`), and
        ``cluster_block[cluster][semantics]``.
    traj_padded : (C, L, 3) array
        Each clip's hit trajectory, padded with its last sample.
    box_lo, box_hi : (C, 3) arrays
        The clips' hit-trajectory boxes in units of their actor's size.
    radius : dict semantics -> (k,) array
        Per cluster the largest aligned distance (units of the actor's size) from its centroid to
        a pose of its block, so that ``D(q, p) >= D(q, m) - r`` (inf for an empty block).
    groups : dict semantics -> dict or None
        The groups of each semantics, cluster by cluster (:meth:`_gather_groups`).

    Raises
    ------
    repro.errors.RetrievalError
        Empty database; ``k`` not an int in ``[1, n_poses]``; bad ``seed``, weights, ``w_q`` or ``w_c``.
    """

    def __init__(self, db: MotionDatabase, *, k: int | None = None, seed: int = 0, weights=None,
                 w_q: float = 1.0, w_c: float = 1.0):
        if not isinstance(db, MotionDatabase):
            raise RetrievalError(f"expected a MotionDatabase, got {type(db).__name__}")
        if db.n_clips == 0 or db.n_poses == 0:
            raise RetrievalError("the motion database is empty")
        self.w_q, self.w_c = check_weight("w_q", w_q), check_weight("w_c", w_c)
        if k is not None:
            k = as_int(k, "k (number of clusters)", 1, db.n_poses, error=RetrievalError)
        seed = as_int(seed, "seed", 0, None, error=RetrievalError)
        self.db = db
        try:
            self.index, self.clusters = build_pose_index(db, k, weights=weights, seed=seed)
        except MotionError as e:
            raise RetrievalError(str(e)) from None
        self.weights = self.index.weights
        self.centroid_index = AlignedPoseIndex(self.clusters.centroids, self.weights)
        pc = db.pose_clip
        self.pose_size = db.size_a[pc]
        self.size_max = float(db.size_a.max())
        self.startable = db.pose_frame < db.hit_frame[pc]
        sem_of_pose = db.semantics[pc]
        self.actors_present = np.unique(db.actor)
        self.sem_rows = {s: np.flatnonzero(self.startable & (sem_of_pose == s)) for s in SEMANTICS}
        self.sem_block = {s: self._block(r) for s, r in self.sem_rows.items()}
        self._cluster_blocks(sem_of_pose)
        L = int((db.traj_start[1:] - db.traj_start[:-1]).max())
        idx = db.traj_start[:-1, None] + np.minimum(np.arange(L)[None, :], (db.n_frames - 1)[:, None])
        self.traj_padded = db.traj[idx]  # (C, L, 3), each padded with its last sample
        self.box_lo = db.box_min / db.size_a[:, None]
        self.box_hi = db.box_max / db.size_a[:, None]
        self.radius = {sem: self._radii(sem) for sem in SEMANTICS}
        self.groups = {sem: self._gather_groups(sem) for sem in SEMANTICS}

    @property
    def k(self) -> int:
        """Number of clusters."""
        return self.clusters.k

    def _block(self, rows: np.ndarray, clips=None, size=None, actor=None) -> Block | None:
        """Contiguous precomputed data of a set of candidate poses (None if empty); ``clips``, ``size``,
        ``actor`` of ``rows`` when already gathered (views, not copied)."""
        if rows.size == 0:
            return None
        db = self.db
        clips = db.pose_clip[rows] if clips is None else clips
        uclips, inv = np.unique(clips, return_inverse=True)
        actor = db.actor[clips] if actor is None else actor
        size = self.pose_size[rows] if size is None else size
        return Block(rows=rows, index=self.index.subset(rows), clips=clips, size=size, actor=actor,
                     uclips=uclips, inv=inv, single_actor=int(actor[0]) if np.all(actor == actor[0]) else None)

    def _cluster_blocks(self, sem_of_pose: np.ndarray) -> None:
        """``cluster_block[cluster][semantics]``: the startable poses of each (cluster, semantics), and
        ``_sem_span[semantics]``, the slice of all of its blocks, cluster by cluster.

        The candidates are gathered once in :func:`~repro.motion.search.index_build.block_order` (the
        index's stored order): each block's rows, clips, sizes and actors are views of those
        arrays, and so are the per-semantics arrays of the groups (:meth:`_gather_groups`).
        """
        db, k = self.db, self.clusters.k
        labels = self.clusters.labels
        order = self.index.order if self.index.order is not None else block_order(labels, self.startable, sem_of_pose)
        clips = db.pose_clip[order]
        self._cand = {"rows": order, "clip": clips, "size": self.pose_size[order], "actor": db.actor[clips]}
        code = np.full(order.size, len(SEMANTICS), dtype=np.intp)
        for i, s in enumerate(SEMANTICS):
            code[sem_of_pose[order] == s] = i
        at = np.searchsorted(code * k + labels[order], np.arange(len(SEMANTICS) * k + 1))
        c = self._cand
        names = ("rows", "clip", "size", "actor")
        self.cluster_block = [{s: self._block(*(c[n][at[i * k + cl]:at[i * k + cl + 1]] for n in names))
                               for i, s in enumerate(SEMANTICS)} for cl in range(k)]
        self._sem_span = {s: slice(int(at[i * k]), int(at[(i + 1) * k])) for i, s in enumerate(SEMANTICS)}

    def _radii(self, sem: str) -> np.ndarray:
        """Per cluster the radius of its block of ``sem`` about the centroid (inf if empty), after splitting
        each block into its groups (:meth:`_split_groups`).

        Radius: the largest aligned distance (units of the actor's size) from the centroid
        to a pose of the block, so that ``D(q, p) >= D(q, m) - r`` for every pose ``p`` of
        it (triangle inequality of the pseudometric ``D``).
        """
        rad = np.full(self.clusters.k, np.inf)
        for cl in range(self.clusters.k):
            b = self.cluster_block[cl][sem]
            if b is None:
                continue
            self._split_groups(b)
            rad[cl] = float(b.index.distances(self.clusters.centroids[cl]).max())
        return rad

    def _split_groups(self, b: Block) -> None:
        """Split a block into its clips' runs of poses: offsets, radius and centroid of each (exact search).

        The radius is the largest aligned distance from the run's centroid
        (:func:`group_centroids`, rounded to float32 and kept, for the runs of more than one
        pose, as ``b.gcent`` until :meth:`_gather_groups` gathers them) to its poses, so that
        ``D(q, p) >= D(q, m) - r`` for each pose ``p`` of the run (the compiled search's bound
        of a run, before its poses are scored).  The radius is measured from the rounded centroid, which
        keeps the bound exact (any centre will do), in half the memory (at 1,000x the float64 terms of the centroids
        took the build's traced peak from 3.4 to 4.3 GB, measured).
        """
        G = b.uclips.size
        gstart = np.concatenate([[0], np.flatnonzero(np.diff(b.inv)) + 1, [b.rows.size]])
        if gstart.size != G + 1:  # rows sorted, so each clip's poses are contiguous
            raise AssertionError("block rows are not grouped by clip")
        b.gstart = gstart
        pts = self.db.pose_points[b.rows]
        cent = group_centroids(self.db, b, pts).astype(np.float32)
        r = aligned_distance(cent[b.inv].astype(float), pts, self.weights)
        b.gradius = np.maximum.reduceat(r, gstart[:-1])
        b.gcent = cent[np.diff(gstart) > 1]  # a run of one pose is bounded by scoring it

    def _gather_groups(self, sem: str) -> dict | None:
        """Flat arrays of the groups (clip runs inside clusters) of ``sem``, cluster by cluster (None if none).

        Poses: ``rows``, ``index`` (their terms), ``size``, ``actor``, ``clip``, ``pu`` (position of
        their clip in ``uclip``); groups: ``gstart`` / ``glen`` (offsets into the poses), ``gclip``,
        ``gsize``, ``gactor``, ``gcluster``, ``gradius``, ``gcent`` (float32 centroids of the runs of
        more than one pose) and ``gci`` (row in ``gcent`` or -1); clusters: ``clstart`` / ``glen_cl``
        (offsets into the groups); clips: ``uclip``, ``gu`` (of each group), ``ulo`` / ``uhi`` (boxes
        in units of size), ``ugroups`` / ``ustart`` (the groups clip by clip), ``usize``, ``smin``,
        ``ucl`` (the cluster of each clip's groups, clip by clip), ``uactor``.
        """
        db, k = self.db, self.clusters.k
        blocks = [b for b in (self.cluster_block[cl][sem] for cl in range(k)) if b is not None]
        gcent = np.empty((sum(b.gcent.shape[0] for b in blocks), self.weights.size, 3), dtype=np.float32)
        nc = 0
        rows, gstart, gcl, rad, clstart = [], [0], [], [], [0]
        for cl in range(k):
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
            return None
        span = self._sem_span[sem]  # the blocks' rows, concatenated: views of the gathered candidates
        rows, psize, pactor, pclip = (self._cand[n][span] for n in ("rows", "size", "actor", "clip"))
        gstart = np.asarray(gstart, dtype=np.intp)
        gclip = db.pose_clip[rows[gstart[:-1]]]
        uclip, gu = np.unique(gclip, return_inverse=True)
        g = {
            "rows": rows, "index": self.index.subset(rows), "gstart": gstart, "glen": np.diff(gstart),
            "gclip": gclip, "gsize": db.size_a[gclip], "gactor": db.actor[gclip], "gcluster": np.concatenate(gcl),
            "gradius": np.concatenate(rad),
            "clstart": np.asarray(clstart, dtype=np.intp), "glen_cl": np.diff(clstart), "size": psize,
            "actor": pactor, "clip": pclip, "sem": sem,
            "uclip": uclip, "gu": gu, "ulo": self.box_lo[uclip], "uhi": self.box_hi[uclip],
            "pu": np.repeat(gu, np.diff(gstart)), "ugroups": np.argsort(gu, kind="stable"),
            "ustart": np.searchsorted(np.sort(gu), np.arange(uclip.size + 1)), "usize": db.size_a[uclip],
            "smin": float(db.size_a[uclip].min()),
        }
        g["gcent"] = gcent  # the centroids (float32) of the runs of more than one pose, in order
        multi = g["glen"] > 1
        g["gci"] = np.where(multi, np.cumsum(multi) - 1, -1).astype(index_dtype(multi.size))  # row in gcent, or -1
        g["ucl"] = g["gcluster"][g["ugroups"]]  # the cluster of each clip's groups, clip by clip
        g["uactor"] = db.actor[uclip]  # a clip's groups are of its actor (gactor == uactor[gu])
        return g


def group_centroids(db: MotionDatabase, b: Block, pts: np.ndarray | None = None) -> np.ndarray:
    """(G, P, 3) float64: the mean cloud of each clip run of block ``b`` of ``db`` (once split in groups)."""
    if pts is None:
        pts = db.pose_points[b.rows]
    cnt = np.diff(b.gstart).astype(float)
    return np.add.reduceat(pts, b.gstart[:-1], axis=0) / cnt[:, None, None]


def index_dtype(n: int):
    """int32 for indices below ``n`` when they fit (half the memory of intp at 1,000x), else int64."""
    return np.int32 if n < 2 ** 31 else np.int64
