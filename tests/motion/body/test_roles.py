"""Body-part roles of any skeleton (repro.motion.body.roles.find_roles)."""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.body.roles import REQUIRED_ROLES, ROLES, check_roles, effector_role, find_roles, is_helper_name
from tests.motion.body.role_tables import (
    BANDAI_EXPECTED,
    BANDAI_NAMES,
    BANDAI_PARENTS,
    CMU_EXPECTED,
    CMU_NAMES,
    CMU_PARENTS,
    MIXAMO_EXPECTED,
    MIXAMO_NAMES,
    MIXAMO_PARENTS,
)


@pytest.mark.parametrize(
    "names, parents, expected",
    [
        (CMU_NAMES, CMU_PARENTS, CMU_EXPECTED),
        (BANDAI_NAMES, BANDAI_PARENTS, BANDAI_EXPECTED),
        (MIXAMO_NAMES, MIXAMO_PARENTS, MIXAMO_EXPECTED),
    ],
    ids=["cmu", "bandai", "mixamo"],
)
def test_find_roles_three_conventions(names, parents, expected):
    # with the tree (trunk from the tree) and from the names alone: same table
    assert find_roles(names, parents) == expected
    assert find_roles(names) == expected
    assert set(expected) <= set(ROLES)


def test_find_roles_namespace_case_and_separators():
    names = ["mixamorig:" + n for n in MIXAMO_NAMES]
    roles = find_roles(names, MIXAMO_PARENTS)
    assert roles["left_elbow"] == "mixamorig:LeftForeArm" and roles["pelvis"] == "mixamorig:Hips"
    # upper-case CMU names, "Left_"/"_R" spellings
    upper = [n.upper() for n in CMU_NAMES]
    assert find_roles(upper, CMU_PARENTS)["right_knee"] == "RTIBIA"
    alt = [n.replace("Left", "Left_").replace("Right", "R_") for n in MIXAMO_NAMES]
    roles = find_roles(alt, MIXAMO_PARENTS)
    assert roles["left_knee"] == "Left_Leg" and roles["right_ankle"] == "R_Foot"


def test_find_roles_missing_role_is_named():
    names = [n for n in MIXAMO_NAMES if n not in ("LeftLeg", "LeftFoot", "LeftToeBase")]
    with pytest.raises(MotionError, match="left_knee") as e:
        find_roles(names)
    assert "left_ankle" in str(e.value) and "overrides" in str(e.value)


def test_find_roles_overrides():
    names = list(MIXAMO_NAMES)
    i = names.index("LeftForeArm")
    names[i] = "L_elbow_jnt_custom"
    with pytest.raises(MotionError, match="left_elbow"):
        find_roles(names, MIXAMO_PARENTS)
    roles = find_roles(names, MIXAMO_PARENTS, overrides={"left_elbow": "L_elbow_jnt_custom"})
    assert roles["left_elbow"] == "L_elbow_jnt_custom"
    with pytest.raises(MotionError, match="no such joint"):
        find_roles(names, MIXAMO_PARENTS, overrides={"left_elbow": "nope"})
    with pytest.raises(MotionError, match="unknown role"):
        find_roles(names, MIXAMO_PARENTS, overrides={"left_pinky": "Hips"})


def test_find_roles_rejects_broken_limb_chain():
    # knee not the child of the hip: two-bone IK impossible
    parents = list(MIXAMO_PARENTS)
    parents[MIXAMO_NAMES.index("LeftLeg")] = MIXAMO_NAMES.index("Hips")
    with pytest.raises(MotionError, match="not a chain down the tree"):
        find_roles(MIXAMO_NAMES, parents)


def test_required_roles_are_roles():
    assert set(REQUIRED_ROLES) <= set(ROLES)


# ------------------------------------------------------------------ hostile arguments (issue 23)
@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(joint_names="Hips"), "joint_names"),
        (dict(joint_names=None), "joint_names"),
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 0.5]), "parents"),
        (dict(joint_names=["Hips", "Spine"], parents="ab"), "parents"),
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 0], offsets="x"), "offsets"),
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 0], offsets=[[0, 0, 0], [0, 1j, 0]]), "offsets"),
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 0], offsets=[[0, 0, 0], [0, 1e300, 0]]), "overflow"),
        (dict(joint_names=["Hips", "Spine"], overrides=["pelvis"]), "overrides"),
        (dict(joint_names=["Hips", "Spine"], required="pelvis"), "required"),
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 0], end_site_parents=[7]), "end_site_parents"),
    ],
)
def test_find_roles_refuses_bad_arguments(kw, match):
    with pytest.raises(MotionError, match=match):
        find_roles(**kw)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: is_helper_name(["Hips"]), "string"),  # an unhashable name used to fail in the cache
        (lambda: is_helper_name(None), "string"),
        (lambda: effector_role(None, "right_fist", "RightHand"), "roles"),
        (lambda: effector_role({}, 3, "RightHand"), "hit_role"),
        (lambda: effector_role({}, "right_fist", None), "hit_joint"),
        (lambda: check_roles(0, "a punch"), "roles"),
        (lambda: check_roles({}, ["a punch"]), "purpose"),
    ],
)
def test_role_helpers_refuse_bad_arguments(call, match):
    with pytest.raises(MotionError, match=match):
        call()


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(joint_names=np.array(1.0)), "joint_names"),  # iteration over a 0-d array
        (dict(joint_names=[[1], [1, 2]]), "joint_names"),
        (dict(joint_names=np.zeros(10**6 + 1)), "joints"),  # 10**7 names took minutes
        (dict(joint_names=["Hips", "Spine"], parents=[-1, 10**9]), "parents"),  # IndexError
        (dict(joint_names=["Hips", "Spine", "Head"], parents=[1, 0, -1]), "parents"),  # reversed: a hang
    ],
)
def test_find_roles_refuses_what_the_argument_fuzzer_found(kw, match):
    with pytest.raises(MotionError, match=match):
        find_roles(**kw)


def test_check_roles_checks_the_joint_names():
    with pytest.raises(MotionError, match="joint_names"):  # list(-1) in the message: a TypeError
        check_roles({}, "a punch", -1)
