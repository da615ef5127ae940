"""Retargeting across joint trees (repro.motion.retargeting.trees; issue 11, item 3; the plan, issue 13, item 4).

What is asserted:

* a clip played by every synthetic rig convention (extra spine joints, twist bones, fingers,
  A-pose, Z up) puts the body parts where the source put them; another stature keeps the
  character's bones and the limbs' directions; joints without a role keep their rest
  rotation; the result writes and reads back as BVH; real CMU and Bandai Namco skeletons
  each way; a rest pose lying and twisted gives the same body; Bandai on CMU keeps its
  heading; ``fix_feet`` pins planted feet above the floor;
* ``retarget_across`` is ``TreePlan(...).apply(...)``; ``TreePlan(motion, character, ...).positions``
  equals ``retarget_across(motion, character, ...).global_positions()`` (``assert_allclose``,
  rtol and atol 1e-12) on one frame and whole clips, with and without the source's world
  transforms given: every synthetic rig convention onto the synthetic actor's Y-up rest pose
  (the ``prepare`` case) and the synthetic clips onto every rig (Y and Z up); real CMU and
  Bandai Namco skeletons each way; the pybvh fixtures (another tool's files) onto the
  synthetic actor;
* the plan refuses what ``retarget_across`` refuses (it builds the plan), with its MotionError;
* the constants cached per pair of skeletons give the numbers of a fresh computation, and a
  character of other proportions gets its own entry;
* ``MotionRetriever.prepare`` across trees gives the cloud of ``retarget_to_tree`` bit for
  bit, caches one plan per (actor, pose skeleton, roles), gives a pose on another skeleton
  its own plan, keeps at most 64, and turns a refusal into the RetrievalError it raised
  before (the MotionError's text, the character remembered as refused);
* bad arguments raise MotionError.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError, RetrievalError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh, retarget, write_bvh
from repro.motion.body.pose_frames import pose_points
from repro.motion.body.skeleton import Skeleton, scale_skeleton, skeleton_of
from repro.motion.core.cache import LRUCache
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import CONVENTIONS, Z_UP, build
from repro.motion.retargeting.dispatch import rest_motion_y_up, retarget_to_tree
from repro.motion.retargeting.trees import TreePlan, body_frame, rest_axes, retarget_across
from repro.motion.search.retrieval import MotionRetriever

Z_UP_CONVENTIONS = {"biped", "unreal"}
ROLES = ("pelvis", "chest", "head", "left_shoulder", "right_elbow", "right_wrist", "left_wrist",
         "left_knee", "right_ankle", "left_ankle", "right_toe")  # fmt: skip


@pytest.fixture(scope="module")
def clips():
    return [synthetic_clip(k, seed=3)[0] for k in ("punch", "kick_round")]


def _role_positions(m, roles, up_z=False):
    sk = skeleton_of(m)
    g = m.global_positions()
    out = np.stack([g[:, m.joint_names.index(sk.roles[r])] for r in roles], axis=1)
    if up_z:  # back to the synthetic world (Y up)
        out = Z_UP.inv().apply(out.reshape(-1, 3)).reshape(out.shape)
    return out


def _read(path, unit=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_bvh(path, unit_m=unit)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_same_body_other_tree_reproduces_positions(clips, convention):
    # extra spine joints, twist bones, fingers, face joints, zero-length helpers, A-pose, Z-up:
    # the body parts land where the source put them, to 0.1 mm
    character = build(convention)[0].motion(unit_m=1.0)
    for clip in clips:
        out = retarget(clip, character)
        assert out.joint_names == character.joint_names
        np.testing.assert_allclose(
            _role_positions(out, ROLES, convention in Z_UP_CONVENTIONS), _role_positions(clip, ROLES), atol=1e-4
        )


def test_renamed_skeleton_reproduces_every_joint(clips):
    clip = clips[0]
    names = ["jnt_" + n.replace("Left", "L_").replace("Right", "R_") for n in clip.joint_names]
    character = dataclasses.replace(clip, joint_names=names)
    out = retarget(clip, character)
    assert out.joint_names == names
    np.testing.assert_allclose(out.global_positions(), clip.global_positions(), atol=1e-4)


@pytest.mark.parametrize("convention", ["motionbuilder", "smpl", "unreal", "secondlife"])
@pytest.mark.parametrize("height", [1.2, 2.2])
def test_other_stature(clips, convention, height):
    character = build(convention, height=height)[0].motion(unit_m=1.0)
    clip = clips[1]
    out = retarget(clip, character)
    # the character's own bones, exactly
    np.testing.assert_array_equal(out.offsets, character.offsets)
    g = out.global_positions()
    parents = out.parents
    lengths = np.linalg.norm(g[:, 1:] - g[:, parents[1:]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(out.offsets[1:], axis=1), lengths.shape), atol=1e-9)
    # the limbs point the same way (normalised limb vectors of Kulpa et al.)
    zu = convention in Z_UP_CONVENTIONS
    s = _role_positions(clip, ("right_shoulder", "right_wrist", "left_hip", "left_ankle"))
    t = _role_positions(out, ("right_shoulder", "right_wrist", "left_hip", "left_ankle"), zu)
    for a, b in ((0, 1), (2, 3)):
        u, v = s[:, b] - s[:, a], t[:, b] - t[:, a]
        cos = np.sum(u * v, -1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(v, axis=-1)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3
    # the pelvis height scales with the hip height
    k = skeleton_of(character).hip_height / Skeleton.from_motion(clip).hip_height
    np.testing.assert_allclose(t[:, 2], s[:, 2] * k, atol=0.02 * height)


def test_result_writes_and_reads_back(clips, tmp_path):
    character = build("unreal")[0].motion(unit_m=1.0)
    out = retarget(clips[0], character)
    back = read_bvh(write_bvh(out, tmp_path / "unreal.bvh"), unit_m=1.0)
    assert back.joint_names == out.joint_names
    np.testing.assert_allclose(back.global_positions(), out.global_positions(), atol=1e-6)


def test_unroled_joints_keep_rest_rotation(clips):
    character = build("mixamo")[0].motion(unit_m=1.0)
    out = retarget(clips[0], character)
    for n in ("mixamorig:LeftHandIndex2", "mixamorig:HeadTop_End", "mixamorig:RightToe_End"):
        q = out.rotations[:, out.joint_names.index(n)]
        np.testing.assert_allclose(np.abs(q[:, 3]), 1.0, atol=1e-12)


def test_bad_characters(clips):
    rig = build("mixamo")[0]
    m = rig.motion(unit_m=1.0)
    keep = [j for j, n in enumerate(m.joint_names) if "Arm" not in n and "Hand" not in n and "Shoulder" not in n]
    # a character without arms: the roles it lacks are named
    with pytest.raises(MotionError, match="left_shoulder|arm"):
        Skeleton([m.joint_names[j] for j in keep], np.array([-1] + [keep.index(m.parents[j]) for j in keep[1:]]),
                 m.offsets[keep])
    no_pos = dataclasses.replace(m, channels=[("Zrotation", "Xrotation", "Yrotation")] * m.n_joints)
    with pytest.raises(MotionError, match="no position channels"):
        retarget_across(clips[0], no_pos)
    with pytest.raises(MotionError, match="Skeleton or a Motion"):
        retarget(clips[0], "mixamo")


@pytest.mark.data("cmu-bvh")
@pytest.mark.data("bandai")
def test_real_cmu_and_bandai_swap_skeletons():
    cmu = _read(data.fetch("mocap/cmu/135_04.bvh"), CMU_UNIT_M)
    cmu = dataclasses.replace(cmu, rotations=cmu.rotations[:120], positions=cmu.positions[:120])
    bandai = _read(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), BANDAI_UNIT_M)
    for src, tgt in ((cmu, bandai), (bandai, cmu)):
        out = retarget(src, tgt)
        assert out.joint_names == tgt.joint_names and out.n_frames == src.n_frames
        g = out.global_positions()
        lengths = np.linalg.norm(g[:, 1:] - g[:, out.parents[1:]], axis=-1)
        np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(tgt.offsets[1:], axis=1), lengths.shape),
                                   atol=1e-6 * skeleton_of(tgt).height)


def _rest_rotated(m, q):
    """``m`` on a rig whose rest pose is the original one turned rigidly by rotation ``q``
    (Bandai Namco's lies along +X): offsets ``q o``, local rotations ``q L q^-1``, the root's
    ``G q^-1``; the same body and the same world positions."""
    from scipy.spatial.transform import Rotation

    Q = Rotation.from_quat(q)
    rot = (Q * Rotation.from_quat(np.array(m.rotations).reshape(-1, 4)) * Q.inv()).as_quat().reshape(m.rotations.shape)
    rot[:, 0] = (Rotation.from_quat(np.array(m.rotations[:, 0])) * Q.inv()).as_quat()
    pos = Q.apply(np.array(m.positions).reshape(-1, 3)).reshape(m.positions.shape)
    pos[:, 0] = m.positions[:, 0]
    return dataclasses.replace(m, offsets=Q.apply(np.array(m.offsets)), rotations=rot, positions=pos,
                               end_site_offsets=Q.apply(np.array(m.end_site_offsets).reshape(-1, 3)).reshape(-1, 3), up="y")


def test_a_rest_pose_lying_and_twisted_gives_the_same_body(clips):
    """The twist about each bone comes from the rest frames, not from the bone directions alone:
    a character whose rest pose is the source's lying along +X and rolled about it (every
    bone direction changed, hips and shoulders turned about the trunk) plays the clip with
    the same world joint positions (0.1 mm)."""
    from scipy.spatial.transform import Rotation

    q = (Rotation.from_euler("x", 90, degrees=True) * Rotation.from_euler("z", -90, degrees=True)).as_quat()
    for clip in clips:
        lying = _rest_rotated(clip, q)
        np.testing.assert_allclose(lying.global_positions(), clip.global_positions(), atol=1e-9)
        assert abs(Skeleton.from_motion(lying).trunk_axis[1]) < 1e-9  # the rest trunk is horizontal
        out = retarget_across(clip, lying)
        err = np.abs(out.global_positions() - clip.global_positions()).max()
        assert err < 1e-4, err


@pytest.mark.data("cmu-bvh", "bandai")
def test_bandai_clip_on_cmu_keeps_its_heading():
    """Bandai Namco's rest pose lies along +X with the pelvis' left along -Y and the chest's
    along +Z: the retargeted CMU pelvis faces where the Bandai one does, every frame."""
    from repro.motion.body.pose_frames import root_frames

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmu = read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)
        ban = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    out = retarget(ban, cmu)
    heads = []
    for m in (ban, out):
        sk = Skeleton.from_motion(m)
        th, _ = root_frames(m.global_positions(), sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip"))
        heads.append(th)
    d = np.degrees(np.angle(np.exp(1j * (heads[1] - heads[0]))))
    # (the constant 1.2 deg: CMU's rest hips and shoulders face 1.2 deg off +Z, body_frame's map)
    assert np.abs(d - d[0]).max() < 1.0 and abs(d[0]) < 2.0, (d[0], np.abs(d - d[0]).max())


@pytest.mark.parametrize("convention", ["mixamo", "unreal"])  # Y-up and Z-up characters
def test_fix_feet_across_trees(clips, convention):
    """retarget(..., fix_feet=True) onto another tree: planted ankles stay put (the source's
    contacts), no ankle/toe below the floor -- even for a source sunk 5 cm into it."""
    from repro.motion.body.feet import foot_contacts, max_foot_slide

    ch = build(convention, height=1.6)[0].motion(unit_m=1.0)
    k = 2 if convention in Z_UP_CONVENTIONS else 1
    for clip in clips:
        sunk = dataclasses.replace(clip, positions=clip.positions - np.array([0.0, 0.05, 0.0]))
        contacts = foot_contacts(sunk)
        assert contacts.any()
        plain, fixed = retarget(sunk, ch), retarget(sunk, ch, fix_feet=True)
        sk = skeleton_of(fixed)
        feet = [sk.index(r) for r in ("left_ankle", "right_ankle", "left_toe", "right_toe")]
        assert plain.global_positions()[:, feet, k].min() < -0.01  # the representation alone sinks
        assert fixed.global_positions()[:, feet, k].min() > -1e-9
        up = ["x", "y", "z"][k]
        slide = max_foot_slide(fixed, contacts, skeleton=sk, up_axis=k)
        assert slide < 1e-9, (up, slide)
        # bones keep their lengths
        g = fixed.global_positions()
        bl = np.linalg.norm(g[:, 1:] - g[:, fixed.parents[1:]], axis=-1)
        np.testing.assert_allclose(bl, np.broadcast_to(np.linalg.norm(fixed.offsets[1:], axis=1), bl.shape), atol=1e-9)


# ---------------------------------------------------------------- the plan (TreePlan)
TOL = dict(rtol=1e-12, atol=1e-12)


def frames(m, sl):
    return dataclasses.replace(m, rotations=m.rotations[sl], positions=m.positions[sl])


def check(motion, character, roles=None, character_roles=None):
    """The plan's positions against retarget_across's, on one frame, three frames and the whole motion."""
    plan = TreePlan(motion, character, roles=roles, character_roles=character_roles)
    F = motion.n_frames
    for sl in (slice(F // 2, F // 2 + 1), slice(0, 3), slice(None)):
        m = frames(motion, sl)
        ref = retarget_across(m, character, roles=roles, character_roles=character_roles).global_positions()
        got = plan.positions(m.rotations, m.local_translations())
        assert got.shape == ref.shape
        np.testing.assert_allclose(got, ref, **TOL)
        got2 = plan.positions(m.rotations, m.local_translations(), source=m.global_transforms())
        np.testing.assert_allclose(got2, ref, **TOL)
    return plan


@pytest.fixture(scope="module")
def clip():
    return synthetic_clip("punch", seed=3)[0]


@pytest.mark.parametrize("convention", list(CONVENTIONS))
def test_rig_pose_onto_actor_rest(synthetic_db, convention):
    """The prepare case: a character of another tree, its pose onto the actor's Y-up rest pose."""
    db = synthetic_db
    actor = db.actors[0]
    rest = rest_motion_y_up(actor)
    rig = build(convention)[0].motion(unit_m=1.0)
    m = retarget(db.motion(3), rig)
    m = m if m.up is not None else dataclasses.replace(m, up="y")
    ch = Skeleton.from_motion(m)
    check(m, rest, roles=dict(ch.roles), character_roles=dict(actor.roles))


