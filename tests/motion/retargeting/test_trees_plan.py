"""TreePlan: ``retarget_across``'s positions between two fixed skeletons of different joint trees,
the pose-independent work cached (issue 13, item 4).

What is asserted:

* ``TreePlan(motion, character, ...).positions`` equals
  ``retarget_across(motion, character, ...).global_positions()`` (``assert_allclose``, rtol and
  atol 1e-12; in practice bit for bit but for a few rounding steps of the stacked limb
  products on some rigs) on one frame and whole clips, with and without the source's world
  transforms given: every synthetic rig convention onto the synthetic actor's Y-up rest pose
  (the ``prepare`` case) and the synthetic clips onto every rig (Y and Z up); real CMU and
  Bandai Namco skeletons each way; the pybvh fixtures (another tool's files) onto the
  synthetic actor;
* the plan refuses what ``retarget_across`` refuses, with the same MotionError message;
* ``MotionRetriever.prepare`` across trees gives the cloud of ``retarget_to_tree`` bit for
  bit, caches one plan per (actor, pose skeleton, roles), gives a pose on another skeleton
  its own plan, keeps at most 64, and turns a refusal into the RetrievalError it raised
  before (the MotionError's text, the character remembered as refused).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError, RetrievalError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh
from repro.motion.body.pose_frames import pose_points
from repro.motion.retargeting.morphology import retarget
from repro.motion.retargeting.trees import TreePlan, body_frame, rest_axes, retarget_across
from repro.motion.retargeting.dispatch import rest_motion_y_up, retarget_to_tree
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import CONVENTIONS, build

TOL = dict(rtol=1e-12, atol=1e-12)


def frames(m, sl):
    return dataclasses.replace(m, rotations=m.rotations[sl], positions=m.positions[sl])


def check(motion, character, roles=None, character_roles=None):
    """The plan's positions against retarget_across's, on one frame, three frames and the whole motion."""
    plan = TreePlan(motion, character, roles=roles, character_roles=character_roles)
    F = motion.n_frames
    for sl in (slice(F // 2, F // 2 + 1), slice(0, 3), slice(None)):
        m = frames(motion, sl)
        ref = retarget_across(m, character, roles=roles, character_roles=character_roles).global_positions()
        got = plan.positions(m.rotations, m.local_translations())
        assert got.shape == ref.shape
        np.testing.assert_allclose(got, ref, **TOL)
        got2 = plan.positions(m.rotations, m.local_translations(), source=m.global_transforms())
        np.testing.assert_allclose(got2, ref, **TOL)
    return plan


@pytest.fixture(scope="module")
def clip():
    return synthetic_clip("punch", seed=3)[0]


@pytest.mark.parametrize("convention", list(CONVENTIONS))
def test_rig_pose_onto_actor_rest(synthetic_db, convention):
    """The prepare case: a character of another tree, its pose onto the actor's Y-up rest pose."""
    db = synthetic_db
    actor = db.actors[0]
    rest = rest_motion_y_up(actor)
    rig = build(convention)[0].motion(unit_m=1.0)
    m = retarget(db.motion(3), rig)
    m = m if m.up is not None else dataclasses.replace(m, up="y")
    ch = Skeleton.from_motion(m)
    check(m, rest, roles=dict(ch.roles), character_roles=dict(actor.roles))


@pytest.mark.parametrize("convention", list(CONVENTIONS))
def test_clip_onto_rig(clip, convention):
    """The other way: the synthetic clip played by every rig (some Z up, other rest poses)."""
    rig = build(convention)[0].motion(unit_m=1.0)
    check(clip, rig)


def _read(path, unit=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_bvh(path, unit_m=unit)


@pytest.mark.data("cmu-bvh")
@pytest.mark.data("bandai")
def test_real_cmu_and_bandai():
    cmu = frames(_read(data.fetch("mocap/cmu/135_04.bvh"), CMU_UNIT_M), slice(0, 40))
    bandai = frames(_read(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), BANDAI_UNIT_M), slice(0, 40))
    for src, tgt in ((cmu, bandai), (bandai, cmu)):
        check(src, tgt)
        check(src, rest_motion_y_up(tgt), character_roles=dict(Skeleton.from_motion(tgt).roles))


