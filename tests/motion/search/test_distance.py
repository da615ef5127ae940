"""Kovar et al.'s aligned distance (repro.motion.search.distance), Pronost et al., Section 3.2.2.

What is asserted:

* the closed form of the aligned distance equals a numerical minimisation over
  (theta, x0, z0), and the transformation it returns achieves it;
* it is zero for identical poses, symmetric, and invariant to rotating either pose about
  the vertical axis and translating it on the floor (hypothesis);
* the vectorised :class:`AlignedPoseIndex` equals the plain function, for all rows and
  for subsets, transformations included, and its direct distance keeps precision at a match;
* the pose functions refuse pose clouds, weights and indices that are not numbers (issue 9, item 7).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import minimize

from repro.errors import MotionError
from repro.motion.body.pose_frames import pose_points, pose_weights, rotate_y
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance
from tests.motion.body.test_pose_frames import angles, move, shifts

seeds = st.integers(0, 10_000)


def cloud(seed: int, n: int = 17) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.normal(scale=0.4, size=(n, 3))
    p[:, 1] += 1.0
    return p


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


def test_pose_functions_refuse_non_numbers():
    p = np.random.default_rng(0).normal(size=(3, 17, 3))  # three random pose clouds
    for bad in ("x", p * 1j, [["a", "b", "c"]] * 17):
        with pytest.raises(MotionError):
            aligned_distance(bad, p[0])
        with pytest.raises(MotionError):
            AlignedPoseIndex(p).distances(bad)
    with pytest.raises(MotionError):
        AlignedPoseIndex("abc")
    with pytest.raises(MotionError):
        pose_weights(17, ["a"] * 17)
    g = np.zeros((4, 20, 3))
    for kw in (dict(window=0), dict(window=1.5), dict(step="2")):
        with pytest.raises(MotionError):
            pose_points(g, [0, 1], 0, 1, 2, **kw)
    with pytest.raises(MotionError):
        pose_points(g, [0, 25], 0, 1, 2)
    with pytest.raises(MotionError):
        pose_points(g, [0, 1], 0, 99, 2)