@pytest.mark.parametrize("convention", list(CONVENTIONS))
def test_clip_onto_rig(clip, convention):
    """The other way: the synthetic clip played by every rig (some Z up, other rest poses)."""
    rig = build(convention)[0].motion(unit_m=1.0)
    check(clip, rig)


@pytest.mark.data("cmu-bvh")
@pytest.mark.data("bandai")
def test_real_cmu_and_bandai():
    cmu = frames(_read(data.fetch("mocap/cmu/135_04.bvh"), CMU_UNIT_M), slice(0, 40))
    bandai = frames(_read(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), BANDAI_UNIT_M), slice(0, 40))
    for src, tgt in ((cmu, bandai), (bandai, cmu)):
        check(src, tgt)
        check(src, rest_motion_y_up(tgt), character_roles=dict(Skeleton.from_motion(tgt).roles))


def test_pybvh_fixtures_onto_the_actor(synthetic_db):
    d = data.data_dir() / "mocap/formats/pybvh"
    names = ("bvh_test1.bvh", "standard_skeleton.bvh", "rotation_first_root.bvh")
    if not all((d / n).exists() for n in names):
        pytest.skip("the pybvh fixtures are not staged")
    actor = synthetic_db.actors[0]
    rest = rest_motion_y_up(actor)
    done = 0
    for n in names:
        m = _read(d / n, 0.0254)  # inches: what the unit inference finds for these files (its warning tested elsewhere)
        try:
            ref = retarget_across(m, rest, character_roles=dict(actor.roles))
        except MotionError as e:  # then the plan refuses it alike
            with pytest.raises(MotionError) as info:
                TreePlan(m, rest, character_roles=dict(actor.roles))
            assert str(info.value) == str(e)
            continue
        assert ref.n_frames == m.n_frames
        check(m, rest, character_roles=dict(actor.roles))
        done += 1
    assert done >= 1