def test_pybvh_fixtures_onto_the_actor(synthetic_db):
    d = data.data_dir() / "mocap/formats/pybvh"
    names = ("bvh_test1.bvh", "standard_skeleton.bvh", "rotation_first_root.bvh")
    if not all((d / n).exists() for n in names):
        pytest.skip("the pybvh fixtures are not staged")
    actor = synthetic_db.actors[0]
    rest = rest_motion_y_up(actor)
    done = 0
    for n in names:
        m = _read(d / n, 0.0254)  # inches: what the unit inference finds for these files (its warning tested elsewhere)
        try:
            ref = retarget_across(m, rest, character_roles=dict(actor.roles))
        except MotionError as e:  # then the plan refuses it alike
            with pytest.raises(MotionError) as info:
                TreePlan(m, rest, character_roles=dict(actor.roles))
            assert str(info.value) == str(e)
            continue
        assert ref.n_frames == m.n_frames
        check(m, rest, character_roles=dict(actor.roles))
        done += 1
    assert done >= 1


def test_refusals_are_retarget_across_s(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    sk = Skeleton.from_motion(rig)
    off = np.array(sk.offsets)
    for r in ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "left_clavicle", "right_clavicle"):
        if r in sk.roles:
            off[sk.index(r), 0] = 0.0  # no left-right extent: the facing cannot be told
    flat = dataclasses.replace(sk, offsets=off)
    no_pos = dataclasses.replace(sk, channels=[("Zrotation", "Xrotation", "Yrotation")] + list(sk.channels[1:]))
    for bad in (flat, no_pos, "mixamo"):
        with pytest.raises(MotionError) as ref:
            retarget_across(clip, bad)
        with pytest.raises(MotionError) as got:
            TreePlan(clip, bad)
        assert str(got.value) == str(ref.value)
    with pytest.raises(MotionError, match="must be a Motion"):
        TreePlan(sk, rig)


def cloud(db, actor, g):
    idx = [actor.index(r) for r in db.pose_roles]
    return pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                       window=db.window, step=db.step)[-1] / actor.size


def as_prepared(pose):
    """The window prepare retargets: the pose, or a new Motion of it when renormalising changes its bits."""
    R = pose.rotations
    return pose if np.array_equal(R / np.linalg.norm(R, axis=-1, keepdims=True), R) else frames(pose, slice(None))


def test_prepare_across_trees_uses_cached_plans(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rng = np.random.default_rng(11)
    n = 0
    for convention in ("mixamo", "unreal", "smpl"):
        rig = build(convention)[0].motion(unit_m=1.0)
        for _ in range(3):
            m = retarget(db.motion(int(rng.integers(db.n_clips))), rig)
            f = int(rng.integers(m.n_frames))
            pose = frames(m, slice(f, f + 1))
            ch = Skeleton.from_motion(m)
            q = r.prepare(pose, ch)
            qr = retarget_to_tree(as_prepared(pose), actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
            assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))
        n += 1
        assert len(r._tree_plans) == n  # one plan per skeleton, reused by its poses
    plan = next(iter(r._tree_plans.values()))
    pose_again = frames(retarget(db.motion(0), build("mixamo")[0].motion(unit_m=1.0)), slice(0, 1))
    assert r.tree_plan(pose_again, 0, Skeleton.from_motion(pose_again).roles) is plan
    # a skeleton of other offsets (same joints) gets its own plan
    rig = build("mixamo")[0].motion(unit_m=1.0)
    longer = dataclasses.replace(rig, offsets=rig.offsets * 1.1)
    m = frames(retarget(db.motion(1), longer), slice(0, 1))
    ch = Skeleton.from_motion(m)
    q = r.prepare(m, ch)
    assert len(r._tree_plans) == n + 1
    qr = retarget_to_tree(as_prepared(m), actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
    assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))
    # bounded
    for k in range(70):
        mk = dataclasses.replace(m, offsets=m.offsets * (1.0 + 0.001 * (k + 1)))
        r.tree_plan(mk, 0, ch.roles)
    assert len(r._tree_plans) <= 64


