"""Every public argument of the retrieval is checked (repro.motion.search.arguments; issue 9, item 7).

What is asserted: a table of (call, bad argument) pairs -- targets of 1e300, NaN, the
wrong shape or type; weights that are strings, bools, negative, infinite or both 0;
``k`` of 0, 2.5 or more than the poses; ``kd_neighbours`` of 0; bad seeds, frames,
semantics, flags, prepared queries; a clip's hit role, joint and frame -- each raises a :class:`ReproError` subclass
(RetrievalError or MotionError) and nothing else, quickly (``k = 10**6`` used to be
cut silently to the number of poses and then take about a minute).  Targets up to
:data:`MAX_TARGET_M` are still answered, with finite distances, by the three searches.  (The
k-means and pose-cloud refusals are in test_kmeans.py and test_distance.py.)
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from repro.errors import ReproError, RetrievalError
from repro.motion.search.retrieval import (
    MAX_TARGET_M,
    MotionRetriever,
    Query,
    make_queries,
    search,
)
from tests.helpers import refusal_failures


@pytest.fixture(scope="module")
def db(synthetic_db):
    full = synthetic_db  # the session's synthetic database (tests/conftest.py), this module's copy
    punch = np.flatnonzero(full.semantics == "punch")[:3]
    kick = np.flatnonzero(full.semantics == "kick")[:3]
    return full.select(np.concatenate([punch, kick]))


@pytest.fixture(scope="module")
def r(db):
    return MotionRetriever(db, seed=0)


@pytest.fixture(scope="module")
def query(db):
    m = db.motion(0)
    pose = dataclasses.replace(m, rotations=m.rotations[:1], positions=m.positions[:1])
    return pose, db.actor_skeleton(0)


GOOD_TARGET = [0.1, 1.4, 0.5]


BAD_TARGETS = [[0.0, 1e300, 0.0], [1e7, 0.0, 0.0], [np.nan, 1.0, 0.0], [0.0, np.inf, 0.0], [1, 2], [[1, 2, 3]],
               "abc", None, [1j, 0, 0], ["a", "b", "c"], object(), 5.0]


@pytest.mark.parametrize("method", ["search", "search_exhaustive", "search_kdtree"])
@pytest.mark.parametrize("target", BAD_TARGETS, ids=lambda t: "object()" if type(t) is object else repr(t))  # ids stable across processes
def test_bad_targets(r, query, method, target):
    with pytest.raises(RetrievalError):
        getattr(r, method)(target, *query, "punch")


@pytest.mark.parametrize("method", ["search", "search_exhaustive", "search_kdtree"])
def test_far_but_allowed_targets_are_answered(r, query, method):
    for c in ([0.0, MAX_TARGET_M, 0.0], [-MAX_TARGET_M, 2.0, MAX_TARGET_M]):
        res = getattr(r, method)(c, *query, "kick")
        assert np.isfinite(res.d) and res.d_cr > 0.9 * MAX_TARGET_M
        assert res.semantics == "kick"


CTOR_BAD = [
    dict(k=0), dict(k=-3), dict(k=2.5), dict(k="4"), dict(k=True), dict(k=10**6), dict(k=10**30),
    dict(seed=-1), dict(seed="a"), dict(seed=1.5), dict(seed=None),
    dict(w_q="x"), dict(w_q=None), dict(w_q=-1.0), dict(w_q=np.inf), dict(w_q=np.nan), dict(w_q=True),
    dict(w_q=1j), dict(w_q=[1.0]), dict(w_c=1e308), dict(w_c=-0.5), dict(w_q=0.0, w_c=0.0), dict(w_q=0.0), dict(w_c=0), dict(w_c=-0.0),
    dict(kd_neighbours=0), dict(kd_neighbours=-1), dict(kd_neighbours=2.5), dict(kd_neighbours="8"),
    dict(weights="x"), dict(weights=[1.0, 2.0]), dict(weights=np.full(17, np.nan)), dict(weights=np.zeros(17)),
    dict(weights=-np.ones(17)), dict(weights=np.ones(17) * 1j), dict(weights={"pelvis": 1.0}),
]


@pytest.mark.parametrize("kw", CTOR_BAD, ids=repr)
def test_bad_retriever_arguments(db, kw):
    t = time.perf_counter()
    with pytest.raises(RetrievalError):
        MotionRetriever(db, **kw)
    assert time.perf_counter() - t < 5.0  # refused up front, not after a k-means run


def test_k_range_is_named(db):
    # repro.checks.as_int writes the range 1..N (it was [1, N] before the one set of validators)
    with pytest.raises(RetrievalError, match=rf"1\.\.{db.n_poses}.*1000000"):
        MotionRetriever(db, k=10**6)
    assert MotionRetriever(db, k=db.n_poses // 4).k <= db.n_poses // 4


def test_bad_databases():
    for x in (None, "db.npz", object()):
        with pytest.raises(RetrievalError):
            MotionRetriever(x)
        with pytest.raises(RetrievalError):
            search(x, GOOD_TARGET, None, None, "punch")


def search_calls(r, query):
    pose, ch = query
    q = r.prepare(pose, ch)
    bad_q = [
        Query(q_n={}, size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=()),
        Query(q_n={7: q.q_n[0]}, size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=(7,)),
        Query(q_n={0: q.q_n[0][:5]}, size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=(0,)),
        Query(q_n={0: q.q_n[0] * np.nan}, size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=(0,)),
        Query(q_n={0: "pose"}, size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=(0,)),
        Query(q_n={0: q.q_n[0]}, size_c=-1.0, heading=0.0, origin=np.zeros(3), actors=(0,)),
        Query(q_n={0: q.q_n[0]}, size_c="1", heading=0.0, origin=np.zeros(3), actors=(0,)),
        Query(q_n=[q.q_n[0]], size_c=q.size_c, heading=0.0, origin=np.zeros(3), actors=(0,)),
    ]
    calls = []
    for name in ("search", "search_exhaustive", "search_kdtree"):
        fn = getattr(r, name)
        calls += [
            (f"{name} semantics", lambda fn=fn: fn(GOOD_TARGET, pose, ch, "headbutt")),
            (f"{name} semantics None", lambda fn=fn: fn(GOOD_TARGET, pose, ch, None)),
            (f"{name} semantics array", lambda fn=fn: fn(GOOD_TARGET, pose, ch, np.array(["punch", "kick"]))),
            (f"{name} semantics list", lambda fn=fn: fn(GOOD_TARGET, pose, ch, ["punch"])),
            (f"{name} frame", lambda fn=fn: fn(GOOD_TARGET, pose, ch, "punch", frame=5)),
            (f"{name} frame -1", lambda fn=fn: fn(GOOD_TARGET, pose, ch, "punch", frame=-1)),
            (f"{name} frame 0.5", lambda fn=fn: fn(GOOD_TARGET, pose, ch, "punch", frame=0.5)),
            (f"{name} frame text", lambda fn=fn: fn(GOOD_TARGET, pose, ch, "punch", frame="0")),
            (f"{name} pose None", lambda fn=fn: fn(GOOD_TARGET, None, ch, "punch")),
            (f"{name} pose array", lambda fn=fn: fn(GOOD_TARGET, np.zeros((17, 3)), ch, "punch")),
            (f"{name} character None", lambda fn=fn: fn(GOOD_TARGET, pose, None, "punch")),
            (f"{name} character text", lambda fn=fn: fn(GOOD_TARGET, pose, "actor", "punch")),
        ]
        calls += [(f"{name} query {i}", lambda fn=fn, b=b: fn(GOOD_TARGET, b, None, "punch"))
                  for i, b in enumerate(bad_q)]
    calls += [
        ("search prune text", lambda: r.search(GOOD_TARGET, pose, ch, "punch", prune="no")),
        ("search scale_target None", lambda: r.search(GOOD_TARGET, pose, ch, "punch", scale_target=None)),
        ("exhaustive scale_target 1", lambda: r.search_exhaustive(GOOD_TARGET, pose, ch, "punch", scale_target=1)),
        ("prepare None", lambda: r.prepare(None, ch)),
        ("prepare frame 10**9", lambda: r.prepare(pose, ch, frame=10**9)),
        ("make_queries n", lambda: make_queries(r.db, -1)),
        ("make_queries n float", lambda: make_queries(r.db, 2.5)),
        ("make_queries seed", lambda: make_queries(r.db, 2, seed=-4)),
        ("make_queries noise", lambda: make_queries(r.db, 2, noise=np.nan)),
        ("make_queries noise text", lambda: make_queries(r.db, 2, noise="0.1")),
        ("make_queries db", lambda: make_queries("db", 2)),
    ]
    return calls


def test_bad_search_arguments(r, query):
    """Each call raises a ReproError subclass, and nothing else."""
    failures = refusal_failures(search_calls(r, query), ReproError)
    assert not failures, "\n".join(failures)


def test_good_calls_still_work(r, query):
    pose, ch = query
    a = r.search(GOOD_TARGET, pose, ch, "punch", frame=np.int64(0), prune=np.bool_(True))
    b = r.search_kdtree(GOOD_TARGET, pose, ch, "punch")
    assert a.semantics == b.semantics == "punch" and np.isfinite(a.d) and np.isfinite(b.d)
    big = MotionRetriever(r.db, kd_neighbours=10**9)  # more than the poses: all of them
    assert big.search_kdtree(GOOD_TARGET, pose, ch, "punch").d == pytest.approx(
        r.search_exhaustive(GOOD_TARGET, pose, ch, "punch").d)


