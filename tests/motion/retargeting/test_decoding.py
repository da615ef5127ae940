"""Decoding the representation on a target skeleton (repro.motion.retargeting.decoding).

Pronost et al., Section 3.4.1, after Kulpa et al. (2005).  What is asserted:

* other morphology: forward kinematics of the decoded motion has exactly the target's
  bone lengths (1e-9 relative), and re-encoding it gives back the normalised limb
  vectors, swivel angles, hand/foot orientations, other joints' rotations and the root
  trajectory that were decoded (the representation is what is transferred); the clipped
  frames are counted;
* Bandai Namco's position channels below the pelvis become the target's offsets; the
  result writes and reads back as BVH;
* NaN, another topology or rest pose, a target that is not a skeleton raise MotionError.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro import data
from repro.errors import MotionError
from repro.motion import BANDAI_UNIT_M, read_bvh, write_bvh
from repro.motion.body.roles import LIMBS
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.retargeting.decoding import decode, decode_with_report
from repro.motion.retargeting.morphology import naive_retarget
from repro.motion.retargeting.representation import LIMB_NAMES, MorphologyIndependentMotion, encode
from tests.motion.retargeting.mixamo_motions import (
    NAMES,
    OFFSETS,
    PARENTS,
    all_points,
    fk_bone_lengths,
    make_motion,
    random_motion,
    rest_skeleton,
    same_rotation,
)


@given(
    seed=st.integers(0, 2**31 - 1),
    height=st.floats(1.2, 2.2),
    arm=st.floats(0.75, 1.25),
    leg=st.floats(0.75, 1.25),
    forearm=st.floats(0.7, 1.4),
    shin=st.floats(0.7, 1.4),
)
def test_decode_on_other_morphology(seed, height, arm, leg, forearm, shin):
    m = random_motion(seed)
    mi = encode(m)
    tgt = scale_skeleton(
        m, height=height, arm_scale=arm, leg_scale=leg,
        bone_scales={"LeftHand": forearm, "RightHand": forearm, "LeftFoot": shin, "RightFoot": shin},
    )  # fmt: skip
    out, rep = decode_with_report(mi, tgt)
    assert all(np.isfinite(a).all() for a in (out.rotations, out.positions))
    # forward kinematics has the target's bone lengths, every bone, every frame
    np.testing.assert_allclose(
        fk_bone_lengths(out), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, len(NAMES) - 1)),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    # the transferred data come back when the result is encoded again
    mi2 = encode(out)
    L = np.array([tgt.limb_lengths[k] for k in LIMB_NAMES])  # "left_arm" = upper arm + forearm ...
    l1 = np.array([tgt.bone_length(LIMBS[k][1]) for k in LIMB_NAMES])
    l2 = np.array([tgt.bone_length(LIMBS[k][2]) for k in LIMB_NAMES])
    dist = mi.limb_extension * L
    reachable = (dist >= np.abs(l1 - l2) * (1 + 1e-6)) & (dist <= L)
    assert sum(rep.clamped.values()) == int((~reachable).sum())
    np.testing.assert_allclose(mi2.limb_vectors[reachable], mi.limb_vectors[reachable], atol=1e-9)
    # swivel (mod 2 pi) where the middle joint is off the axis by more than 1e-6 of the limb
    circle = np.sqrt(np.clip(1 - ((l1**2 + dist**2 - l2**2) / (2 * l1 * np.maximum(dist, 1e-12))) ** 2, 0, 1))
    ok = reachable & (circle > 1e-6)
    dphi = np.angle(np.exp(1j * (mi2.limb_swivel - mi.limb_swivel)))
    assert np.abs(dphi[ok]).max(initial=0.0) <= 1e-6
    assert same_rotation(mi2.limb_end_rotations, mi.limb_end_rotations) <= 1e-9
    limb_joints = {NAMES.index(tgt.roles[r]) for k in LIMB_NAMES for r in LIMBS[k]}
    others = [j for j in range(len(NAMES)) if j not in limb_joints]
    assert same_rotation(out.rotations[:, others], m.rotations[:, others]) <= 1e-12
    np.testing.assert_allclose(out.root_positions, m.root_positions * tgt.hip_height / mi.source_hip_height)


def test_errors_nan_in_representation():
    mi = encode(random_motion(2))
    sw = mi.limb_swivel.copy()
    sw[0, 0] = np.nan
    with pytest.raises(MotionError, match="NaN"):
        decode(dataclasses.replace(mi, limb_swivel=sw), rest_skeleton())
    lv = mi.limb_vectors * 2.0
    with pytest.raises(MotionError, match="longer than 1"):
        decode(dataclasses.replace(mi, limb_vectors=lv), rest_skeleton())


@pytest.mark.data("bandai")
def test_errors_other_topology():
    cmu_like = random_motion(4)
    bandai = read_bvh(data.fetch("mocap/bandai/dataset-1_walk_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    with pytest.raises(MotionError, match="topology"):
        decode(encode(cmu_like), bandai)
    with pytest.raises(MotionError, match="topology"):
        naive_retarget(cmu_like, bandai)


def test_errors_other_topology_synthetic():
    m = random_motion(5)
    parents = PARENTS.copy()
    parents[NAMES.index("Head")] = NAMES.index("Spine1")  # same names, other tree
    other = make_motion(m.rotations, m.root_positions, parents=parents)
    with pytest.raises(MotionError, match="topology"):
        decode(encode(m), other)


def test_errors_other_rest_pose():
    m = random_motion(6)
    off = OFFSETS.copy()
    off[NAMES.index("LeftForeArm")] = [0.2, -0.2, 0.0]  # upper arm pointing 45 deg down at rest (A-pose)
    with pytest.raises(MotionError, match="rest pose"):
        decode(encode(m), make_motion(m.rotations, m.root_positions, offsets=off))


def test_decode_rejects_non_skeleton():
    with pytest.raises(MotionError):
        decode(encode(random_motion(8)), "tall fighter")
    assert isinstance(encode(random_motion(8)), MorphologyIndependentMotion)


@pytest.mark.data("bandai")
def test_bandai_roundtrip_and_retarget(tmp_path):
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    sk = Skeleton.from_motion(m)
    mi = encode(m)
    assert np.abs(all_points(decode(mi, m)) - all_points(m)).max() <= 1e-9 * sk.height
    tgt = scale_skeleton(sk, height=1.8, arm_scale=0.8)
    out = decode(mi, tgt)
    # every joint has position channels in these files (equal to the offsets up to the file's
    # rounding, 1e-5 cm): below the pelvis they become the target's offsets
    below = [j for j in range(m.n_joints) if j not in mi.root_path]
    np.testing.assert_allclose(
        out.positions[:, below], np.broadcast_to(tgt.offsets[below], (m.n_frames, len(below), 3)), atol=1e-4
    )
    # bone lengths (Hips is on the root path: its translation is the animated root trajectory)
    bones = np.array(below) - 1
    np.testing.assert_allclose(
        fk_bone_lengths(out)[:, bones],
        np.broadcast_to(np.linalg.norm(out.positions[0, below], axis=1), (m.n_frames, len(below))),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    np.testing.assert_allclose(tgt.bone_lengths[below], np.linalg.norm(out.positions[0, below], axis=1), atol=1e-4)
    back = read_bvh(write_bvh(out, tmp_path / "bandai_tall.bvh"))
    np.testing.assert_allclose(back.global_positions(), out.global_positions(), atol=1e-6)
