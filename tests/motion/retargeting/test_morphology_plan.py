"""RetargetPlan: ``retarget`` between two fixed skeletons, the per-skeleton work cached (issue 13, item 4).

What is asserted:

* on random poses (one frame and whole clips) of characters whose proportions differ from
  the actor's (per-bone factors inside a limb, trunk, legs, uniform size on top),
  ``RetargetPlan(source, actor).positions`` equals ``retarget(pose, actor).global_positions()``
  bit for bit, with and without the source's world transforms given;
* ``MotionRetriever.prepare`` (which uses the plan for such characters) gives the same
  ``q_r`` as the retargeting it replaces (``retarget`` then the pose cloud), bit for bit;
  plans are cached per (actor, pose skeleton) and a pose on another skeleton gets its own;
* across joint trees (a Mixamo rig on the synthetic database) ``prepare`` (through its cached
  ``TreePlan``) still gives the cloud of ``retarget_to_tree``;
* ``retarget_across``'s constants cached per pair of skeletons give the numbers of a fresh
  computation, and a character of other proportions gets its own entry;
* the plan refuses what ``retarget`` refuses (a target whose rest pose is turned, another
  topology), with MotionError.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.body.pose_frames import pose_points
from repro.motion.retargeting.morphology import RetargetPlan, retarget
from repro.motion.core.cache import LRUCache
from repro.motion.retargeting.dispatch import rest_motion_y_up, retarget_to_tree
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.database.synthetic.conventions import build

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


def test_prepare_across_trees_equals_retarget_to_tree(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    rig = build("mixamo")[0].motion(unit_m=1.0)
    actor = db.actors[0]
    rng = np.random.default_rng(5)
    for _ in range(3):
        m = retarget(db.motion(int(rng.integers(db.n_clips))), rig)
        f = int(rng.integers(m.n_frames))
        pose = dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])
        ch = Skeleton.from_motion(m)
        q = r.prepare(pose, ch)
        qr = retarget_to_tree(pose, actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
        assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))


def test_plan_refuses_what_retarget_refuses(synthetic_db):
    db = synthetic_db
    actor = db.actors[0]
    pose = on(scale_skeleton(actor, **CHARACTERS[0]), db.motion(0), slice(0, 1))
    off = np.array(actor.offsets)
    j = actor.index("LeftForeArm")
    off[j] = np.array([off[j][1], -off[j][0], off[j][2]])  # the forearm turned by 90 degrees at rest
    turned = dataclasses.replace(actor, offsets=off)
    with pytest.raises(MotionError, match="rest pose"):
        retarget(pose, turned)
    with pytest.raises(MotionError, match="rest pose"):
        RetargetPlan(pose, turned)
    rig = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(MotionError, match="joint names and parents"):
        RetargetPlan(pose, rig)


def test_retarget_across_constants_cached_per_pair(synthetic_db, monkeypatch):
    """The per-pair constants of retarget_across give the numbers of a fresh computation, and a
    character of other proportions gets its own entry (never another pair's)."""
    import repro.motion.retargeting.trees as rt

    db = synthetic_db
    rig = build("mixamo")[0].motion(unit_m=1.0)
    m = db.motion(2)
    other = scale_skeleton(Skeleton.from_motion(rig), scale=1.2, bone_scales={"mixamorig:LeftForeArm": 1.4})
    monkeypatch.setattr(rt, "_PAIRS", LRUCache(32))
    first = rt.retarget_across(m, rig).global_positions()
    assert len(rt._PAIRS) == 1
    again = rt.retarget_across(m, rig).global_positions()
    o = rt.retarget_across(m, other).global_positions()
    assert len(rt._PAIRS) == 2
    monkeypatch.setattr(rt, "_PAIRS", LRUCache(32))
    fresh = rt.retarget_across(m, other).global_positions()
    assert np.array_equal(first, again) and np.array_equal(o, fresh)
    assert not np.allclose(o, first)