def test_prepare_refusal_unchanged(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rig = build("mixamo")[0].motion(unit_m=1.0)
    m = frames(retarget(db.motion(2), rig), slice(0, 1))
    sk = Skeleton.from_motion(m)
    off = np.array(m.offsets)
    for role in ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "left_clavicle", "right_clavicle"):
        off[sk.index(role), 0] = 0.0
    flat = dataclasses.replace(m, offsets=off)
    ch = Skeleton.from_motion(flat, roles=dict(sk.roles))
    with pytest.raises(MotionError) as ref:
        retarget_to_tree(flat, actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
    for _ in range(2):  # the second time from the refusal remembered for the character
        with pytest.raises(RetrievalError) as got:
            r.prepare(flat, ch)
        assert str(ref.value) in str(got.value)


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"blend_time": float("nan"), "fix_feet": True}, "blend_time"),  # was a ValueError in _fix_feet
        ({"blend_time": -1.0, "fix_feet": True}, "blend_time"),
        ({"blend_time": "x"}, "blend_time"),
        ({"fix_feet": "yes"}, "fix_feet"),
        ({"character_roles": ["a"]}, "character_roles"),  # was a bare exception
        ({"character_roles": {"pelvis": 3}}, "character_roles"),
        ({"roles": "pelvis"}, "roles"),
    ],
)
def test_retarget_across_checks_its_arguments(clip, kw, match):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(MotionError, match=match):
        retarget_across(clip, rig, **kw)
    if "blend_time" not in kw and "fix_feet" not in kw:
        with pytest.raises(MotionError, match=match):
            TreePlan(clip, rig, **kw)


def test_a_blend_longer_than_the_clip_is_the_whole_clip(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    a = retarget_across(clip, rig, fix_feet=True, blend_time=1.7e308)  # / frame_time = inf: used to overflow in round()
    b = retarget_across(clip, rig, fix_feet=True, blend_time=1e6)
    np.testing.assert_array_equal(a.rotations, b.rotations)


@pytest.mark.parametrize("call", [lambda sk: body_frame("sk", "y"), lambda sk: body_frame(sk, "x"),
                                  lambda sk: body_frame(sk, ["y"]), lambda sk: rest_axes(None)])
def test_body_frame_and_rest_axes_check_their_arguments(call):
    sk = Skeleton.from_motion(build("mixamo")[0].motion(unit_m=1.0))
    with pytest.raises(MotionError):
        call(sk)


def test_plans_check_the_source_transforms(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    plan = TreePlan(clip, rig)
    rot, tr = clip.rotations, clip.local_translations()
    for bad in ("x", (rot,), (np.zeros((2, 3, 4)), np.zeros((2, 3, 3))), [clip.global_transforms()]):
        with pytest.raises(MotionError, match="source"):  # "x" used to fail unpacking (ValueError)
            plan.positions(rot, tr, source=bad)
    np.testing.assert_array_equal(plan.positions(rot.tolist(), tr.tolist()), plan.positions(rot, tr))
    # found by the argument fuzzer: NaN results, overflow and division warnings, dropped imaginary parts
    for r, t, match in ((rot[:, :3], tr, "rotations"), (rot * 1e-300, tr, "unit quaternions"),
                        (rot * 1e300, tr, "unit quaternions"), (rot + 1j, tr, "complex"),
                        (rot, tr * 1e300, "translations beyond"), (rot, np.where(tr == tr.max(), np.nan, tr), "NaN")):
        with pytest.raises(MotionError, match=match):
            plan.positions(r, t)