def test_refusals_are_retarget_across_s(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    sk = Skeleton.from_motion(rig)
    off = np.array(sk.offsets)
    for r in ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "left_clavicle", "right_clavicle"):
        if r in sk.roles:
            off[sk.index(r), 0] = 0.0  # no left-right extent: the facing cannot be told
    flat = dataclasses.replace(sk, offsets=off)
    no_pos = dataclasses.replace(sk, channels=[("Zrotation", "Xrotation", "Yrotation")] + list(sk.channels[1:]))
    for bad in (flat, no_pos, "mixamo"):
        with pytest.raises(MotionError) as ref:
            retarget_across(clip, bad)
        with pytest.raises(MotionError) as got:
            TreePlan(clip, bad)
        assert str(got.value) == str(ref.value)
    with pytest.raises(MotionError, match="must be a Motion"):
        TreePlan(sk, rig)


def cloud(db, actor, g):
    idx = [actor.index(r) for r in db.pose_roles]
    return pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                       window=db.window, step=db.step)[-1] / actor.size


def as_prepared(pose):
    """The window prepare retargets: the pose, or a new Motion of it when renormalising changes its bits."""
    R = pose.rotations
    return pose if np.array_equal(R / np.linalg.norm(R, axis=-1, keepdims=True), R) else frames(pose, slice(None))


