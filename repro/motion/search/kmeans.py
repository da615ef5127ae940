"""k-means of pose clouds (Pronost et al., Section 3.2.2, Clustering).

"we choose the K-mean clustering algorithm [...] to gather poses of various motions into
clusters in order to minimize the total intra-cluster variance."

k-means and the aligned distance
--------------------------------
:func:`cluster_poses` runs :func:`scipy.cluster.vq.kmeans2` (k-means++ seeding, a fixed
seed, so the result is deterministic) on the poses in their canonical root frame
(flattened and multiplied by ``sqrt(w)``, so that squared Euclidean distance is the
weighted squared distance *without* alignment).  Because the identity is one of the
transformations the aligned distance (:mod:`repro.motion.search.distance`) minimises over,
``D(p, q) <= |p - q|_w`` for poses in canonical frames: k-means minimises an upper bound of the aligned intra-cluster
variance, and each centroid (the weighted mean cloud of its members in the canonical
frame) is itself a pose cloud that the aligned distance can compare with a query; the
retrieval (:mod:`repro.motion.search.retrieval`) picks the cluster whose centroid is nearest
to the query in the aligned distance.  Putting poses in the canonical heading frame
before k-means removes most of what the alignment would remove (the residual is the
heading-estimation error), which is why the bound is tight in practice.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.sparse import csr_matrix

from repro.checks import as_int
from repro.errors import MotionError, ReproWarning
from repro.motion.body.pose_frames import CHUNK, float_poses, pose_weights

__all__ = ["PoseClusters", "cluster_poses", "default_k", "MAX_ITERATIONS"]

#: Most k-means iterations :func:`cluster_poses` accepts (each is one pass over the poses).
MAX_ITERATIONS: int = 10_000


@dataclass(eq=False)
class PoseClusters:
    """Result of :func:`cluster_poses`.

    Attributes
    ----------
    centroids : (k, P, 3) array
        Mean cloud of each cluster, in the canonical root frame (same units as the
        poses).
    labels : (N,) int array
        Cluster of each pose.
    members : list of (n_c,) int arrays
        Pose indices of each cluster (sorted).
    weights : (P,) array
        Point weights used.
    seed : int
    inertia : float
        Mean weighted squared distance of the poses to their centroid (unaligned, in the
        canonical frame): the k-means objective, an upper bound of the aligned one.
    """

    centroids: np.ndarray
    labels: np.ndarray
    members: list
    weights: np.ndarray
    seed: int
    inertia: float

    @property
    def k(self) -> int:
        """Number of clusters."""
        return int(self.centroids.shape[0])

    def sizes(self) -> np.ndarray:
        """(k,) number of poses per cluster."""
        return np.array([m.size for m in self.members])


def default_k(n_poses: int) -> int:
    """Default number of clusters: ``round(sqrt(n_poses / 8))``, in [1, 256].

    About 16 clusters for the ~2,000 poses of the CMU database at 30 Hz (a cluster
    holds ~125 poses, so the pruned search scores ~1/16 of the poses).
    """
    n_poses = as_int(n_poses, "n_poses", 0, None, error=MotionError)
    return int(np.clip(round(math.sqrt(max(n_poses, 1) / 8.0)), 1, 256))


def _nearest_centroid(X: np.ndarray, C: np.ndarray, chunk: int = CHUNK) -> np.ndarray:
    """Index of the nearest row of C for every row of X (squared Euclidean, via BLAS).

    ``argmin_c |c|^2 - 2 x.c`` (``|x|^2`` does not change the argmin), one matrix product per
    chunk into a reused buffer.
    """
    c2 = np.einsum("ij,ij->i", C, C)
    out = np.empty(X.shape[0], dtype=np.intp)
    buf = np.empty((min(chunk, X.shape[0]), C.shape[0]), dtype=np.result_type(X, C))
    for a in range(0, X.shape[0], chunk):
        Xa = X[a:a + chunk]
        D = np.matmul(Xa, C.T, out=buf[:Xa.shape[0]])
        D *= -2.0
        D += c2
        out[a:a + Xa.shape[0]] = np.argmin(D, axis=1)
    return out


def _label_sums(labels: np.ndarray, X: np.ndarray, k: int) -> np.ndarray:
    """(k, D) float64 sums of the rows of X per label: one sparse product (the same sums, in the same
    order, as one :func:`numpy.bincount` per column)."""
    n = labels.size
    onehot = csr_matrix((np.ones(n), (labels, np.arange(n))), shape=(k, n))
    return np.asarray(onehot @ X.astype(np.float64, copy=False))


def _kmeans_sample(X: np.ndarray, k: int, iterations: int, rng) -> np.ndarray:
    """k-means++ seeding and Lloyd iterations on a sample, with BLAS distances (float32).

    The seeding keeps every point's squared distance to its nearest chosen centre and
    updates it with one new centre at a time (O(n k), where
    :func:`scipy.cluster.vq.kmeans2`'s ``minit="++"`` recomputes the distances to all
    chosen centres at every step, O(n k^2)).
    """
    n = X.shape[0]
    x2 = np.einsum("ij,ij->i", X, X)
    C = np.empty((k, X.shape[1]), dtype=X.dtype)
    C[0] = X[rng.integers(n)]
    best = np.maximum(x2 - 2.0 * (X @ C[0]) + C[0] @ C[0], 0.0)
    for j in range(1, k):
        tot = float(best.sum(dtype=np.float64))
        i = int(rng.integers(n)) if tot <= 0 else int(np.searchsorted(np.cumsum(best, dtype=np.float64),
                                                                      rng.random() * tot))
        C[j] = X[min(i, n - 1)]
        np.minimum(best, np.maximum(x2 - 2.0 * (X @ C[j]) + C[j] @ C[j], 0.0), out=best)
    for _ in range(iterations):
        lab = _nearest_centroid(X, C)
        C = _means(X, lab, k, C)
    return C


def _means(X: np.ndarray, labels: np.ndarray, k: int, previous: np.ndarray) -> np.ndarray:
    """Mean of every label's rows (one bincount per column); an empty label keeps ``previous``."""
    cnt = np.bincount(labels, minlength=k).astype(np.float64)
    S = _label_sums(labels, X, k)
    out = np.array(previous, dtype=np.float64)
    nz = cnt > 0
    out[nz] = S[nz] / cnt[nz, None]
    return out.astype(X.dtype)


