"""The paper's pruned search (repro.motion.search.pruned), Pronost et al. Section 3.3.

What is asserted:

* with pruning disabled the search returns the exhaustive optimum;
* the pruned search obeys the paper: the selected pose is in the selected cluster
  (nearest centroid, or the next ones when flagged), its clip's box contains ``c_r``,
  it is the best such pose, and it is never better than the exhaustive optimum;
* on the synthetic database a target inside a clip's box (its hit point) retrieves a
  clip of the requested semantics whose hit trajectory passes within a few centimetres.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.motion.body.skeleton import rescale_constraint
from repro.motion.retargeting.morphology import retarget
from tests.motion.search.queries import frame_of, queries


def test_unpruned_search_is_the_exhaustive_optimum(db, retriever):
    for c, pose, ch, sem in queries(db, 25, seed=1):
        q = retriever.prepare(pose, ch)
        a = retriever.search(c, q, semantics=sem, prune=False)
        b = retriever.search_exhaustive(c, q, semantics=sem)
        assert (a.clip, a.start_frame, a.pose) == (b.clip, b.start_frame, b.pose)
        assert a.d == b.d and a.fallback == "disabled"
        assert a.semantics == sem


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