def test_prepare_across_trees_uses_cached_plans(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rng = np.random.default_rng(11)
    n = 0
    for convention in ("mixamo", "unreal", "smpl"):
        rig = build(convention)[0].motion(unit_m=1.0)
        for _ in range(3):
            m = retarget(db.motion(int(rng.integers(db.n_clips))), rig)
            f = int(rng.integers(m.n_frames))
            pose = frames(m, slice(f, f + 1))
            ch = Skeleton.from_motion(m)
            q = r.prepare(pose, ch)
            qr = retarget_to_tree(as_prepared(pose), actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
            assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))
        n += 1
        assert len(r._tree_plans) == n  # one plan per skeleton, reused by its poses
    plan = next(iter(r._tree_plans.values()))
    pose_again = frames(retarget(db.motion(0), build("mixamo")[0].motion(unit_m=1.0)), slice(0, 1))
    assert r.tree_plan(pose_again, 0, Skeleton.from_motion(pose_again).roles) is plan
    # a skeleton of other offsets (same joints) gets its own plan
    rig = build("mixamo")[0].motion(unit_m=1.0)
    longer = dataclasses.replace(rig, offsets=rig.offsets * 1.1)
    m = frames(retarget(db.motion(1), longer), slice(0, 1))
    ch = Skeleton.from_motion(m)
    q = r.prepare(m, ch)
    assert len(r._tree_plans) == n + 1
    qr = retarget_to_tree(as_prepared(m), actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
    assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))
    # bounded
    for k in range(70):
        mk = dataclasses.replace(m, offsets=m.offsets * (1.0 + 0.001 * (k + 1)))
        r.tree_plan(mk, 0, ch.roles)
    assert len(r._tree_plans) <= 64


