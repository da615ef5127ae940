"""The whole Section 3.4.2 edit (repro.motion.adaptation.adapt_clip.adapt, AdaptOptions).

Pronost et al.: d(t) grows from 0 at the current frame t0 to d(tc) = X - M(tc) at the
contact; at each frame the wrist / foot is brought to p(t) + d(t), by the limb first
(analytic) and by CCD over a longer chain when the limb cannot reach.  What is asserted:
adapt on the real CMU clips 135_09 (lunge punches) and 135_04 (front kicks): the fist /
foot moved 10 cm is reached within 1 cm at tc, frames <= t0 are untouched, bone lengths
unchanged, planted feet do not slide more than 2 cm; a target 1 m beyond reach gives
reached=False with a residual of the order of the excess; bad inputs and options raise
MotionError.

No timing is asserted (see ``repro.bench.adaptation.time_adaptation`` for the numbers).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError
from repro.motion import CMU_UNIT_M, read_bvh
from repro.motion.adaptation import (
    AdaptOptions,
    Adaptation,
    adapt,
    ccd,
    default_chain,
    offset_curve,
    reach_limb,
)
from repro.motion.core.quaternion import quat_multiply
from tests.motion.adaptation.fixture import IDX, fixture_motion, quat_angle

OPTION_NAMES = {f.name for f in dataclasses.fields(AdaptOptions)}


def _adapt(motion, effector, target, t0, tc, **kw):
    """:func:`adapt` with its options given as keywords among the per-call data (for the refusal tables)."""
    options = AdaptOptions(**{k: kw.pop(k) for k in list(kw) if k in OPTION_NAMES})
    return adapt(motion, effector, target, t0, tc, options=options, **kw)


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
    m = fixture_motion()
    args = {"effector": "right_fist", "target": [-0.3, 1.4, 0.4], "t0": 2, "tc": 6}
    args.update(kw)
    with pytest.raises(MotionError, match=match):
        _adapt(m, args.pop("effector"), args.pop("target"), args.pop("t0"), args.pop("tc"), **args)


def test_adapt_on_fixture_is_continuous_and_exact():
    m = fixture_motion(n_frames=12)
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
        assert quat_angle(one.rotations[0], batch.rotations[i]).max() < 1e-9
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
    m = fixture_motion()
    with pytest.raises(MotionError, match=match):
        _adapt(m, "right_wrist", [0.0, 1.0, 0.5], 0, 5, **kw)


def test_the_solvers_refuse_bad_tolerances_rotations_and_repeats():
    from repro.motion.adaptation.cost import adaptation_cost

    m = fixture_motion()
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
    m = fixture_motion()
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
    m = fixture_motion()
    args = dict(motion=m, effector="right_wrist", target=[0.0, 1.0, 0.5], t0=0, tc=5)
    args.update(kw)
    with pytest.raises(MotionError, match=match):
        _adapt(**args)


def test_solvers_refuse_far_targets_and_huge_frame_ranges():
    m = fixture_motion()
    with pytest.raises(MotionError, match="targets"):
        reach_limb(m, [1, 2], "right_wrist", np.full(3, 1e300))
    with pytest.raises(MotionError, match="frames"):
        ccd(m, range(10**12), "right_wrist", [0.0, 1.0, 0.5])


def test_rigs_of_one_skeleton_share_its_skeleton():
    """A character's clips (every order's) share one Skeleton (its roles found once); another skeleton, a
    role table or a motion without a unit gets its own."""
    from repro.motion.adaptation.rig import Rig

    m = dataclasses.replace(fixture_motion(), unit_m=1.0)
    other = dataclasses.replace(m, rotations=np.asarray(m.rotations)[::-1])  # another clip, the same skeleton
    assert Rig(m).sk is Rig(other).sk
    longer = dataclasses.replace(m, offsets=np.asarray(m.offsets) * 1.1)
    assert Rig(longer).sk is not Rig(m).sk and Rig(longer).sk.size > Rig(m).sk.size
    roles = dict(Rig(m).sk.roles)
    assert Rig(m, roles).sk is not Rig(m).sk and Rig(m, roles).sk.roles == roles
