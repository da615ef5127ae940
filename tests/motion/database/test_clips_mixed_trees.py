"""Mixed-skeleton databases and any-humanoid characters (issue 11, item 4).

What is asserted:

* a :class:`MotionDatabase` holds clips of several joint trees (the synthetic skeleton
  and the same clips rewritten onto Mixamo and MotionBuilder rigs of
  :mod:`repro.motion.database.synthetic.conventions`): one base actor per tree, role-based pose
  clouds in units of stature that agree across the trees, and its ``.npz`` file
  round-trips;
* ``MotionRetriever`` retargets the current pose to every actor (the rest pose per actor
  made once, cached), so a clip of another tree is served, by default (without the
  caller asking: ``across_trees=True`` is the default); with ``across_trees=False`` the
  single-tree behaviour is unchanged (the other trees are not candidates); the exact search is
  the exhaustive optimum either way (every actor in the query, or one);
* :func:`strike` and :class:`KungFuFighter` play the selected clip on a character of
  another tree (a Mixamo-named rig given as a Motion), hitting the target;
* bad characters: no arm for a punch / no leg for a kick (named, for what), another
  tree on a single-tree fighter; a Z-up character is turned to the fighter's Y-up world;
* on the staged data: the CMU + Bandai database serves a CMU character a Bandai clip,
  and a Bandai character a CMU clip (in the fighter).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import repro.motion.search.query as query_mod
from repro.motion.retargeting import dispatch
from repro.errors import MotionError, RetrievalError
from repro.motion.database.clips import Clip, MotionDatabase
from repro.motion.runtime.fighter import KungFuFighter
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.body.units import UnitWarning
from repro.motion.body.skeleton import Skeleton
from repro.motion.runtime.strike import strike
from repro.motion.database.synthetic.conventions import build


def frame_of(m, f):
    return dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])


def rewritten(clip: Clip, rig_motion, suffix: str) -> Clip:
    """``clip`` retargeted onto another joint tree, its annotations carried over by role."""
    m = retarget(clip.motion, rig_motion)
    sk = Skeleton.from_motion(m)
    return Clip(name=f"{clip.name}_{suffix}", motion=m, semantics=clip.semantics, hit_role=clip.hit_role,
                hit_joint=sk.roles[clip.hit_role], hit_where=clip.hit_where, hit_frame=clip.hit_frame,
                kind=clip.kind, level=clip.level, source=clip.source)


@pytest.fixture(scope="module")
def rigs():
    return {c: build(c)[0].motion(unit_m=1.0) for c in ("mixamo", "motionbuilder", "unreal")}


@pytest.fixture(scope="module")
def mixed(synthetic_db, rigs):
    """Clips 0, 3, 6 ... on the synthetic tree, 1, 4 ... on Mixamo, 2, 5 ... on MotionBuilder."""
    db = synthetic_db
    idx = np.arange(0, db.n_clips, 2)  # half the clips keep the test quick
    clips = []
    for n, i in enumerate(idx.tolist()):
        c = db.clip(i)
        if n % 3 == 1:
            c = rewritten(c, rigs["mixamo"], "mixamo")
        elif n % 3 == 2:
            c = rewritten(c, rigs["motionbuilder"], "mb")
        clips.append(c)
    return MotionDatabase.from_clips(clips), idx


@pytest.fixture(scope="module")
def across(mixed):
    return MotionRetriever(mixed[0], seed=0, across_trees=True)


def tree_of(db, i):
    return db.actors[int(db.actor[i])].joint_names[0]


# ------------------------------------------------------------------ the database
def test_actors_of_several_trees_coexist_and_round_trip(mixed, synthetic_db, tmp_path):
    db, idx = mixed
    roots = sorted({a.joint_names[0] for a in db.actors})
    assert roots == ["Hips", "mixamorig:Hips"]  # MotionBuilder keeps the synthetic root name ...
    assert len(db.actors) == 3  # ... but has another tree (Chest2, Chest3): its own base actor
    assert len({tuple(a.joint_names) for a in db.actors}) == 3
    # pose clouds are role point clouds in units of stature: a clip rewritten onto another tree
    # (same body proportions) has the pose clouds of the original
    for n in (1, 2):
        orig = synthetic_db.poses_of(int(idx[n]))
        here = db.poses_of(n)
        err = np.abs(db.pose_points[here] - synthetic_db.pose_points[orig]).max()
        assert err < 2e-3, err
    path = db.save(tmp_path / "mixed.npz")
    back = MotionDatabase.load(path)
    assert back.equals(db)
    assert [a.joint_names for a in back.actors] == [a.joint_names for a in db.actors]
    assert back.motion(1).joint_names == db.motion(1).joint_names


# ------------------------------------------------------------------ the retrieval
def test_single_tree_retriever_keeps_to_the_characters_tree(mixed):
    db, _ = mixed
    r = MotionRetriever(db, seed=0, across_trees=False)
    assert r.across_trees is False
    pose = frame_of(db.motion(1), 0)  # a Mixamo clip's pose, on the Mixamo character
    q = r.prepare(pose, Skeleton.from_motion(pose))
    assert q.actors == (int(db.actor[1]),)


def test_the_default_retriever_serves_every_tree(mixed, across):
    """Nobody has to know to ask: the default retriever compares the other trees' poses too,
    and its q_r on every actor is the across-trees one."""
    db, _ = mixed
    r = MotionRetriever(db, seed=0)
    assert r.across_trees is True
    pose = frame_of(db.motion(1), 0)
    ch = Skeleton.from_motion(pose)
    q, qa = r.prepare(pose, ch), across.prepare(pose, ch)
    assert sorted(q.actors) == [0, 1, 2]
    for a in q.actors:
        np.testing.assert_array_equal(q.q_n[a], qa.q_n[a])
    # the own tree's q_r is what the single-tree retriever computes (same numbers)
    q1 = MotionRetriever(db, seed=0, across_trees=False).prepare(pose, ch)
    a1 = int(db.actor[1])
    np.testing.assert_array_equal(q.q_n[a1], q1.q_n[a1])


def test_across_trees_serves_clips_of_every_tree(mixed, across):
    db, _ = mixed
    pose = frame_of(db.motion(1), 0)
    ch = Skeleton.from_motion(pose)  # Mixamo character
    q = across.prepare(pose, ch)
    assert sorted(q.actors) == [0, 1, 2]
    served = set()
    for i in (0, 2, 3, 5):  # targets at hit points of synthetic and MotionBuilder clips
        c = db.hit_position[i] * ch.size / db.size_a[i]
        res = across.search(c, q, None, str(db.semantics[i]), method="exhaustive")
        assert res.d_cr < 0.05
        served.add(tree_of(db, res.clip) if int(db.actor[res.clip]) != int(db.actor[1]) else "own")
    assert served - {"own"}  # a clip of another tree was chosen
    with pytest.raises(RetrievalError, match="True or False"):
        MotionRetriever(db, across_trees="yes")


@pytest.mark.parametrize("across_trees", [True, False])
def test_exact_search_on_several_actors(mixed, across, across_trees):
    """The exact search (compiled) is the exhaustive optimum, same numbers, when the
    query has every actor and when it has one (the other actors' clips are not candidates)."""
    from repro.motion.search.retrieval import make_queries

    db, _ = mixed
    r = across if across_trees else MotionRetriever(db, seed=0, across_trees=False)
    seen = set()
    for c, pose, ch, sem in make_queries(db, 40, seed=4):
        q = r.prepare(pose, ch)
        assert len(q.actors) == (3 if across_trees else 1)
        a = r.search(c, q, None, sem, method="exact")
        b = r.search(c, q, None, sem, method="exhaustive")
        assert (a.pose, a.d, a.d_qr, a.d_cr) == (b.pose, b.d, b.d_qr, b.d_cr)
        assert int(db.actor[a.clip]) in q.actors
        seen.add(int(db.actor[a.clip]))
    assert len(seen) > 1


def test_across_trees_caches_the_actor_rest_poses(mixed, monkeypatch):
    db, _ = mixed
    r = MotionRetriever(db, seed=0, across_trees=True)
    calls = []
    real = query_mod.rest_motion_y_up
    monkeypatch.setattr(query_mod, "rest_motion_y_up", lambda sk: calls.append(sk) or real(sk))
    pose = frame_of(db.motion(1), 0)
    ch = Skeleton.from_motion(pose)
    for f in range(3):
        r.prepare(frame_of(db.motion(1), f), ch)
    assert len(calls) == 2  # the two other trees, once each
    # and q_r on each actor is what retargeting the pose to it gives
    q = r.prepare(pose, ch)
    a0 = db.actors[0]
    g = dispatch.retarget_to_tree(pose, a0).global_positions()
    from repro.motion.body.pose_frames import pose_points

    pts = pose_points(g, [a0.index(x) for x in db.pose_roles], a0.index("pelvis"), a0.index("left_hip"),
                      a0.index("right_hip"))[-1] / a0.size
    np.testing.assert_allclose(q.q_n[0], pts, atol=1e-12)


def test_a_strike_on_a_character_of_another_tree(synthetic_db, rigs):
    db = synthetic_db
    r = MotionRetriever(db, seed=0, across_trees=True)
    ch_m = rigs["mixamo"]
    ch = Skeleton.from_motion(ch_m)
    stance = dispatch.retarget_to_tree(frame_of(db.motion(0), 0), ch)
    i = int(np.flatnonzero(db.semantics == "punch")[0])
    c = db.hit_position[i] * ch.size / db.size_a[i]
    s = strike(r, ch, stance, c, "punch", frame="root")
    assert s.motion.joint_names == ch.joint_names
    assert s.reached and s.hit_error < 0.01
    with pytest.raises(RetrievalError, match="joint tree"):  # the single-tree retriever refuses it
        strike(MotionRetriever(db.select(np.arange(6)), seed=0, across_trees=False), ch, stance, c, "punch",
               frame="root")


# ------------------------------------------------------------------ the fighter
def test_fighter_accepts_a_humanoid_of_another_tree(synthetic_db, rigs):
    f = KungFuFighter(synthetic_db, character=rigs["mixamo"], seed=0)
    assert f.retriever.across_trees
    assert f.stance.joint_names == rigs["mixamo"].joint_names
    head = (0.0, 0.85 * f.character.size, 0.0)
    f.follow(head, 0.0, snap=True)
    for kind, target in (("punch", head), ("kick", (0.0, 0.55 * f.character.size, 0.0))):
        s = f.order(kind, target)
        assert s.motion.joint_names == rigs["mixamo"].joint_names
        assert s.reached and s.hit_error < 0.01, (kind, s.hit_error)
    f.set_character(rigs["motionbuilder"])  # and another tree again
    assert "Chest3" in f.stance.joint_names


def _without(m, drop_under: tuple[str, ...]):
    """The skeleton of ``m`` without the subtrees rooted at ``drop_under``."""
    sk = Skeleton.from_motion(m)
    par = sk.parents
    gone = np.zeros(sk.n_joints, dtype=bool)
    for j in range(sk.n_joints):
        gone[j] = sk.joint_names[j] in drop_under or (par[j] >= 0 and gone[par[j]])
    keep = np.flatnonzero(~gone)
    new = {int(o): n for n, o in enumerate(keep)}
    esp = [n for n, p in enumerate(sk.end_site_parents) if not gone[p]]
    return dataclasses.replace(
        m, joint_names=[sk.joint_names[j] for j in keep],
        parents=np.array([-1 if par[j] < 0 else new[int(par[j])] for j in keep]), offsets=sk.offsets[keep],
        channels=[m.channels[j] for j in keep], rotations=m.rotations[:, keep], positions=m.positions[:, keep],
        end_site_parents=np.array([new[int(sk.end_site_parents[e])] for e in esp], dtype=np.intp),
        end_site_offsets=sk.end_site_offsets[esp].reshape(-1, 3))


def test_bad_characters_are_refused_naming_what_is_missing(synthetic_db, rigs):
    f = KungFuFighter(synthetic_db, character=rigs["mixamo"], seed=0)
    legs_only = _without(rigs["mixamo"], ("mixamorig:LeftShoulder", "mixamorig:RightShoulder"))
    with pytest.raises(MotionError, match="a punch needs .*an arm"):
        f.set_character(legs_only)
    no_legs = _without(rigs["mixamo"], ("mixamorig:LeftUpLeg", "mixamorig:RightUpLeg"))
    with pytest.raises(MotionError, match="a kick needs .*a leg"):
        f.set_character(no_legs)
    with pytest.raises(MotionError, match="a punch needs .*an arm"):
        strike(f.retriever, legs_only, legs_only, np.array([0.0, 1.5, 0.5]), "punch")
    assert f.character.joint_names == rigs["mixamo"].joint_names  # unchanged by the refusals
    with pytest.warns(UnitWarning, match="up axis Z"):
        f.set_character(rigs["unreal"])  # a Z-up character is turned to the fighter's Y-up world (no longer refused)
    assert f.character.joint_names == rigs["unreal"].joint_names
    assert f.stance.global_positions()[0, f.character.index("head"), 1] > 1.0
    single = KungFuFighter(synthetic_db, retriever=MotionRetriever(synthetic_db, seed=0, across_trees=False), seed=0)
    with pytest.raises(MotionError, match="across_trees"):
        single.set_character(rigs["mixamo"])


# ------------------------------------------------------------------ real data
@pytest.mark.data("cmu-bvh", "bandai")
def test_cmu_character_gets_a_bandai_clip():
    from repro.motion.database.sources import build_real_database, clip_source_dataset

    db = build_real_database()
    src = clip_source_dataset(db)
    r = MotionRetriever(db, seed=0, across_trees=True)
    cmu_i = int(np.flatnonzero(src == "cmu135")[0])
    pose = frame_of(db.motion(cmu_i), 0)
    ch = db.actors[int(db.actor[cmu_i])]
    q = r.prepare(pose, ch)
    assert sorted(q.actors) == [0, 1]
    j = int(np.flatnonzero((db.semantics == "punch") & (src == "bandai"))[0])
    c = db.hit_position[j] * ch.size / db.size_a[j]  # a Bandai clip's hit point, Eq. 1
    res = r.search(c, q, None, "punch", method="exhaustive")
    assert src[res.clip] == "bandai" and res.d_cr < 1e-9
    s = strike(r, ch, pose, c, "punch", frame="root", query=q)
    assert src[s.retrieval.clip] == "bandai"
    assert s.motion.joint_names == ch.joint_names and s.reached and s.hit_error < 0.01
    # the single-tree retriever still keeps the CMU character to CMU clips; the default one does not
    assert MotionRetriever(db, seed=0, across_trees=False).prepare(pose, ch).actors == (0,)
    assert sorted(MotionRetriever(db, seed=0).prepare(pose, ch).actors) == [0, 1]
    # and the fighter takes the Bandai skeleton as its character, served a CMU clip
    f = KungFuFighter(db, character=db.actors[1], retriever=r)
    head = (0.0, 0.85 * f.character.size, 0.0)
    f.follow(head, 0.0, snap=True)
    s = f.punch(head)
    assert s.motion.joint_names == db.actors[1].joint_names and s.reached


def test_a_partial_character_at_construction_is_refused_for_what_it_lacks(synthetic_db, rigs):
    arms_only = _without(rigs["mixamo"], ("mixamorig:LeftUpLeg", "mixamorig:RightUpLeg"))
    with pytest.raises(MotionError, match="a kick needs"):
        KungFuFighter(synthetic_db, character=arms_only, seed=0)
