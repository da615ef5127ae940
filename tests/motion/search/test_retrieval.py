"""Motion retrieval (repro.motion.search.retrieval), Pronost et al. Section 3.3.

What is asserted:

* :class:`MotionRetriever` takes a prepared :class:`Query`, and the module-level :func:`search`
  gives what it gives; the k-d tree baseline is never better than the exhaustive optimum;
* bad input raises RetrievalError / MotionError with clear messages;
* on the CMU database a kick and a punch are retrieved, the same for a smaller character (Eq. 1);
* ``make_queries(db, 10**12)`` (which ran until killed) is a :class:`RetrievalError` naming the
  count and its bound :data:`MAX_QUERIES`.

The searches' own tests are named after their modules (test_pruned, test_exact, test_exhaustive,
test_results, test_scoring, test_query, test_index, test_arguments; the k-d tree baseline is here).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.errors import MotionError, RetrievalError
from repro.motion.database.clips import MotionDatabase
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.retrieval import MAX_QUERIES, MotionRetriever, Query, make_queries, search
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from tests.motion.search.queries import frame_of, queries


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


@pytest.fixture(scope="module")
def small(synthetic_db):
    return synthetic_db.select(np.arange(3))


@pytest.mark.parametrize("n", [MAX_QUERIES + 1, 10**12])
def test_query_counts_are_bounded(small, n):
    with pytest.raises(RetrievalError, match=rf"^n \(number of queries\) must be an integer in 0\.\.{MAX_QUERIES}"):
        make_queries(small, n)


def test_query_counts_in_range(small):
    assert len(make_queries(small, 3)) == 3
