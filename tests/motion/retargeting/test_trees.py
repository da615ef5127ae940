"""Retargeting across joint trees (issue 11, item 3)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh, retarget, write_bvh
from repro.motion.retargeting.trees import retarget_across
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import CONVENTIONS, Z_UP, build

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


def _read(path, unit):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_bvh(path, unit_m=unit)


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