def test_prepare_refusal_unchanged(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rig = build("mixamo")[0].motion(unit_m=1.0)
    m = frames(retarget(db.motion(2), rig), slice(0, 1))
    sk = Skeleton.from_motion(m)
    off = np.array(m.offsets)
    for role in ("left_hip", "right_hip", "left_shoulder", "right_shoulder", "left_clavicle", "right_clavicle"):
        off[sk.index(role), 0] = 0.0
    flat = dataclasses.replace(m, offsets=off)
    ch = Skeleton.from_motion(flat, roles=dict(sk.roles))
    with pytest.raises(MotionError) as ref:
        retarget_to_tree(flat, actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
    for _ in range(2):  # the second time from the refusal remembered for the character
        with pytest.raises(RetrievalError) as got:
            r.prepare(flat, ch)
        assert str(ref.value) in str(got.value)


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"blend_time": float("nan"), "fix_feet": True}, "blend_time"),  # was a ValueError in _fix_feet
        ({"blend_time": -1.0, "fix_feet": True}, "blend_time"),
        ({"blend_time": "x"}, "blend_time"),
        ({"fix_feet": "yes"}, "fix_feet"),
        ({"character_roles": ["a"]}, "character_roles"),  # was a bare exception
        ({"character_roles": {"pelvis": 3}}, "character_roles"),
        ({"roles": "pelvis"}, "roles"),
    ],
)
def test_retarget_across_checks_its_arguments(clip, kw, match):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(MotionError, match=match):
        retarget_across(clip, rig, **kw)
    if "blend_time" not in kw and "fix_feet" not in kw:
        with pytest.raises(MotionError, match=match):
            TreePlan(clip, rig, **kw)


