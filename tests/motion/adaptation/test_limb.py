"""The limb step of Section 3.4.2 (repro.motion.adaptation.limb): reachable targets reached to rounding,
hand orientation kept, bone lengths unchanged, elbow kept in its plane, one-frame scalar path == numpy
batch path; unreachable targets give the exact excess distance, not an exception."""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.adaptation import reach_limb
from tests.motion_fixtures import MIXAMO
from tests.motion.adaptation.fixture import IDX, OFFSETS, PARENTS, fixture_motion, quat_angle, with_rotations


def test_reach_limb_reaches_keeps_hand_and_bone_lengths():
    m = fixture_motion()
    gq, gp = m.global_transforms()
    w = IDX["RightHand"]
    goal = gp[:, w] + np.array([0.05, -0.08, 0.03])
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert sol.reached.all() and sol.residual.max() < 1e-12
    m2 = with_rotations(m, slice(None), sol.rotations)
    gq2, gp2 = m2.global_transforms()
    np.testing.assert_allclose(gp2[:, w], goal, atol=1e-12)
    np.testing.assert_allclose(sol.hit_positions, goal, atol=1e-12)
    assert quat_angle(gq2[:, w], gq[:, w]).max() < 1e-9  # hand keeps its world orientation
    # only the arm's three joints changed, bone lengths are the offsets'
    changed = np.any(np.abs(sol.rotations - m.rotations) > 1e-12, axis=(0, 2))
    assert set(np.flatnonzero(changed)) <= {IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]}
    lengths = np.linalg.norm(gp2[:, 1:] - gp2[:, PARENTS[1:]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(OFFSETS[1:], axis=1), lengths.shape), atol=1e-12)


def test_reach_limb_identity_and_swivel_plane_kept():
    m = fixture_motion()
    gq, gp = m.global_transforms()
    s, e, w = IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]
    same = reach_limb(m, np.arange(m.n_frames), "right_wrist", gp[:, w])
    assert quat_angle(same.rotations, np.asarray(m.rotations)).max() < 1e-7
    # moving the wrist within the arm's plane keeps the elbow in that plane
    n = np.cross(gp[:, e] - gp[:, s], gp[:, w] - gp[:, s])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    toward = gp[:, s] - gp[:, w]
    goal = gp[:, w] + 0.2 * toward
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    gp2 = with_rotations(m, slice(None), sol.rotations).global_positions()
    assert np.abs(np.sum((gp2[:, e] - gp[:, s]) * n, axis=1)).max() < 1e-9
    # and on the same side of the shoulder->wrist axis (the elbow bends the same way)
    side0 = np.sum(np.cross(gp[:, w] - gp[:, s], gp[:, e] - gp[:, s]) * n, axis=1)
    side1 = np.sum(np.cross(gp2[:, w] - gp[:, s], gp2[:, e] - gp[:, s]) * n, axis=1)
    assert np.all(np.sign(side0) == np.sign(side1))


def test_reach_limb_scalar_path_equals_batch():
    m = fixture_motion(n_frames=8, seed=3)
    gp = m.global_positions()
    goal = gp[:, IDX["LeftHand"]] + np.array([-0.1, 0.12, 0.2])  # partly out of reach
    batch = reach_limb(m, np.arange(8), "left_fist", goal, hit_point="end_site")
    assert not batch.reached.all()
    for f in range(8):
        one = reach_limb(m, f, "left_fist", goal[f], hit_point="end_site")
        # 1e-7 rad, not rounding: a fully extended arm is the singular pose of two-bone IK
        # (sin of the elbow angle ~ sqrt(rounding)), where both paths are equally right
        assert quat_angle(one.rotations[0], batch.rotations[f]).max() < 1e-7
        g1 = with_rotations(m, [f], one.rotations).global_positions()[f]
        g2 = with_rotations(m, [f], batch.rotations[[f]]).global_positions()[f]
        np.testing.assert_allclose(g1, g2, atol=1e-8)
        np.testing.assert_allclose(one.residual[0], batch.residual[f], atol=1e-12)
        np.testing.assert_allclose(one.hit_positions[0], batch.hit_positions[f], atol=1e-12)
    for ext in (1.0, 0.9):  # also with a reach limit
        b = reach_limb(m, np.arange(8), "left_fist", goal, max_extension=ext)
        o = reach_limb(m, 5, "left_fist", goal[5], max_extension=ext)
        assert quat_angle(o.rotations[0], b.rotations[5]).max() < 1e-9


def test_reach_limb_unreachable_gives_excess_distance():
    m = fixture_motion()
    gp = m.global_positions()
    s, w = IDX["RightArm"], IDX["RightHand"]
    L = np.linalg.norm(OFFSETS[IDX["RightForeArm"]]) + np.linalg.norm(OFFSETS[w])
    direction = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    goal = gp[:, s] + (L + 0.25) * direction
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert not sol.reached.any()
    np.testing.assert_allclose(sol.residual, 0.25, atol=1e-9)
    gp2 = with_rotations(m, slice(None), sol.rotations).global_positions()
    np.testing.assert_allclose(gp2[:, w], gp[:, s] + L * direction, atol=1e-9)  # fully extended towards it
    # too close (closer than |upper - forearm|): folded as far as it goes, no NaN
    close = reach_limb(m, 0, "right_wrist", gp[0, s] + 1e-3 * direction)
    assert np.all(np.isfinite(close.rotations)) and not close.reached[0]


def test_the_tip_of_a_joint_without_an_end_site_is_its_knuckles_or_itself():
    """hit_point="end_site" on a joint with no End Site (issue 25: a hand with fingers): the knuckles of the
    joints below it, else the joint itself (repro.motion.body.hit_points), never a refusal."""
    from repro.motion.body.hit_points import hit_offset
    from repro.motion.body.skeleton import skeleton_of
    from repro.motion.core.quaternion import quat_rotate

    m = fixture_motion()
    sk = skeleton_of(m)
    foot = sk.index("right_foot")
    off, src = hit_offset(sk, foot)
    assert not np.any(sk.end_site_parents == foot) and src in ("knuckles", "joint")
    gp = m.global_positions()
    target = gp[0, foot] + np.array([0.0, 0.05, 0.1])
    tip = reach_limb(m, 0, "right_foot", target, hit_point="end_site")
    assert tip.reached[0]
    g = with_rotations(m, slice(0, 1), tip.rotations).global_transforms()
    np.testing.assert_allclose(g[1][0, foot] + quat_rotate(g[0][0, foot], off), target, atol=1e-6)


def test_reach_limb_bad_inputs():
    m = fixture_motion()
    with pytest.raises(MotionError, match="out of range"):
        reach_limb(m, [0, 12], "right_fist", [0, 1, 0])
    with pytest.raises(MotionError, match="NaN"):
        reach_limb(m, [0, 1], "right_fist", [[0, 1, 0], [np.inf, 0, 0]])
    with pytest.raises(MotionError, match="targets must be"):
        reach_limb(m, [0, 1, 2], "right_fist", np.zeros((2, 3)))
    with pytest.raises(MotionError, match="hit_point"):
        reach_limb(m, 0, "right_foot", [0, 0, 0], hit_point="tip")
    with pytest.raises(MotionError, match="rotations must be"):
        reach_limb(m, [0, 1], "right_fist", [0, 1, 0], rotations=np.zeros((3, len(MIXAMO), 4)))
    with pytest.raises(MotionError, match="Motion"):
        reach_limb("not a motion", 0, "right_fist", [0, 1, 0])
