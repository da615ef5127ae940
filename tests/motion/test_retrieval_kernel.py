"""The compiled branch and bound of the exact search (repro.motion.retrieval_kernel).

What is asserted:

* its stable argsort gives numpy's stable order (random keys with ties and infinities);
* the exact search (compiled for ``scoring="first"``) returns the exhaustive optimum with the
  very same numbers with one seed, or as many seeds as clip runs or more (several actors, some
  of them not the query's: tests/motion/test_mixed_database.py);
* :func:`compile_search` compiles the very specialisation a real search calls (one signature
  after both), so that the fighter's set-up leaves nothing to compile at its first order;
* :meth:`AlignedPoseIndex.terms` gives the stored terms of every candidate (they reproduce
  :meth:`~AlignedPoseIndex.distances`), and refuses an index stored in another order.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.clustering import AlignedPoseIndex
from repro.motion.retrieval import MotionRetriever, make_queries
from repro.motion.retrieval_kernel import _argsort, compile_search, search_first


@pytest.fixture(scope="module")
def db(synthetic_db):
    return synthetic_db


@pytest.fixture(scope="module")
def retriever(db):
    return MotionRetriever(db, seed=0)


def test_argsort_is_numpys_stable_order():
    rng = np.random.default_rng(0)
    for n in (0, 1, 2, 3, 7, 64, 1000):
        keys = rng.integers(0, max(n // 3, 1), n).astype(float)  # many ties
        keys[rng.random(n) < 0.1] = np.inf
        assert np.array_equal(_argsort(keys), np.argsort(keys, kind="stable"))


def test_exact_with_more_seeds_than_clip_runs(db, retriever):
    r = retriever
    for c, pose, ch, sem in make_queries(db, 30, seed=5):
        q = r.prepare(pose, ch)
        G = r._ex[sem]["gsize"].size
        for batch in (1, G, G + 5):
            got = r._search_exact(c, q, sem, "first", True, batch=batch)
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
