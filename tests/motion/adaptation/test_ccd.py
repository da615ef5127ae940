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


# ------------------------------------------------------------------ the compiled sweeps
def test_compiled_sweeps_equal_the_numpy_sweeps_on_the_fixture():
    """The kernel (repro.motion.adaptation.ccd_kernel) and the numpy sweeps: the same sweeps and poses to
    rounding, with the analytic finish and without it (plain CCD, the elbow hinge), reachable or not.

    ``ccd_sweeps``' poses agree to 1e-12 (the 3x3 products round differently: BLAS against loops); ``ccd``
    then places the hand by the limb step, whose arccos near full extension magnifies 1e-16 into about
    1e-8 in the arm's angles (sqrt of the machine epsilon) but not in where the hand is: its hit points
    agree to 1e-12, its rotations to 1e-7."""
    from repro.motion.adaptation.ccd_solver import ccd_spec, ccd_sweeps
    from repro.motion.adaptation.limb import limb_dmax
    from repro.motion.adaptation.rig import rig_of

    m = fixture_motion()
    gp = m.global_positions()
    s, w = IDX["RightArm"], IDX["RightHand"]
    frames = np.arange(m.n_frames)
    d = (gp[:, w] - gp[:, s]) / np.linalg.norm(gp[:, w] - gp[:, s], axis=1, keepdims=True)
    cases = [dict(targets=gp[:, s] + 0.7 * d + np.array([0.0, 0.05, 0.0])),  # beyond the arm: the spine turns
             dict(targets=gp[:, s] + np.array([3.0, 0.0, 0.0])),  # out of reach: best effort, creeping stops it
             dict(targets=gp[:, w] + np.array([0.05, 0.1, 0.05]), finish_with_limb=False, max_iter=200, tol=1e-3)]
    rig = rig_of(m)
    ch = rig.chain("right_wrist")
    spec = ccd_spec(rig, ch, None, None, (0.0, 160.0))
    ref = np.asarray(m.rotations)
    for kw in cases:
        a = ccd(m, frames, "right_wrist", **kw)
        b = ccd(m, frames, "right_wrist", compiled=False, **kw)
        assert a.iterations.max() > 0
        np.testing.assert_array_equal(a.iterations, b.iterations)
        np.testing.assert_allclose(a.hit_positions, b.hit_positions, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.rotations, b.rotations, rtol=0, atol=1e-7)
        finish = kw.get("finish_with_limb", True)
        goal = np.broadcast_to(kw["targets"], (m.n_frames, 3)).copy()
        dmax = limb_dmax(ch, ref, rig.trans, 1.0)
        out = []
        for compiled in (True, False):
            rot = ref.copy()
            it, hit = ccd_sweeps(rig, ch, rot, rig.trans, goal, ref, spec, kw.get("max_iter", 50),
                                 kw.get("tol", 1e-4), finish, dmax, compiled)
            out.append((it, hit, rot))
        np.testing.assert_array_equal(out[0][0], out[1][0])
        np.testing.assert_allclose(out[0][1], out[1][1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(out[0][2], out[1][2], rtol=0, atol=1e-12)
    with pytest.raises(MotionError, match="compiled"):
        ccd(m, frames, "right_wrist", cases[0]["targets"], compiled="yes")


#: Real rigs where CCD runs the most (a long spine: mocopi; a Unity humanoid; a CMU-style conversion with
#: fingers: bvh_test3)
CCD_RIGS = ["realrigs/mocopi_MCPM_20230410_150228.BVH", "realrigs/shadermotion_unity_humanoid.bvh",
            "pybvh/bvh_test3.bvh"]


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
@pytest.mark.parametrize("name", CCD_RIGS)
def test_compiled_sweeps_give_the_same_strikes_on_real_rigs(synthetic_db, name):
    """The fighter's kicks and punches with the compiled sweeps (the default) and with the numpy ones: the
    same strikes.  CCD's poses agree to 1e-13 (the 3x3 products round differently: BLAS against loops);
    the limb step after CCD turns them into the arm's or leg's angles through an arccos near full extension,
    which magnifies 1e-16 into about 1e-8 (sqrt of the machine epsilon), so the strikes' rotations are
    compared to 1e-7, their levels and reach exactly.  A frame whose CCD ends on the limb's reach exactly may
    run one more sweep (undone) on one side: the sweep counts agree within one."""
    from repro.motion import read_bvh
    from repro.motion.runtime.fighter import KungFuFighter
    import dataclasses
    import warnings

    from repro import data

    path = data.data_dir() / "mocap/formats" / name
    if not path.is_file():
        pytest.skip(f"{name} not staged")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = KungFuFighter(synthetic_db, character=read_bvh(path), seed=0)
    size = f.character.size
    f.follow((0.0, 0.85 * size, 0.0), 0.0, snap=True)
    new = f.options
    old = dataclasses.replace(new, adapt=dataclasses.replace(new.adapt, compiled=False))
    rng = np.random.default_rng(3)
    n_ccd = 0
    for i in range(8):
        kind = ("kick", "punch")[i % 2]
        X = np.array([rng.uniform(-0.15, 0.15), (0.55 if kind == "kick" else 0.85) * size + rng.uniform(-0.1, 0.1) * size,
                      rng.uniform(-0.15, 0.15)])
        f.options = new
        a = f.order(kind, X, commit=False)
        f.options = old
        b = f.order(kind, X, commit=False)
        assert (a.clip_name, a.level, a.reached, a.tc) == (b.clip_name, b.level, b.reached, b.tc)
        np.testing.assert_allclose(a.motion.rotations, b.motion.rotations, rtol=0, atol=1e-7)
        np.testing.assert_allclose(a.motion.positions, b.motion.positions, rtol=0, atol=1e-9)
        assert abs(a.hit_error - b.hit_error) < 1e-9
        assert np.abs(a.adaptation.ccd_iterations - b.adaptation.ccd_iterations).max() <= 1
        assert np.array_equal(a.adaptation.solver, b.adaptation.solver)
        n_ccd += int(np.sum(a.adaptation.solver == "ccd"))
    assert n_ccd > 0  # CCD ran


@pytest.mark.parametrize("compiled", [True, False])
def test_plain_ccd_turns_the_elbow_about_the_same_axis_with_twist_joints(compiled):
    """Twist segments inside the upper arm and forearm (MakeHuman's ``upperarm02``, ``lowerarm02``), each turned
    about its bone by up to 35 degrees: the same body, so plain CCD (no limb finish) gives the same arm.  The
    elbow's hinge axis is fixed in the upper arm's (proximal) frame, not in the twist segment's above the elbow."""
    from tests.motion.adaptation.test_limb import _with_twist_joints

    m = fixture_motion(n_frames=6, seed=5)
    twisted = _with_twist_joints(m, ["RightForeArm", "RightHand"], 35.0 * np.arange(1, 7) / 6)
    frames = np.arange(m.n_frames)
    goal = m.global_positions()[:, IDX["RightHand"]] + np.array([0.05, -0.08, 0.03])
    kw = dict(finish_with_limb=False, max_iter=200, tol=1e-3, compiled=compiled)
    a = ccd(m, frames, "right_wrist", goal, **kw)
    b = ccd(twisted, frames, "right_wrist", goal, **kw)
    assert a.residual.max() < 0.01 and b.residual.max() < 0.01
    keep = [twisted.joint_names.index(n) for n in m.joint_names]
    ga = with_rotations(m, frames, a.rotations).global_positions()
    gb = with_rotations(twisted, frames, b.rotations).global_positions()[:, keep]
    np.testing.assert_allclose(gb, ga, atol=1e-9)
