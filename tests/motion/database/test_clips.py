"""The annotated motion database (repro.motion.database.clips), Pronost et al. Section 3.2.

What is asserted:

* resampling reproduces source frames exactly (120 Hz -> 30 Hz is every 4th frame);
  mirroring reflects forward kinematics exactly and is an involution;
* hit detection finds the annotated hit segment and hit frame of every synthetic clip
  (ground truth known by construction) and nothing in idle stances;
* :func:`build_database` on the synthetic folder keeps every strike of the manifest with
  its semantics, hit segment and hit *time*, and the stored hit position is the
  manifest's world hit position expressed in the clip's first-frame root frame
  (recomputed independently from the 60 Hz source); boxes contain their trajectories;
* save/load round trip is exact (also for an augmented database), without pickles,
  leaving no temporary file; augmentation is deterministic, mirrors hit sides, and its
  rebuilt motions give back the stored trajectories;
* on the real CMU takes: 14 kicks, 9 lunge punches, ~50 kata arm strikes, 30 fps, hit
  at 0.6 s into each clip, the actor of subject 135;
* bad inputs raise :class:`MotionError`.
"""

from __future__ import annotations

import csv
import dataclasses
import os

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion import read_bvh
from repro.motion.body.pose_frames import root_frames, to_root_frame
from repro.motion.database.annotation import detect_hits, hit_frame_for
from repro.motion.database.augment import augment
from repro.motion.database.clips import Clip, MotionDatabase
from repro.motion.core.ops import cut, mirror_joint_map, mirror_motion, resample
from repro.motion.database.sources import CMU_WINDOW, build_cmu_database, build_database
from repro.motion.body.skeleton import Skeleton

from repro.motion.database import synthetic  # noqa: E402  (a broken import must fail, not skip)


@pytest.fixture(scope="module")
def syn_dir(synthetic_dir):
    d = synthetic_dir  # the session's synthetic folder (tests/conftest.py): read, never written
    return d


@pytest.fixture(scope="module")
def syn_db(synthetic_db):
    return synthetic_db  # build_database(synthetic_dir), this module's copy


