"""Root frames and pose clouds (repro.motion.body.pose_frames), Pronost et al., Section 3.2.2.

What is asserted: heading 0 for a body facing +z, pi/2 facing +x, and the root frame's
inverse; pose clouds are the same whatever the body's heading and floor position; a pose
window takes past frames, clamped at the first.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro.motion.body.pose_frames import (
    from_root_frame,
    heading_from_hips,
    pose_points,
    root_frames,
    rotate_y,
    to_root_frame,
)


def move(p: np.ndarray, theta: float, tx: float, tz: float) -> np.ndarray:
    return rotate_y(p, theta) + np.array([tx, 0.0, tz])


angles = st.floats(-np.pi, np.pi, allow_nan=False)
shifts = st.floats(-5.0, 5.0, allow_nan=False)


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
