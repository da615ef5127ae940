"""The morphology-independent representation and encode (repro.motion.retargeting.representation).

Pronost et al., Section 3.4.1, after Kulpa et al. (2005).  What is asserted:

* same skeleton: ``decode(encode(m), m)`` gives the world positions of *every* joint and
  End Site of ``m`` to 1e-9 of the body height (rounding only), and the same world
  rotations (random poses, a real CMU front kick);
* ``|normalised distal vector| <= 1``; full extension and a fully folded limb give no NaN;
  an undefined swivel carries the last defined one;
* missing roles and zero-length limbs raise :class:`MotionError`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from repro.errors import MotionError
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.retargeting.decoding import decode, decode_with_report
from repro.motion.retargeting.representation import LIMB_NAMES, encode
from tests.motion.retargeting.mixamo_motions import (
    NAMES,
    OFFSETS,
    all_points,
    fk_bone_lengths,
    make_motion,
    random_motion,
    same_rotation,
)


@given(seed=st.integers(0, 2**31 - 1))
def test_roundtrip_same_skeleton_random_poses(seed):
    m = random_motion(seed)
    sk = Skeleton.from_motion(m)
    mi = encode(m)
    out = decode(mi, m)
    assert out.joint_names == m.joint_names and out.channels == m.channels
    np.testing.assert_array_equal(out.offsets, m.offsets)
    err = np.abs(all_points(out) - all_points(m)).max()
    assert err <= 1e-9 * sk.height
    assert same_rotation(out.global_transforms()[0], m.global_transforms()[0]) <= 1e-9
    assert np.all(mi.limb_extension <= 1.0 + 1e-12)
    assert np.all(np.isfinite(mi.limb_swivel)) and np.all(np.abs(mi.limb_swivel) <= np.pi)


def test_full_extension_no_nan_and_swivel_carried():
    F, J = 5, len(NAMES)
    q = np.tile([0, 0, 0, 1.0], (F, J, 1))
    elbow = NAMES.index("LeftForeArm")
    knee = NAMES.index("RightLeg")
    # frames 0, 4 bent (elbow 60 deg about z, knee 50 deg about x), frames 1-3 straight (T-pose)
    for f, a in ((0, 60.0), (4, 30.0)):
        q[f, elbow] = Rotation.from_euler("z", a, degrees=True).as_quat()
        q[f, knee] = Rotation.from_euler("x", -50.0, degrees=True).as_quat()
    m = make_motion(q, np.tile([0, 0.98, 0], (F, 1)))
    mi = encode(m)
    ext = mi.limb_extension
    assert np.allclose(ext[1:4], 1.0) and np.all(ext <= 1 + 1e-12)
    assert np.all(np.isfinite(mi.limb_swivel))
    la, rl = LIMB_NAMES.index("left_arm"), LIMB_NAMES.index("right_leg")
    # undefined at full extension: the last defined angle is carried forward
    assert np.all(mi.limb_swivel[1:4, la] == mi.limb_swivel[0, la])
    assert np.all(mi.limb_swivel[1:4, rl] == mi.limb_swivel[0, rl])
    # fully straight limbs on every frame: 0
    assert np.all(mi.limb_swivel[:, LIMB_NAMES.index("right_arm")] == 0.0)
    for tgt in (m, scale_skeleton(m, height=2.0, arm_scale=0.8, bone_scales={"LeftHand": 1.3})):
        out = decode(mi, tgt)
        assert np.all(np.isfinite(out.rotations))
        mi2 = encode(out)
        np.testing.assert_allclose(mi2.limb_extension[1:4], 1.0, atol=1e-9)
    assert np.abs(all_points(decode(mi, m)) - all_points(m)).max() <= 1e-12


def test_fully_folded_equal_limb_no_nan():
    off = OFFSETS.copy()
    off[NAMES.index("LeftHand")] = [0.28, 0, 0]  # forearm = upper arm: the wrist can reach the shoulder
    q = np.tile([0, 0, 0, 1.0], (2, len(NAMES), 1))
    q[:, NAMES.index("LeftForeArm")] = Rotation.from_euler("z", [[180.0], [179.0]], degrees=True).as_quat()
    m = make_motion(q, np.tile([0, 0.98, 0], (2, 1)), offsets=off)
    mi = encode(m)
    assert mi.limb_extension[0, 0] < 1e-12 and np.all(np.isfinite(mi.limb_vectors))
    assert np.all(np.isfinite(mi.limb_swivel))
    out = decode(mi, m)
    # frame 0: wrist exactly on the shoulder, the limb axis is undefined and the elbow's
    # direction is lost (the representation keeps one angle, the elbow has a sphere of
    # positions): only ask for a valid pose there; frame 1 (1 degree open) is exact
    g = out.global_positions()
    sh, wr = NAMES.index("LeftArm"), NAMES.index("LeftHand")
    assert np.linalg.norm(g[0, wr] - g[0, sh]) < 1e-12
    np.testing.assert_allclose(fk_bone_lengths(out)[0], np.linalg.norm(off[1:], axis=1), atol=1e-12)
    assert np.abs(all_points(out)[1] - all_points(m)[1]).max() <= 1e-9
    # a target whose forearm is shorter cannot fold that far: clipped, no NaN
    tgt = scale_skeleton(m, bone_scales={"LeftHand": 0.5})
    out, rep = decode_with_report(mi, tgt)
    assert rep.clamped["left_arm"] == 2 and np.all(np.isfinite(out.rotations))


def test_errors_missing_roles():
    names = [n.replace("LeftLeg", "Something") for n in NAMES]
    m = random_motion(1)
    m2 = dataclasses.replace(m, joint_names=names)
    # roles come from the structure first (issue 11): a knee named "Something" is still the
    # knee of a leg; it is missing when the structure has no knee either (a zero-length shin)
    assert Skeleton.from_motion(m2).roles["left_knee"] == "Something"
    off = np.array(m2.offsets)
    off[names.index("LeftFoot")] = 0.0
    m3 = dataclasses.replace(m2, offsets=off, positions=np.broadcast_to(off, m2.positions.shape).copy())
    with pytest.raises(MotionError, match="left_knee"):
        encode(m3)


def test_errors_zero_length_limbs():
    off = OFFSETS.copy()
    off[NAMES.index("RightFoot")] = 0.0  # zero shin
    m = make_motion(np.tile([0, 0, 0, 1.0], (1, len(NAMES), 1)), [[0, 1, 0]], offsets=off)
    with pytest.raises(MotionError, match="zero-length"):
        encode(m)
    with pytest.raises(MotionError, match="zero-length"):
        decode(encode(random_motion(0)), m)


@pytest.mark.data("cmu-bvh")
def test_cmu_front_kick_roundtrip(front_kick):
    m = front_kick
    sk = Skeleton.from_motion(m)
    mi = encode(m)
    assert mi.n_frames == 1316
    assert np.all(mi.limb_extension <= 1.0)
    out = decode(mi, m)
    roles = [sk.index(r) for r in sk.roles]
    err = np.abs(out.global_positions()[:, roles] - m.global_positions()[:, roles]).max()
    assert err <= 1e-9 * sk.height
    assert np.abs(all_points(out) - all_points(m)).max() <= 1e-9 * sk.height
