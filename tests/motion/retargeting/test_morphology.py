"""Morphology-independent representation and retargeting (repro.motion.retargeting.morphology).

Pronost et al., Section 3.4.1, after Kulpa et al. (2005).  What is asserted:

* same skeleton: ``decode(encode(m), m)`` gives the world positions of *every* joint and
  End Site of ``m`` to 1e-9 of the body height (rounding only), and the same world
  rotations;
* other morphology: forward kinematics of the decoded motion has exactly the target's
  bone lengths (1e-9 relative), and re-encoding it gives back the normalised limb
  vectors, swivel angles, hand/foot orientations, other joints' rotations and the root
  trajectory that were decoded (the representation is what is transferred);
* ``|normalised distal vector| <= 1``; full extension and a fully folded limb give no NaN;
* a real CMU front kick (135_04) retargeted to a 1.2x taller character with 25 % longer
  legs keeps the planted ankle on the floor (height within 3 cm of the source's planted
  height scaled by the foot ratio, no penetration), whereas copying angles with the
  unscaled root translation sinks the feet ~15 cm into the floor and slides more;
  with ``fix_feet`` planted feet do not slide at all;
* ``retarget`` is ``RetargetPlan(...).apply(...)``: its result equals ``decode(encode(m), target)``
  bit for bit, with and without ``fix_feet``; on random poses (one frame and whole clips) of
  characters whose proportions differ from the actor's (per-bone factors inside a limb,
  trunk, legs, uniform size on top) ``RetargetPlan(source, actor).positions`` equals
  ``retarget(pose, actor).global_positions()`` bit for bit, with and without the source's
  world transforms given;
* ``MotionRetriever.prepare`` (which uses the plan for such characters) gives the same
  ``q_r`` as the retargeting it replaces (``retarget`` then the pose cloud), bit for bit;
  plans are cached per (actor, pose skeleton) and a pose on another skeleton gets its own;
* the plan refuses what ``retarget`` refuses (a target whose rest pose is turned, another
  topology), with MotionError;
* bad inputs raise :class:`MotionError`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from repro import data
from repro.errors import MotionError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, Motion, read_bvh, write_bvh
from repro.motion.body.feet import foot_contacts, foot_metrics
from repro.motion.body.pose_frames import pose_points
from repro.motion.body.roles import LIMBS
from repro.motion.body.skeleton import Skeleton, scale_skeleton
from repro.motion.database.synthetic.conventions import build
from repro.motion.retargeting.morphology import (
    LIMB_NAMES,
    MorphologyIndependentMotion,
    RetargetPlan,
    decode,
    decode_with_report,
    encode,
    naive_retarget,
    retarget,
)
from repro.motion.search.retrieval import MotionRetriever

# Mixamo / cgspeed naming (the synthetic kung-fu database's), T-pose, metres, Y up, facing +Z.
from tests.motion_fixtures import MIXAMO, MIXAMO_NAMES as NAMES  # noqa: E402
PARENTS = np.array([-1 if p is None else NAMES.index(p) for _, p, _ in MIXAMO])
OFFSETS = np.array([o for _, _, o in MIXAMO])
ROT = ("Zrotation", "Xrotation", "Yrotation")
CHANNELS = [("Xposition", "Yposition", "Zposition") + ROT] + [ROT] * (len(NAMES) - 1)
ES_PARENTS = np.array([NAMES.index("Head"), NAMES.index("LeftHand"), NAMES.index("RightHand")])
ES_OFFSETS = np.array([[0, 0.18, 0], [0.18, 0, 0], [-0.18, 0, 0]])


def make_motion(rotations, root, offsets=OFFSETS, names=NAMES, parents=PARENTS) -> Motion:
    F = rotations.shape[0]
    pos = np.broadcast_to(offsets, (F, len(names), 3)).copy()
    pos[:, 0] = root
    return Motion(
        joint_names=names,
        parents=parents,
        offsets=offsets,
        channels=CHANNELS,
        frame_time=1 / 30,
        rotations=rotations,
        positions=pos,
        end_site_parents=ES_PARENTS,
        end_site_offsets=ES_OFFSETS,
        unit_m=1.0,
    )


def random_motion(seed: int, F: int = 12, max_angle: float = np.pi) -> Motion:
    """Random local rotations (angles up to ``max_angle``) and root positions."""
    rng = np.random.default_rng(seed)
    J = len(NAMES)
    rv = rng.normal(size=(F, J, 3))
    rv *= (rng.uniform(0, max_angle, size=(F, J)) / np.linalg.norm(rv, axis=-1))[..., None]
    q = Rotation.from_rotvec(rv.reshape(-1, 3)).as_quat().reshape(F, J, 4)
    root = rng.normal(scale=[1.0, 0.1, 1.0], size=(F, 3)) + [0, 0.9, 0]
    return make_motion(q, root)


def rest_skeleton() -> Skeleton:
    return Skeleton.from_motion(make_motion(np.tile([0, 0, 0, 1.0], (1, len(NAMES), 1)), [[0, 0.98, 0]]))


def _all_points(m: Motion) -> np.ndarray:
    return np.concatenate([m.global_positions(), m.end_site_positions()], axis=1)


def _same_rotation(a, b) -> float:
    """Largest ``1 - |<a, b>|`` between unit quaternions (0 = same rotation)."""
    return float(np.max(1.0 - np.abs(np.sum(a * b, axis=-1))))


def _fk_bone_lengths(m: Motion) -> np.ndarray:
    g = m.global_positions()
    return np.linalg.norm(g[:, 1:] - g[:, m.parents[1:]], axis=-1)


# ---------------------------------------------------------------- round trip
@given(seed=st.integers(0, 2**31 - 1))
def test_roundtrip_same_skeleton_random_poses(seed):
    m = random_motion(seed)
    sk = Skeleton.from_motion(m)
    mi = encode(m)
    out = decode(mi, m)
    assert out.joint_names == m.joint_names and out.channels == m.channels
    np.testing.assert_array_equal(out.offsets, m.offsets)
    err = np.abs(_all_points(out) - _all_points(m)).max()
    assert err <= 1e-9 * sk.height
    assert _same_rotation(out.global_transforms()[0], m.global_transforms()[0]) <= 1e-9
    assert np.all(mi.limb_extension <= 1.0 + 1e-12)
    assert np.all(np.isfinite(mi.limb_swivel)) and np.all(np.abs(mi.limb_swivel) <= np.pi)


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
        _fk_bone_lengths(out), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, len(NAMES) - 1)),
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
    assert _same_rotation(mi2.limb_end_rotations, mi.limb_end_rotations) <= 1e-9
    limb_joints = {NAMES.index(tgt.roles[r]) for k in LIMB_NAMES for r in LIMBS[k]}
    others = [j for j in range(len(NAMES)) if j not in limb_joints]
    assert _same_rotation(out.rotations[:, others], m.rotations[:, others]) <= 1e-12
    np.testing.assert_allclose(out.root_positions, m.root_positions * tgt.hip_height / mi.source_hip_height)


# ------------------------------------------------------- singular configurations
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
    assert np.abs(_all_points(decode(mi, m)) - _all_points(m)).max() <= 1e-12


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
    np.testing.assert_allclose(_fk_bone_lengths(out)[0], np.linalg.norm(off[1:], axis=1), atol=1e-12)
    assert np.abs(_all_points(out)[1] - _all_points(m)[1]).max() <= 1e-9
    # a target whose forearm is shorter cannot fold that far: clipped, no NaN
    tgt = scale_skeleton(m, bone_scales={"LeftHand": 0.5})
    out, rep = decode_with_report(mi, tgt)
    assert rep.clamped["left_arm"] == 2 and np.all(np.isfinite(out.rotations))


# ----------------------------------------------------------------- baselines
def test_naive_retarget_copies_angles():
    m = random_motion(3)
    tgt = scale_skeleton(m, height=1.9, leg_scale=1.2)
    nv = naive_retarget(m, tgt)
    np.testing.assert_allclose(nv.rotations, m.rotations)
    np.testing.assert_allclose(nv.root_positions, m.root_positions)
    np.testing.assert_array_equal(nv.offsets, tgt.offsets)
    ns = naive_retarget(m, tgt, scale_root=True)
    np.testing.assert_allclose(ns.root_positions, m.root_positions * tgt.hip_height / Skeleton.from_motion(m).hip_height)
    # when both bones of every limb scale alike, decoding the representation = angle copy + scaled root
    out = retarget(m, tgt)
    assert np.abs(out.global_positions() - ns.global_positions()).max() <= 1e-9
    # ... and not when the upper/lower ratio changes
    tgt2 = scale_skeleton(m, bone_scales={"LeftHand": 1.4})
    assert np.abs(retarget(m, tgt2).global_positions() - naive_retarget(m, tgt2, scale_root=True).global_positions()).max() > 1e-3


def test_retarget_writes_bvh(tmp_path):
    m = random_motion(7, F=4, max_angle=2.0)
    out = retarget(m, scale_skeleton(m, height=1.5, arm_scale=1.2))
    path = write_bvh(out, tmp_path / "retargeted.bvh")
    back = read_bvh(path)
    assert back.joint_names == out.joint_names
    np.testing.assert_allclose(back.global_positions(), out.global_positions(), atol=1e-8)


# -------------------------------------------------------------------- errors
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


def test_errors_nan_in_representation():
    mi = encode(random_motion(2))
    sw = mi.limb_swivel.copy()
    sw[0, 0] = np.nan
    with pytest.raises(MotionError, match="NaN"):
        decode(dataclasses.replace(mi, limb_swivel=sw), rest_skeleton())
    lv = mi.limb_vectors * 2.0
    with pytest.raises(MotionError, match="longer than 1"):
        decode(dataclasses.replace(mi, limb_vectors=lv), rest_skeleton())


def test_errors_zero_length_limbs():
    off = OFFSETS.copy()
    off[NAMES.index("RightFoot")] = 0.0  # zero shin
    m = make_motion(np.tile([0, 0, 0, 1.0], (1, len(NAMES), 1)), [[0, 1, 0]], offsets=off)
    with pytest.raises(MotionError, match="zero-length"):
        encode(m)
    with pytest.raises(MotionError, match="zero-length"):
        decode(encode(random_motion(0)), m)


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


# ----------------------------------------------------------------- real data
@pytest.fixture(scope="module")
def front_kick():
    return read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)


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
    assert np.abs(_all_points(out) - _all_points(m)).max() <= 1e-9 * sk.height


@pytest.mark.data("cmu-bvh")
def test_cmu_front_kick_to_taller_long_legged_fighter(front_kick):
    m = front_kick
    src = Skeleton.from_motion(m)
    tgt = scale_skeleton(src, height=1.2 * src.size, leg_scale=1.25)
    assert tgt.size == pytest.approx(1.2 * src.size)
    contacts = foot_contacts(m)
    assert contacts.any(axis=0).all()
    ref = foot_metrics(m, contacts)
    foot_ratio = tgt.limb_lengths["left_foot"] / src.limb_lengths["left_foot"]
    expected_planted = ref["planted_height_mean"] * foot_ratio

    ours = retarget(m, tgt)
    np.testing.assert_allclose(
        _fk_bone_lengths(ours), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, m.n_joints - 1)),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    o = foot_metrics(ours, contacts)
    naive = foot_metrics(naive_retarget(m, tgt), contacts)
    # ours: planted ankle stays on the floor plane (within 3 cm), toes never below -1 cm
    assert abs(o["planted_height_mean"] - expected_planted) < 0.03
    assert o["min_toe_height"] > -0.01
    # naive angle copy, unscaled root: the longer legs sink the feet > 10 cm into the floor
    assert naive["planted_height_mean"] < -0.10 and naive["min_toe_height"] < -0.15
    assert naive["slide_per_contact"] > 1.5 * o["slide_per_contact"]
    # with feet correction planted feet do not slide and stay at the expected height
    fixed_motion = retarget(m, tgt, fix_feet=True)
    np.testing.assert_allclose(
        _fk_bone_lengths(fixed_motion), np.broadcast_to(tgt.bone_lengths[1:], (m.n_frames, m.n_joints - 1)),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    fixed = foot_metrics(fixed_motion, contacts)
    assert fixed["slide_per_contact"] < 1e-3 and fixed["slide_speed"] < 0.01
    assert abs(fixed["planted_height_mean"] - expected_planted) < 0.005


@pytest.mark.data("cmu-bvh")
def test_cmu_front_kick_other_thigh_shin_ratio(front_kick):
    """Where the representation differs from angle copying: thigh 30 % longer, shin 20 % shorter."""
    m = front_kick
    tgt = scale_skeleton(m, bone_scales={"ltibia": 1.3, "rtibia": 1.3, "lfoot": 0.8, "rfoot": 0.8})
    contacts = foot_contacts(m)
    ours = foot_metrics(retarget(m, tgt), contacts)
    angles = foot_metrics(naive_retarget(m, tgt, scale_root=True), contacts)
    assert ours["slide_speed"] < angles["slide_speed"]
    assert ours["planted_height_std"] < 0.5 * angles["planted_height_std"]


@pytest.mark.data("bandai")
def test_bandai_roundtrip_and_retarget(tmp_path):
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    sk = Skeleton.from_motion(m)
    mi = encode(m)
    assert np.abs(_all_points(decode(mi, m)) - _all_points(m)).max() <= 1e-9 * sk.height
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
        _fk_bone_lengths(out)[:, bones],
        np.broadcast_to(np.linalg.norm(out.positions[0, below], axis=1), (m.n_frames, len(below))),
        rtol=0, atol=1e-9 * tgt.height,
    )  # fmt: skip
    np.testing.assert_allclose(tgt.bone_lengths[below], np.linalg.norm(out.positions[0, below], axis=1), atol=1e-4)
    back = read_bvh(write_bvh(out, tmp_path / "bandai_tall.bvh"))
    np.testing.assert_allclose(back.global_positions(), out.global_positions(), atol=1e-6)


# --------------------------------------------------------------- hostile arguments (issue 23)
@pytest.mark.parametrize(
    "call, match",
    [
        (lambda m, sk: encode("m"), "Motion"),
        (lambda m, sk: encode(m, roles=["a"]), "roles"),
        (lambda m, sk: decode("mi", sk), "MorphologyIndependentMotion"),
        (lambda m, sk: decode(encode(m), sk, blend_time=float("nan")), "blend_time"),
        (lambda m, sk: decode(encode(m), sk, blend_time=-1.0, fix_feet=True), "blend_time"),
        (lambda m, sk: decode(encode(m), sk, fix_feet="yes"), "fix_feet"),
        (lambda m, sk: decode(encode(m), sk, max_rest_angle_deg="5"), "max_rest_angle_deg"),
        (lambda m, sk: decode_with_report(encode(m), sk, max_rest_angle_deg=float("inf")), "max_rest_angle_deg"),
        (lambda m, sk: retarget("m", sk), "Motion"),
        (lambda m, sk: retarget(m, "sk"), "target"),
        (lambda m, sk: retarget(m, sk, fix_feet=1), "fix_feet"),
        (lambda m, sk: retarget(m, sk, roles="x"), "roles"),
        (lambda m, sk: naive_retarget(m, sk, scale_root="yes"), "scale_root"),
        (lambda m, sk: naive_retarget(m, None), "target"),
    ],
)
def test_morphology_entries_refuse_bad_arguments(call, match):
    with pytest.raises(MotionError, match=match):
        call(random_motion(0, F=4), rest_skeleton())


def test_a_blend_longer_than_any_clip_does_not_overflow():
    m = random_motion(0, F=4)
    a = decode(encode(m), rest_skeleton(), fix_feet=True, blend_time=1.7e308)  # used to overflow in round()
    b = decode(encode(m), rest_skeleton(), fix_feet=True, blend_time=1e6)
    np.testing.assert_array_equal(a.rotations, b.rotations)


def test_retarget_plan_checks_the_source_transforms():
    m = random_motion(0, F=4)
    plan = RetargetPlan(m, rest_skeleton())
    with pytest.raises(MotionError, match="source"):
        plan.positions(m.rotations, m.local_translations(), source="x")
    with pytest.raises(MotionError, match="source"):
        plan.positions(m.rotations, m.local_translations(), source=(m.rotations, m.positions[:, :3]))
    with pytest.raises(MotionError, match="unit quaternions"):  # found by the argument fuzzer: 0/0
        plan.positions(np.zeros_like(m.rotations), m.local_translations())
    with pytest.raises(MotionError, match="NaN"):
        plan.positions(m.rotations, m.local_translations() * np.nan)


# ------------------------------------------------------------------ the plan (RetargetPlan)
@pytest.mark.parametrize("fix_feet", [False, True])
def test_retarget_is_decode_of_encode(fix_feet):
    """The plan's composition of encoding and decoding (stacked limb frames, the source's world
    rotations reused) gives the numbers of the two functions, the feet pinned or not."""
    m = random_motion(11, F=20, max_angle=1.5)
    for tgt in (scale_skeleton(m, height=1.9, leg_scale=1.2, bone_scales={"LeftHand": 1.3}), rest_skeleton()):
        want = decode(encode(m), tgt, fix_feet=fix_feet)
        got = retarget(m, tgt, fix_feet=fix_feet)
        np.testing.assert_array_equal(got.rotations, want.rotations)
        np.testing.assert_array_equal(got.positions, want.positions)
        assert got.channels == want.channels and got.joint_names == want.joint_names
    with pytest.raises(MotionError, match="source skeleton"):
        RetargetPlan(m, tgt).apply(dataclasses.replace(m, joint_names=[n + "_x" for n in NAMES]))


CHARACTERS = [
    dict(scale=1.1, arm_scale=1.2, leg_scale=0.9, bone_scales={"LeftForeArm": 1.3, "RightLeg": 0.8}),
    dict(scale=0.8, bone_scales={"LeftArm": 1.5, "LeftUpLeg": 1.2, "Spine": 0.7}),
    dict(trunk_scale=1.3, bone_scales={"RightForeArm": 0.6, "LeftFoot": 1.4}),
]


def on(character, m, frames):
    """Frames ``frames`` of ``m`` played by ``character`` (same rotations, its offsets)."""
    t = np.where(m.position_mask[None], m.local_translations(), character.offsets[None])[frames]
    return character.motion_with(m.rotations[frames], t, frame_time=m.frame_time)


def cloud(db, actor, g):
    idx = [actor.index(r) for r in db.pose_roles]
    return pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                       window=db.window, step=db.step)[-1] / actor.size


@pytest.mark.parametrize("kw", CHARACTERS)
def test_plan_equals_retarget(synthetic_db, kw):
    db = synthetic_db
    actor = db.actors[0]
    ch = scale_skeleton(actor, **kw)
    rng = np.random.default_rng(len(str(kw)))
    for _ in range(4):
        m = db.motion(int(rng.integers(db.n_clips)))
        f = int(rng.integers(m.n_frames))
        for frames in (slice(f, f + 1), slice(None)):
            pose = on(ch, m, frames)
            want = retarget(pose, actor).global_positions()
            plan = RetargetPlan(pose, actor)
            got = plan.positions(pose.rotations, pose.local_translations())
            assert np.array_equal(got, want)
            got = plan.positions(pose.rotations, pose.local_translations(), source=pose.global_transforms())
            assert np.array_equal(got, want)


def test_prepare_equals_retarget(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    rng = np.random.default_rng(3)
    for kw in CHARACTERS:
        ch = scale_skeleton(actor, **kw)
        assert r._scaling_of(on(ch, db.motion(0), slice(0, 1)), 0) is None  # not the uniform fast path
        for _ in range(5):
            m = db.motion(int(rng.integers(db.n_clips)))
            pose = on(ch, m, slice(int(rng.integers(m.n_frames)), None))
            q = r.prepare(pose, ch)
            last = dataclasses.replace(pose, rotations=pose.rotations[-1:], positions=pose.positions[-1:])
            want = cloud(db, actor, retarget(last, actor).global_positions())
            assert np.array_equal(q.q_n[0], want)
    n = len(r._plans)
    assert 1 <= n <= len(CHARACTERS)  # one plan per character skeleton, reused
    r.prepare(on(scale_skeleton(actor, **CHARACTERS[0]), db.motion(1), slice(0, 1)), scale_skeleton(actor, **CHARACTERS[0]))
    assert len(r._plans) == n


def test_plan_refuses_what_retarget_refuses(synthetic_db):
    db = synthetic_db
    actor = db.actors[0]
    pose = on(scale_skeleton(actor, **CHARACTERS[0]), db.motion(0), slice(0, 1))
    off = np.array(actor.offsets)
    j = actor.index("LeftForeArm")
    off[j] = np.array([off[j][1], -off[j][0], off[j][2]])  # the forearm turned by 90 degrees at rest
    turned = dataclasses.replace(actor, offsets=off)
    with pytest.raises(MotionError, match="rest pose"):
        retarget(pose, turned)
    with pytest.raises(MotionError, match="rest pose"):
        RetargetPlan(pose, turned)
    rig = build("mixamo")[0].motion(unit_m=1.0)
    with pytest.raises(MotionError, match="joint names and parents"):
        RetargetPlan(pose, rig)
