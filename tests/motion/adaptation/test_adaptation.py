"""Constraints solver of Section 3.4.2 (repro.motion.adaptation).

Pronost et al.: d(t) grows from 0 at the current frame t0 to d(tc) = X - M(tc) at the
contact; at each frame the wrist / foot is brought to p(t) + d(t), by the limb first
(analytic) and by CCD over a longer chain when the limb cannot reach.  What is asserted:

* d(t): 0 up to t0, d(tc) at tc, monotone in between (smoothstep: zero slope at both
  ends), released back to 0 after tc when asked;
* limb step: reachable targets reached to rounding, hand orientation kept, bone lengths
  unchanged, elbow kept in its plane, one-frame scalar path == numpy batch path;
  unreachable targets give the exact excess distance, not an exception;
* CCD: reduces the error when the limb alone cannot reach, respects its joint limits
  (cone limits, elbow hinge never hyperextends), terminates on impossible targets;
* adapt on the real CMU clips 135_09 (lunge punches) and 135_04 (front kicks): the fist /
  foot moved 10 cm is reached within 1 cm at tc, frames <= t0 are untouched, bone lengths
  unchanged, planted feet do not slide more than 2 cm; a target 1 m beyond reach gives
  reached=False with a residual of the order of the excess; bad inputs raise MotionError.

No timing is asserted (see ``repro.bench.adaptation.time_adaptation`` for the numbers).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro import data
from repro.errors import MotionError
from repro.motion import CMU_UNIT_M, Motion, read_bvh
from repro.motion.adaptation import (
    DEFAULT_LIMITS_DEG,
    AdaptOptions,
    Adaptation,
    adapt,
    ccd,
    default_chain,
    offset_curve,
    reach_limb,
)
from repro.motion.core.quaternion import euler_to_quat, quat_multiply, quat_rotate
from tests.motion_fixtures import MIXAMO, MIXAMO_NAMES

PARENTS = np.array([-1 if p is None else MIXAMO_NAMES.index(p) for _, p, _ in MIXAMO])
OFFSETS = np.array([o for _, _, o in MIXAMO], dtype=float)
IDX = {n: i for i, n in enumerate(MIXAMO_NAMES)}


OPTION_NAMES = {f.name for f in dataclasses.fields(AdaptOptions)}


def _adapt(motion, effector, target, t0, tc, **kw):
    """:func:`adapt` with its options given as keywords among the per-call data (for the refusal tables)."""
    options = AdaptOptions(**{k: kw.pop(k) for k in list(kw) if k in OPTION_NAMES})
    return adapt(motion, effector, target, t0, tc, options=options, **kw)


def _fixture_motion(n_frames: int = 12, seed: int = 0) -> Motion:
    """The shared Mixamo skeleton (metres, T-pose along X) with the arms bent forward."""
    rng = np.random.default_rng(seed)
    J = len(MIXAMO_NAMES)
    eul = np.zeros((n_frames, J, 3))
    for side, s in (("Right", -1.0), ("Left", 1.0)):
        # upper arm swung forward (about Y), elbow bent about Y (hinge), small noise
        eul[:, IDX[f"{side}Arm"], 1] = -s * (60 + 10 * rng.standard_normal(n_frames))
        eul[:, IDX[f"{side}Arm"], 2] = -s * 20
        eul[:, IDX[f"{side}ForeArm"], 1] = -s * (70 + 20 * rng.random(n_frames))
        eul[:, IDX[f"{side}UpLeg"], 0] = -10
        eul[:, IDX[f"{side}Leg"], 0] = 20
        eul[:, IDX[f"{side}Foot"], 0] = -10
    eul[:, IDX["Spine"], 0] = 5 * rng.standard_normal(n_frames)
    rot = euler_to_quat("ZXY", eul[..., [2, 0, 1]])
    pos = np.broadcast_to(OFFSETS, (n_frames, J, 3)).copy()
    rot_ch = ("Zrotation", "Xrotation", "Yrotation")
    channels = [("Xposition", "Yposition", "Zposition") + rot_ch] + [rot_ch] * (J - 1)
    return Motion(
        joint_names=MIXAMO_NAMES,
        parents=PARENTS,
        offsets=OFFSETS,
        channels=channels,
        frame_time=1 / 30,
        rotations=rot,
        positions=pos,
        end_site_parents=np.array([IDX["RightHand"], IDX["LeftHand"]]),
        end_site_offsets=np.array([[-0.08, 0.0, 0.0], [0.08, 0.0, 0.0]]),
        unit_m=1.0,
    )


def _with_rotations(m: Motion, frames, rotations) -> Motion:
    rot = np.array(m.rotations)
    rot[frames] = rotations
    return dataclasses.replace(m, rotations=rot)


def _quat_angle(a, b):
    """Angle of the rotation between unit quaternions (precise near 0)."""
    d = quat_multiply(np.asarray(a) * np.array([-1, -1, -1, 1.0]), np.asarray(b))
    return 2 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


# ------------------------------------------------------------------- d(t)
def test_offset_curve_endpoints_monotone_smooth():
    d_tc = np.array([0.1, -0.05, 0.02])
    d = offset_curve(10, 40, d_tc, 60)
    assert d.shape == (60, 3)
    assert np.all(d[:11] == 0.0)
    np.testing.assert_allclose(d[40], d_tc, atol=0)
    np.testing.assert_allclose(d[40:], np.broadcast_to(d_tc, (20, 3)))  # held by default
    # every d(t) is a multiple s(t) d_tc with s increasing from 0 to 1
    s = d[:, 0] / d_tc[0]
    np.testing.assert_allclose(d, s[:, None] * d_tc[None], atol=1e-15)
    assert np.all(np.diff(s[10:41]) > 0)
    # smoothstep: slope vanishes at both ends (first/last steps are the smallest)
    steps = np.diff(s[10:41])
    assert steps[0] < steps[15] / 10 and steps[-1] < steps[15] / 10
    assert steps.max() <= 1.5 / 30 + 1e-12  # max slope of 3u^2 - 2u^3 is 1.5


def test_offset_curve_linear_release_and_degenerate():
    d = offset_curve(0, 4, [1.0, 0, 0], 12, kind="linear", release=4)
    np.testing.assert_allclose(d[:, 0], [0, 0.25, 0.5, 0.75, 1, 0.75, 0.5, 0.25, 0, 0, 0, 0])
    d = offset_curve(3, 3, [0, 1.0, 0], 6)  # t0 == tc: a step at tc
    np.testing.assert_array_equal(d[:, 1], [0, 0, 0, 1, 1, 1])
    d = offset_curve(1, 3, [0, 0, 2.0], 6, release=0)
    np.testing.assert_array_equal(d[4:, 2], [0, 0])
    d = offset_curve(0, 10, [1.0, 0, 0], 11, kind="smootherstep")
    assert np.all(np.diff(d[:, 0]) > 0) and d[10, 0] == 1.0


@given(
    F=st.integers(2, 200),
    a=st.floats(0, 1),
    b=st.floats(0, 1),
    d=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
    kind=st.sampled_from(["linear", "smoothstep", "smootherstep"]),
    rel=st.one_of(st.none(), st.integers(0, 30)),
)
def test_offset_curve_properties(F, a, b, d, kind, rel):
    t0, tc = sorted((int(a * (F - 1)), int(b * (F - 1))))
    out = offset_curve(t0, tc, d, F, kind=kind, release=rel)
    assert np.all(out[: t0 + (tc > t0)] == 0.0) if tc > t0 else np.all(out[:tc] == 0.0)
    np.testing.assert_array_equal(out[tc], np.asarray(d, dtype=float))
    w = np.linalg.norm(out, axis=1)
    assert np.all(np.diff(w[t0: tc + 1]) >= -1e-12)  # grows monotonically to |d(tc)|
    assert np.all(w <= np.linalg.norm(d) + 1e-12)
    if rel is not None:
        assert np.all(np.diff(w[tc:]) <= 1e-12)  # then decreases back
        assert np.all(out[tc + rel + 1:] == 0.0) if rel > 0 else np.all(out[tc + 1:] == 0.0)


@pytest.mark.parametrize(
    "args, kw, match",
    [
        ((5, 3, [0, 0, 0], 10), {}, "after the contact"),
        ((0, 10, [0, 0, 0], 10), {}, "out of range"),
        ((-1, 3, [0, 0, 0], 10), {}, "out of range"),
        ((0, 3, [np.nan, 0, 0], 10), {}, "NaN"),
        ((0, 3, [0, 0], 10), {}, "3-vector"),
        ((0, 3, [0, 0, 0], 10), {"kind": "cubic"}, "kind"),
        ((0, 3, [0, 0, 0], 10), {"release": -1}, "release"),
        ((0.5, 3, [0, 0, 0], 10), {}, "integer"),
    ],
)
def test_offset_curve_bad_inputs(args, kw, match):
    with pytest.raises(MotionError, match=match):
        offset_curve(*args, **kw)


# ------------------------------------------------------------- limb step
def test_reach_limb_reaches_keeps_hand_and_bone_lengths():
    m = _fixture_motion()
    gq, gp = m.global_transforms()
    w = IDX["RightHand"]
    goal = gp[:, w] + np.array([0.05, -0.08, 0.03])
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert sol.reached.all() and sol.residual.max() < 1e-12
    m2 = _with_rotations(m, slice(None), sol.rotations)
    gq2, gp2 = m2.global_transforms()
    np.testing.assert_allclose(gp2[:, w], goal, atol=1e-12)
    np.testing.assert_allclose(sol.hit_positions, goal, atol=1e-12)
    assert _quat_angle(gq2[:, w], gq[:, w]).max() < 1e-9  # hand keeps its world orientation
    # only the arm's three joints changed, bone lengths are the offsets'
    changed = np.any(np.abs(sol.rotations - m.rotations) > 1e-12, axis=(0, 2))
    assert set(np.flatnonzero(changed)) <= {IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]}
    lengths = np.linalg.norm(gp2[:, 1:] - gp2[:, PARENTS[1:]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(OFFSETS[1:], axis=1), lengths.shape), atol=1e-12)


def test_reach_limb_identity_and_swivel_plane_kept():
    m = _fixture_motion()
    gq, gp = m.global_transforms()
    s, e, w = IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]
    same = reach_limb(m, np.arange(m.n_frames), "right_wrist", gp[:, w])
    assert _quat_angle(same.rotations, np.asarray(m.rotations)).max() < 1e-7
    # moving the wrist within the arm's plane keeps the elbow in that plane
    n = np.cross(gp[:, e] - gp[:, s], gp[:, w] - gp[:, s])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    toward = gp[:, s] - gp[:, w]
    goal = gp[:, w] + 0.2 * toward
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    gp2 = _with_rotations(m, slice(None), sol.rotations).global_positions()
    assert np.abs(np.sum((gp2[:, e] - gp[:, s]) * n, axis=1)).max() < 1e-9
    # and on the same side of the shoulder->wrist axis (the elbow bends the same way)
    side0 = np.sum(np.cross(gp[:, w] - gp[:, s], gp[:, e] - gp[:, s]) * n, axis=1)
    side1 = np.sum(np.cross(gp2[:, w] - gp[:, s], gp2[:, e] - gp[:, s]) * n, axis=1)
    assert np.all(np.sign(side0) == np.sign(side1))


def test_reach_limb_scalar_path_equals_batch():
    m = _fixture_motion(n_frames=8, seed=3)
    gp = m.global_positions()
    goal = gp[:, IDX["LeftHand"]] + np.array([-0.1, 0.12, 0.2])  # partly out of reach
    batch = reach_limb(m, np.arange(8), "left_fist", goal, hit_point="end_site")
    assert not batch.reached.all()
    for f in range(8):
        one = reach_limb(m, f, "left_fist", goal[f], hit_point="end_site")
        # 1e-7 rad, not rounding: a fully extended arm is the singular pose of two-bone IK
        # (sin of the elbow angle ~ sqrt(rounding)), where both paths are equally right
        assert _quat_angle(one.rotations[0], batch.rotations[f]).max() < 1e-7
        g1 = _with_rotations(m, [f], one.rotations).global_positions()[f]
        g2 = _with_rotations(m, [f], batch.rotations[[f]]).global_positions()[f]
        np.testing.assert_allclose(g1, g2, atol=1e-8)
        np.testing.assert_allclose(one.residual[0], batch.residual[f], atol=1e-12)
        np.testing.assert_allclose(one.hit_positions[0], batch.hit_positions[f], atol=1e-12)
    for ext in (1.0, 0.9):  # also with a reach limit
        b = reach_limb(m, np.arange(8), "left_fist", goal, max_extension=ext)
        o = reach_limb(m, 5, "left_fist", goal[5], max_extension=ext)
        assert _quat_angle(o.rotations[0], b.rotations[5]).max() < 1e-9


def test_reach_limb_unreachable_gives_excess_distance():
    m = _fixture_motion()
    gp = m.global_positions()
    s, w = IDX["RightArm"], IDX["RightHand"]
    L = np.linalg.norm(OFFSETS[IDX["RightForeArm"]]) + np.linalg.norm(OFFSETS[w])
    direction = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    goal = gp[:, s] + (L + 0.25) * direction
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert not sol.reached.any()
    np.testing.assert_allclose(sol.residual, 0.25, atol=1e-9)
    gp2 = _with_rotations(m, slice(None), sol.rotations).global_positions()
    np.testing.assert_allclose(gp2[:, w], gp[:, s] + L * direction, atol=1e-9)  # fully extended towards it
    # too close (closer than |upper - forearm|): folded as far as it goes, no NaN
    close = reach_limb(m, 0, "right_wrist", gp[0, s] + 1e-3 * direction)
    assert np.all(np.isfinite(close.rotations)) and not close.reached[0]


# ------------------------------------------------------------------- CCD
def test_ccd_reduces_error_and_respects_limits():
    m = _fixture_motion()
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
        ang = np.degrees(_quat_angle(sol.rotations[:, j], np.asarray(m.rotations)[:, j]))
        assert ang.max() <= DEFAULT_LIMITS_DEG[kind] + 1e-6
    # the pelvis is not in an arm's chain
    assert np.all(sol.rotations[:, IDX["Hips"]] == np.asarray(m.rotations)[:, IDX["Hips"]])


def test_ccd_alone_hinge_never_hyperextends_and_terminates():
    m = _fixture_motion()
    gp = m.global_positions()
    s, e, w = IDX["LeftArm"], IDX["LeftForeArm"], IDX["LeftHand"]
    frames = np.arange(m.n_frames)
    # pure CCD (no analytic finish) on a reachable goal: elbow kept within [0, 160] degrees
    goal = gp[:, w] + np.array([0.05, 0.1, 0.05])
    sol = ccd(m, frames, "left_wrist", goal, finish_with_limb=False, max_iter=200, tol=1e-3)
    assert sol.residual.max() < 0.01
    gp2 = _with_rotations(m, frames, sol.rotations).global_positions()
    n0 = np.cross(gp[:, e] - gp[:, s], gp[:, w] - gp[:, e])
    n1 = np.cross(gp2[:, e] - gp2[:, s], gp2[:, w] - gp2[:, e])
    # the bend keeps its direction relative to the upper arm's frame: same sign of the
    # (rotated) hinge normal, i.e. no hyperextension through the straight pose
    gq = m.global_transforms()[0]
    gq2 = _with_rotations(m, frames, sol.rotations).global_transforms()[0]
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
    m = _fixture_motion()
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


# ------------------------------------------------------------ bad inputs
@pytest.mark.parametrize(
    "kw, match",
    [
        ({"target": [np.nan, 1.0, 0.5]}, "NaN"),
        ({"target": [1.0, 0.5]}, "3-vector"),
        ({"effector": "right_elbow"}, "unknown effector"),
        ({"effector": "nose"}, "unknown effector"),
        ({"effector": 3}, "role name"),
        ({"t0": 8, "tc": 5}, "after the contact"),
        ({"tc": 12}, "out of range"),
        ({"t0": -1}, "out of range"),
        ({"t0": 1.5}, "integer"),
        ({"feet": "glue"}, "feet"),
        ({"max_extension": 1.5}, "max_extension"),
        ({"release": -0.1}, "release"),
        ({"hit_point": "tip"}, "hit_point"),
        ({"chain": ["LeftArm"]}, "not an ancestor"),
    ],
)
def test_adapt_bad_inputs_raise_motion_error(kw, match):
    m = _fixture_motion()
    args = {"effector": "right_fist", "target": [-0.3, 1.4, 0.4], "t0": 2, "tc": 6}
    args.update(kw)
    with pytest.raises(MotionError, match=match):
        _adapt(m, args.pop("effector"), args.pop("target"), args.pop("t0"), args.pop("tc"), **args)


def test_reach_limb_bad_inputs():
    m = _fixture_motion()
    with pytest.raises(MotionError, match="out of range"):
        reach_limb(m, [0, 12], "right_fist", [0, 1, 0])
    with pytest.raises(MotionError, match="NaN"):
        reach_limb(m, [0, 1], "right_fist", [[0, 1, 0], [np.inf, 0, 0]])
    with pytest.raises(MotionError, match="targets must be"):
        reach_limb(m, [0, 1, 2], "right_fist", np.zeros((2, 3)))
    with pytest.raises(MotionError, match="End Site"):
        reach_limb(m, 0, "right_foot", [0, 0, 0], hit_point="end_site")
    with pytest.raises(MotionError, match="rotations must be"):
        reach_limb(m, [0, 1], "right_fist", [0, 1, 0], rotations=np.zeros((3, len(MIXAMO), 4)))
    with pytest.raises(MotionError, match="Motion"):
        reach_limb("not a motion", 0, "right_fist", [0, 1, 0])


def test_adapt_on_fixture_is_continuous_and_exact():
    m = _fixture_motion(n_frames=12)
    gp = m.global_positions()
    hit = gp[8, IDX["RightHand"]]
    a = adapt(m, "right_fist", hit + [0.0, 0.05, 0.05], 2, 8, options=AdaptOptions(release=None, feet=None, floor=None))
    assert isinstance(a, Adaptation)
    assert a.reached and a.residual < 1e-9
    np.testing.assert_array_equal(a.motion.rotations[:3], m.rotations[:3])
    assert not a.changed[:3].any() and a.changed[3:].all()
    assert np.all(a.hit_error < 1e-9)
    assert a.bone_length_error < 1e-12
    assert set(a.solver[3:]) <= {"limb", "ccd"} and np.all(a.solver[:3] == "")
    summary = a.summary()
    assert summary["reached"] and summary["bone_length_error"] < 1e-12
    # the paper's plain limb-first rule (no reach margin) reaches as well
    b = adapt(m, "right_fist", hit + [0.0, 0.05, 0.05], 2, 8, options=AdaptOptions(max_extension=1.0, feet=None, floor=None))
    assert b.reached and np.all(b.solver[3:9] == "limb")
    # t0 == tc: the contact frame itself jumps to the target, earlier frames untouched
    c = adapt(m, "right_fist", hit + [0.0, 0.05, 0.0], 8, 8, options=AdaptOptions(feet=None, floor=None))
    assert c.reached and not c.changed[:8].any() and c.changed[8]


# ---------------------------------------------------------- real CMU data
@pytest.fixture(scope="module")
def punch():
    return read_bvh(data.fetch("mocap/cmu/135_09.bvh"), unit_m=CMU_UNIT_M).to_metres()


@pytest.fixture(scope="module")
def kick():
    return read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M).to_metres()


PUNCH_TC = 303  # right lunge punch of 135_09: arm at its most extended (0.479 of 0.482 m)
KICK_TC = 375  # right front kick of 135_04: toes at their highest (1.31 m)


def _hit_and_out(m, tc, hit_joint, prox_joint):
    gp = m.global_positions()
    hit = gp[tc, m.joint_index(hit_joint)]
    prox = gp[tc, m.joint_index(prox_joint)]
    return gp, hit, (hit - prox) / np.linalg.norm(hit - prox)


def _check_common(m, a, t0):
    # continuity: nothing changes up to t0
    np.testing.assert_array_equal(a.motion.rotations[: t0 + 1], m.rotations[: t0 + 1])
    np.testing.assert_array_equal(a.motion.positions, m.positions)
    assert a.bone_length_error < 1e-9
    gp2 = a.motion.global_positions()
    gp = m.global_positions()
    lengths = lambda g: np.linalg.norm(g[:, 1:] - g[:, m.parents[1:]], axis=-1)  # noqa: E731
    assert np.abs(lengths(gp2) - lengths(gp)).max() < 1e-9
    # planted feet: pinned frames exist and no pinned ankle slides more than 2 cm
    assert a.foot_pinned.any()
    for s, name in enumerate(("lfoot", "rfoot")):
        pinned = np.flatnonzero(a.foot_pinned[:, s])
        if pinned.size:
            j = m.joint_index(name)
            starts = pinned[np.concatenate([[True], np.diff(pinned) > 1])]
            for f0 in starts:
                run = pinned[(pinned >= f0)]
                run = run[: np.argmax(np.diff(np.concatenate([run, [run[-1] + 2]])) > 1) + 1]
                slide = np.linalg.norm(gp2[run][:, j][:, [0, 2]] - gp2[f0, j, [0, 2]], axis=-1).max()
                assert slide < 0.02
    assert max(a.foot_slide.values()) < 0.02


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("direction", ["back_down", "forward"])
def test_adapt_real_punch_reaches_moved_target(punch, direction):
    gp, hit, out = _hit_and_out(punch, PUNCH_TC, "rhand", "rhumerus")
    move = 0.1 * out if direction == "forward" else 0.1 * np.array([0.0, -0.6, 0.0]) - 0.08 * out
    move = 0.1 * move / np.linalg.norm(move)
    target = hit + move
    t0 = PUNCH_TC - 40
    a = adapt(punch, "right_fist", target, t0, PUNCH_TC, options=AdaptOptions(feet="pin", floor=None))
    assert a.reached and a.residual < 0.01
    np.testing.assert_allclose(a.offsets[PUNCH_TC], move, atol=1e-12)
    assert np.all(a.offsets[: t0 + 1] == 0)
    assert np.all(a.hit_error < 0.01)  # the goal p(t) + d(t) is followed on every frame
    _check_common(punch, a, t0)
    # the hit point moves smoothly: per-frame steps at most the original's plus d's slope
    steps = np.linalg.norm(np.diff(a.hit_positions[t0: a.stop], axis=0), axis=1)
    steps0 = np.linalg.norm(np.diff(a.original_hit[t0: a.stop], axis=0), axis=1)
    assert np.all(steps <= steps0 + 1.5 * 0.1 / 40 + 1e-3)
    if direction == "forward":
        # the arm is already extended: the limb alone cannot reach, CCD does
        limb = reach_limb(punch, PUNCH_TC, "right_fist", target)
        assert limb.residual[0] > 0.05
        assert a.solver[PUNCH_TC] == "ccd"
        assert a.residual < limb.residual[0] / 100


@pytest.mark.data("cmu-bvh")
def test_adapt_real_kick_reaches_moved_target(kick):
    gp, hit, out = _hit_and_out(kick, KICK_TC, "rtoes", "rfemur")
    target = hit + np.array([0.0, 0.1, 0.0])  # 10 cm higher
    t0 = KICK_TC - 75  # the right foot is still planted on frames 309-317
    a = adapt(kick, "right_foot", target, t0, KICK_TC, options=AdaptOptions(feet="pin", floor=None))
    assert a.reached and a.residual < 0.01
    _check_common(kick, a, t0)
    # the kicking foot was still planted after t0: d(t) starts at lift-off, so the
    # planted kicking foot does not move
    assert a.t_start > t0
    np.testing.assert_allclose(a.hit_positions[: a.t_start + 1], a.original_hit[: a.t_start + 1], atol=1e-12)
    assert not a.foot_pinned[:, 1].any()  # the kicking (right) foot is never pinned
    assert a.foot_pinned[:, 0].any()  # the support foot is


@pytest.mark.data("cmu-bvh")
def test_adapt_real_kick_forward_ccd_reduces_error(kick):
    gp, hit, out = _hit_and_out(kick, KICK_TC, "rtoes", "rfemur")
    target = hit + 0.1 * out
    limb = reach_limb(kick, KICK_TC, "right_foot", target)
    a = adapt(kick, "right_foot", target, KICK_TC - 40, KICK_TC, options=AdaptOptions(feet="pin", floor=None))
    assert limb.residual[0] > 0.04
    assert a.solver[KICK_TC] == "ccd"
    assert a.residual < limb.residual[0] / 2
    _check_common(kick, a, KICK_TC - 40)


@pytest.mark.data("cmu-bvh")
def test_adapt_real_unreachable_target_best_effort(punch):
    gp, hit, out = _hit_and_out(punch, PUNCH_TC, "rhand", "rhumerus")
    sh = gp[PUNCH_TC, punch.joint_index("rhumerus")]
    wr = gp[PUNCH_TC, punch.joint_index("rwrist")]
    arm = sum(np.linalg.norm(punch.offsets[punch.joint_index(n)]) for n in ("rradius", "rwrist"))
    reach = arm + np.linalg.norm(hit - wr)  # farthest the fist can be from the shoulder
    target = sh + (reach + 1.0) * out  # 1 m beyond the arm's reach
    a = adapt(punch, "right_fist", target, PUNCH_TC - 40, PUNCH_TC, options=AdaptOptions(max_iter=50, feet="pin", floor=None))
    assert not a.reached
    limb = reach_limb(punch, PUNCH_TC, "right_fist", target)
    assert limb.residual[0] >= 1.0 - 1e-6
    # best effort: the trunk leans within its limits, the rest is the residual
    assert 0.6 < a.residual < 1.0
    assert a.residual < limb.residual[0]
    assert a.ccd_iterations.max() <= 50
    assert a.bone_length_error < 1e-9
    np.testing.assert_array_equal(a.motion.rotations[: PUNCH_TC - 39], punch.rotations[: PUNCH_TC - 39])


@pytest.mark.data("cmu-bvh")
def test_real_scalar_equals_batch_and_feet_modes(punch, kick):
    gp = punch.global_positions()
    frames = np.arange(280, 320)
    goal = gp[frames, punch.joint_index("rhand")] + [0.0, -0.05, -0.05]
    batch = reach_limb(punch, frames, "right_fist", goal)
    for i in (0, 17, 39):
        one = reach_limb(punch, int(frames[i]), "right_fist", goal[i])
        assert _quat_angle(one.rotations[0], batch.rotations[i]).max() < 1e-9
    # feet=None: a punch edit leaves the legs alone
    target = gp[PUNCH_TC, punch.joint_index("rhand")] + [0, -0.05, 0]
    a = adapt(punch, "right_fist", target, PUNCH_TC - 40, PUNCH_TC, options=AdaptOptions(feet=None, floor=None))
    legs = [punch.joint_index(n) for n in ("lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot")]
    np.testing.assert_array_equal(a.motion.rotations[:, legs], punch.rotations[:, legs])
    # feet="track" on a kick whose pelvis is turned by CCD: the support ankle follows its
    # original trajectory exactly
    gk, hit, out = _hit_and_out(kick, KICK_TC, "rtoes", "rfemur")
    b = adapt(kick, "right_foot", hit + 0.1 * out, KICK_TC - 40, KICK_TC,
              options=AdaptOptions(feet="track", floor=None))
    assert (b.solver == "ccd").any()
    la = kick.joint_index("lfoot")
    np.testing.assert_allclose(b.motion.global_positions()[:, la], gk[:, la], atol=1e-9)


def test_synthetic_punch_end_site_hit_point():
    from repro.motion.database import synthetic
    m, ann = synthetic.synthetic_clip("punch", "right", "middle", seed=1)
    assert ann["hit_joint"] == "RightHand" and ann["hit_point"] == "end_site"
    tc = ann["hit_frame"]
    X = np.array(ann["hit_position"]) + [0.0, 0.1, 0.0]
    a = adapt(m, "right_fist", X, tc - 20, tc, options=AdaptOptions(hit_point="end_site", feet="pin", floor=None))
    assert a.reached and a.residual < 1e-6
    np.testing.assert_allclose(a.original_hit[tc], ann["hit_position"], atol=1e-9)
    assert max(a.foot_slide.values()) < 1e-6
    assert a.bone_length_error < 1e-12


def test_quat_multiply_and_cross_fill_in_place_with_the_same_numbers():
    """The solvers' products (filled in place, no moveaxis/stack) equal the stacked formulas bit for bit, broadcast."""
    from repro.motion.core.quaternion import cross

    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 7, 4))
    for b in (rng.normal(size=(5, 7, 4)), rng.normal(size=(7, 4)), rng.normal(size=4), rng.normal(size=(5, 1, 4))):
        ax, ay, az, aw = np.moveaxis(a, -1, 0)
        bx, by, bz, bw = np.moveaxis(np.broadcast_to(b, a.shape), -1, 0)
        want = np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                         aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=-1)
        np.testing.assert_array_equal(quat_multiply(a, b), want)
        np.testing.assert_array_equal(quat_multiply(b, a).shape, want.shape)
        np.testing.assert_array_equal(cross(a[..., :3], b[..., :3]), np.cross(a[..., :3], b[..., :3]))
    assert quat_multiply([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]).tolist() == [0.0, 0.0, 0.0, 1.0]


