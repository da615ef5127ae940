"""Roles from the joint tree and the rest pose first, names second (issue 11, item 1)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro import data
from repro.errors import MotionError
from repro.motion import read_bvh
from repro.motion.body.roles import check_roles, find_roles, is_helper_name
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic.conventions import CONVENTIONS, build, expected_roles
from tests.motion.body.role_tables import MIXAMO_EXPECTED, MIXAMO_NAMES, MIXAMO_PARENTS


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_roles_of_every_convention(convention):
    rig, _ = build(convention)
    m = rig.motion(unit_m=1.0)
    assert find_roles(m.joint_names, m.parents, offsets=m.offsets) == expected_roles(convention)
    Skeleton.from_motion(m)  # and the skeleton accepts it (no zero-length limb bone)


@pytest.mark.parametrize("convention", ["motionbuilder", "secondlife", "smpl", "unsided"])
def test_names_alone_do_not_find_these(convention):
    # the conventions the issue reported as failing: only the structure finds them
    rig, _ = build(convention)
    m = rig.motion(unit_m=1.0)
    with pytest.raises(MotionError):
        find_roles(m.joint_names, m.parents)


def test_motionbuilder_shoulder_is_the_upper_arm():
    m = build("motionbuilder")[0].motion(1.0)
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets)
    assert r["right_clavicle"] == "RightCollar" and r["right_shoulder"] == "RightShoulder"
    assert r["chest"] == "Chest4" and r["spine"] == "Chest"


def test_side_from_rest_pose_when_names_are_silent():
    m = build("unsided")[0].motion(1.0)
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets)
    left = m.joint_names.index(r["left_shoulder"])
    # the synthetic actor faces +Z with its left on +X
    assert Skeleton.from_motion(m).rest_positions()[left, 0] > 0
    # mirror the rig (x -> -x): the sides swap
    off = m.offsets * np.array([-1.0, 1.0, 1.0])
    r2 = find_roles(m.joint_names, m.parents, offsets=off)
    assert r2["left_shoulder"] == r["right_shoulder"] and r2["left_hip"] == r["right_hip"]


def test_names_still_decide_without_offsets():
    assert find_roles(MIXAMO_NAMES, MIXAMO_PARENTS) == MIXAMO_EXPECTED


def test_helper_names():
    for n in ("upperarm_twist_01_l", "mixamorig:LeftHandIndex1", "mFaceJaw", "HeadTop_End", "LeftEye",
              "mHandThumb1Left", "RightHandPinky3", "Bip01 L Finger0", "sword_prop", "lIndex1"):
        assert is_helper_name(n), n
    for n in ("LeftHand", "hand.L", "lhand", "Hand_L", "mWristLeft", "LeftForeArm", "upperarm_l", "Spine",
              "Head", "LeftToeBase", "Bip01 L Hand", "lShldr", "lShin", "RightShoulder", "mHipLeft"):
        assert not is_helper_name(n), n


def test_explicit_roles_override_structure():
    m = build("mixamo")[0].motion(1.0)
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets, overrides={"head": "mixamorig:Neck", "neck": "mixamorig:Spine1"})
    assert r["head"] == "mixamorig:Neck" and r["neck"] == "mixamorig:Spine1"


def test_conflicting_overrides():
    m = build("mixamo")[0].motion(1.0)
    with pytest.raises(MotionError, match="conflicting.*mixamorig:Spine"):
        find_roles(m.joint_names, m.parents, offsets=m.offsets,
                   overrides={"chest": "mixamorig:Spine", "spine": "mixamorig:Spine"})


def test_non_humanoid_tree():
    # a chain (a snake) and a two-branch tree: no pelvis hub
    names = [f"bone{i}" for i in range(6)]
    with pytest.raises(MotionError, match="humanoid|lacks"):
        find_roles(names, list(range(-1, 5)), offsets=np.tile([0.0, 0.1, 0.0], (6, 1)))


def test_two_arms_on_one_side():
    m = build("mixamo")[0].motion(1.0)
    names = [n.replace("RightArm", "LeftArmB").replace("RightForeArm", "LeftForeArmB") for n in m.joint_names]
    with pytest.raises(MotionError, match="two candidate arms on the left"):
        find_roles(names, m.parents, offsets=m.offsets)


def test_partial_skeleton_says_what_for():
    legs_only = {"pelvis": "Hips", "left_hip": "LH", "left_knee": "LK", "left_ankle": "LA", "left_foot": "LA"}
    check_roles(legs_only, "a kick")
    with pytest.raises(MotionError, match="a punch needs .*an arm") as e:
        check_roles(legs_only, "a punch", ["Hips", "LH", "LK", "LA"])
    assert "chest" in str(e.value)
    arms_only = {"pelvis": "P", "chest": "C", "left_shoulder": "S", "left_elbow": "E", "left_wrist": "W", "left_fist": "W"}
    check_roles(arms_only, "a punch")
    with pytest.raises(MotionError, match="a kick needs .*a leg"):
        check_roles(arms_only, "a kick")
    with pytest.raises(MotionError, match="retargeting needs"):
        check_roles(arms_only, "retargeting")
    with pytest.raises(MotionError, match="unknown purpose"):
        check_roles(arms_only, "a dance")


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_bvh(path)


def _formats(name):
    root = os.environ.get("REPRO_DATA_DIR")
    p = Path(root or "/nonexistent") / "mocap" / "formats" / "pybvh" / name
    if not p.is_file():
        pytest.skip(f"{p} not staged (set REPRO_DATA_DIR)")
    return p


def test_real_motionbuilder_and_60_joint_fixtures():
    m = _read(_formats("bvh_test2.bvh"))  # Chest..Chest4, RightShoulder = upper arm
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets)
    assert r["right_shoulder"] == "RightShoulder" and r["right_clavicle"] == "RightCollar"
    assert r["chest"] == "Chest4" and r["left_toe"] == "LeftToe"
    m = _read(_formats("bvh_test3.bvh"))  # 60 joints with fingers
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets)
    assert r["left_wrist"] == "LeftHand" and "left_hand" not in r and r["left_toe"] == "LeftForeFoot"
    assert r["chest"] == "Spine3" and r["neck"] == "Neck"


@pytest.mark.data("cmu-bvh")
def test_real_cmu_structure_agrees_with_names():
    m = _read(data.fetch("mocap/cmu/135_04.bvh"))
    assert find_roles(m.joint_names, m.parents, offsets=m.offsets) == find_roles(m.joint_names, m.parents)


@pytest.mark.data("bandai")
def test_real_bandai_line_rest_pose_falls_back_to_names():
    m = _read(data.fetch("mocap/bandai/dataset-1_kick_normal_001.bvh"))
    assert find_roles(m.joint_names, m.parents, offsets=m.offsets) == find_roles(m.joint_names, m.parents)
