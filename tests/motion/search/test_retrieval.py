"""Motion retrieval (repro.motion.search.retrieval), Pronost et al. Section 3.3.

What is asserted:

* with pruning disabled the search returns the exhaustive optimum, and the exhaustive
  search equals an independent brute-force evaluation of ``d = w_q d_qr + w_c d_cr``
  (plain :func:`aligned_distance`, a loop over clips);
* the pruned search obeys the paper: the selected pose is in the selected cluster
  (nearest centroid, or the next ones when flagged), its clip's box contains ``c_r``,
  it is the best such pose, and it is never better than the exhaustive optimum;
* on the synthetic database a target inside a clip's box (its hit point) retrieves a
  clip of the requested semantics whose hit trajectory passes within a few centimetres;
* Eq. 1 matters: a 1 m character aiming at a target at its own face height retrieves a
  *high* punch, whereas without the rescaling a low punch would be chosen; ``c_r`` is
  ``rescale_constraint(c, size_a, size_c)``;
* the alignment puts the selected start pose onto the current pose, wherever the
  character stands and whichever way it faces;
* bad input raises RetrievalError / MotionError with clear messages;
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import MotionError, RetrievalError
from repro.motion.body.pose_frames import rotate_y
from repro.motion.search.distance import aligned_distance
from repro.motion.database.clips import MotionDatabase
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.retrieval import MotionRetriever, Query, search
from repro.motion.body.skeleton import Skeleton, rescale_constraint, scale_skeleton


def frame_of(m, f):
    return dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])


def queries(db, n, seed=0):
    """(target, pose, character, semantics): a pose of one clip, a target near another's hit."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        i = int(rng.integers(db.n_clips))
        m = db.motion(i)
        pose = frame_of(m, int(rng.integers(m.n_frames)))
        j = int(rng.integers(db.n_clips))
        c = db.hit_position[j] * (db.size_a[i] / db.size_a[j]) + rng.normal(0, 0.03, 3)
        out.append((c, pose, db.actor_skeleton(i), str(db.semantics[j])))
    return out


def brute_force(db, c, pose, character, semantics, w_q=1.0, w_c=1.0):
    """Independent evaluation of d over every startable pose of the semantics."""
    sk = db.actors[0]
    qr = retarget(pose, sk)
    g = qr.global_positions()
    from repro.motion.body.pose_frames import pose_points

    q = pose_points(g, [sk.index(r) for r in db.pose_roles], sk.index("pelvis"), sk.index("left_hip"),
                    sk.index("right_hip"))[-1] / sk.size
    size_c = Skeleton.from_motion(pose).size if character is None else character.size
    best = (np.inf, None)
    for i in range(db.n_clips):
        if db.semantics[i] != semantics:
            continue
        c_r = c * db.size_a[i] / size_c
        d_cr = np.min(np.linalg.norm(db.trajectory(i) - c_r, axis=1))
        for p in db.poses_of(i):
            if db.pose_frame[p] >= db.hit_frame[i]:
                continue
            d_qr = db.size_a[i] * aligned_distance(q, db.pose_points[p])
            d = w_q * d_qr + w_c * d_cr
            if d < best[0]:
                best = (d, p)
    return best


def test_unpruned_search_is_the_exhaustive_optimum(db, retriever):
    for c, pose, ch, sem in queries(db, 25, seed=1):
        q = retriever.prepare(pose, ch)
        a = retriever.search(c, q, semantics=sem, prune=False)
        b = retriever.search_exhaustive(c, q, semantics=sem)
        assert (a.clip, a.start_frame, a.pose) == (b.clip, b.start_frame, b.pose)
        assert a.d == b.d and a.fallback == "disabled"
        assert a.semantics == sem


def test_exhaustive_equals_brute_force(db, retriever):
    for c, pose, ch, sem in queries(db, 4, seed=2):
        r = retriever.search_exhaustive(c, pose, ch, sem)
        d, p = brute_force(db, c, pose, ch, sem)
        assert r.d == pytest.approx(d, rel=1e-6, abs=1e-7)
        assert r.d == pytest.approx(r.w_q * r.d_qr + r.w_c * r.d_cr, rel=1e-12)
        assert r.pose == p or r.d == pytest.approx(d, abs=1e-9)


