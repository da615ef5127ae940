"""k-means of pose clouds (repro.motion.search.kmeans), Pronost et al., Section 3.2.2.

What is asserted: k-means is deterministic for a fixed seed, its clusters partition the
poses, its centroids are the member means, and the aligned distance to the centroid never
exceeds the canonical (unaligned) one; beyond ``max_fit`` poses it runs on a seeded subset;
bad ``k`` / ``iterations`` / ``seed`` / ``max_fit`` / weights and pose clouds of strings or complex
numbers are a MotionError, and ``k`` above the poses warns and says so (issue 9, item 7).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from repro.errors import MotionError, ReproWarning
from repro.motion.search.distance import aligned_distance
from repro.motion.search.kmeans import cluster_poses, default_k
from tests.motion.search.test_distance import cloud


def _pose_set(n: int = 300, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = np.stack([cloud(s) for s in range(4)])
    return centres[rng.integers(0, 4, n)] + rng.normal(scale=0.03, size=(n, 17, 3))


def test_kmeans_is_deterministic_for_a_seed():
    P = _pose_set()
    a = cluster_poses(P, 6, seed=3)
    b = cluster_poses(P, 6, seed=3)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.centroids, b.centroids)
    assert a.inertia == b.inertia


def test_kmeans_partition_centroids_and_bound():
    P = _pose_set()
    w = np.linspace(1, 2, 17)
    cl = cluster_poses(P, 4, weights=w, seed=0)
    assert cl.k == 4
    allm = np.sort(np.concatenate(cl.members))
    np.testing.assert_array_equal(allm, np.arange(len(P)))
    for c, m in enumerate(cl.members):
        np.testing.assert_allclose(cl.centroids[c], P[m].mean(axis=0), atol=1e-10)
        np.testing.assert_array_equal(cl.labels[m], c)
    # well separated groups are recovered: each cluster is one group (tiny inertia)
    assert cl.inertia < 0.01
    # aligned distance to the own centroid <= canonical (identity-transform) distance
    wn = w / w.sum()
    cen = cl.centroids[cl.labels]
    canon = np.sqrt(np.sum(wn * np.sum((P - cen) ** 2, axis=2), axis=1))
    aligned = aligned_distance(P, cen, w)
    assert np.all(aligned <= canon + 1e-12)


def test_kmeans_edge_cases():
    P = _pose_set(20)
    with pytest.warns(ReproWarning, match="using k = 20"):  # cut, and said so
        assert cluster_poses(P, 50).k <= 20
    one = cluster_poses(P, 1)
    assert one.k == 1 and np.all(one.labels == 0)
    with pytest.raises(MotionError):
        cluster_poses(np.zeros((0, 17, 3)))
    with pytest.raises(MotionError):
        cluster_poses(np.full((4, 17, 3), np.nan), 2)
    with pytest.raises(MotionError):
        cluster_poses(P, 0)
    assert default_k(2000) == 16
    assert default_k(1) == 1


def test_kmeans_on_a_subset_for_large_sets():
    """Above ``max_fit`` poses, k-means runs on a seeded subset; all poses get the nearest centroid."""
    P = _pose_set(600, seed=2)
    a = cluster_poses(P, 4, seed=1, max_fit=150)
    b = cluster_poses(P, 4, seed=1, max_fit=150)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.centroids, b.centroids)
    assert a.inertia < 0.01  # the four groups are still recovered
    np.testing.assert_array_equal(np.sort(np.concatenate(a.members)), np.arange(600))


# ----------------------------------------------------------------- refusals (issue 9, item 7)
# ----------------------------------------------------------------- k-means
def _poses(n=40, seed=0):
    return np.random.default_rng(seed).normal(size=(n, 17, 3))


KMEANS_BAD = [
    dict(k=0), dict(k=2.5), dict(k="3"), dict(k=True), dict(seed=-1), dict(seed="s"), dict(seed=0.5),
    dict(iterations=0), dict(iterations=2.5), dict(iterations=10**9), dict(max_fit=0), dict(max_fit=2, k=5),
    dict(max_fit=3.5), dict(weights="x"), dict(weights=np.ones(17) * 1j), dict(weights=np.ones(3)),
]


@pytest.mark.parametrize("kw", KMEANS_BAD, ids=repr)
def test_bad_kmeans_arguments(kw):
    kw = {"k": 3, **kw}
    with pytest.raises(MotionError):
        cluster_poses(_poses(), **kw)


@pytest.mark.parametrize("points", [np.full((5, 17, 3), "a"), _poses() * 1j, None, "poses", [[1, 2, 3]]], ids=repr)
def test_bad_kmeans_points(points):
    with pytest.raises(MotionError):
        cluster_poses(points, 2)


def test_kmeans_k_above_n_warns_and_says_so():
    with pytest.warns(ReproWarning, match="k = 50 .* 40 poses"):
        assert cluster_poses(_poses(), 50).k <= 40
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cluster_poses(_poses(), 4)