# ------------------------------------------------------------- every argument checked (issue 23)
@pytest.mark.parametrize(
    "kw, match",
    [
        ({"floor": "x"}, "floor"),
        ({"release": "x"}, "release"),
        ({"release": float("inf")}, "release"),
        ({"foot_blend": None}, "foot_blend"),
        ({"tol": "1e-3"}, "tol"),
        ({"tol": 0.0}, "tol"),
        ({"max_extension": "0.5"}, "max_extension"),
        ({"max_extension": True}, "max_extension"),
        ({"max_foot_error": "x"}, "max_foot_error"),
        ({"kind": ["linear"]}, "kind"),
        ({"feet": ["pin"]}, "feet"),
        ({"hinge_range_deg": ("a", "b")}, "hinge_range_deg"),
        ({"hinge_range_deg": (0.0, 1.0, 2.0)}, "hinge_range_deg"),
        ({"limits": {"spine": "x"}}, "limit"),
    ],
)
def test_adapt_refuses_bad_options_with_motion_errors(kw, match):
    """Strings, None, booleans and non-finite values used to reach float() (bare ValueError / TypeError)."""
    m = _fixture_motion()
    with pytest.raises(MotionError, match=match):
        _adapt(m, "right_wrist", [0.0, 1.0, 0.5], 0, 5, **kw)