def test_pruned_search_follows_the_paper(db, retriever):
    n_none = 0
    for c, pose, ch, sem in queries(db, 40, seed=3):
        q = retriever.prepare(pose, ch)
        r = retriever.search(c, q, semantics=sem)
        ex = retriever.search_exhaustive(c, q, semantics=sem)
        assert r.semantics == sem
        assert r.d >= ex.d - 1e-12  # never better than the optimum
        assert r.start_frame < r.hit_frame
        c_r = rescale_constraint(c, r.size_a, r.size_c)
        np.testing.assert_allclose(r.c_r, c_r, rtol=1e-12)
        # d_cr is the distance from the trajectory to c_r
        assert r.d_cr == pytest.approx(np.min(np.linalg.norm(db.trajectory(r.clip) - c_r, axis=1)), rel=1e-9)
        if r.fallback in ("none", "neighbour_clusters"):
            n_none += r.fallback == "none"
            assert np.all(db.box_min[r.clip] <= c_r) and np.all(c_r <= db.box_max[r.clip])
            cl = retriever.clusters
            assert cl.labels[r.pose] == r.cluster
            dc = retriever.centroid_index.distances(next(iter(q.q_n.values())))
            assert np.argsort(dc, kind="stable")[r.cluster_rank] == r.cluster
            # best pose among the cluster's candidates whose box contains c_r
            members = cl.members[r.cluster]
            ok = [p for p in members if db.semantics[db.pose_clip[p]] == sem
                  and db.pose_frame[p] < db.hit_frame[db.pose_clip[p]]
                  and np.all(db.box_min[db.pose_clip[p]] <= rescale_constraint(c, db.size_a[db.pose_clip[p]], r.size_c))
                  and np.all(rescale_constraint(c, db.size_a[db.pose_clip[p]], r.size_c) <= db.box_max[db.pose_clip[p]])]
            assert r.n_candidates == len(ok)
        else:
            assert r.fallback == "no_box"
            assert r.d == pytest.approx(ex.d, rel=1e-12)  # all poses of the semantics are scored
    assert n_none > 5


@pytest.mark.parametrize("semantics", ["punch", "kick"])
def test_target_in_a_box_retrieves_a_clip_passing_near_it(db, retriever, semantics):
    rng = np.random.default_rng(5)
    clips = np.flatnonzero(db.semantics == semantics)
    for j in rng.choice(clips, 8, replace=False):
        actor = db.actor_skeleton(j)
        m = db.motion(int(rng.choice(clips)))
        pose = frame_of(retarget(m, actor), 0)  # a fighting stance of this clip's actor
        # the hit point of clip j, nudged inside its box (the hit point is usually on the
        # box's boundary: it is the farthest reach)
        c = 0.999 * db.hit_position[j] + 0.001 * (db.box_min[j] + db.box_max[j]) / 2
        r = retriever.search(c, pose, actor, semantics)
        assert r.semantics == semantics
        assert r.fallback in ("none", "neighbour_clusters")
        assert np.all(db.box_min[r.clip] <= r.c_r) and np.all(r.c_r <= db.box_max[r.clip])
        assert r.d_cr < 0.08, (db.names[j], r.name, r.d_cr)


def test_eq1_changes_the_choice_for_a_small_character(db, retriever):
    """A 1 m fighter punching at its own face height needs a high punch of the 1.75 m actor."""
    j = next(i for i in range(db.n_clips) if db.names[i] == "actor2_punch_right_high")
    actor = db.actor_skeleton(j)
    assert actor.size == pytest.approx(1.75)
    small = scale_skeleton(actor, height=1.0)
    stance = frame_of(retarget(db.motion(j), small), 0)
    c = db.hit_position[j] * small.size / actor.size  # face height of the small fighter, at its reach
    with_eq1 = retriever.search(c, stance, small, "punch")
    without = retriever.search(c, stance, small, "punch", scale_target=False)
    assert db.levels[with_eq1.clip] == "high"
    assert with_eq1.d_cr < 0.05
    assert db.levels[without.clip] != "high"
    assert with_eq1.clip != without.clip
    # the unscaled target lies far below the high punch's trajectory
    assert np.min(np.linalg.norm(db.trajectory(with_eq1.clip) - c, axis=1)) > 0.3


