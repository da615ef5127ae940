"""Sizes and characters of other morphologies (repro.motion.body.skeleton); roles: test_roles.py.

Pronost et al., Section 3.3 (Eq. 1: ``c_r = c * size_a / size_c``) and Section 3.4.1
(limb lengths for the morphology-independent representation).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from repro import data
from repro.errors import MotionError
from repro.motion import BANDAI_UNIT_M, CMU_UNIT_M, read_bvh
from repro.motion.body.skeleton import (
    Skeleton,
    rescale_constraint,
    scale_skeleton,
    skeleton_of,
)
from repro.motion.body.stature import ANKLE_PER_LEG, HEAD_JOINT_FRACTION
from repro.motion.database.synthetic import synthetic_skeleton
from repro.motion.database.synthetic.conventions import CONVENTIONS, build
from tests.motion.body.role_tables import BANDAI_EXPECTED, CMU_EXPECTED, MIXAMO, MIXAMO_NAMES, MIXAMO_PARENTS


def mixamo_skeleton(**kw) -> Skeleton:
    rot = ("Zrotation", "Xrotation", "Yrotation")
    channels = [("Xposition", "Yposition", "Zposition") + rot] + [rot] * (len(MIXAMO) - 1)
    head = MIXAMO_NAMES.index("Head")
    toes = [MIXAMO_NAMES.index("LeftToeBase"), MIXAMO_NAMES.index("RightToeBase")]
    args = dict(
        joint_names=MIXAMO_NAMES,
        parents=np.array(MIXAMO_PARENTS),
        offsets=np.array([o for _, _, o in MIXAMO]),
        channels=channels,
        end_site_parents=np.array([head] + toes),
        end_site_offsets=np.array([[0, 0.18, 0], [0, 0, 0.06], [0, 0, 0.06]]),
        unit_m=1.0,
    )
    args.update(kw)
    return Skeleton(**args)


# ------------------------------------------------------------------- sizes
def test_mixamo_sizes_by_hand():
    sk = mixamo_skeleton()
    L = sk.limb_lengths
    assert L["left_upper_arm"] == pytest.approx(0.28) and L["left_forearm"] == pytest.approx(0.25)
    assert L["right_arm"] == pytest.approx(0.53) and L["left_thigh"] == pytest.approx(0.45)
    assert L["left_leg"] == pytest.approx(0.87) and L["left_foot"] == pytest.approx(np.hypot(0.06, 0.14))
    assert sk.leg_length == pytest.approx(0.87) and sk.arm_length == pytest.approx(0.53)
    assert sk.ankle_height == pytest.approx(0.06)  # toe joint 6 cm below the ankle
    assert sk.hip_drop == pytest.approx(0.05)
    assert sk.trunk_length == pytest.approx(0.10 + 0.15 + 0.20 + 0.10)
    assert sk.head_top == pytest.approx(0.18)
    assert sk.hip_height == pytest.approx(0.06 + 0.87 + 0.05)
    # straightened stature = rest-pose extent of this upright rig: head top 1.71 above the toe joint
    assert sk.height == pytest.approx(0.06 + 0.87 + 0.05 + 0.55 + 0.18)
    rest = sk.rest_positions()
    top = rest[sk.index("head"), 1] + 0.18
    assert sk.height == pytest.approx(top - rest[sk.index("left_toe"), 1])
    assert sk.size == pytest.approx(sk.height)  # unit_m = 1
    assert sk.bone_length("LeftForeArm") == pytest.approx(0.28)


def test_size_needs_units():
    sk = mixamo_skeleton(unit_m=None)
    assert sk.height == pytest.approx(1.71)
    with pytest.raises(MotionError, match="unit"):
        sk.size
    with pytest.raises(MotionError, match="unit"):
        scale_skeleton(sk, height=1.8)
    assert scale_skeleton(sk, scale=2.0).height == pytest.approx(3.42)


def test_rescale_constraint_eq1():
    c = np.array([1.0, 1.2, 0.5])
    # a target 1 m in front of a 2 m character is 0.8 m in front of a 1.6 m actor
    np.testing.assert_allclose(rescale_constraint(c, 1.6, 2.0), c * 0.8)
    with pytest.raises(MotionError):
        rescale_constraint(c, 1.6, 0.0)
    with pytest.raises(MotionError):
        rescale_constraint([np.nan, 0, 0], 1.6, 2.0)


# ------------------------------------------------------------ scale_skeleton
@given(
    height=st.floats(1.2, 2.2),
    arm=st.floats(0.75, 1.25),
    leg=st.floats(0.75, 1.25),
    trunk=st.floats(0.8, 1.2),
)
def test_scale_skeleton_height_and_proportions(height, arm, leg, trunk):
    sk = mixamo_skeleton()
    t = scale_skeleton(sk, height=height, arm_scale=arm, leg_scale=leg, trunk_scale=trunk)
    assert t.joint_names == sk.joint_names and np.array_equal(t.parents, sk.parents)
    assert t.roles == sk.roles and t.channels == sk.channels
    assert t.size == pytest.approx(height, rel=1e-12)
    # every bone keeps its direction
    bl0, bl1 = sk.bone_lengths, t.bone_lengths
    nz = bl0 > 0
    np.testing.assert_allclose(t.offsets[nz] / bl1[nz, None], sk.offsets[nz] / bl0[nz, None], atol=1e-12)
    # proportions relative to the untouched bones (e.g. the hand-to-foot bones, pelvis width)
    k = t.bone_length("left_toe") / sk.bone_length("left_toe")  # the uniform factor
    assert t.limb_lengths["left_arm"] == pytest.approx(k * arm * sk.limb_lengths["left_arm"])
    assert t.limb_lengths["right_leg"] == pytest.approx(k * leg * sk.limb_lengths["right_leg"])
    assert t.trunk_length == pytest.approx(k * trunk * sk.trunk_length)
    assert t.head_top == pytest.approx(k * trunk * sk.head_top)


def test_scale_skeleton_from_motion_and_bone_scales():
    sk = mixamo_skeleton()
    m = sk.rest_motion(n_frames=2)
    t = scale_skeleton(m, bone_scales={"LeftForeArm": 1.5})
    assert isinstance(t, Skeleton)
    assert t.limb_lengths["left_upper_arm"] == pytest.approx(1.5 * 0.28)
    assert t.limb_lengths["left_forearm"] == pytest.approx(0.25)
    assert t.limb_lengths["right_upper_arm"] == pytest.approx(0.28)


@pytest.mark.parametrize(
    "kw, msg",
    [
        (dict(height=float("nan")), "height"),
        (dict(height=-1.0), "height"),
        (dict(arm_scale=0.0), "arm_scale"),
        (dict(leg_scale=float("inf")), "leg_scale"),
        (dict(height=1.8, scale=1.1), "not both"),
        (dict(bone_scales={"nope": 1.1}), "no joint"),
    ],
)
def test_scale_skeleton_errors(kw, msg):
    with pytest.raises(MotionError, match=msg):
        scale_skeleton(mixamo_skeleton(), **kw)


def test_zero_length_limb_bone_is_refused():
    off = np.array([o for _, _, o in MIXAMO])
    off[MIXAMO_NAMES.index("LeftHand")] = 0.0  # zero forearm
    with pytest.raises(MotionError, match="zero-length"):
        mixamo_skeleton(offsets=off)
    off = np.array([o for _, _, o in MIXAMO])
    off[MIXAMO_NAMES.index("RightLeg")] = 0.0  # zero thigh
    with pytest.raises(MotionError, match="RightLeg"):
        mixamo_skeleton(offsets=off)
    # a scaled skeleton cannot make it zero either (factors are > 0), but bone_scales=0 is refused
    with pytest.raises(MotionError):
        scale_skeleton(mixamo_skeleton(), bone_scales={"LeftLeg": 0.0})


def test_nan_offsets_and_bad_tree_are_refused():
    off = np.array([o for _, _, o in MIXAMO])
    off[3, 1] = np.nan
    with pytest.raises(MotionError, match="NaN"):
        mixamo_skeleton(offsets=off)
    with pytest.raises(MotionError):
        mixamo_skeleton(parents=np.array([-1] + MIXAMO_PARENTS[1:-1] + [30]))
    with pytest.raises(MotionError):
        skeleton_of("not a skeleton")


def test_rest_motion_roundtrips_through_skeleton():
    sk = mixamo_skeleton()
    m = sk.rest_motion(3)
    assert m.n_frames == 3
    np.testing.assert_allclose(m.global_positions()[1], sk.rest_positions())
    sk2 = Skeleton.from_motion(m)
    assert sk2.roles == sk.roles and sk2.height == pytest.approx(sk.height)


# --------------------------------------------------------------- real data
@pytest.mark.data("cmu-bvh")
def test_cmu_135_sizes():
    m = read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)
    sk = Skeleton.from_motion(m)
    assert sk.roles == CMU_EXPECTED
    # mocap/cmu/PROVENANCE.md: subject 135 leg (femur+tibia) 0.830 m, arm (humerus+radius) 0.485 m
    assert sk.to_metres(sk.limb_lengths["left_leg"]) == pytest.approx(0.830, abs=1e-3)
    assert sk.to_metres(sk.limb_lengths["left_arm"]) == pytest.approx(0.485, abs=1e-3)
    # rest-pose head-top-to-toe height is 28.15 units (1.589 m); the straightened stature is
    # longer (legs abducted ~20 degrees in the CMU rest pose) but within 5 %
    assert 28.15 < sk.height < 1.05 * 28.15
    assert 1.58 < sk.size < 1.67
    assert sk.head_top > 0 and sk.ankle_height > 0


@pytest.mark.data("bandai")
def test_bandai_sizes():
    m = read_bvh(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"), unit_m=BANDAI_UNIT_M)
    sk = Skeleton.from_motion(m)
    assert sk.roles == BANDAI_EXPECTED
    # mocap/bandai/PROVENANCE.md: leg (UpperLeg->Foot) 0.80 m, arm (UpperArm->Hand) 0.47 m
    assert sk.to_metres(sk.leg_length) == pytest.approx(0.80, abs=0.01)
    assert sk.to_metres(sk.arm_length) == pytest.approx(0.47, abs=0.01)
    # the rest pose is a straight line along +X: the ankle height is not measurable and the head End
    # Site has zero length, so the stature estimates both (issue 25); the hip height stands on the
    # stature's sole (it counted 0 there: 0.823 m, 6.4 cm short of it)
    assert sk.ankle_height == sk.stature.sole_to_ankle > 0
    assert sk.hip_height == pytest.approx(sk.stature.sole_to_ankle + sk.leg_length + sk.hip_drop, rel=1e-12)
    assert sk.to_metres(sk.hip_height) == pytest.approx(0.886, abs=1e-3)
    assert sk.stature.foot == "estimated" and sk.stature.top == "estimated"
    assert "head top estimated" in sk.stature_method and sk.head_top > 0
    # the Head joint stands 1.34-1.41 m above the lowest joint; the stature is 1.46 m
    assert 1.40 < sk.size < 1.52
    # the one Bandai take whose head has an End Site measures the same actor within 1 %
    bow = Skeleton.from_motion(read_bvh(data.fetch("mocap/bandai/dataset-1_bow_normal_001.bvh"),
                                        unit_m=BANDAI_UNIT_M))
    assert bow.stature.top == "End Site"
    assert bow.size == pytest.approx(sk.size, rel=0.01)


# ------------------------------------------------------- stature, one way on every rig (issue 25)
def _rig_stature(rig, roles=None) -> Skeleton:
    return Skeleton.from_motion(rig.motion(unit_m=1.0), roles=roles)


@pytest.mark.parametrize("height", [1.6, 1.75, 1.9])
def test_the_synthetic_actors_measure_their_built_height(height):
    sk = Skeleton.from_motion(synthetic_skeleton(height))
    assert sk.size == pytest.approx(height, rel=1e-14)
    assert sk.stature.foot != "estimated" and sk.stature.top == "End Site"


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_every_convention_measures_the_built_height(convention):
    rig, _ = build(convention, height=1.8)
    assert _rig_stature(rig).size == pytest.approx(1.8, rel=1e-12)


def test_rest_posture_and_helper_joints_do_not_change_the_stature():
    sk = _rig_stature(build("secondlife")[0])
    base = sk.height
    # Second Life bento: mSpine1 goes up, mSpine2 comes back (the bone lengths summed gave 2.20 m)
    rig, _ = build("secondlife")
    rig.offsets[rig.i("mSpine1")] = np.array([0.0, 0.084, 0.0])
    rig.offsets[rig.i("mSpine2")] = np.array([0.0, -0.084, 0.0])
    assert _rig_stature(rig).height == pytest.approx(base, rel=1e-12)
    # a twist joint halfway along each thigh and shin (the roles as before: found in roles.py)
    rig, _ = build("secondlife")
    for j in ("mKneeLeft", "mAnkleLeft", "mKneeRight", "mAnkleRight"):
        rig.insert_above(j, j + "Twist", 0.5)
    assert _rig_stature(rig, roles=sk.roles).height == pytest.approx(base, rel=1e-12)
    # the whole rig lying along +X, or turned Z up, or in an A pose
    for rot in (Rotation.from_euler("z", -90, degrees=True), Rotation.from_euler("x", 90, degrees=True)):
        assert _rig_stature(build("secondlife")[0].transform(rot)).height == pytest.approx(base, rel=1e-12)
    assert _rig_stature(build("smpl")[0]).height == pytest.approx(base, rel=1e-12)


def test_a_head_without_top_is_estimated_and_said():
    rig, _ = build("mixamo")
    rig.end_sites["mixamorig:Head"] = np.array([0.0, 1e-3, 0.0])  # a stub End Site
    rig.remove("mixamorig:HeadTop_End")
    sk = _rig_stature(rig)
    st = sk.stature
    assert st.top == "estimated" and "head top estimated" in sk.stature_method
    # the head joint at HEAD_JOINT_FRACTION of the stature (the synthetic actor's is at 0.90)
    assert st.head_top == pytest.approx((st.height - st.head_top) * (1 / HEAD_JOINT_FRACTION - 1))
    assert 1.65 < sk.size < 1.75
    # the eyes, in front of the head joint, are no head top
    rig.add_leaf("mixamorig:Head", "mixamorig:LeftEye", (0.03, 0.08, 0.09))
    assert _rig_stature(rig).stature.top == "estimated"
    # Mixamo's HeadTop_End joint is one
    rig.add_leaf("mixamorig:Head", "mixamorig:HeadTop_End", (0.0, 0.175, 0.0))
    assert _rig_stature(rig).stature.top == "joint mixamorig:HeadTop_End"
    assert _rig_stature(rig).size == pytest.approx(1.75)


def test_a_foot_along_the_shin_is_estimated():
    rig, _ = build("motionbuilder")
    for s in ("Left", "Right"):  # toes straight below the ankle: the rest foot tells no sole
        rig.offsets[rig.i(f"{s}Toe")] = np.array([0.0, -0.13, 0.0])
        rig.end_sites[f"{s}Toe"] = np.array([0.0, -0.06, 0.0])
    sk = _rig_stature(rig)
    assert sk.stature.foot == "estimated"
    assert sk.stature.sole_to_ankle == pytest.approx(ANKLE_PER_LEG * sk.stature.leg)
    assert ANKLE_PER_LEG == pytest.approx(0.039 / 0.491)


# ------------------------------------------------------------------- hostile arguments (issue 23)
@pytest.mark.parametrize("factor", [1e300, 1e200, 1e160])
def test_offsets_too_large_are_named_as_overflow_not_zero_length(factor):
    """Scaled by 1e300 the squared lengths overflow: it used to be reported as zero-length limb bones."""
    with pytest.raises(MotionError, match="overflow") as info:
        scale_skeleton(mixamo_skeleton(), scale=factor)
    assert "zero-length" not in str(info.value)
    off = np.array([o for _, _, o in MIXAMO]) * factor
    with pytest.raises(MotionError, match="overflow"):
        mixamo_skeleton(offsets=off)
    with pytest.raises(MotionError, match="overflow"):
        mixamo_skeleton(offsets=off, roles=dict(mixamo_skeleton().roles))


def test_offsets_too_small_are_named_as_underflow():
    with pytest.raises(MotionError, match="underflow"):
        scale_skeleton(mixamo_skeleton(), scale=1e-300)


def test_a_large_but_computable_skeleton_is_accepted():
    sk = scale_skeleton(mixamo_skeleton(), scale=1e50)
    assert np.isfinite(sk.bone_lengths).all() and sk.leg_length > 1e49


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda sk: skeleton_of(sk, roles=["a"]), "roles"),
        (lambda sk: skeleton_of(sk, roles={"pelvis": 0}), "roles"),
        (lambda sk: sk.index(["Hips"]), "string"),
        (lambda sk: sk.bone_length(None), "string"),
        (lambda sk: sk.path(1, "Head"), "string"),
        (lambda sk: sk.to_metres("x"), "value"),
        (lambda sk: sk.rest_motion(0), "n_frames"),
        (lambda sk: sk.rest_motion("3"), "n_frames"),
        (lambda sk: sk.rest_motion(10**12), "n_frames"),  # a budget, not a MemoryError
        (lambda sk: sk.is_compatible("sk"), "Skeleton or a Motion"),
        (lambda sk: scale_skeleton(sk, arm_scale="1"), "arm_scale"),
        (lambda sk: scale_skeleton(sk, height=True), "height"),
        (lambda sk: scale_skeleton(sk, bone_scales=[("Hips", 2.0)]), "bone_scales"),
        (lambda sk: mixamo_skeleton(unit_m="m"), "unit_m"),
    ],
)
def test_skeleton_methods_refuse_bad_arguments(call, match):
    with pytest.raises(MotionError, match=match):
        call(mixamo_skeleton())


def test_from_motion_with_offsets_and_rescale_constraint_check_their_arguments():
    sk = mixamo_skeleton()
    with pytest.raises(MotionError, match="Motion"):
        Skeleton.from_motion(sk)
    with pytest.raises(MotionError, match="offsets"):
        sk.with_offsets("x")
    with pytest.raises(MotionError, match="end_site_offsets"):
        sk.with_offsets(sk.offsets, [1.0, 2.0])
    with pytest.raises(MotionError, match="constraint"):
        rescale_constraint("abc", 1.0, 1.0)
    with pytest.raises(MotionError, match="constraint"):
        rescale_constraint([1.0, 2.0], 1.0, 1.0)


def test_rescale_constraint_refuses_a_ratio_that_overflows():
    with pytest.raises(MotionError, match="overflows"):
        rescale_constraint([0.1, 1.2, 0.5], 1.7, 1e-320)  # was [inf, inf, inf]
    with pytest.raises(MotionError, match="overflows"):  # was a RuntimeWarning (overflow in multiply)
        rescale_constraint(np.full(3, 1e300), 1e12, 1.0)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(joint_names=None), "joint_names"),  # found by the argument fuzzer: TypeError
        (dict(joint_names=np.array(1.0)), "joint_names"),
        (dict(parents=range(10**12)), "parents"),  # MemoryError
        (dict(channels=float("nan")), "channels"),  # TypeError
        (dict(end_site_parents="x"), "end_site_parents"),  # ValueError from astype
        (dict(end_site_parents=None), "end_site_parents"),
    ],
)
def test_skeleton_fields_of_the_wrong_type_are_motion_errors(kw, match):
    with pytest.raises(MotionError, match=match):
        mixamo_skeleton(**kw)