def test_the_solvers_refuse_bad_tolerances_rotations_and_repeats():
    from repro.motion.adaptation.cost import adaptation_cost

    m = _fixture_motion()
    with pytest.raises(MotionError, match="tol"):
        reach_limb(m, 0, "right_wrist", [0.0, 1.0, 0.5], tol="x")
    with pytest.raises(MotionError, match="tol"):
        ccd(m, 0, "right_wrist", [0.0, 1.0, 0.5], tol=float("nan"))
    with pytest.raises(MotionError, match="finish_with_limb"):
        ccd(m, 0, "right_wrist", [0.0, 1.0, 0.5], finish_with_limb="no")
    with pytest.raises(MotionError, match="targets"):
        reach_limb(m, 0, "right_wrist", [1j, 0.0, 0.0])
    with pytest.raises(MotionError, match="non-zero quaternions"):
        reach_limb(m, [0], "right_wrist", [0.0, 1.0, 0.5], rotations=np.zeros((1, m.n_joints, 4)))
    with pytest.raises(MotionError, match="include_pelvis"):
        default_chain(m, "right_wrist", include_pelvis="yes")
    with pytest.raises(MotionError, match="frames"):
        adaptation_cost(m, m, frames=[1, 2])
    with pytest.raises(MotionError, match="skeleton"):
        adaptation_cost(m, m, "sk")


