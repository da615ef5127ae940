"""Retargeting on one joint tree (repro.motion.retargeting.morphology).

Pronost et al., Section 3.4.1, after Kulpa et al. (2005).  What is asserted:

* a real CMU front kick (135_04) retargeted to a 1.2x taller character with 25 % longer
  legs keeps the planted ankle on the floor (height within 3 cm of the source's planted
  height scaled by the foot ratio, no penetration), whereas copying angles with the
  unscaled root translation sinks the feet ~15 cm into the floor and slides more;
  with ``fix_feet`` planted feet do not slide at all; with another thigh/shin ratio the
  representation slides less than angle copying;
* ``naive_retarget`` copies angles (and equals the representation when both bones of every
  limb scale alike); the result writes and reads back as BVH;
* ``retarget`` is ``RetargetPlan(...).apply(...)``: its result equals ``decode(encode(m), target)``
  bit for bit, with and without ``fix_feet``; on random poses (one frame and whole clips) of
  characters whose proportions differ from the actor's (per-bone factors inside a limb,
  trunk, legs, uniform size on top) ``RetargetPlan(source, actor).positions`` equals
  ``retarget(pose, actor).global_positions()`` bit for bit, with and without the source's
  world transforms given;
* ``MotionRetriever.prepare`` (which uses the plan for such characters) gives the same
  ``q_r`` as the retargeting it replaces (``retarget`` then the pose cloud), bit for bit;
  plans are cached per (actor, pose skeleton) and a pose on another skeleton gets its own;
* the plan refuses what ``retarget`` refuses (another topology), with MotionError; a target whose
  rest pose is turned gets the poses re-expressed on its rest directions, as ``retarget`` does (1e-9);
* bad inputs raise :class:`MotionError`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import MotionError
from repro import data
from repro.motion import CMU_UNIT_M, read_bvh, write_bvh
from repro.motion.body.feet import foot_contacts, foot_metrics
from repro.motion.body.pose_frames import pose_points
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.database.synthetic.conventions import build
from repro.motion.retargeting.morphology import (
    RetargetPlan,
    decode,
    decode_with_report,
    encode,
    naive_retarget,
    retarget,
)
from repro.motion.search.retrieval import MotionRetriever
from tests.motion.retargeting.mixamo_motions import NAMES, fk_bone_lengths, random_motion, rest_skeleton


def test_naive_retarget_copies_angles():
    m = random_motion(3)
    tgt = scale_skeleton(m, height=1.9, leg_scale=1.2)
    nv = naive_retarget(m, tgt)
    np.testing.assert_allclose(nv.rotations, m.rotations)
    np.testing.assert_allclose(nv.root_positions, m.root_positions)
    np.testing.assert_array_equal(nv.offsets, tgt.offsets)
    ns = naive_retarget(m, tgt, scale_root=True)
    np.testing.assert_allclose(ns.root_positions, m.root_positions * tgt.hip_height / Skeleton.from_motion(m).hip_height)
    # when both bones of every limb scale alike, decoding the representation = angle copy + scaled root
    out = retarget(m, tgt)
    assert np.abs(out.global_positions() - ns.global_positions()).max() <= 1e-9
    # ... and not when the upper/lower ratio changes
    tgt2 = scale_skeleton(m, bone_scales={"LeftHand": 1.4})
    assert np.abs(retarget(m, tgt2).global_positions() - naive_retarget(m, tgt2, scale_root=True).global_positions()).max() > 1e-3


def test_retarget_writes_bvh(tmp_path):
    m = random_motion(7, F=4, max_angle=2.0)
    out = retarget(m, scale_skeleton(m, height=1.5, arm_scale=1.2))
    path = write_bvh(out, tmp_path / "retargeted.bvh")
    back = read_bvh(path)
    assert back.joint_names == out.joint_names
    np.testing.assert_allclose(back.global_positions(), out.global_positions(), atol=1e-8)


@pytest.mark.data("cmu-bvh")
def test_cmu_front_kick_to_taller_long_legged_fighter(front_kick):
    m = front_kick
    src = Skeleton.from_motion(m)
    tgt = scale_skeleton(src, height=1.2 * src.size, leg_scale=1.25)
    assert tgt.size == pytest.approx(1.2 * src.size)
    contacts = foot_contacts(m)
    assert contacts.any(axis=0).all()
    ref = foot_metrics(m, contacts)
    foot_ratio = tgt.limb_lengths["left_foot"] / src.limb_lengths["left_foot"]
    expected_planted = ref["planted_height_mean"] * foot_ratio

    ours = retarget(m, tgt)
    np.testing.assert_allclose(
        fk_bone_lengths(ours), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, m.n_joints - 1)),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    o = foot_metrics(ours, contacts)
    naive = foot_metrics(naive_retarget(m, tgt), contacts)
    # ours: planted ankle stays on the floor plane (within 3 cm), toes never below -1 cm
    assert abs(o["planted_height_mean"] - expected_planted) < 0.03
    assert o["min_toe_height"] > -0.01
    # naive angle copy, unscaled root: the longer legs sink the feet > 10 cm into the floor
    assert naive["planted_height_mean"] < -0.10 and naive["min_toe_height"] < -0.15
    assert naive["slide_per_contact"] > 1.5 * o["slide_per_contact"]
    # with feet correction planted feet do not slide and stay at the expected height
    fixed_motion = retarget(m, tgt, fix_feet=True)
    np.testing.assert_allclose(
        fk_bone_lengths(fixed_motion), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, m.n_joints - 1)),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    fixed = foot_metrics(fixed_motion, contacts)
    assert fixed["slide_per_contact"] < 1e-3 and fixed["slide_speed"] < 0.01
    assert abs(fixed["planted_height_mean"] - expected_planted) < 0.005


@pytest.mark.data("cmu-bvh")
def test_cmu_front_kick_other_thigh_shin_ratio(front_kick):
    """Where the representation differs from angle copying: thigh 30 % longer, shin 20 % shorter."""
    m = front_kick
    tgt = scale_skeleton(m, bone_scales={"ltibia": 1.3, "rtibia": 1.3, "lfoot": 0.8, "rfoot": 0.8})
    contacts = foot_contacts(m)
    ours = foot_metrics(retarget(m, tgt), contacts)
    angles = foot_metrics(naive_retarget(m, tgt, scale_root=True), contacts)
    assert ours["slide_speed"] < angles["slide_speed"]
    assert ours["planted_height_std"] < 0.5 * angles["planted_height_std"]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda m, sk: encode("m"), "Motion"),
        (lambda m, sk: encode(m, roles=["a"]), "roles"),
        (lambda m, sk: decode("mi", sk), "MorphologyIndependentMotion"),
        (lambda m, sk: decode(encode(m), sk, blend_time=float("nan")), "blend_time"),
        (lambda m, sk: decode(encode(m), sk, blend_time=-1.0, fix_feet=True), "blend_time"),
        (lambda m, sk: decode(encode(m), sk, fix_feet="yes"), "fix_feet"),
        (lambda m, sk: decode(encode(m), sk, max_rest_angle_deg="5"), "max_rest_angle_deg"),
        (lambda m, sk: decode_with_report(encode(m), sk, max_rest_angle_deg=float("inf")), "max_rest_angle_deg"),
        (lambda m, sk: retarget("m", sk), "Motion"),
        (lambda m, sk: retarget(m, "sk"), "target"),
        (lambda m, sk: retarget(m, sk, fix_feet=1), "fix_feet"),
        (lambda m, sk: retarget(m, sk, roles="x"), "roles"),
        (lambda m, sk: naive_retarget(m, sk, scale_root="yes"), "scale_root"),
        (lambda m, sk: naive_retarget(m, None), "target"),
    ],
)
def test_morphology_entries_refuse_bad_arguments(call, match):
    with pytest.raises(MotionError, match=match):
        call(random_motion(0, F=4), rest_skeleton())


def test_retarget_plan_checks_the_source_transforms():
    m = random_motion(0, F=4)
    plan = RetargetPlan(m, rest_skeleton())
    with pytest.raises(MotionError, match="source"):
        plan.positions(m.rotations, m.local_translations(), source="x")
    with pytest.raises(MotionError, match="source"):
        plan.positions(m.rotations, m.local_translations(), source=(m.rotations, m.positions[:, :3]))
    with pytest.raises(MotionError, match="unit quaternions"):  # found by the argument fuzzer: 0/0
        plan.positions(np.zeros_like(m.rotations), m.local_translations())
    with pytest.raises(MotionError, match="NaN"):
        plan.positions(m.rotations, m.local_translations() * np.nan)


@pytest.mark.parametrize("fix_feet", [False, True])
def test_retarget_is_decode_of_encode(fix_feet):
    """The plan's composition of encoding and decoding (stacked limb frames, the source's world
    rotations reused) gives the numbers of the two functions, the feet pinned or not."""
    m = random_motion(11, F=20, max_angle=1.5)
    for tgt in (scale_skeleton(m, height=1.9, leg_scale=1.2, bone_scales={"LeftHand": 1.3}), rest_skeleton()):
        want = decode(encode(m), tgt, fix_feet=fix_feet)
        got = retarget(m, tgt, fix_feet=fix_feet)
        np.testing.assert_array_equal(got.rotations, want.rotations)
        np.testing.assert_array_equal(got.positions, want.positions)
        assert got.channels == want.channels and got.joint_names == want.joint_names
    with pytest.raises(MotionError, match="source skeleton"):
        RetargetPlan(m, tgt).apply(dataclasses.replace(m, joint_names=[n + "_x" for n in NAMES]))


CHARACTERS = [
    dict(scale=1.1, arm_scale=1.2, leg_scale=0.9, bone_scales={"LeftForeArm": 1.3, "RightLeg": 0.8}),
    dict(scale=0.8, bone_scales={"LeftArm": 1.5, "LeftUpLeg": 1.2, "Spine": 0.7}),
    dict(trunk_scale=1.3, bone_scales={"RightForeArm": 0.6, "LeftFoot": 1.4}),
]


def on(character, m, frames):
    """Frames ``frames`` of ``m`` played by ``character`` (same rotations, its offsets)."""
    t = np.where(m.position_mask[None], m.local_translations(), character.offsets[None])[frames]
    return character.motion_with(m.rotations[frames], t, frame_time=m.frame_time)


def cloud(db, actor, g):
    idx = [actor.index(r) for r in db.pose_roles]
    return pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                       window=db.window, step=db.step)[-1] / actor.size


@pytest.mark.parametrize("kw", CHARACTERS)
def test_plan_equals_retarget(synthetic_db, kw):
    db = synthetic_db
    actor = db.actors[0]
    ch = scale_skeleton(actor, **kw)
    rng = np.random.default_rng(len(str(kw)))
    for _ in range(4):
        m = db.motion(int(rng.integers(db.n_clips)))
        f = int(rng.integers(m.n_frames))
        for frames in (slice(f, f + 1), slice(None)):
            pose = on(ch, m, frames)
            want = retarget(pose, actor).global_positions()
            plan = RetargetPlan(pose, actor)
            got = plan.positions(pose.rotations, pose.local_translations())
            assert np.array_equal(got, want)
            got = plan.positions(pose.rotations, pose.local_translations(), source=pose.global_transforms())
            assert np.array_equal(got, want)


def test_prepare_equals_retarget(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rng = np.random.default_rng(3)
    for kw in CHARACTERS:
        ch = scale_skeleton(actor, **kw)
        assert r._scaling_of(on(ch, db.motion(0), slice(0, 1)), 0) is None  # not the uniform fast path
        for _ in range(5):
            m = db.motion(int(rng.integers(db.n_clips)))
            pose = on(ch, m, slice(int(rng.integers(m.n_frames)), None))
            q = r.prepare(pose, ch)
            last = dataclasses.replace(pose, rotations=pose.rotations[-1:], positions=pose.positions[-1:])
            want = cloud(db, actor, retarget(last, actor).global_positions())
            assert np.array_equal(q.q_n[0], want)
    n = len(r._plans)
    assert 1 <= n <= len(CHARACTERS)  # one plan per character skeleton, reused
    r.prepare(on(scale_skeleton(actor, **CHARACTERS[0]), db.motion(1), slice(0, 1)), scale_skeleton(actor, **CHARACTERS[0]))
    assert len(r._plans) == n


def test_plan_matches_another_rest_pose_as_retarget(synthetic_db):
    db = synthetic_db
    actor = db.actors[0]
    pose = on(scale_skeleton(actor, **CHARACTERS[0]), db.motion(0), slice(0, 1))
    off = np.array(actor.offsets)
    j = actor.index("LeftForeArm")
    off[j] = np.array([off[j][1], -off[j][0], off[j][2]])  # the forearm turned by 90 degrees at rest
    turned = dataclasses.replace(actor, offsets=off)
    # the plan re-expresses the poses on the target's rest directions as retarget does (issue 25, leftovers)
    plan = RetargetPlan(pose, turned)
    assert plan.rest is not None
    want = retarget(pose, turned)
    assert np.abs(plan.apply(pose).global_positions() - want.global_positions()).max() <= 1e-9
    assert np.abs(plan.apply(pose).rotations - want.rotations).max() <= 1e-9
    g = plan.positions(pose.rotations, pose.local_translations())
    assert np.abs(g - want.global_positions()).max() <= 1e-9
    g2 = plan.positions(pose.rotations, pose.local_translations(), source=pose.global_transforms())
    assert np.abs(g2 - want.global_positions()).max() <= 1e-9
    # retarget re-expresses the motion on the target's rest directions first (issue 25, item 5): the same
    # poses, so the arm's limb vector (shoulder -> wrist, Kulpa et al.'s normalised vector) is the source's
    out = retarget(pose, turned)
    src, got = pose.global_positions()[0], out.global_positions()[0]
    s_, w = actor.index("LeftArm"), actor.index("LeftHand")
    u, v = src[w] - src[s_], got[w] - got[s_]
    assert np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)) > 1 - 1e-9
    rig = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(MotionError, match="joint names and parents"):
        RetargetPlan(pose, rig)


@pytest.mark.data("cmu-bvh")
def test_plan_other_cmu_subject_equals_retarget(front_kick):
    """Subject 131 (rest directions 11.7 degrees from subject 135's) onto the 135 actor: the plan's
    precomputed rest step gives retarget's numbers (1e-9), with and without the feet fixed."""
    m = read_bvh(data.fetch("mocap/cmu/131_01.bvh"), unit_m=CMU_UNIT_M)
    m = dataclasses.replace(m, rotations=m.rotations[:120:3], positions=m.positions[:120:3])
    plan = RetargetPlan(m, front_kick)
    assert plan.rest is not None
    for fix_feet in (False, True):
        want = retarget(m, front_kick, fix_feet=fix_feet)
        got = plan.apply(m, fix_feet=fix_feet)
        assert np.abs(got.global_positions() - want.global_positions()).max() <= 1e-9
    g = plan.positions(m.rotations, m.local_translations(), source=m.global_transforms())
    assert np.abs(g - retarget(m, front_kick).global_positions()).max() <= 1e-9


def test_plan_same_rest_pose_unchanged():
    """A target with the source's rest directions: no rest step, the plan's usual numbers."""
    m = random_motion(5, F=6)
    tgt = scale_skeleton(m, height=1.8, leg_scale=1.1)
    plan = RetargetPlan(m, tgt)
    assert plan.rest is None
    assert np.array_equal(plan.apply(m).global_positions(), retarget(m, tgt).global_positions())
