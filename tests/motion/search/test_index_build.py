"""The index build that scales (repro.motion.search.index_build; issue 13, item 3): the ``order`` of
AlignedPoseIndex, float32 pose clouds, the batched augmentation.

What is asserted:

* an :class:`AlignedPoseIndex` with an ``order`` gives the same distances (and transforms) as
  the plain one, for stored rows, rows outside the order and all rows; a subset of
  consecutive stored rows is a view, any other subset a copy with the same values;
* float32 pose clouds are kept as given (not copied to float64) and the float64 terms built
  from them equal those of the same clouds cast to float64;
* :func:`block_order` puts every (semantics, cluster) block and every semantics' cluster run
  in consecutive, ascending rows; the retriever's per-cluster and exact-search blocks are
  then views of its index, and its choices are those of an index built without an order;
* :func:`augment` with ``pose_dtype=float32`` equals the float64 one to float32 rounding; the
  batched variants of a database with a pose window > 1 equal the clips rebuilt one by one
  (the window is clamped at each variant's first frame);
* bad ``order`` and ``pose_dtype`` are library errors naming the value.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.augment import augment
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance
from repro.motion.search.kmeans import cluster_poses
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.index_build import block_order, build_pose_index, startable_poses
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.retrieval import MotionRetriever, make_queries


@pytest.fixture(scope="module")
def db(synthetic_db):
    return synthetic_db


def _clouds(n=400, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.normal(scale=0.3, size=(n, 17, 3))
    p[..., 1] += 0.5
    return p


def test_ordered_index_equals_the_plain_one():
    p = _clouds()
    rng = np.random.default_rng(1)
    order = rng.permutation(p.shape[0])[:250]
    plain = AlignedPoseIndex(p)
    ix = AlignedPoseIndex(p, order=order)
    q = _clouds(1, seed=7)[0]
    outside = np.setdiff1d(np.arange(p.shape[0]), order)
    for rows in (order[:40], outside[:30], np.concatenate([outside[:5], order[:5]]), None):
        np.testing.assert_array_equal(ix.distances(q, rows), plain.distances(q, rows))
        for a, b in zip(ix.distances(q, rows, return_transform=True), plain.distances(q, rows, return_transform=True)):
            np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(ix.distances(q), aligned_distance(q, p), atol=1e-9)
    # a run of the order, in order or permuted, is a view; anything else a copy; all score like the plain subset
    run = ix.subset(order[100:180])
    permuted = ix.subset(np.sort(order[100:180]))
    scattered = ix.subset(np.sort(order[100:180:2]))
    dup = ix.subset(np.concatenate([order[100:102], order[100:101], order[103:104]]))  # not a permutation of a run
    assert np.shares_memory(run._M, ix._M) and np.shares_memory(permuted._M, ix._M)
    assert np.shares_memory(run._X, ix._T) and np.shares_memory(permuted._Y2, ix._T)  # the scalar terms too
    assert not np.shares_memory(scattered._M, ix._M) and not np.shares_memory(dup._M, ix._M)
    mixed = ix.subset(outside[:10])
    for sub, rows in ((run, order[100:180]), (permuted, np.sort(order[100:180])), (scattered, np.sort(order[100:180:2])),
                      (dup, np.concatenate([order[100:102], order[100:101], order[103:104]])), (mixed, outside[:10])):
        ref = plain.subset(rows)
        np.testing.assert_array_equal(sub.distances(q), ref.distances(q))
        sel = np.arange(0, rows.size, 3)
        np.testing.assert_array_equal(sub.distances(q, sel), ref.distances(q, sel))
        np.testing.assert_array_equal(sub.subset(sel).distances(q), ref.subset(sel).distances(q))
        for a, b in zip(sub.distances(q, return_transform=True), ref.distances(q, return_transform=True)):
            np.testing.assert_array_equal(a, b)


def test_float32_clouds_are_not_copied():
    p = _clouds().astype(np.float32)
    ix = AlignedPoseIndex(p)
    assert ix.points is p
    ref = AlignedPoseIndex(p.astype(np.float64))
    np.testing.assert_array_equal(ix._M, ref._M)
    np.testing.assert_array_equal(ix._H, ref._H)
    cl32, cl64 = cluster_poses(p, 6, seed=0), cluster_poses(p.astype(np.float64), 6, seed=0)
    np.testing.assert_array_equal(cl32.labels, cl64.labels)


def test_bad_order():
    p = _clouds(20)
    for bad in ([0, 0, 1], [25], [-1], [[0, 1]], [0.5], "ab"):
        with pytest.raises(MotionError, match="order"):
            AlignedPoseIndex(p, order=np.asarray(bad))


def test_block_order_makes_blocks_consecutive(db):
    cl = cluster_poses(db.pose_points, 8, seed=0)
    st = startable_poses(db)
    sem = db.semantics[db.pose_clip]
    order = block_order(cl.labels, st, sem)
    assert np.array_equal(np.sort(order), np.flatnonzero(st))
    pos = np.empty(db.n_poses, dtype=np.intp)
    pos[order] = np.arange(order.size)
    for s in SEMANTICS:
        run = []
        for c, m in enumerate(cl.members):
            rows = m[st[m] & (sem[m] == s)]
            if rows.size:
                at = pos[rows]
                assert np.all(np.diff(at) == 1)  # consecutive and ascending
                run.append(at)
        if run:
            at = np.concatenate(run)
            assert np.all(np.diff(at) == 1)


def test_retriever_blocks_share_the_index(db, monkeypatch):
    r = MotionRetriever(db, k=8)
    blocks = [b for bs in r.cluster_block for b in bs.values()] + list(r.sem_block.values())
    blocks = [b.index for b in blocks if b is not None] + [ex["index"] for ex in r.exact.arrays.values() if ex is not None]
    assert blocks and all(np.shares_memory(b._M, r.index._M) for b in blocks)
    assert all(np.shares_memory(t, r.index._T) for b in blocks for t in (b._X, b._Z, b._H, b._Y2))
    _, clusters = build_pose_index(db, 8)
    np.testing.assert_array_equal(clusters.labels, r.clusters.labels)
    # the same choices as with the terms of every pose stored in pose order and copied per block (the
    # previous layout)
    import sys

    def previous(db, k, *, weights=None, seed=0):
        return AlignedPoseIndex(db.pose_points, weights), cluster_poses(db.pose_points, k, weights=weights, seed=seed)

    monkeypatch.setattr(sys.modules[RetrievalIndex.__module__], "build_pose_index", previous)
    plain = MotionRetriever(db, k=8)
    b = next(b for bs in plain.cluster_block for b in bs.values() if b is not None)
    assert not np.shares_memory(b.index._M, plain.index._M)
    for c, pose, ch, sem in make_queries(db, 30, 3):
        q = r.prepare(pose, ch)
        for name in ("search", "search_exhaustive", "search_exact", "search_kdtree"):
            a, b = getattr(r, name)(c, q, None, sem), getattr(plain, name)(c, q, None, sem)
            assert (a.clip, a.start_frame, a.d) == (b.clip, b.start_frame, b.d)


def test_augment_float32(db):
    base = db.select(np.arange(6))
    a = augment(base, 4, seed=2)
    b = augment(base, 4, seed=2, pose_dtype=np.float32)
    assert b.pose_points.dtype == np.float32 and a.pose_points.dtype == np.float64
    np.testing.assert_allclose(b.pose_points, a.pose_points, rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(b.traj, a.traj)
    assert augment(base, 1, pose_dtype=np.float32).pose_points.dtype == np.float32
    for bad in (np.int32, "complex128", "nonsense"):
        with pytest.raises(MotionError, match="pose_dtype"):
            augment(base, 2, pose_dtype=bad)


def test_batched_variants_with_a_pose_window(db):
    clips = [db.clip(i) for i in range(3)]
    base = MotionDatabase.from_clips(clips, window=3, step=2)
    a = augment(base, 4, seed=5, noise=0.0)
    for i in range(base.n_clips, a.n_clips):
        again = MotionDatabase.from_clips([a.clip(i)], window=3, step=2)
        np.testing.assert_allclose(again.pose_points, a.pose_points[a.poses_of(i)], atol=1e-9)
        np.testing.assert_allclose(again.trajectory(0), a.trajectory(i), atol=1e-9)
        np.testing.assert_allclose(again.pose_heading, a.pose_heading[a.poses_of(i)], atol=1e-9)
        np.testing.assert_allclose(again.box_min[0], a.box_min[i], atol=1e-9)
        assert again.hit_frame[0] == a.hit_frame[i]


def test_float32_clouds_survive_save_and_load(db, tmp_path):
    """A float32 database saved to npz reloads float32 (not silently doubled to float64), same numbers."""
    from repro.motion.database.clips import MotionDatabase

    b = augment(db, 2, seed=1, pose_dtype=np.float32)
    back = MotionDatabase.load(b.save(tmp_path / "f32.npz"))
    assert back.pose_points.dtype == np.float32
    np.testing.assert_array_equal(back.pose_points, b.pose_points)
    assert MotionDatabase.load(db.save(tmp_path / "f64.npz")).pose_points.dtype == np.float64
