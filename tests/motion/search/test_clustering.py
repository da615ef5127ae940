"""Pose clouds, Kovar et al.'s aligned distance and k-means (repro.motion.search.clustering).

Pronost et al., Section 3.2.2.  What is asserted:

* the closed form of the aligned distance equals a numerical minimisation over
  (theta, x0, z0), and the transformation it returns achieves it;
* it is zero for identical poses, symmetric, and invariant to rotating either pose about
  the vertical axis and translating it on the floor (hypothesis);
* the vectorised :class:`AlignedPoseIndex` equals the plain function, for all rows and
  for subsets, transformations included;
* root frames: heading 0 for a body facing +z, pi/2 facing +x; pose clouds are the same
  whatever the body's heading and floor position;
* k-means is deterministic for a fixed seed, its clusters partition the poses, its
  centroids are the member means, and the aligned distance to the centroid never exceeds
  the canonical (unaligned) one.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import minimize

from repro.errors import MotionError, ReproWarning
from repro.motion.search.clustering import (
    AlignedPoseIndex,
    aligned_distance,
    cluster_poses,
    default_k,
    heading_from_hips,
    pose_points,
    root_frames,
    rotate_y,
    to_root_frame,
    from_root_frame,
)


def cloud(seed: int, n: int = 17) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.normal(scale=0.4, size=(n, 3))
    p[:, 1] += 1.0
    return p


def move(p: np.ndarray, theta: float, tx: float, tz: float) -> np.ndarray:
    return rotate_y(p, theta) + np.array([tx, 0.0, tz])


def test_closed_form_equals_numerical_minimum():
    for seed in range(5):
        a, b = cloud(seed), cloud(100 + seed)
        w = np.random.default_rng(seed).uniform(0.2, 2.0, a.shape[0])
        d, th, x0, z0 = aligned_distance(a, b, w, return_transform=True)
        wn = w / w.sum()

        def cost(x):
            return np.sum(wn * np.sum((a - move(b, *x)) ** 2, axis=1))

        best = min((minimize(cost, [t, 0.0, 0.0], method="BFGS") for t in np.linspace(-3, 3, 7)),
                   key=lambda r: r.fun)
        assert d**2 == pytest.approx(best.fun, rel=1e-7, abs=1e-10)
        assert cost([th, x0, z0]) == pytest.approx(d**2, rel=1e-10, abs=1e-12)


angles = st.floats(-np.pi, np.pi, allow_nan=False)
shifts = st.floats(-5.0, 5.0, allow_nan=False)
seeds = st.integers(0, 10_000)


@given(seeds, seeds, angles, shifts, shifts)
def test_invariant_to_vertical_rotation_and_floor_translation(sa, sb, theta, tx, tz):
    a, b = cloud(sa), cloud(sb + 1)
    d0 = aligned_distance(a, b)
    assert aligned_distance(a, move(b, theta, tx, tz)) == pytest.approx(d0, rel=1e-7, abs=1e-7)
    assert aligned_distance(move(a, -theta, tz, tx), b) == pytest.approx(d0, rel=1e-7, abs=1e-7)


@given(seeds, angles, shifts, shifts)
def test_zero_for_identical_and_rigidly_moved_pose(s, theta, tx, tz):
    a = cloud(s)
    assert aligned_distance(a, a) == pytest.approx(0.0, abs=1e-7)
    assert aligned_distance(a, move(a, theta, tx, tz)) == pytest.approx(0.0, abs=1e-6)


@given(seeds, seeds)
def test_symmetric(sa, sb):
    a, b = cloud(sa), cloud(sb + 7)
    assert aligned_distance(a, b) == pytest.approx(aligned_distance(b, a), rel=1e-9, abs=1e-9)


def test_vertical_translation_is_not_aligned():
    """Heights count: lifting a pose by h gives distance h (Kovar et al. align x, z only)."""
    a = cloud(3)
    b = a + np.array([0.0, 0.25, 0.0])
    assert aligned_distance(a, b) == pytest.approx(0.25, rel=1e-9)


def test_index_matches_plain_function():
    rng = np.random.default_rng(0)
    cands = np.stack([cloud(s) for s in range(50)])
    w = rng.uniform(0.5, 1.5, 17)
    q = cloud(999)
    idx = AlignedPoseIndex(cands, w)
    d, th, x0, z0 = idx.distances(q, return_transform=True)
    d2, th2, x02, z02 = aligned_distance(q, cands, w, return_transform=True)
    np.testing.assert_allclose(d, d2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.cos(th - th2), 1.0, atol=1e-9)
    np.testing.assert_allclose(x0, x02, atol=1e-9)
    np.testing.assert_allclose(z0, z02, atol=1e-9)
    rows = np.array([3, 17, 17, 42])
    np.testing.assert_allclose(idx.distances(q, rows), d2[rows], rtol=1e-9, atol=1e-9)
    # the transformation maps each candidate onto the query with RMS equal to d
    k = 5
    moved = rotate_y(cands[k], th[k]) + np.array([x0[k], 0, z0[k]])
    wn = w / w.sum()
    assert np.sqrt(np.sum(wn * np.sum((q - moved) ** 2, axis=1))) == pytest.approx(d[k], rel=1e-9)


def test_bad_inputs():
    with pytest.raises(MotionError):
        aligned_distance(np.zeros((3, 3)), np.zeros((4, 3)))
    with pytest.raises(MotionError):
        aligned_distance(np.full((3, 3), np.nan), np.zeros((3, 3)))
    with pytest.raises(MotionError):
        aligned_distance(np.zeros((3, 3)), np.zeros((3, 3)), weights=[1, -1, 1])
    with pytest.raises(MotionError):
        AlignedPoseIndex(np.zeros((2, 3, 3))).distances(np.zeros((4, 3)))


# ------------------------------------------------------------------ root frames
def test_heading_convention():
    # left hip at +x: the body faces +z (BVH rest pose of CMU and the synthetic actor)
    assert heading_from_hips([0.1, 1, 0], [-0.1, 1, 0]) == pytest.approx(0.0)
    # left hip at -z: the body faces +x
    assert heading_from_hips([0, 1, -0.1], [0, 1, 0.1]) == pytest.approx(np.pi / 2)
    th = 0.7
    p = np.array([0.3, 1.2, -0.4])
    o = np.array([2.0, 0.0, -1.0])
    np.testing.assert_allclose(from_root_frame(to_root_frame(p, th, o), th, o), p, atol=1e-12)
    # forward (sin th, 0, cos th) is +z in the root frame
    np.testing.assert_allclose(to_root_frame(o + [np.sin(th), 0, np.cos(th)], th, o), [0, 0, 1], atol=1e-12)


def _toy_motion(F: int = 6, seed: int = 0) -> np.ndarray:
    """(F, 5, 3) positions: pelvis, left hip, right hip, hand, foot."""
    rng = np.random.default_rng(seed)
    base = np.array([[0, 1.0, 0], [0.1, 0.95, 0], [-0.1, 0.95, 0], [0.3, 1.3, 0.4], [0.1, 0.05, 0.1]])
    return base[None] + rng.normal(scale=0.05, size=(F, 5, 3))


@given(angles, shifts, shifts, st.integers(1, 3))
def test_pose_points_do_not_depend_on_heading_or_floor_position(theta, tx, tz, window):
    g = _toy_motion()
    g2 = move(g, theta, tx, tz)
    p1 = pose_points(g, [0, 3, 4], 0, 1, 2, window=window)
    p2 = pose_points(g2, [0, 3, 4], 0, 1, 2, window=window)
    assert p1.shape == (6, 3 * window, 3)
    np.testing.assert_allclose(p1, p2, atol=1e-9)
    th, o = root_frames(g2, 0, 1, 2)
    np.testing.assert_allclose(o[:, 1], 0.0)


def test_pose_points_window_uses_past_frames():
    g = _toy_motion(F=5)
    p = pose_points(g, [3], 0, 1, 2, window=3, step=2)  # frames f-4, f-2, f (clamped)
    th, o = root_frames(g, 0, 1, 2)
    np.testing.assert_allclose(p[4, 0], to_root_frame(g[0, 3], th[4], o[4]), atol=1e-12)
    np.testing.assert_allclose(p[4, 1], to_root_frame(g[2, 3], th[4], o[4]), atol=1e-12)
    np.testing.assert_allclose(p[1, 0], to_root_frame(g[0, 3], th[1], o[1]), atol=1e-12)


# ------------------------------------------------------------------- k-means
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


def test_direct_distance_equals_the_closed_form_and_keeps_precision_at_a_match():
    """``AlignedPoseIndex.direct_distance``: the closed form's distance and transform, but summed
    directly, so a query equal to a stored pose (moved and turned) is at ~0, not ~1e-8."""
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(20, 9, 3)) + [0.0, 1.0, 0.0]
    w = rng.uniform(0.5, 2.0, 9)
    idx = AlignedPoseIndex(pts, w)
    q = rng.normal(size=(9, 3))
    for row in (0, 7, 19):
        d, theta, x0, z0 = idx.direct_distance(q, row)
        ref, rt, rx, rz = aligned_distance(q, pts[row], w, return_transform=True)
        assert d == pytest.approx(float(ref), rel=1e-10, abs=1e-12)
        assert (theta, x0, z0) == pytest.approx((float(rt), float(rx), float(rz)), abs=1e-12)
    match = rotate_y(pts[5], 0.7) + [3.0, 0.0, -2.0]  # pose 5, turned about y and moved
    assert idx.direct_distance(match, 5)[0] < 1e-13
    with pytest.raises(MotionError, match="subset"):
        idx.subset([1, 2]).direct_distance(q, 0)
