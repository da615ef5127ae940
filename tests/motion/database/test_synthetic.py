"""The synthetic kung-fu database: determinism, BVH round trip, and plausibility per clip.

The default database (3 actors x 25 clips) is generated once per module; every clip is
then regenerated from its manifest seed (so the annotation, with its contacts, is at
hand) and read back from its BVH file.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from repro.errors import MotionError
from repro.motion import read_bvh, read_manifest, synthetic_clip, synthetic_database, synthetic_skeleton
from repro.motion.database.annotation import hit_point_trajectory
from repro.motion.core.quaternion import quat_multiply
from repro.motion.database.synthetic import (
    ELBOW_FLEXION_LIMITS_DEG,
    HINGE_AXES,
    HIT_LEVELS,
    JOINT_NAMES,
    KINDS,
    KNEE_FLEXION_LIMITS_DEG,
    MANIFEST_COLUMNS,
    MANIFEST_NAME,
    REFERENCE_HEIGHT_M,
    SIDES,
    STRIKE_KINDS,
    TARGET_HEIGHT_FRACTION,
    database_actor_heights,
)

# the joint names other code (the role mapper) relies on, spelled out independently
EXPECTED_JOINTS = [
    "Hips", "Spine", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
]  # fmt: skip
SLIDE_TOL_M = 0.01  # the brief: a planted foot slides less than 1 cm
GROUND_TOL_M = 0.01  # nothing below y = -1 cm


@dataclasses.dataclass
class Clip:
    record: dict  # manifest row
    path: Path
    generated: object  # Motion from synthetic_clip(clip_seed)
    ann: dict
    read: object  # Motion from read_bvh(path)

    @property
    def name(self) -> str:
        return self.record["file"]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    return synthetic_database(tmp_path_factory.mktemp("synthetic_db"))


@pytest.fixture(scope="module")
def clips(db) -> list[Clip]:
    out = []
    for rec, path in zip(db.records, db.paths):
        motion, ann = synthetic_clip(rec["kind"], rec["side"], rec["level"], rec["actor_height_m"],
                                     seed=rec["clip_seed"])  # fmt: skip
        out.append(Clip(rec, path, motion, ann, read_bvh(path, unit_m=1.0)))
    return out


def _strikes(clips):
    return [c for c in clips if c.record["kind"] in STRIKE_KINDS]


def _all_points(motion) -> np.ndarray:
    """(F, J + E, 3): joints and End Sites."""
    return np.concatenate([motion.global_positions(), motion.end_site_positions()], axis=1)


# ---------------------------------------------------------------- content and files
def test_database_has_every_kind_side_level_per_actor(db):
    recs = db.records
    assert len(recs) == len(db.paths) == 75
    heights = sorted({r["actor_height_m"] for r in recs})
    assert heights == pytest.approx([1.60, 1.75, 1.90])
    for h in heights:
        mine = [r for r in recs if r["actor_height_m"] == h]
        combos = {(r["kind"], r["side"], r["level"]) for r in mine if r["kind"] != "stance"}
        assert combos == set(itertools.product(STRIKE_KINDS, SIDES, HIT_LEVELS))
        assert sum(r["kind"] == "stance" for r in mine) == 1
    assert {r["kind"] for r in recs} == set(KINDS)
    semantics = {r["kind"]: r["semantics"] for r in recs}
    assert semantics == {"punch": "punch", "kick_front": "kick", "kick_side": "kick", "kick_round": "kick",
                         "stance": "other"}  # fmt: skip
    for r in recs:
        assert (db.manifest_path.parent / r["file"]).is_file()
        if r["kind"] == "stance":
            assert r["hit_frame"] == -1 and r["hit_joint"] == "" and r["hit_y_m"] is None
        else:
            side = "Left" if r["side"] == "left" else "Right"
            assert r["hit_joint"].startswith(side)
            assert 0 < r["hit_frame"] < r["frames"] - 1
    assert len({r["file"] for r in recs}) == 75
    header = db.manifest_path.read_text().splitlines()[0].split(",")
    assert tuple(header) == MANIFEST_COLUMNS
    assert [p.name for p in sorted(db.manifest_path.parent.iterdir())] == sorted([r["file"] for r in recs]
                                                                                  + [MANIFEST_NAME])  # fmt: skip


def test_generation_is_deterministic_to_the_byte(db, tmp_path):
    again = synthetic_database(tmp_path / "again")
    for a, b in zip(db.paths + [db.manifest_path], again.paths + [again.manifest_path]):
        assert a.name == b.name
        assert a.read_bytes() == b.read_bytes(), a.name
    m1, _ = synthetic_clip("kick_side", "left", "high", 1.7, seed=11)
    m2, _ = synthetic_clip("kick_side", "left", "high", 1.7, seed=11)
    m3, _ = synthetic_clip("kick_side", "left", "high", 1.7, seed=12)
    assert np.array_equal(m1.rotations, m2.rotations) and np.array_equal(m1.positions, m2.positions)
    assert m1.n_frames != m3.n_frames or not np.allclose(m1.rotations, m3.rotations)


def test_other_seed_gives_other_clips(db, tmp_path):
    other = synthetic_database(tmp_path / "other", n_actors=1, seed=1)
    mine = {r["file"]: r["sha256"] for r in db.records}
    assert all(mine[r["file"]] != r["sha256"] for r in other.records)


def test_manifest_matches_files_and_reader(db):
    rows = read_manifest(db.manifest_path, verify=True)
    assert rows == db.records
    for r in rows:
        assert isinstance(r["hit_frame"], int) and isinstance(r["frames"], int)
        assert r["frame_time"] == pytest.approx(1 / 60, rel=1e-10)


def test_files_read_back_equal_the_generated_motions(clips):
    for c in clips:
        g, r = c.generated, c.read
        assert r.joint_names == EXPECTED_JOINTS == list(JOINT_NAMES)
        assert r.n_frames == g.n_frames == c.record["frames"]
        assert r.frame_time == pytest.approx(g.frame_time, rel=1e-10)
        assert r.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
        assert all(ch == ("Zrotation", "Xrotation", "Yrotation") for ch in r.channels[1:])
        assert np.abs(r.global_positions() - g.global_positions()).max() < 1e-6, c.name
        assert np.abs(r.end_site_positions() - g.end_site_positions()).max() < 1e-6, c.name
        if c.ann["hit_frame"] >= 0:  # the manifest's hit point is where the file puts it
            hp = hit_point_trajectory(r, c.ann["hit_joint"], c.ann["hit_point"])[c.ann["hit_frame"]]
            assert hp == pytest.approx([c.record["hit_x_m"], c.record["hit_y_m"], c.record["hit_z_m"]], abs=2e-6)
            assert hp == pytest.approx(c.ann["hit_position"], abs=1e-6)


# ---------------------------------------------------------------- plausibility
def test_planted_feet_do_not_slide(clips):
    for c in clips:
        gp = c.read.global_positions()
        F = c.read.n_frames
        contacts = c.ann["contacts"]
        for foot, runs in contacts.items():
            assert runs, (c.name, foot)
            for start, stop in runs:
                joints = [foot, foot.replace("Foot", "ToeBase")] if foot.endswith("Foot") else [foot]
                for name in joints:
                    p = gp[start:stop, c.read.joint_index(name)]
                    slide = np.linalg.norm(p - p[0], axis=1).max()
                    assert slide < SLIDE_TOL_M, (c.name, name, start, stop, slide)
                    assert slide < 1e-6, (c.name, name, slide)  # by construction (leg IK)
                ball = gp[start:stop, c.read.joint_index(foot.replace("Foot", "ToeBase"))]
                assert np.abs(ball[:, 1]).max() < 1e-6  # the ball of the foot is on the ground
        kind = c.record["kind"]
        if kind in ("punch", "stance"):
            assert all(runs == [(0, F)] for runs in contacts.values()), c.name
        else:
            support = c.ann["support_foot"]
            kicker = c.record["hit_joint"].replace("ToeBase", "Foot")
            assert support != kicker and support[:4] != kicker[:4]
            assert contacts[support] == [(0, F)]
            (a0, a1), (b0, b1) = contacts[kicker]
            assert a0 == 0 and a1 < c.record["hit_frame"] < b0 and b1 == F
            # the ball stays down a little longer than the flat foot (heel-off, heel-down)
            (t0, t1), (u0, u1) = contacts[kicker.replace("Foot", "ToeBase")]
            assert t0 == 0 and a1 < t1 < c.record["hit_frame"] < u0 < b0 and u1 == F


def test_nothing_goes_below_the_ground(clips):
    lowest = min(_all_points(c.read)[..., 1].min() for c in clips)
    assert lowest >= -GROUND_TOL_M
    assert lowest >= -0.002  # what the generator achieves (toe tips near lift-off and touch-down)


def test_elbows_and_knees_are_hinges_within_limits(clips):
    for c in clips:
        m = c.read
        gp = m.global_positions()
        for joint, axis in HINGE_AXES.items():
            lo, hi = ELBOW_FLEXION_LIMITS_DEG if "Arm" in joint else KNEE_FLEXION_LIMITS_DEG
            rv = Rotation.from_quat(m.rotations[:, m.joint_index(joint)]).as_rotvec()
            flex = np.degrees(rv @ np.array(axis))
            off_axis = np.linalg.norm(rv - np.outer(rv @ np.array(axis), axis), axis=1)
            assert off_axis.max() < 1e-6, (c.name, joint)  # one axis: no twist, no sideways bend
            assert flex.min() >= lo - 1e-6 and flex.max() <= hi + 1e-6, (c.name, joint, flex.min(), flex.max())
            # the same from the world positions: angle between the two bones
            j = m.joint_index(joint)
            upper, lower = gp[:, j] - gp[:, m.parents[j]], gp[:, j + 1] - gp[:, j]
            cosang = np.sum(upper * lower, 1) / np.linalg.norm(upper, axis=1) / np.linalg.norm(lower, axis=1)
            assert np.degrees(np.arccos(np.clip(cosang, -1, 1))) == pytest.approx(np.abs(flex), abs=1e-4)


def test_knees_bend_backwards_and_elbows_forwards():
    """Positive flexion about the hinge axes bends the shin back and the forearm forward (rest pose)."""
    m = synthetic_skeleton()
    for joint, axis in HINGE_AXES.items():
        child_offset = np.array(m.offsets[m.joint_index(joint) + 1])
        bent = Rotation.from_rotvec(np.radians(90) * np.array(axis)).apply(child_offset)
        if "Leg" in joint:
            assert bent[2] < -0.9 * np.linalg.norm(child_offset)  # shin to -Z (behind)
        else:
            assert bent[2] > 0.9 * np.linalg.norm(child_offset)  # forearm to +Z (in front)


def test_bone_lengths_are_constant(clips):
    for c in clips:
        m = c.read
        gq, gp = m.global_transforms()
        rel = gp[:, 1:] - gp[:, m.parents[1:]]
        lengths = np.linalg.norm(rel, axis=2)
        assert np.abs(lengths - np.linalg.norm(m.offsets[1:], axis=1)).max() < 1e-6, c.name
        es = m.end_site_positions() - gp[:, m.end_site_parents]
        assert np.abs(np.linalg.norm(es, axis=2) - np.linalg.norm(m.end_site_offsets, axis=1)).max() < 1e-9


def _hit_geometry(c: Clip):
    m = c.read
    joint, where = c.ann["hit_joint"], c.ann["hit_point"]
    traj = hit_point_trajectory(m, joint, where)
    side = joint[:4] if joint.startswith("Left") else joint[:5]
    if c.record["semantics"] == "punch":
        base = side + "Arm"
        chain = [side + "ForeArm", side + "Hand"]
        extra = np.linalg.norm(m.end_site_offsets[list(m.end_site_parents).index(m.joint_index(joint))])
    else:
        base = side + "UpLeg"
        chain = [side + "Leg", side + "Foot"] + ([side + "ToeBase"] if joint.endswith("ToeBase") else [])
        extra = 0.0
    length = sum(np.linalg.norm(m.offsets[m.joint_index(n)]) for n in chain) + extra
    dist = np.linalg.norm(traj - m.global_positions()[:, m.joint_index(base)], axis=1)
    speed = np.linalg.norm(np.diff(traj, axis=0), axis=1) / m.frame_time  # speed[f]: frame f -> f + 1
    return traj, dist, length, speed


def test_hit_frame_is_full_extension_after_a_speed_peak(clips):
    for c in _strikes(clips):
        h = c.record["hit_frame"]
        traj, dist, length, speed = _hit_geometry(c)
        assert abs(int(np.argmax(dist)) - h) <= 1, (c.name, np.argmax(dist), h)  # farthest at the hit
        assert dist[h] >= 0.97 * length, (c.name, dist[h] / length)  # near full extension
        peak = int(np.argmax(speed))  # fastest over the whole clip, just before the hit
        assert h - 8 <= peak <= h - 1, (c.name, peak, h)
        assert speed[h - 1] < 0.7 * speed[peak] and speed[h] < 0.2 * speed[peak]  # decelerates into the hit
        assert 5.0 < speed[peak] < 20.0, (c.name, speed[peak])  # m/s: a fast but human strike


def test_hit_height_follows_the_level(clips):
    by = {}
    for c in _strikes(clips):
        r = c.record
        H = r["actor_height_m"]
        frac = TARGET_HEIGHT_FRACTION[r["semantics"]][r["level"]]
        assert r["hit_y_m"] == pytest.approx(c.ann["target_height_m"], abs=1e-5)
        assert abs(r["hit_y_m"] / H - frac) <= 0.02 + 1e-6, (c.name, r["hit_y_m"] / H)
        by[(H, r["kind"], r["side"], r["level"])] = r["hit_y_m"]
    for H, kind, side in {k[:3] for k in by}:
        hi, mid, lo = (by[(H, kind, side, lv)] for lv in HIT_LEVELS)
        assert hi > mid + 0.1 > lo + 0.2, (H, kind, side, hi, mid, lo)


def test_no_pose_flips_between_frames(clips):
    """Every local rotation changes by less than 45 degrees per frame (60 fps): no IK flips."""
    for c in clips:
        q = c.read.rotations
        d = quat_multiply(q[1:] * np.array([-1.0, -1.0, -1.0, 1.0]), q[:-1])
        step = 2 * np.degrees(np.arccos(np.clip(np.abs(d[..., 3]), 0, 1)))
        assert step.max() < 45.0, (c.name, c.read.joint_names[int(np.argmax(step.max(0)))], step.max())
        root = c.read.positions[:, 0]
        assert np.linalg.norm(np.diff(root, axis=0), axis=1).max() / c.read.frame_time < 3.0  # m/s


def test_clips_start_and_end_in_the_same_stance(clips):
    for c in clips:
        gp = c.read.global_positions()
        assert np.abs(gp[0] - gp[-1]).max() < 1e-6, c.name


# ---------------------------------------------------------------- actor size
def test_actor_height_scales_the_skeleton_proportionally(clips):
    ref = synthetic_skeleton()
    assert _all_points(ref)[0, :, 1].max() == pytest.approx(REFERENCE_HEIGHT_M)  # head top at rest
    assert _all_points(ref)[0, :, 1].min() == pytest.approx(0.0, abs=1e-12)  # soles on the ground
    for h in (1.5, 1.6, 1.9, 2.05):
        sk = synthetic_skeleton(h)
        assert np.allclose(sk.offsets, ref.offsets * h / REFERENCE_HEIGHT_M, atol=1e-12)
        assert np.allclose(sk.end_site_offsets, ref.end_site_offsets * h / REFERENCE_HEIGHT_M, atol=1e-12)
        assert _all_points(sk)[0, :, 1].max() == pytest.approx(h)
    for c in clips:
        k = c.record["actor_height_m"] / REFERENCE_HEIGHT_M
        assert np.allclose(c.read.offsets, ref.offsets * k, atol=1e-9), c.name
    assert database_actor_heights(3) == [1.6, 1.75, 1.9]


def test_other_frame_rate_and_height():
    m, ann = synthetic_clip("punch", "left", "high", actor_height=1.55, seed=4, fps=30)
    assert m.frame_time == pytest.approx(1 / 30) and ann["fps"] == 30
    assert ann["hit_position"][1] == pytest.approx(ann["target_height_m"], abs=1e-5)
    assert 0.85 * 1.55 < ann["target_height_m"] < 0.95 * 1.55
    dist = np.linalg.norm(hit_point_trajectory(m, "LeftHand", "end_site") - m.global_positions()[:, 6], axis=1)
    assert abs(int(np.argmax(dist)) - ann["hit_frame"]) <= 1


def test_stance_clip():
    m, ann = synthetic_clip("stance", "right", actor_height=1.8, seed=2)
    assert ann["semantics"] == "other" and ann["level"] == "none"
    assert ann["hit_frame"] == -1 and ann["hit_joint"] == "" and ann["hit_position"] is None
    assert 1.5 < m.duration < 2.5
    gp = m.global_positions()
    assert np.ptp(gp[:, 0], axis=0).max() > 0.005  # it does sway


# ---------------------------------------------------------------- writing policy and errors
def test_rerun_is_a_noop_and_changed_files_are_not_overwritten(tmp_path):
    out = tmp_path / "db"
    first = synthetic_database(out, n_actors=1, seed=3)
    assert len(first.paths) == 25
    stamps = {p: os.stat(p).st_mtime_ns for p in first.paths}
    second = synthetic_database(out, n_actors=1, seed=3)  # same arguments: nothing to do
    assert second.records == first.records
    assert {p: os.stat(p).st_mtime_ns for p in first.paths} == stamps
    (out / "notes.txt").write_text("mine")
    victim = first.paths[4]
    victim.write_text("edited by hand\n")
    manifest_before = first.manifest_path.read_bytes()
    with pytest.raises(FileExistsError, match="overwrite=True"):
        synthetic_database(out, n_actors=1, seed=3)
    assert victim.read_text() == "edited by hand\n"  # untouched
    with pytest.raises(FileExistsError):
        synthetic_database(out, n_actors=1, seed=4)  # another seed: every file differs
    assert first.manifest_path.read_bytes() == manifest_before
    with pytest.raises(MotionError, match="sha256"):
        read_manifest(first.manifest_path, verify=True)
    third = synthetic_database(out, n_actors=1, seed=3, overwrite=True)
    assert victim.read_bytes() == (tmp_path / "db").joinpath(victim.name).read_bytes()
    assert read_manifest(third.manifest_path, verify=True) == first.records
    assert (out / "notes.txt").read_text() == "mine"  # foreign files are left alone
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []  # no staging left


@pytest.mark.parametrize(
    "kwargs",
    [
        {"kind": "hook"},
        {"kind": "punch", "side": "both"},
        {"kind": "kick_front", "level": "head"},
        {"kind": "punch", "actor_height": 0.3},
        {"kind": "punch", "actor_height": float("nan")},
        {"kind": "punch", "fps": 10},
    ],
)
def test_bad_clip_arguments(kwargs):
    with pytest.raises(MotionError):
        synthetic_clip(**kwargs)


@pytest.mark.parametrize("kwargs", [{"n_actors": 0}, {"n_actors": 2.5}, {"seed": -1}, {"seed": "x"}])
def test_bad_database_arguments(tmp_path, kwargs):
    with pytest.raises(MotionError):
        synthetic_database(tmp_path / "x", **kwargs)
    assert not (tmp_path / "x").exists()


def test_manifest_reader_rejects_bad_files(tmp_path):
    p = tmp_path / MANIFEST_NAME
    p.write_text("file,kind\na.bvh,punch\n")
    with pytest.raises(MotionError, match="lacks column"):
        read_manifest(p)
    p.write_text(",".join(MANIFEST_COLUMNS) + "\n" + ",".join(["x"] * len(MANIFEST_COLUMNS)) + "\n")
    with pytest.raises(MotionError, match="line 2"):
        read_manifest(p)
