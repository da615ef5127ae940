"""The real sources of the motion database beyond CMU subject 135 (repro.motion.database.clips).

Pronost et al., Section 3.2: the database is built from real clips -- CMU subject 135
(karate), the Bandai Namco clips (another skeleton: 22 joints, 30 fps, every joint with 6
channels) and walks/runs of other CMU subjects for non-fighting poses
(``mocap/*/manifest.csv``, ``mocap/*/PROVENANCE.md``).

What is asserted:

* :data:`BANDAI_TAKES` / :data:`NON_FIGHTING_TAKES` agree with the staged manifests;
* :func:`build_bandai_database` finds the strikes of PROVENANCE.md (3 right kicks, 2 left
  and 5 right punches) with the right semantics, hit limb and hit joint; lengths are in
  metres, the actor's leg is 0.80 m and arm 0.47 m (PROVENANCE.md);
* :func:`build_real_database` holds the CMU 135 clips of :func:`build_cmu_database`
  unchanged plus the Bandai ones, with two base actors of different joint trees, and
  survives a save/load round trip exactly;
* on the combined database the retrieval returns a clip of the requested semantics,
  *only* among the clips of the character's joint tree (CMU character -> CMU clip,
  Bandai character -> Bandai clip); a Bandai character on a CMU-only database is refused;
* :func:`non_fighting_poses` loads every walk/run/bow take in metres at 30 fps; the other
  CMU subjects are refused by the retargeting as they are (other rest directions) and
  accepted after :func:`match_rest_pose`, which keeps joint positions and bone lengths.
"""

from __future__ import annotations

import csv
import dataclasses
import math

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError, RetrievalError
from repro.motion import BANDAI_UNIT_M, read_bvh
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.clips import MotionDatabase
from repro.motion.body.rest_pose import match_rest_pose
from repro.motion.database.sources import (
    BANDAI_TAKES,
    NON_FIGHTING_TAKES,
    build_bandai_database,
    build_cmu_database,
    build_real_database,
    clip_source_dataset,
    non_fighting_poses,
)
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.body.skeleton import Skeleton


def frame_of(m, f):
    return dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])


@pytest.fixture(scope="module")
def bandai_db():
    return build_bandai_database()


@pytest.fixture(scope="module")
def real_db():
    return build_real_database()


@pytest.fixture(scope="module")
def real_retriever(real_db):
    return MotionRetriever(real_db, seed=0, across_trees=False)  # each character to its own tree's clips