def _manifest(d):
    with open(d / "manifest.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------ motions
def test_resample_reproduces_source_frames():
    m, _ = synthetic.synthetic_clip("punch", "right", "middle", seed=1, fps=120)
    r = resample(m, 30.0)
    assert r.fps == pytest.approx(30.0)
    assert r.n_frames == (m.n_frames - 1) // 4 + 1
    np.testing.assert_allclose(r.rotations, m.rotations[::4][: r.n_frames], rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.global_positions(), m.global_positions()[::4][: r.n_frames], atol=1e-12)
    # halfway samples lie between their neighbours
    h = resample(m, frames=[10.5])
    g, g0, g1 = h.global_positions()[0], m.global_positions()[10], m.global_positions()[11]
    assert np.all(np.linalg.norm(g - 0.5 * (g0 + g1), axis=1) < 0.01)
    with pytest.raises(MotionError):
        resample(m, frames=[-1.0])
    assert cut(m, 3, 7).n_frames == 4
    with pytest.raises(MotionError):
        cut(m, 5, 5)


def test_mirror_reflects_forward_kinematics():
    m, _ = synthetic.synthetic_clip("kick_round", "left", "high", seed=2)
    mm = mirror_motion(m)
    pi = mirror_joint_map(m.joint_names, m.parents)
    assert m.joint_names[pi[m.joint_index("LeftHand")]] == "RightHand"
    assert pi[m.joint_index("Spine")] == m.joint_index("Spine")
    g, gm = m.global_positions(), mm.global_positions()
    np.testing.assert_allclose(gm, g[:, pi] * [-1, 1, 1], atol=1e-9)
    np.testing.assert_allclose(mm.end_site_positions()[:, :1], m.end_site_positions()[:, :1] * [-1, 1, 1], atol=1e-9)
    back = mirror_motion(mm)
    np.testing.assert_allclose(back.global_positions(), g, atol=1e-9)


def test_mirror_map_of_cmu_names():
    names = ["root", "lfemur", "ltibia", "rfemur", "rtibia", "lowerback", "lhumerus", "rhumerus"]
    parents = [-1, 0, 1, 0, 3, 0, 5, 5]
    pi = mirror_joint_map(names, parents)
    assert [names[i] for i in pi] == ["root", "rfemur", "rtibia", "lfemur", "ltibia", "lowerback", "rhumerus",
                                      "lhumerus"]
    assert list(mirror_joint_map(["root", "lfemur"], [-1, 0])) == [0, 1]  # unpaired: its own partner
    with pytest.raises(MotionError):  # rfemur hangs below lfemur: not left/right symmetric
        mirror_joint_map(["root", "lfemur", "rfemur"], [-1, 0, 1])


# ------------------------------------------------------------- hit detection
@pytest.mark.parametrize("kind", ["punch", "kick_front", "kick_side", "kick_round"])
@pytest.mark.parametrize("level", ["high", "middle", "low"])
def test_detector_finds_the_annotated_hit(kind, level):
    for side in ("left", "right"):
        m, ann = synthetic.synthetic_clip(kind, side, level, actor_height=1.7, seed=11)
        role = f"{side}_{'fist' if kind == 'punch' else 'foot'}"
        assert hit_frame_for(m, role) == ann["hit_frame"]
        hits = [h for h in detect_hits(m) if h.role == role]
        assert len(hits) == 1
        assert hits[0].semantics == ann["semantics"]
        assert abs(hits[0].frame - ann["hit_frame"]) <= 1


def test_detector_ignores_idle_stance():
    m, _ = synthetic.synthetic_clip("stance", "left", seed=4)
    assert detect_hits(m) == []
    with pytest.raises(MotionError):
        hit_frame_for(m, "left_hand")


# ------------------------------------------------------------------ building
def test_build_from_synthetic_manifest(syn_dir, syn_db):
    rows = [r for r in _manifest(syn_dir) if r["semantics"] in ("punch", "kick")]
    db = syn_db
    assert db.n_clips == len(rows) == 72
    assert db.fps == 30.0
    assert len(db.actors) == 1  # three statures, one proportional base actor
    assert sorted(set(np.round(db.size_a, 3))) == pytest.approx([1.6, 1.75, 1.9], abs=1e-3)
    by_name = {n: i for i, n in enumerate(db.names)}
    for r in rows[::5]:
        i = by_name[r["file"][:-4]]
        assert db.semantics[i] == r["semantics"]
        assert db.hit_joints[i] == r["hit_joint"]
        assert db.hit_wheres[i] == r["hit_point"]
        assert db.hit_roles[i] == f"{r['side']}_{'fist' if r['semantics'] == 'punch' else 'foot'}"
        ft = float(r["frame_time"])
        t_hit = int(r["hit_frame"]) * ft
        # the clip is resampled on a grid through the hit: the hit stays on a frame
        assert db.source_time[i] + db.hit_frame[i] / 30.0 == pytest.approx(t_hit, abs=1e-9)
        # hit position = manifest world position in the root frame of the clip's first frame,
        # recomputed from the 60 Hz source at the clip's start time
        src = read_bvh(syn_dir / r["file"], unit_m=1.0)  # the synthetic files are in metres
        sk = Skeleton.from_motion(src)
        g = src.global_positions()
        k0 = int(round(db.source_time[i] / ft))
        assert k0 * ft == pytest.approx(db.source_time[i], abs=1e-9)
        th, o = root_frames(g[k0:k0 + 1], sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip"))
        world = np.array([float(r["hit_x_m"]), float(r["hit_y_m"]), float(r["hit_z_m"])])
        np.testing.assert_allclose(db.hit_position[i], to_root_frame(world, th[0], o[0]), atol=1e-4)
        tr = db.trajectory(i)
        assert np.all(db.box_min[i] <= tr + 1e-12) and np.all(tr <= db.box_max[i] + 1e-12)
        np.testing.assert_array_equal(db.box_min[i], tr.min(axis=0))
        # forward strikes: the hit point is in front of the actor
        assert db.hit_position[i][2] > 0.2


def test_pose_arrays_are_consistent(syn_db):
    db = syn_db
    assert db.pose_points.shape == (db.n_poses, len(db.pose_roles), 3)
    assert db.pose_start[-1] == db.n_poses == db.n_frames.sum()
    i = 7
    rows = db.poses_of(i)
    np.testing.assert_array_equal(db.pose_clip[rows], i)
    np.testing.assert_array_equal(db.pose_frame[rows], np.arange(db.n_frames[i]))
    # pose clouds are adimensional: the pelvis height over the stature is about 0.55
    pel = db.pose_points[rows, db.pose_roles.index("pelvis")]
    assert 0.4 < pel[0, 1] < 0.65
    np.testing.assert_allclose(pel[:, [0, 2]], 0.0, atol=1e-12)  # origin below the pelvis


def test_build_without_manifest_detects_and_cuts(tmp_path):
    m, ann = synthetic.synthetic_clip("kick_front", "left", "high", seed=5)
    from repro.motion import write_bvh

    write_bvh(m, tmp_path / "take.bvh")
    db = build_database(tmp_path)
    assert db.n_clips == 1
    assert db.semantics[0] == "kick" and db.hit_roles[0] == "left_foot"
    assert db.hit_frame[0] == round(CMU_WINDOW[0] * 30)
    assert db.source_time[0] + db.hit_frame[0] / 30 == pytest.approx(ann["hit_frame"] / 60, abs=1e-9)


def test_save_load_round_trip(syn_db, tmp_path):
    p = syn_db.save(tmp_path / "db.npz")
    assert p.exists()
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]
    with np.load(p, allow_pickle=False) as z:
        assert "header" in z.files
    back = MotionDatabase.load(p)
    assert back.equals(syn_db)
    assert repr(back) == repr(syn_db)
    np.testing.assert_array_equal(back.motion(3).rotations, syn_db.motion(3).rotations)
    # a changed database is not equal
    other = syn_db.select(np.arange(syn_db.n_clips) != 5)
    assert not other.equals(syn_db)


def test_augment_deterministic_and_round_trip(syn_db, tmp_path):
    base = syn_db.select(np.arange(12))
    a = augment(base, 10, seed=3)
    b = augment(base, 10, seed=3)
    c = augment(base, 10, seed=4)
    assert a.n_clips == 120 and a.equals(b) and not a.equals(c)
    assert a.summary()["augmented"] == 108
    np.testing.assert_array_equal(a.pose_points[: base.n_poses], base.pose_points)
    mir = np.flatnonzero(a.mirror)
    assert mir.size > 20
    for i in mir[:5]:
        s = int(a.source_clip[i])
        assert a.sides[i] != a.sides[s]
        assert a.hit_roles[i].split("_")[0] == a.sides[i]
        assert a.hit_position[i][0] == pytest.approx(-a.hit_position[s][0], abs=0.1)
    p = a.save(tmp_path / "aug.npz")
    assert MotionDatabase.load(p).equals(a)


def test_augmented_motion_is_rebuilt(syn_db):
    base = syn_db.select(np.arange(4))
    a = augment(base, 3, seed=1, noise=0.0)
    for i in range(4, 12):
        clip = a.clip(i)
        assert clip.motion.n_frames == a.n_frames[i]
        again = MotionDatabase.from_clips([clip])
        np.testing.assert_allclose(again.trajectory(0), a.trajectory(i), atol=1e-9)
        np.testing.assert_allclose(again.pose_points, a.pose_points[a.poses_of(i)], atol=1e-9)
        assert again.size_a[0] == pytest.approx(a.size_a[i], rel=1e-9)


def test_bad_inputs(tmp_path, syn_db):
    m = syn_db.motion(0)
    with pytest.raises(MotionError):
        Clip(name="x", motion=m, semantics="headbutt", hit_role="right_fist", hit_joint="RightHand",
             hit_where="joint", hit_frame=3)
    with pytest.raises(MotionError):
        Clip(name="x", motion=m, semantics="punch", hit_role="right_fist", hit_joint="RightHand",
             hit_where="joint", hit_frame=10_000)
    with pytest.raises(MotionError):
        Clip(name="x", motion=dataclasses.replace(m, unit_m=0.01), semantics="punch", hit_role="right_fist",
             hit_joint="RightHand", hit_where="joint", hit_frame=3)
    with pytest.raises(MotionError):
        MotionDatabase.from_clips([])
    with pytest.raises(MotionError):
        build_database(tmp_path)  # no BVH file at all
    with pytest.raises(MotionError):
        augment(syn_db, 0)
    with pytest.raises(MotionError):
        syn_db.select(np.zeros(syn_db.n_clips, dtype=bool))


# ------------------------------------------------------------------ real data
@pytest.mark.data("cmu-bvh")
def test_cmu_database():
    db = build_cmu_database()
    s = db.summary()
    kinds = s["per_kind"]
    assert kinds["front_kick"] + kinds["roundhouse_kick"] + kinds["side_kick"] == 14
    assert kinds["lunge_punch"] == 9
    assert 40 <= kinds["kata_arm"] <= 60
    assert 60 <= db.n_clips <= 90
    assert s["per_semantics"]["kick"] == 14
    assert db.fps == 30.0 and len(db.actors) == 1
    assert db.size_a[0] == pytest.approx(1.636, abs=0.01)
    # windows of 0.6 s before the hit (unless the take starts earlier)
    assert np.mean(db.hit_frame == 18) > 0.9
    assert np.all(db.n_frames <= 28)
    # kicks hit high and in front, punches at arm's length
    kick = db.semantics == "kick"
    assert np.all(db.hit_position[kick, 1] > 0.6)
    assert np.median(np.linalg.norm(db.hit_position[~kick][:, [0, 2]], axis=1)) > 0.4


def test_load_or_build(tmp_path, syn_dir):
    from repro.motion.database.sources import load_or_build

    calls = []

    def build(**kw):
        calls.append(kw)
        return build_database(**kw)

    p = tmp_path / "cache.npz"
    a = load_or_build(p, build, source=syn_dir)
    b = load_or_build(p, build, source=syn_dir)
    assert len(calls) == 1 and p.exists() and a.equals(b)