@pytest.mark.parametrize("theta, shift", [(0.0, (0.0, 0.0)), (2.1, (3.0, -1.5)), (-0.8, (-4.0, 2.0))])
def test_alignment_places_the_start_pose_on_the_current_pose(db, retriever, theta, shift):
    i = 20
    m = db.motion(i)
    f = 5
    # the current pose: clip i's frame f, turned by theta and moved on the floor
    pose = frame_of(m, f)
    pos = np.array(pose.positions)
    pos[:, 0] = rotate_y(pos[:, 0], theta) + [shift[0], 0.0, shift[1]]
    qroot = np.array(pose.rotations)
    qy = np.array([0.0, np.sin(theta / 2), 0.0, np.cos(theta / 2)])
    from repro.motion.core.quaternion import quat_multiply

    qroot[:, 0] = quat_multiply(qy, qroot[:, 0])
    pose = dataclasses.replace(pose, positions=pos, rotations=qroot)
    actor = db.actor_skeleton(i)
    r = MotionRetriever(db, w_c=1e-9).search(db.hit_position[i], pose, actor, str(db.semantics[i]), prune=False)
    assert r.d_qr < 1e-6  # the same pose (or an identical one) is found
    start = db.motion(r.clip).global_positions()[r.start_frame]
    placed = r.place(start)
    np.testing.assert_allclose(placed, pose.global_positions()[0], atol=1e-5)


def test_search_accepts_query_and_module_function(db, retriever):
    c, pose, ch, sem = queries(db, 1, seed=9)[0]
    q = retriever.prepare(pose, ch)
    assert isinstance(q, Query)
    a = retriever.search(c, q, semantics=sem)
    b = search(db, c, pose, ch, sem)
    assert (a.clip, a.start_frame) == (b.clip, b.start_frame)
    k = retriever.search_kdtree(c, q, semantics=sem)
    assert k.semantics == sem and k.method == "kdtree"
    assert k.d >= retriever.search_exhaustive(c, q, semantics=sem).d - 1e-12


def test_bad_inputs(db, retriever):
    c, pose, ch, sem = queries(db, 1, seed=9)[0]
    with pytest.raises(RetrievalError, match="NaN"):
        retriever.search([0.0, np.nan, 0.5], pose, ch, "punch")
    with pytest.raises(RetrievalError, match="3-vector"):
        retriever.search([0.0, 1.0], pose, ch, "punch")
    with pytest.raises(RetrievalError, match="unknown semantics"):
        retriever.search(c, pose, ch, "headbutt")
    with pytest.raises(RetrievalError, match="no 'kick'"):
        MotionRetriever(db.select(db.semantics == "punch")).search(c, pose, ch, "kick")
    with pytest.raises(RetrievalError, match="MotionDatabase"):
        MotionRetriever(None)
    with pytest.raises(MotionError):  # an empty database cannot even be built
        MotionDatabase.from_clips([])
    with pytest.raises(RetrievalError, match="Motion"):
        retriever.search(c, np.zeros((21, 3)), ch, "punch")
    # a character with another joint tree cannot be retargeted to the actor
    renamed = [{"Spine1": "Chest"}.get(n, n) for n in pose.joint_names]
    odd_pose = dataclasses.replace(pose, joint_names=renamed)
    with pytest.raises(RetrievalError, match="joint tree"):
        MotionRetriever(db, seed=0, across_trees=False).search(c, odd_pose, Skeleton.from_motion(odd_pose), "punch")
    with pytest.raises(RetrievalError, match="not on the character"):
        retriever.search(c, odd_pose, ch, "punch")
    with pytest.raises(RetrievalError):
        MotionRetriever(db, w_q=-1.0)


@pytest.mark.data("cmu-bvh")
def test_cmu_retrieval_kick_and_punch(tmp_path):
    from repro.motion.database.sources import build_cmu_database

    db = build_cmu_database()
    p = db.save(tmp_path / "cmu.npz")
    db = MotionDatabase.load(p)
    r = MotionRetriever(db)
    actor = db.actors[0]
    stance = frame_of(db.motion(0), 0)
    for sem in ("kick", "punch"):
        j = int(np.flatnonzero(db.semantics == sem)[0])
        res = r.search(db.hit_position[j], stance, actor, sem)
        assert res.semantics == sem
        assert res.d_cr < 0.1
        # a smaller character's equivalent target gives the same choice (Eq. 1 is exact here)
        small = scale_skeleton(actor, height=1.3)
        pose = retarget(stance, small)
        res2 = r.search(db.hit_position[j] * small.size / actor.size, pose, small, sem)
        assert res2.clip == res.clip and res2.start_frame == res.start_frame
