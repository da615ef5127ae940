"""Building the retrieval's pose index for databases up to 1,000x (Pronost et al., Section 3.2.2).

"We propose to organize the database into clusters in a precomputation process": k-means of
all poses (:func:`repro.motion.search.kmeans.cluster_poses`: beyond 20,000 poses, k-means on a
seeded sample then one chunked assignment pass over all poses) and the closed-form terms of
the aligned distance (:class:`~repro.motion.search.distance.AlignedPoseIndex`).

Why a sample and one assignment pass is enough: the exact search
(:meth:`repro.motion.search.retrieval.MotionRetriever.search_exact`) only needs *valid* bounds, each
cluster's centroid and radius (largest aligned distance of its poses to the centroid, computed
on the poses actually assigned), whatever the clustering; the paper's pruned search uses the
clusters as its approximation, so a different clustering changes which poses it looks at, and
its miss rate is measured against the exhaustive optimum in the same run
(``retrieval_latency``).  The sampled k-means is the one the 10x and 100x figures already used.

Memory: the retriever's candidate blocks (per semantics; per cluster and semantics; the exact
search's per semantics, cluster by cluster) are subsets of the startable poses.  Built as
copies, they held the float64 terms (51 doubles a pose) three times over besides the full
index: above 6 GB for the 1,000x database.  :func:`build_pose_index` stores the terms of the
startable poses once, ordered by (semantics, cluster, pose) (:func:`block_order`), so that the
per-cluster blocks and the exact search's blocks are views of it
(:meth:`AlignedPoseIndex.subset`), scalar terms included (and only for the startable poses);
the retriever gathers the candidates' rows, clips, sizes and actors once in that order too, and
keeps no centroid per clip run (only their radii).  Measured by ``repro bench index`` (2 cores,
shared): 1,000x, 4,557,581 float32 poses, database and index in 80 s, 3.41 GB peak traced
(3.69 GB max RSS), from 4.72 GB.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from repro.motion.database.annotation import SEMANTICS
from repro.motion.search.distance import AlignedPoseIndex
from repro.motion.search.kmeans import PoseClusters, cluster_poses
from repro.motion.database.clips import MotionDatabase

__all__ = ["block_order", "build_pose_index", "startable_poses"]


def startable_poses(db: MotionDatabase) -> np.ndarray:
    """(N,) bool: poses a clip can be started from (before its hit frame), the search's candidates."""
    return db.pose_frame < db.hit_frame[db.pose_clip]


def block_order(labels: np.ndarray, candidates: np.ndarray, semantics: np.ndarray,
                order: Sequence[str] = SEMANTICS) -> np.ndarray:
    """The candidate poses ordered by (semantics in ``order``, cluster label, pose index).

    Parameters
    ----------
    labels : (N,) int array
        Cluster of every pose (:attr:`PoseClusters.labels`).
    candidates : (N,) bool array
        Poses to store (:func:`startable_poses`).
    semantics : (N,) str array
        Semantics of every pose's clip.

    Returns
    -------
    (n,) int array
        Every pose of ``candidates`` whose semantics is in ``order``, once: the rows of each
        (semantics, cluster) block are consecutive and ascending, and so are the rows of
        each semantics taken cluster by cluster.
    """
    code = np.full(labels.size, len(order), dtype=np.intp)
    for i, s in enumerate(order):
        code[semantics == s] = i
    rows = np.flatnonzero(candidates & (code < len(order)))
    return rows[np.lexsort((rows, labels[rows], code[rows]))]


def build_pose_index(db: MotionDatabase, k: int | None = None, *, weights=None,
                     seed: int = 0) -> tuple[AlignedPoseIndex, PoseClusters]:
    """The clusters of all poses of ``db`` and the aligned-distance index of its poses.

    ``k``, ``weights``, ``seed``: as :func:`cluster_poses`.  The index stores the terms of
    the startable poses in :func:`block_order` (the others, never candidates, are recomputed
    if asked for).  Raises :class:`~repro.errors.MotionError` as :func:`cluster_poses` does.
    """
    clusters = cluster_poses(db.pose_points, k, weights=weights, seed=seed)
    order = block_order(clusters.labels, startable_poses(db), db.semantics[db.pose_clip])
    return AlignedPoseIndex(db.pose_points, weights, order=order), clusters