def cluster_poses(points: np.ndarray, k: int | None = None, *, weights=None, seed: int = 0,
                  iterations: int = 20, max_fit: int | None = 20_000) -> PoseClusters:
    """k-means of pose clouds (Section 3.2.2), deterministic for a fixed seed.

    Parameters
    ----------
    points : (N, P, 3) array
        Pose clouds in their canonical root frames (:func:`~repro.motion.body.pose_frames.pose_points`); float32 or
        float64, never copied whole (the passes over all poses work by chunks of
        :data:`~repro.motion.body.pose_frames.CHUNK` rows).
    k : int, optional
        Number of clusters, an int >= 1 (default :func:`default_k`); more than N is cut
        to N with a :class:`~repro.errors.ReproWarning` saying so.
    weights : (P,) array, optional
        Point weights; default uniform.
    seed : int, default 0
        Seed (an int >= 0) of the k-means++ initialisation (:func:`scipy.cluster.vq.kmeans2`).
    iterations : int, default 20
        k-means iterations, in ``[1, MAX_ITERATIONS]`` (10,000).
    max_fit : int or None, default 20,000
        With more poses than this (the 10x / 100x / 1,000x augmented databases), k-means
        runs on a random subset of ``max_fit`` poses (drawn with ``seed``; k-means++
        seeding and Lloyd iterations with BLAS distances in float32, linear in ``k`` per
        seed, :func:`_kmeans_sample`), then every pose is assigned to its nearest
        centroid in chunks and the centroids are recomputed as the means of their
        members (one more Lloyd step on all poses).  Memory: float32 chunks, never a
        second copy of all poses.  Up to ``max_fit`` poses (the paper-size databases)
        :func:`scipy.cluster.vq.kmeans2` runs on all of them.  None: always the latter.

    Returns
    -------
    PoseClusters
        Empty clusters (possible with k-means) are dropped, so ``k`` may be smaller
        than asked.

    Raises
    ------
    repro.errors.MotionError
        Empty, non-numeric or non-finite input; ``k``, ``seed``, ``iterations`` or
        ``max_fit`` not an integer in range (``max_fit`` must be >= ``k``).
    """
    p = float_poses(points, "poses")
    N, P, _ = p.shape
    k = default_k(N) if k is None else as_int(k, "k (number of clusters)", 1, error=MotionError)
    seed = as_int(seed, "seed", 0, error=MotionError)
    iterations = as_int(iterations, "iterations", 1, MAX_ITERATIONS, error=MotionError)
    if k > N:
        warnings.warn(f"k = {k} clusters asked for {N} poses; using k = {N}", ReproWarning, stacklevel=2)
        k = N
    if max_fit is not None:
        max_fit = as_int(max_fit, "max_fit", k, error=MotionError)
    w = pose_weights(P, weights)
    sw = np.sqrt(w)[None, :, None]
    if max_fit is not None and N > max_fit and k > 1:
        return _cluster_large(p, k, w, seed, iterations, int(max_fit))
    X = (p.astype(float, copy=False) * sw).reshape(N, 3 * P)
    if k == 1:
        labels = np.zeros(N, dtype=np.intp)
        C = X.mean(axis=0, keepdims=True)
    else:
        rng = np.random.default_rng(seed)
        C, labels = kmeans2(X, k, iter=iterations, minit="++", rng=rng)
        labels = labels.astype(np.intp)
    used = np.unique(labels)
    remap = np.full(max(k, 1), -1, dtype=np.intp)
    remap[used] = np.arange(used.size)
    labels = remap[labels]
    C = np.stack([X[labels == c].mean(axis=0) for c in range(used.size)])
    inertia = float(np.mean(np.sum((X - C[labels]) ** 2, axis=1)))
    centroids = C.reshape(-1, P, 3) / sw
    members = [np.flatnonzero(labels == c) for c in range(used.size)]
    return PoseClusters(centroids=centroids, labels=labels, members=members, weights=w, seed=int(seed),
                        inertia=inertia)


