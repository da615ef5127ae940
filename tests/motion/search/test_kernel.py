"""The compiled branch and bound of the exact search (repro.motion.search.kernel).

What is asserted:

* its stable argsort gives numpy's stable order (random keys with ties and infinities);
* the exact search (compiled) returns the exhaustive optimum with the
  very same numbers with one seed, or as many seeds as clip runs or more (several actors, some
  of them not the query's: tests/motion/database/test_clips_mixed_trees.py);
* :func:`compile_search` compiles the very specialisation a real search calls (one signature
  after both), so that the fighter's set-up leaves nothing to compile at its first order;
* the nearest trajectory samples from the grid (:func:`sample_grid`, ``_nearest_samples``) are those
  of a brute-force sort, by increasing distance, for targets inside, at the edge of and far
  outside the samples, flat clouds, fewer samples than asked for, one sample and none;
* a clip run's bound, its float32 centroid's distance (``_cloud_distance``, the aligned distance
  to within rounding) minus its radius, is below the distance of each of its poses;
* :meth:`AlignedPoseIndex.terms` gives the stored terms of every candidate (they reproduce
  :meth:`~AlignedPoseIndex.distances`), and refuses an index stored in another order.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance
from repro.motion.search.retrieval import make_queries
from repro.motion.search.exact import sample_grid
from repro.motion.search.kernel import _argsort, _cloud_distance, _nearest_samples, compile_search, search_first


def test_argsort_is_numpys_stable_order():
    rng = np.random.default_rng(0)
    for n in (0, 1, 2, 3, 7, 64, 1000):
        keys = rng.integers(0, max(n // 3, 1), n).astype(float)  # many ties
        keys[rng.random(n) < 0.1] = np.inf
        assert np.array_equal(_argsort(keys), np.argsort(keys, kind="stable"))


@pytest.mark.parametrize("shape", ["cloud", "flat", "line", "few", "one", "none"])
def test_nearest_samples_are_a_brute_force_sort(shape):
    rng = np.random.default_rng(len(shape))
    n = {"few": 5, "one": 1, "none": 0, "line": 20000}.get(shape, 3000)
    pts = rng.normal(size=(n, 3)) * [1.0, 0.3, 2.0]
    if shape == "flat":
        pts[:, 1] = 0.25
    if shape == "line":
        pts[:, 1:] = 0.0
    label = rng.integers(0, 40, n)
    grid = sample_grid(pts)
    targets = [np.zeros(3), np.array([40.0, -3.0, 9.0]), np.array([1e5, 1e5, -1e5]), *rng.normal(size=(20, 3)) * 2.0]
    if n:
        targets += [pts[0], pts.max(axis=0), pts.min(axis=0) - 0.01]
    for c in targets:
        got_label, got_d = _nearest_samples(c, 64, *grid, pts, label)
        ref = np.sqrt(((pts - c) ** 2).sum(axis=1))
        o = np.argsort(ref, kind="stable")[:64]
        np.testing.assert_allclose(got_d, ref[o], rtol=1e-12, atol=0)
        assert np.array_equal(np.sort(got_label), np.sort(label[o]))


def test_clip_run_bound_is_below_each_of_its_poses(db, retriever):
    r = retriever
    rng = np.random.default_rng(4)
    for c, pose, ch, sem in make_queries(db, 8, seed=7):
        ex = r.exact.arrays[sem]
        q = r.prepare(pose, ch)
        (qn,) = q.q_n.values()
        qs = np.array(r.index.query_matrix(qn)[1:])
        multi = np.flatnonzero(ex["gci"] >= 0)
        assert np.array_equal(multi, np.flatnonzero(ex["glen"] > 1))
        for g in rng.choice(multi, 40, replace=False):
            j = ex["gci"][g]
            dg = _cloud_distance(ex["gcent"], j, np.ascontiguousarray(qn.T), qs, r.weights)
            ref = float(aligned_distance(qn, ex["gcent"][j].astype(float), r.weights))
            assert dg == pytest.approx(ref, rel=1e-9, abs=1e-7)
            rows = ex["rows"][ex["gstart"][g]:ex["gstart"][g + 1]]
            d_poses = aligned_distance(qn[None], db.pose_points[rows].astype(float), r.weights)
            assert np.all(dg - ex["gradius"][g] - 1e-6 <= d_poses)


def test_exact_with_more_seeds_than_clip_runs(db, retriever):
    r = retriever
    for c, pose, ch, sem in make_queries(db, 30, seed=5):
        q = r.prepare(pose, ch)
        G = r.exact.arrays[sem]["gsize"].size
        for batch in (1, G, G + 5):
            got = r.exact.search(q, sem, r.targets.c_r(c, q.size_c, True), c / q.size_c, batch=batch)
            ref = r.search_exhaustive(c, q, semantics=sem)
            assert (got.pose, got.d) == (ref.pose, ref.d)


def test_compile_search_compiles_what_a_search_calls(db, retriever):
    compile_search()
    c, pose, ch, sem = make_queries(db, 1, seed=2)[0]
    retriever.search_exact(c, retriever.prepare(pose, ch), semantics=sem)
    assert len(search_first.signatures) == 1


def test_index_terms(db):
    rng = np.random.default_rng(1)
    pts = db.pose_points[:300].astype(float)
    q = pts[7] + rng.normal(0, 0.01, pts[7].shape)
    full = AlignedPoseIndex(pts)
    rows = rng.permutation(300)[:50]
    for index, cand in ((full, np.arange(300)), (full.subset(rows), rows)):
        M, X, Z, H, Y2, perm = index.terms()
        Q, Xa, Za, Ha, Ya2 = index.query_matrix(q)
        R = M[perm] @ Q
        A = R[:, 0] - (Xa * X[perm] + Za * Z[perm])
        B = R[:, 1] - (Xa * Z[perm] - Za * X[perm])
        d = np.sqrt(np.maximum(Ya2 - 2 * R[:, 2] + Y2[perm] + Ha + H[perm] - 2 * np.hypot(A, B), 0))
        np.testing.assert_allclose(d, full.distances(q, cand), rtol=1e-12, atol=1e-12)
    ordered = AlignedPoseIndex(pts, order=np.arange(300)[::-1])
    with pytest.raises(MotionError, match="candidate order"):
        ordered.terms()
    sub = ordered.subset(np.arange(300)[::-1][10:40])  # a run of the stored order: a view, readable
    assert sub.terms()[0].shape == (30, 3 * pts.shape[1])