def _manifest(folder):
    p = data.data_dir() / "mocap" / folder / "manifest.csv"
    if not p.is_file():
        pytest.skip(f"{p} not staged")
    with open(p, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------ tables
@pytest.mark.data("bandai", "cmu-bvh")
def test_take_tables_match_the_manifests():
    rows = _manifest("bandai")
    strikes = {r["file"][:-4]: r["semantics"] for r in rows if r["semantics"] in SEMANTICS}
    assert strikes == BANDAI_TAKES
    other = {f"mocap/bandai/{r['file']}" for r in rows if r["semantics"] == "other"}
    assert other <= set(NON_FIGHTING_TAKES)
    cmu = _manifest("cmu")
    walks = {f"mocap/cmu/{r['file']}" for r in cmu if r["subject"] != "135"}
    assert walks == {k for k, v in NON_FIGHTING_TAKES.items() if v[0] in ("cmu131", "cmu07", "cmu09")}
    assert all(r["semantics"] == "other" for r in cmu if f"mocap/cmu/{r['file']}" in NON_FIGHTING_TAKES)


# ------------------------------------------------------------------ Bandai
@pytest.mark.data("bandai")
def test_bandai_clips_semantics_and_hit_limbs(bandai_db):
    db = bandai_db
    got = {}
    for take in BANDAI_TAKES:
        sel = np.char.startswith(db.names, take)
        got[take] = sorted(zip(db.semantics[sel].tolist(), db.hit_roles[sel].tolist(), db.hit_joints[sel].tolist()))
    # mocap/bandai/PROVENANCE.md, "Strikes found": kicks 0/3, punches 2/0 and 0/5
    assert got["dataset-1_kick_normal_001"] == [("kick", "right_foot", "Toes_R")] * 3
    assert got["dataset-1_punch_normal_001"] == [("punch", "left_fist", "Hand_L")] * 2
    assert got["dataset-1_punch_normal_002"] == [("punch", "right_fist", "Hand_R")] * 5
    assert db.n_clips == 10 and db.meta["sources"] == {"bandai": 10}
    assert set(db.kinds.tolist()) == {"kick_normal", "punch_normal"}
    assert np.all(np.char.startswith(db.sources, "mocap/bandai/"))
    # the arm swings of the kick take are not punches of the database
    assert not np.any((db.semantics == "punch") & np.char.startswith(db.names, "dataset-1_kick"))
    # cut 0.6 s before / 0.3 s after each hit, at 30 fps
    assert db.fps == 30.0
    assert np.all(db.hit_frame == 18) and np.all(db.n_frames == 28)


@pytest.mark.data("bandai")
def test_bandai_units_and_actor(bandai_db):
    db = bandai_db
    assert len(db.actors) == 1
    actor = db.actors[0]
    assert actor.n_joints == 22 and actor.unit_m == 1.0
    # PROVENANCE.md: leg (UpperLeg->Foot) 0.80 m, arm (UpperArm->Hand) 0.47 m
    assert actor.leg_length == pytest.approx(0.80, abs=0.01)
    assert actor.arm_length == pytest.approx(0.47, abs=0.01)
    # the stature measured as on every rig (repro.motion.body.stature): the file has no head top and its
    # rest pose does not tell the ankle height, both estimated (about 1.46 m; 1.30 m when measured up to
    # the Head joint)
    assert np.all(db.size_a == actor.size) and 1.40 < actor.size < 1.52
    # the same as reading the file in centimetres directly
    raw = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    assert Skeleton.from_motion(raw).size == pytest.approx(actor.size, rel=1e-9)
    for i in range(db.n_clips):
        m = db.motion(i)
        assert m.unit_m == 1.0
        g = m.global_positions()
        pelvis = g[:, actor.index("pelvis"), 1]
        assert 0.6 < np.median(pelvis) < 1.05  # metres, not centimetres
    kick = db.semantics == "kick"
    # kicks hit high (about 1 m), punches at head height and in front of the body
    assert np.all((db.hit_position[kick, 1] > 0.8) & (db.hit_position[kick, 1] < 1.3))
    assert np.all((db.hit_position[~kick, 1] > 1.0) & (db.hit_position[~kick, 1] < 1.45))
    assert np.all(np.linalg.norm(db.hit_position[~kick][:, [0, 2]], axis=1) > 0.4)


@pytest.mark.data("bandai")
def test_bandai_retrieval(bandai_db):
    db = bandai_db
    r = MotionRetriever(db, seed=0)
    stance = frame_of(db.motion(0), 0)
    actor = db.actors[0]
    for sem in ("kick", "punch"):
        j = int(np.flatnonzero(db.semantics == sem)[0])
        res = r.search(db.hit_position[j], stance, actor, sem)
        assert res.semantics == sem and db.semantics[res.clip] == sem
        assert res.d_cr < 0.05
        assert res.d >= r.search_exhaustive(db.hit_position[j], stance, actor, sem).d - 1e-9


# ------------------------------------------------------------------ combined
@pytest.mark.data("cmu-bvh", "bandai")
def test_combined_database(real_db, bandai_db):
    db = real_db
    src = clip_source_dataset(db)
    assert db.meta["sources"] == {"cmu135": 72, "bandai": 10}
    assert int(np.sum(src == "cmu135")) == 72 and int(np.sum(src == "bandai")) == 10
    assert db.summary()["per_semantics"] == {"punch": 58 + 7, "kick": 14 + 3}
    # two base actors: CMU (31 joints) and Bandai (22 joints), each clip on its own
    assert [a.n_joints for a in db.actors] == [31, 22]
    assert np.all(db.actor[src == "cmu135"] == 0) and np.all(db.actor[src == "bandai"] == 1)
    assert db.size_a[src == "cmu135"] == pytest.approx(1.636, abs=0.01)
    assert db.actors[1].leg_length == pytest.approx(0.80, abs=0.01)
    # the CMU part is build_cmu_database's, the Bandai part build_bandai_database's
    cmu = build_cmu_database()
    c = src == "cmu135"
    assert np.array_equal(db.names[c], cmu.names) and np.array_equal(db.hit_frame[c], cmu.hit_frame)
    rows = np.isin(db.pose_clip, np.flatnonzero(c))
    assert np.array_equal(db.pose_points[rows], cmu.pose_points)
    b = src == "bandai"
    assert np.array_equal(db.names[b], bandai_db.names)
    assert np.array_equal(db.hit_position[b], bandai_db.hit_position)
    # only strikes: the non-fighting takes are not database clips
    with pytest.raises(MotionError, match="non_fighting_poses"):
        build_real_database(include=("cmu135", "cmu-walks"))


@pytest.mark.data("cmu-bvh", "bandai")
def test_combined_save_load_round_trip(real_db, tmp_path):
    p = real_db.save(tmp_path / "real.npz")
    back = MotionDatabase.load(p)
    assert back.equals(real_db)
    assert [a.joint_names for a in back.actors] == [a.joint_names for a in real_db.actors]
    i = int(np.flatnonzero(clip_source_dataset(back) == "bandai")[0])
    assert np.array_equal(back.motion(i).global_positions(), real_db.motion(i).global_positions())


@pytest.mark.data("cmu-bvh", "bandai")
def test_combined_retrieval_stays_in_the_characters_joint_tree(real_db, real_retriever):
    db, r = real_db, real_retriever
    src = clip_source_dataset(db)
    cmu_i = int(np.flatnonzero(src == "cmu135")[0])
    ban_i = int(np.flatnonzero(src == "bandai")[0])
    chars = {"cmu135": (frame_of(db.motion(cmu_i), 0), db.actors[0]),
             "bandai": (frame_of(db.motion(ban_i), 0), db.actors[1])}
    for family, (pose, character) in chars.items():
        q = r.prepare(pose, character)
        assert q.actors == ((0,) if family == "cmu135" else (1,))
        for sem in SEMANTICS:
            for target_family in ("cmu135", "bandai"):
                j = int(np.flatnonzero((db.semantics == sem) & (src == target_family))[0])
                c = db.hit_position[j] * character.size / db.size_a[j]
                res = r.search(c, q, None, sem)
                ex = r.search_exhaustive(c, q, None, sem)
                assert res.semantics == sem
                assert src[res.clip] == family and src[ex.clip] == family
                assert res.d >= ex.d - 1e-9
                if target_family == family:  # the target is one of the family's hit points
                    assert ex.d_cr < 1e-9


@pytest.mark.data("cmu-bvh", "bandai")
def test_bandai_character_on_cmu_database_is_refused(bandai_db):
    cmu = build_real_database(include=("cmu135",))
    pose = frame_of(bandai_db.motion(0), 0)
    with pytest.raises(RetrievalError, match="joint tree"):
        MotionRetriever(cmu, across_trees=False).search(np.array([0.0, 1.2, 0.6]), pose, bandai_db.actors[0],
                                                        "punch")


# ------------------------------------------------------------------ non-fighting
@pytest.mark.data("cmu-bvh", "bandai")
def test_non_fighting_poses_load():
    poses = non_fighting_poses()
    assert set(poses) == {k.split("/")[-1][:-4] for k in NON_FIGHTING_TAKES}
    for name, m in poses.items():
        kind = NON_FIGHTING_TAKES[m.source][1]
        assert m.unit_m == 1.0 and m.fps == pytest.approx(30.0)
        assert m.n_joints == (22 if m.source.startswith("mocap/bandai/") else 31)
        sk = Skeleton.from_motion(m)
        g = m.global_positions()
        pelvis = g[:, sk.index("pelvis"), 1]
        assert 0.6 < np.median(pelvis) < 1.1, name  # standing, metres
        if kind in ("walk", "run"):
            pel = sk.index("pelvis")
            travel = np.linalg.norm(g[-1, pel, [0, 2]] - g[0, pel, [0, 2]])
            assert travel > 0.5, name  # they do move
    walks = non_fighting_poses(kinds=("walk", "run"), fps=None)
    assert "dataset-1_bow_normal_001" not in walks and len(walks) == len(poses) - 1
    assert walks["09_06"].fps == pytest.approx(120.0, rel=1e-4)
    # durations agree with the manifest (CMU 120 Hz -> 30 Hz)
    assert poses["09_06"].n_frames == pytest.approx(141 / 4, abs=1.5)
    assert poses["131_09"].n_frames == pytest.approx(2293 / 4, abs=1.5)


@pytest.mark.data("cmu-bvh", "bandai")
def test_non_fighting_poses_as_queries(real_db, real_retriever):
    db, r = real_db, real_retriever
    src = clip_source_dataset(db)
    raw = non_fighting_poses(takes=["mocap/cmu/131_01.bvh"])["131_01"]
    pose = frame_of(raw, raw.n_frames // 2)
    matched = non_fighting_poses(rest_like=db)
    # other CMU subjects: same joint tree, other rest directions -> the query path re-expresses the pose on the
    # actor's rest directions itself (RetargetPlan's rest step, issue 25), as rest_like does beforehand
    target = np.array([0.0, 1.2, 0.6])
    as_is = r.search(target, pose, Skeleton.from_motion(pose), "punch", method="exact")
    twin = frame_of(matched["131_01"], raw.n_frames // 2)
    before = r.search(target, twin, Skeleton.from_motion(twin), "punch", method="exact")
    assert (as_is.clip, as_is.start_frame) == (before.clip, before.start_frame)
    # d differs a little: Eq. 1 scales the target by the character's size, measured on each pose's own rest pose
    ratio = Skeleton.from_motion(pose).size / Skeleton.from_motion(twin).size
    assert np.isfinite(as_is.d) and as_is.d == pytest.approx(before.d, rel=0.25), ratio
    for name, m in matched.items():
        family = "bandai" if m.source.startswith("mocap/bandai/") else "cmu135"
        pose = frame_of(m, m.n_frames // 2)
        ch = Skeleton.from_motion(pose)
        for sem in SEMANTICS:
            j = int(np.flatnonzero((db.semantics == sem) & (src == family))[-1])
            # the exact optimum of Eq. 1's d: the paper's pruning keeps the nearest cluster only, and which
            # clusters k-means makes moves with the actors' sizes (Bandai's stature, issue 25)
            res = r.search(db.hit_position[j] * ch.size / db.size_a[j], pose, ch, sem, method="exact")
            assert res.semantics == sem and src[res.clip] == family, name
            assert np.isfinite(res.d) and res.d_cr < 0.1, name


@pytest.mark.data("cmu-bvh")
def test_match_rest_pose_on_cmu_subjects(real_db):
    actor = real_db.actors[0]
    for rel in ("mocap/cmu/131_01.bvh", "mocap/cmu/07_05.bvh", "mocap/cmu/09_06.bvh"):
        m = non_fighting_poses(takes=[rel])[rel.split("/")[-1][:-4]]
        m = dataclasses.replace(m, rotations=m.rotations[::10], positions=m.positions[::10])
        out, err = match_rest_pose(m, actor, return_error=True)
        # same joint positions, same bone lengths, the actor's rest directions
        assert err < 1e-9
        np.testing.assert_allclose(out.global_positions(), m.global_positions(), atol=1e-9)
        src, new = Skeleton.from_motion(m), Skeleton.from_motion(out)
        np.testing.assert_allclose(new.bone_lengths, src.bone_lengths, atol=1e-12)
        ok = actor.bone_lengths > 0
        cos = np.sum(new.offsets[ok] * actor.offsets[ok], axis=1) / (new.bone_lengths[ok] * actor.bone_lengths[ok])
        assert np.degrees(np.arccos(np.clip(cos.min(), -1, 1))) < 1e-3
        # retarget matches the rest pose itself (issue 25, item 5): the same as matching it first
        direct = retarget(frame_of(m, 0), actor)
        np.testing.assert_allclose(direct.global_positions(), retarget(frame_of(out, 0), actor).global_positions(),
                                   rtol=0, atol=1e-12)


def _rot(axis, deg):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.radians(deg) * np.asarray(axis, float) / np.linalg.norm(axis)).as_matrix()


@pytest.mark.data("bandai")
def test_match_rest_pose_exact_and_least_squares():
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_walk_normal_001.bvh"), unit_m=BANDAI_UNIT_M).to_metres()
    m = dataclasses.replace(m, rotations=m.rotations[::20], positions=m.positions[::20])
    sk = Skeleton.from_motion(m)
    rng = np.random.default_rng(0)
    hips = sk.joint_names.index("Hips")
    # (a) the children of every joint turned together: an exact change of rest pose
    Q = [np.eye(3) if j == 0 else _rot(rng.normal(size=3), 20.0) for j in range(sk.n_joints)]
    off = np.array([sk.offsets[c] if c == 0 else Q[sk.parents[c]] @ sk.offsets[c] for c in range(sk.n_joints)])
    eso = np.array([Q[p] @ o for p, o in zip(sk.end_site_parents, sk.end_site_offsets)]).reshape(-1, 3)
    ref = sk.with_offsets(off, eso)
    out, err = match_rest_pose(m, ref, return_error=True)
    # exact up to the file's own rounding: its constant position channels differ from the
    # OFFSETs by < 1e-7 m, and are replaced by the (new) offsets
    assert err < 1e-6
    # position channels: the root trajectory (Hips) kept, the constant ones follow the offsets
    np.testing.assert_allclose(out.positions[:, hips], m.positions[:, hips], atol=1e-12)
    np.testing.assert_allclose(out.positions[:, 2:], np.broadcast_to(out.offsets[2:], out.positions[:, 2:].shape))
    # (b) every bone turned on its own by up to 10 degrees: siblings change their angles,
    # the fit is least squares; rest directions and bone lengths are still exact
    off2 = np.array([sk.offsets[c] if c <= hips else _rot(rng.normal(size=3), 10.0) @ sk.offsets[c]
                     for c in range(sk.n_joints)])
    ref2 = sk.with_offsets(off2, sk.end_site_offsets)
    out2, err2 = match_rest_pose(m, ref2, return_error=True)
    new = Skeleton.from_motion(out2)
    np.testing.assert_allclose(new.bone_lengths, sk.bone_lengths, atol=1e-12)
    ok = sk.bone_lengths > 0
    ok[: hips + 1] = False
    cos = np.sum(new.offsets[ok] * off2[ok], axis=1) / (new.bone_lengths[ok] * sk.bone_lengths[ok])
    assert cos.min() > 1 - 1e-9
    assert 0 < err2 < 0.1  # metres: the siblings of the chest and hips cannot all be kept
    from repro.motion.database.synthetic import synthetic_skeleton

    with pytest.raises(MotionError, match="joint tree"):
        match_rest_pose(m, synthetic_skeleton())


# ---------------------------------------------------------------- arguments checked before any file is read
@pytest.mark.parametrize("bad", [0, -1, math.nan, 10**12, "135_01", [1], object()])
def test_take_lists_are_checked_before_reading(bad):
    """A number, a lone string or non-string names raised TypeError ('int' object is not iterable)."""
    from repro.motion.database.sources import build_bandai_database, build_cmu_database, build_real_database, non_fighting_poses

    for call in (lambda: build_cmu_database(takes=bad), lambda: build_bandai_database(takes=bad),
                 lambda: build_real_database(cmu_takes=bad), lambda: build_real_database(bandai_takes=bad),
                 lambda: non_fighting_poses(takes=bad), lambda: non_fighting_poses(kinds=bad)):
        with pytest.raises(MotionError, match="takes|kinds"):
            call()


@pytest.mark.parametrize("bad", ["x", 0, -30.0, math.inf, 10**12, 1e300])
def test_non_fighting_poses_fps_is_checked(bad):
    """fps='x' raised TypeError, 10**12 asked numpy for 60 TiB, 1e300 a ValueError."""
    from repro.motion.database.sources import non_fighting_poses

    with pytest.raises(MotionError, match="fps"):
        non_fighting_poses(fps=bad)


def test_real_database_include_entries_must_be_source_names():
    from repro.motion.database.sources import build_real_database

    for bad in ([1], [np.zeros(2)], 5):
        with pytest.raises(MotionError, match="include"):
            build_real_database(include=bad)
