"""Exact retrieval (branch and bound) (repro.motion.search.exact).

What is asserted:

* Kovar et al.'s aligned distance obeys the triangle inequality (random triples of real
  poses of the synthetic database and of random clouds, uniform and non-uniform
  weights): the bounds the exact search prunes with hold (the radii: test_index.py);
* ``method="exact"`` returns the exhaustive optimum (same pose, same ``d``) on hundreds
  of seeded queries, on the 72-clip database and on an augmented
  one, while scoring fewer poses than the exhaustive scan (counted, not timed);
* ties go to the lowest pose index in both searches (a database holding a clip twice);
* the paper's ``d_cr`` is the first-frame trajectory's distance to ``c_r``, whole clip;
* bad ``method`` values are refused, naming the value;
* the exact search returns the exhaustive optimum with the very same ``d``, ``d_qr``, ``d_cr``
  (both re-score the near-best candidates one by one);
* a database without clips of a semantics is refused by every method, naming the semantics;
* ``stats`` is anything but a dict (or None): refused before the search.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import RetrievalError
from repro.motion.database.augment import augment
from repro.motion.body.pose_frames import rotate_y
from repro.motion.search.distance import aligned_distance
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.retrieval import MotionRetriever, make_queries


@pytest.fixture(scope="module")
def prepared(db, retriever):
    return [(c, retriever.prepare(pose, ch), sem) for c, pose, ch, sem in make_queries(db, 300, seed=7)]


@pytest.mark.parametrize("weighted", [False, True])
def test_triangle_inequality_of_the_aligned_distance(db, weighted):
    rng = np.random.default_rng(0)
    P = db.pose_points.shape[1]
    w = rng.uniform(0.0, 3.0, P) if weighted else None
    real = db.pose_points[rng.integers(0, db.n_poses, (2000, 3))]  # real poses (canonical frames)
    # random clouds, each turned and moved on the floor at random (the distance must not care)
    synth = rng.normal(0, 0.5, (2000, 3, P, 3))
    synth[:1000, 1] = 0.5 * (synth[:1000, 0] + synth[:1000, 2])  # half the triples nearly "collinear"
    synth = rotate_y(synth, rng.uniform(-np.pi, np.pi, (2000, 3, 1))) + np.array([1.0, 0.0, 1.0]) * rng.normal(
        0, 2.0, (2000, 3, 1, 3))
    for t in (real, synth):
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ac = aligned_distance(a, b, w), aligned_distance(b, c, w), aligned_distance(a, c, w)
        assert np.all(ac <= ab + bc + 1e-9)
        assert np.all(np.abs(ab - aligned_distance(b, a, w)) <= 1e-9)
        # not vacuous: some triples are close to equality
        assert np.min(ab + bc - ac) < 0.05 * np.median(ac)


def test_exact_is_the_exhaustive_optimum(db, retriever, prepared):
    scored, total = 0, 0
    for c, q, sem in prepared:
        st = {}
        a = retriever.search(c, q, semantics=sem, method="exact")
        b = retriever.search_exhaustive(c, q, semantics=sem)
        e = retriever.search_exact(c, q, semantics=sem, stats=st)
        assert (a.pose, a.clip, a.start_frame) == (b.pose, b.clip, b.start_frame) == (e.pose, e.clip, e.start_frame)
        assert a.d == pytest.approx(b.d, rel=1e-12, abs=1e-15)
        assert a.method == "exact" and b.method == "exhaustive"
        scored += st["poses_scored"]
        total += retriever.sem_rows[sem].size
    assert scored < 0.6 * total  # the bounds prune (a count, not a time)


def test_exact_on_an_augmented_database(db):
    big = augment(db, 3, seed=1)
    r = MotionRetriever(big, seed=0, k=40)
    scored = total = 0
    for c, pose, ch, sem in make_queries(big, 150, seed=3):
        q = r.prepare(pose, ch)
        st = {}
        a = r.search_exact(c, q, semantics=sem, stats=st)
        b = r.search_exhaustive(c, q, semantics=sem)
        assert a.pose == b.pose and a.d == pytest.approx(b.d, rel=1e-12, abs=1e-15)
        scored += st["poses_scored"]
        total += r.sem_rows[sem].size
    assert scored < 0.3 * total


def test_ties_go_to_the_lowest_pose(db):
    i = int(np.flatnonzero(db.semantics == "punch")[0])
    clip = db.clip(i)
    twice = MotionDatabase.from_clips([clip, dataclasses.replace(clip, name=clip.name + "_copy")])
    assert twice.n_clips == 2
    r = MotionRetriever(twice, seed=0, k=2)
    m = twice.motion(0)
    for f in (0, 3, 6):
        pose = dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])
        c = twice.hit_position[0] + np.array([0.05, -0.02, 0.03])
        a = r.search(c, pose, twice.actor_skeleton(0), "punch", method="exact")
        b = r.search(c, pose, twice.actor_skeleton(0), "punch", method="exhaustive")
        assert a.pose == b.pose and a.clip == 0  # the first copy


def test_paper_d_cr_is_the_first_frame_trajectory(db, retriever, prepared):
    for c, q, sem in prepared[:60]:
        # the paper's scoring: the first-frame trajectory, whole clip
        p = retriever.search(c, q, semantics=sem)
        assert p.d_cr == pytest.approx(np.min(np.linalg.norm(db.trajectory(p.clip) - p.c_r, axis=1)), rel=1e-9)


@pytest.mark.parametrize("kw", [{"method": "fast"}, {"method": 1}])
def test_bad_method(retriever, prepared, kw):
    c, q, sem = prepared[0]
    with pytest.raises(RetrievalError, match="method"):
        retriever.search(c, q, semantics=sem, **kw)


def test_exact_without_eq1(retriever, prepared):
    c, q, sem = prepared[0]
    # exact without Eq. 1 is still the exhaustive optimum
    a = retriever.search(c, q, semantics=sem, method="exact", scale_target=False)
    b = retriever.search_exhaustive(c, q, semantics=sem, scale_target=False)
    assert a.pose == b.pose


@pytest.mark.data("cmu-bvh")
def test_cmu_triangle_inequality_and_exact_search():
    from repro.motion.database.sources import build_cmu_database

    cmu = build_cmu_database()
    rng = np.random.default_rng(1)
    t = cmu.pose_points[rng.integers(0, cmu.n_poses, (3000, 3))]
    ab, bc = aligned_distance(t[:, 0], t[:, 1]), aligned_distance(t[:, 1], t[:, 2])
    assert np.all(aligned_distance(t[:, 0], t[:, 2]) <= ab + bc + 1e-9)
    r = MotionRetriever(cmu, seed=0)
    for c, pose, ch, sem in make_queries(cmu, 200, seed=5):
        q = r.prepare(pose, ch)
        a = r.search(c, q, semantics=sem, method="exact")
        b = r.search_exhaustive(c, q, semantics=sem)
        assert a.pose == b.pose and a.d == pytest.approx(b.d, rel=1e-12, abs=1e-15)


def test_exact_and_exhaustive_report_identical_numbers(db, retriever, prepared):
    """Exact and exhaustive report the very same numbers."""
    for c, q, sem in prepared[:80]:
        b = retriever.search_exhaustive(c, q, semantics=sem)
        a = retriever.search_exact(c, q, semantics=sem)
        assert (a.pose, a.d, a.d_qr, a.d_cr) == (b.pose, b.d, b.d_qr, b.d_cr)


def test_exact_on_a_database_without_the_semantics(db):
    punches = MotionDatabase.from_clips([db.clip(int(i)) for i in np.flatnonzero(db.semantics == "punch")[:4]])
    r = MotionRetriever(punches, seed=0, k=3)
    c, pose, ch, _ = make_queries(punches, 1, seed=0)[0]
    for method in ("exact", "exhaustive", "pruned", "kdtree"):
        with pytest.raises(RetrievalError, match="'kick'"):
            r.search(c, pose, ch, "kick", method=method)


@pytest.mark.parametrize("stats", ["x", 1, [], (), np.zeros(2)], ids=repr)
def test_search_exact_stats(synthetic_db, stats):
    """``stats`` is filled after the search: anything but a dict (or None) was an AttributeError then."""
    from repro.motion.runtime.strike import one_frame

    small = synthetic_db.select(np.arange(3))
    r = MotionRetriever(small, seed=0)
    with pytest.raises(RetrievalError, match="^stats must be a dict"):
        r.search_exact([0.3, 1.4, 0.5], one_frame(small.motion(0), 0), small.actor_skeleton(0), "punch", stats=stats)