def _cluster_large(p: np.ndarray, k: int, w: np.ndarray, seed: int, iterations: int, max_fit: int,
                   chunk: int = CHUNK) -> PoseClusters:
    """:func:`cluster_poses` beyond ``max_fit`` poses: k-means of a sample, one pass over all."""
    N, P, _ = p.shape
    sw = np.sqrt(w).astype(np.float32)[None, :, None]
    rng = np.random.default_rng(seed)
    fit = np.sort(rng.choice(N, max_fit, replace=False))
    C = _kmeans_sample((p[fit].astype(np.float32) * sw).reshape(max_fit, 3 * P), k, iterations, rng)
    labels = np.empty(N, dtype=np.intp)
    S = np.zeros((k, 3 * P))
    for a in range(0, N, chunk):
        Xc = (p[a:a + chunk].astype(np.float32) * sw).reshape(-1, 3 * P)
        lab = _nearest_centroid(Xc, C)
        labels[a:a + chunk] = lab
        S += _label_sums(lab, Xc, k)
    cnt = np.bincount(labels, minlength=k)
    used = np.flatnonzero(cnt)
    remap = np.full(k, -1, dtype=np.intp)
    remap[used] = np.arange(used.size)
    labels = remap[labels]
    Cm = S[used] / cnt[used, None]
    inertia = 0.0
    for a in range(0, N, chunk):
        Xc = (p[a:a + chunk].astype(float, copy=False) * sw).reshape(-1, 3 * P)
        inertia += float(np.sum((Xc - Cm[labels[a:a + chunk]]) ** 2))
    order = np.argsort(labels, kind="stable")
    members = np.split(order, np.cumsum(cnt[used])[:-1])
    centroids = Cm.reshape(-1, P, 3) / np.sqrt(w)[None, :, None]
    return PoseClusters(centroids=centroids, labels=labels, members=members, weights=w, seed=int(seed),
                        inertia=inertia / N)