def test_effector_of_any_type_and_huge_offset_curves_are_motion_errors():
    m = _fixture_motion()
    for eff in (["right_wrist"], np.zeros(2)):  # unhashable: used to fail in the chain cache
        with pytest.raises(MotionError, match="effector"):
            reach_limb(m, 0, eff, [0.0, 1.0, 0.5])
    with pytest.raises(MotionError, match="hit_point"):
        reach_limb(m, 0, "right_wrist", [0.0, 1.0, 0.5], hit_point=["joint"])
    with pytest.raises(MotionError, match="budget"):  # was a MemoryError
        offset_curve(0, 3, [0.0, 0.0, 0.1], 10**12)


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"chain": float("nan")}, "chain"),  # list(nan): TypeError
        ({"chain": np.array(1.0)}, "chain"),
        ({"chain": [["RightArm"]]}, "chain"),
        ({"root_offsets": np.ones((12, 3), dtype=complex)}, "root_offsets"),  # ComplexWarning, imaginary dropped
        ({"frames": range(10**12)}, "frames"),  # MemoryError
        ({"floor": 1e300}, "floor"),  # overflow in the norms
        ({"target": np.full(3, 1e300)}, "target"),
    ],
)
def test_adapt_refuses_what_the_argument_fuzzer_found(kw, match):
    m = _fixture_motion()
    args = dict(motion=m, effector="right_wrist", target=[0.0, 1.0, 0.5], t0=0, tc=5)
    args.update(kw)
    with pytest.raises(MotionError, match=match):
        _adapt(**args)


def test_solvers_refuse_far_targets_and_huge_frame_ranges():
    m = _fixture_motion()
    with pytest.raises(MotionError, match="targets"):
        reach_limb(m, [1, 2], "right_wrist", np.full(3, 1e300))
    with pytest.raises(MotionError, match="frames"):
        ccd(m, range(10**12), "right_wrist", [0.0, 1.0, 0.5])