def test_a_blend_longer_than_the_clip_is_the_whole_clip(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    a = retarget_across(clip, rig, fix_feet=True, blend_time=1.7e308)  # / frame_time = inf: used to overflow in round()
    b = retarget_across(clip, rig, fix_feet=True, blend_time=1e6)
    np.testing.assert_array_equal(a.rotations, b.rotations)


@pytest.mark.parametrize("call", [lambda sk: body_frame("sk", "y"), lambda sk: body_frame(sk, "x"),
                                  lambda sk: body_frame(sk, ["y"]), lambda sk: rest_axes(None)])
def test_body_frame_and_rest_axes_check_their_arguments(call):
    sk = Skeleton.from_motion(build("mixamo")[0].motion(unit_m=1.0))
    with pytest.raises(MotionError):
        call(sk)


def test_plans_check_the_source_transforms(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    plan = TreePlan(clip, rig)
    rot, tr = clip.rotations, clip.local_translations()
    for bad in ("x", (rot,), (np.zeros((2, 3, 4)), np.zeros((2, 3, 3))), [clip.global_transforms()]):
        with pytest.raises(MotionError, match="source"):  # "x" used to fail unpacking (ValueError)
            plan.positions(rot, tr, source=bad)
    np.testing.assert_array_equal(plan.positions(rot.tolist(), tr.tolist()), plan.positions(rot, tr))
    # found by the argument fuzzer: NaN results, overflow and division warnings, dropped imaginary parts
    for r, t, match in ((rot[:, :3], tr, "rotations"), (rot * 1e-300, tr, "unit quaternions"),
                        (rot * 1e300, tr, "unit quaternions"), (rot + 1j, tr, "complex"),
                        (rot, tr * 1e300, "translations beyond"), (rot, np.where(tr == tr.max(), np.nan, tr), "NaN")):
        with pytest.raises(MotionError, match=match):
            plan.positions(r, t)


def test_prepare_across_trees_equals_retarget_to_tree(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    rig = build("mixamo")[0].motion(unit_m=1.0)
    actor = db.actors[0]
    rng = np.random.default_rng(5)
    for _ in range(3):
        m = retarget(db.motion(int(rng.integers(db.n_clips))), rig)
        f = int(rng.integers(m.n_frames))
        pose = dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])
        ch = Skeleton.from_motion(m)
        q = r.prepare(pose, ch)
        qr = retarget_to_tree(pose, actor, roles=dict(ch.roles), target=rest_motion_y_up(actor))
        assert np.array_equal(q.q_n[0], cloud(db, actor, qr.global_positions()))


def test_retarget_across_constants_cached_per_pair(synthetic_db, monkeypatch):
    """The per-pair constants of retarget_across give the numbers of a fresh computation, and a
    character of other proportions gets its own entry (never another pair's)."""
    import repro.motion.retargeting.trees as rt

    db = synthetic_db
    rig = build("mixamo")[0].motion(unit_m=1.0)
    m = db.motion(2)
    other = scale_skeleton(Skeleton.from_motion(rig), scale=1.2, bone_scales={"mixamorig:LeftForeArm": 1.4})
    monkeypatch.setattr(rt, "_PAIRS", LRUCache(32))
    monkeypatch.setattr(rt, "_PLANS", LRUCache(32))  # the plans built, not taken from retarget_across's cache
    first = rt.retarget_across(m, rig).global_positions()
    assert len(rt._PAIRS) == 1
    again = rt.retarget_across(m, rig).global_positions()
    o = rt.retarget_across(m, other).global_positions()
    assert len(rt._PAIRS) == 2
    monkeypatch.setattr(rt, "_PAIRS", LRUCache(32))
    monkeypatch.setattr(rt, "_PLANS", LRUCache(32))
    fresh = rt.retarget_across(m, other).global_positions()
    assert np.array_equal(first, again) and np.array_equal(o, fresh)
    assert not np.allclose(o, first)


def test_plan_applies_to_its_source_skeleton_only(clip):
    rig = build("mixamo")[0].motion(unit_m=1.0)
    plan = TreePlan(clip, rig)
    np.testing.assert_array_equal(plan.apply(clip, fix_feet=True).rotations,
                                  retarget_across(clip, rig, fix_feet=True).rotations)
    with pytest.raises(MotionError, match="source skeleton"):
        plan.apply(rig)


def test_retarget_across_plans_cached_per_pair_of_skeletons(synthetic_db, monkeypatch):
    """retarget_across keeps its plan per pair of skeletons and role tables (the fighter puts every
    retrieved clip on its character with one): another clip of the same actor takes it and gives a
    fresh plan's numbers bit for bit; a character of other proportions, another role table or a
    Skeleton for the Motion get their own; a motion whose up axis or unit is not given (the plan would
    read its frames or warn) is never cached."""
    import repro.motion.retargeting.trees as rt

    db = synthetic_db
    a, b = (dataclasses.replace(db.motion(i), up="y") for i in (2, 3))
    assert a.unit_m is not None
    rig = dataclasses.replace(build("mixamo")[0].motion(unit_m=1.0), up="y")
    monkeypatch.setattr(rt, "_PLANS", LRUCache(32))
    first = rt.retarget_across(a, rig)
    assert len(rt._PLANS) == 1
    got = rt.retarget_across(b, rig)
    assert len(rt._PLANS) == 1
    fresh = TreePlan(b, rig).apply(b)
    assert np.array_equal(got.rotations, fresh.rotations) and np.array_equal(got.positions, fresh.positions)
    assert np.array_equal(rt.retarget_across(a, rig).rotations, first.rotations)
    sk = Skeleton.from_motion(rig)
    other = scale_skeleton(sk, scale=1.2, bone_scales={"mixamorig:LeftForeArm": 1.4})
    roles = dict(Skeleton.from_motion(a).roles)
    for kw in (dict(character=other), dict(character=sk), dict(character=rig, roles=roles)):
        n = len(rt._PLANS)
        rt.retarget_across(a, **{"character": rig, **kw})
        assert len(rt._PLANS) == n + 1
    assert np.array_equal(rt.retarget_across(a, other).rotations, TreePlan(a, other).apply(a).rotations)
    n = len(rt._PLANS)
    for m, ch in ((dataclasses.replace(a, up=None), rig), (dataclasses.replace(a, unit_m=None), rig),
                  (a, dataclasses.replace(rig, up=None))):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rt.retarget_across(m, ch)
    assert len(rt._PLANS) == n
