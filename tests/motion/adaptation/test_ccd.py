"""CCD of Section 3.4.2 (repro.motion.adaptation.ccd_solver): reduces the error when the limb alone cannot
reach, respects its joint limits (cone limits, elbow hinge never hyperextends), terminates on impossible
targets."""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.adaptation import DEFAULT_LIMITS_DEG, ccd, default_chain, reach_limb
from repro.motion.core.quaternion import quat_rotate
from tests.motion.adaptation.fixture import IDX, OFFSETS, fixture_motion, quat_angle, with_rotations


def test_ccd_reduces_error_and_respects_limits():
    m = fixture_motion()
    gp = m.global_positions()
    s, w = IDX["RightArm"], IDX["RightHand"]
    L = np.linalg.norm(OFFSETS[IDX["RightForeArm"]]) + np.linalg.norm(OFFSETS[w])
    d = (gp[:, w] - gp[:, s]) / np.linalg.norm(gp[:, w] - gp[:, s], axis=1, keepdims=True)
    goal = gp[:, s] + (L + 0.08) * d  # 8 cm beyond the arm's reach
    frames = np.arange(m.n_frames)
    limb = reach_limb(m, frames, "right_wrist", goal)
    sol = ccd(m, frames, "right_wrist", goal, rotations=limb.rotations)
    assert limb.residual.min() > 0.079
    assert np.all(sol.residual < limb.residual)
    assert sol.reached.all() and sol.residual.max() < 1e-4  # default tol: 1e-4 of the arm
    assert sol.chain == ["RightForeArm", "RightArm", "RightShoulder", "Spine1", "Spine"]
    # cone limits around the original local rotations
    for name, kind in (("RightShoulder", "clavicle"), ("Spine1", "spine"), ("Spine", "spine")):
        j = IDX[name]
        ang = np.degrees(quat_angle(sol.rotations[:, j], np.asarray(m.rotations)[:, j]))
        assert ang.max() <= DEFAULT_LIMITS_DEG[kind] + 1e-6
    # the pelvis is not in an arm's chain
    assert np.all(sol.rotations[:, IDX["Hips"]] == np.asarray(m.rotations)[:, IDX["Hips"]])


def test_ccd_alone_hinge_never_hyperextends_and_terminates():
    m = fixture_motion()
    gp = m.global_positions()
    s, e, w = IDX["LeftArm"], IDX["LeftForeArm"], IDX["LeftHand"]
    frames = np.arange(m.n_frames)
    # pure CCD (no analytic finish) on a reachable goal: elbow kept within [0, 160] degrees
    goal = gp[:, w] + np.array([0.05, 0.1, 0.05])
    sol = ccd(m, frames, "left_wrist", goal, finish_with_limb=False, max_iter=200, tol=1e-3)
    assert sol.residual.max() < 0.01
    gp2 = with_rotations(m, frames, sol.rotations).global_positions()
    n0 = np.cross(gp[:, e] - gp[:, s], gp[:, w] - gp[:, e])
    n1 = np.cross(gp2[:, e] - gp2[:, s], gp2[:, w] - gp2[:, e])
    # the bend keeps its direction relative to the upper arm's frame: same sign of the
    # (rotated) hinge normal, i.e. no hyperextension through the straight pose
    gq = m.global_transforms()[0]
    gq2 = with_rotations(m, frames, sol.rotations).global_transforms()[0]
    inv = np.array([-1, -1, -1, 1.0])
    n0_local = quat_rotate(gq[:, s] * inv, n0)
    n1_local = quat_rotate(gq2[:, s] * inv, n1)
    assert np.all(np.sum(n0_local * n1_local, axis=1) >= -1e-12)
    # an impossible goal: best effort, bounded sweeps, no exception
    far = gp[:, s] + np.array([3.0, 0, 0])
    bad = ccd(m, frames, "left_wrist", far, finish_with_limb=False, max_iter=40)
    assert not bad.reached.any() and np.all(bad.iterations <= 40)
    assert np.all(bad.residual > 2.0)


def test_ccd_chain_validation():
    m = fixture_motion()
    with pytest.raises(MotionError, match="not an ancestor"):
        ccd(m, 0, "right_wrist", [0, 1, 0.5], chain=["LeftArm"])
    with pytest.raises(MotionError, match="no joint or role"):
        ccd(m, 0, "right_wrist", [0, 1, 0.5], chain=["Nope"])
    with pytest.raises(MotionError, match="string"):
        ccd(m, 0, "right_wrist", [0, 1, 0.5], chain="RightArm")
    with pytest.raises(MotionError, match="limits"):
        ccd(m, 0, "right_wrist", [0, 1, 0.5], limits={"elbw": 10})
    with pytest.raises(MotionError, match="hinge_range_deg"):
        ccd(m, 0, "right_wrist", [0, 1, 0.5], hinge_range_deg=(30, 10))
    assert default_chain(m, "left_foot") == ["LeftLeg", "LeftUpLeg", "Hips"]
    assert default_chain(m, "left_foot", include_pelvis=False) == ["LeftLeg", "LeftUpLeg"]
