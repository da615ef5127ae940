"""Roles on the conventions of real rigs (issue 25, "Real files to build on"): MakeHuman's default
rig (``.L``/``.R``, numbered twist segments ``01``/``02`` inside the bones: the roles on the ``01``s, a root above ``pelvis.L``/``.R`` and
``spine05``), its game rig (``Root`` the spine base, ``Hips`` a separate child carrying the legs,
``UpArm_L``/``LoArm_L``, ``__`` helpers) and a CMU-style rig without a head joint."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro.motion import read_bvh
from repro.motion.body.roles import find_roles
from repro.motion.body.skeleton import Skeleton


def rig(joints, z_up: bool = False, scale: float = 1.0):
    """(names, parents, offsets) of ``(name, parent, offset)`` rows (Y up, facing +Z, left on
    +X); ``z_up`` turns it to Z up (facing -Y), ``scale`` is the file unit."""
    names = [n for n, _, _ in joints]
    par = np.array([-1 if p is None else names.index(p) for _, p, _ in joints])
    off = np.array([o for _, _, o in joints], dtype=float) * scale
    if z_up:
        off = off[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0])
    return names, par, off


def sided(rows, left, right):
    """Rows ``(name, parent, left offset)`` on both sides: ``{}`` in a name is the side (``left``,
    ``right``), a parent ``=name`` a joint of the trunk; x mirrored."""
    out = []
    for tok, x in ((left, 1.0), (right, -1.0)):
        for stem, pstem, o in rows:
            parent = pstem[1:] if pstem.startswith("=") else pstem.format(tok)
            out.append((stem.format(tok), parent, (x * o[0], o[1], o[2])))
    return out


def arm_down(deg: float, length: float):
    """An offset of ``length`` along +X turned ``deg`` below the horizontal (A-pose)."""
    a = np.radians(deg)
    return (length * np.cos(a), -length * np.sin(a), 0.0)


def makehuman_default(deg: float = 48.0):
    """MakeHuman's default skeleton in miniature: a root with pelvis.L/.R and spine05 .. spine01,
    twist segments 01/02 on the limbs, fingers and a face bone; A-pose, Z up, decimetres."""
    j = [("root", None, (0, 9.6, 0)), ("spine05", "root", (0, 0.3, 0)), ("spine04", "spine05", (0, 0.8, 0)),
         ("spine03", "spine04", (0, 0.7, 0)), ("spine02", "spine03", (0, 0.8, 0)),
         ("spine01", "spine02", (0, 1.4, 0)), ("neck01", "spine01", (0, 1.7, 0)), ("neck02", "neck01", (0, 0.4, 0)),
         ("head", "neck02", (0, 0.4, 0)), ("jaw", "head", (0, -0.2, 0.6)), ("special06", "head", (0, 1.3, 0)),
         ("oculi01", "head", (0, 0.5, 0.9))]
    legs = [("pelvis{}", "=root", (0.0, -0.3, 0.0)), ("upperleg01{}", "pelvis{}", (1.0, -0.1, 0)),
            ("upperleg02{}", "upperleg01{}", (0.1, -0.8, 0)), ("lowerleg01{}", "upperleg02{}", (0.3, -3.2, 0)),
            ("lowerleg02{}", "lowerleg01{}", (0.1, -2.0, 0)), ("foot{}", "lowerleg02{}", (0.1, -2.0, 0)),
            ("metatarsal1{}", "foot{}", (0.0, -0.3, 0.7)), ("toe1-1{}", "metatarsal1{}", (0.0, -0.2, 0.7))]
    arms = [("clavicle{}", "=spine01", (0.2, 1.0, 0)), ("shoulder01{}", "clavicle{}", (0.8, 0.2, 0)),
            ("upperarm01{}", "shoulder01{}", arm_down(deg, 0.6)), ("upperarm02{}", "upperarm01{}", arm_down(deg, 0.7)),
            ("lowerarm01{}", "upperarm02{}", arm_down(deg, 1.8)), ("lowerarm02{}", "lowerarm01{}", arm_down(deg, 1.2)),
            ("wrist{}", "lowerarm02{}", arm_down(deg, 1.2)), ("finger2-1{}", "wrist{}", arm_down(deg, 0.7)),
            ("finger3-1{}", "wrist{}", arm_down(deg, 0.8)), ("metacarpal1{}", "wrist{}", arm_down(deg, 0.3))]
    return rig(j + sided(legs, ".L", ".R") + sided(arms, ".L", ".R"), z_up=True)


MAKEHUMAN_DEFAULT_ROLES = {
    "pelvis": "root", "spine": "spine05", "chest": "spine01", "neck": "neck01", "head": "head",
    "left_hip": "upperleg01.L", "left_knee": "lowerleg01.L", "left_ankle": "foot.L", "left_toe": "metatarsal1.L",
    "left_shoulder": "upperarm01.L", "left_elbow": "lowerarm01.L", "left_wrist": "wrist.L",
    "left_fist": "wrist.L", "left_clavicle": "clavicle.L",
}  # fmt: skip


def test_makehuman_default_rig_roles_land_on_the_anatomical_joints():
    names, par, off = makehuman_default()
    r = find_roles(names, par, offsets=off)
    # the twist segments (upperarm02, lowerarm02, upperleg02, lowerleg02) lie inside the bones,
    # between the anatomical joints: shoulder upperarm01 -> elbow lowerarm01 -> wrist wrist.L
    assert {k: r[k] for k in MAKEHUMAN_DEFAULT_ROLES} == MAKEHUMAN_DEFAULT_ROLES
    assert r["right_elbow"] == "lowerarm01.R" and r["right_knee"] == "lowerleg01.R"
    assert "left_hand" not in r  # the wrist branches into fingers
    assert not {"upperarm02.L", "lowerarm02.L", "upperleg02.L", "lowerleg02.L"} & set(r.values())
    Skeleton(names, par, off)  # and a Skeleton takes it


@pytest.mark.parametrize("bent", [0.0, 40.0])
def test_a_bent_numbered_segment_is_a_joint(bent):
    """A numbered segment is a twist joint only where the bone runs straight through it: bent
    there, it is a joint of the chain (here it makes the wrist the end of a third bone)."""
    from repro.motion.body.role_structure import TWIST_COLLINEAR_DEG, _without_twist_joints

    names = ["a", "upperarm01.L", "upperarm02.L", "lowerarm01.L"]
    P = np.array([[0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [2.0 + np.cos(np.radians(bent)), np.sin(np.radians(bent)), 0]])
    kept = _without_twist_joints([0, 1, 2, 3], names, P)
    assert kept == ([0, 1, 3] if bent <= TWIST_COLLINEAR_DEG else [0, 1, 2, 3])


def makehuman_game():
    """MakeHuman's game rig in miniature: Root (the spine base) with Spine1 .. Neck, Head and a
    separate Hips carrying the legs, ``__`` helpers above the clavicles and thighs; Z up, dm."""
    j = [("Root", None, (0, 9.6, 0)), ("Spine1", "Root", (0, 0.5, 0)), ("Spine2", "Spine1", (0, 1.0, 0)),
         ("Spine3", "Spine2", (0, 1.3, 0)), ("Neck", "Spine3", (0, 2.0, 0)), ("Head", "Neck", (0, 1.1, 0)),
         ("__Jaw", "Head", (0, 1.3, 0)), ("Jaw", "__Jaw", (0, -1.4, 0.5)), ("Hips", "Root", (0, 0.5, 0))]
    legs = [("__UpLeg{}", "=Hips", (0, -0.8, 0)), ("UpLeg{}", "__UpLeg{}", (1.0, -0.2, 0)),
            ("LoLeg{}", "UpLeg{}", (0, -4.2, 0)), ("Foot{}", "LoLeg{}", (0, -3.9, 0)), ("Toe{}", "Foot{}", (0, -0.7, 1.1))]
    arms = [("__Clavicle{}", "=Spine3", (0, 2.0, 0)), ("Clavicle{}", "__Clavicle{}", (0.25, -0.6, 0)),
            ("UpArm{}", "Clavicle{}", (1.5, 0.5, 0)), ("LoArm{}", "UpArm{}", (2.0, 0, 0)),
            ("Hand{}", "LoArm{}", (2.4, 0, 0)), ("__Index1{}", "Hand{}", (1.0, 0, 0)),
            ("Index1{}", "__Index1{}", (0.2, 0, 0)), ("Middle1{}", "Hand{}", (1.0, 0, 0)),
            ("Middle2{}", "Middle1{}", (0.3, 0, 0)), ("__Ring1{}", "Hand{}", (1.0, 0, 0)),
            ("Ring1{}", "__Ring1{}", (0.2, 0, 0))]
    return rig(j + sided(legs, "_L", "_R") + sided(arms, "_L", "_R"), z_up=True)


def test_makehuman_game_rig_root_is_the_spine_base_and_hips_carry_the_legs():
    names, par, off = makehuman_game()
    want = {"pelvis": "Root", "spine": "Spine1", "chest": "Spine3", "neck": "Neck", "head": "Head",
            "left_hip": "UpLeg_L", "left_knee": "LoLeg_L", "left_ankle": "Foot_L", "left_toe": "Toe_L",
            "left_shoulder": "UpArm_L", "left_elbow": "LoArm_L", "left_wrist": "Hand_L", "left_fist": "Hand_L",
            "right_elbow": "LoArm_R", "right_knee": "LoLeg_R"}
    r = find_roles(names, par, offsets=off)
    assert {k: r[k] for k in want} == want
    # the names and the tree alone agree on the limbs (no "__" helper taken for the thigh)
    r2 = find_roles(names, par)
    assert {k: r2[k] for k in want} == want
    Skeleton(names, par, off)


def cmu_without_head(arms_down: bool = True):
    """CMU/ASF names, no head joint (the neck chain ``LowerNeck`` -> ``Neck`` ends the trunk), no
    End Site; arms hanging down, Z up, inches."""
    arm = (0, -10.6, 0) if arms_down else (10.6, 0, 0)
    j = [("pelvis", None, (0, 36, 0)), ("lowerback", "pelvis", (0, 3.6, -2)), ("upperback", "lowerback", (0, 5.7, 1)),
         ("LowerNeck", "upperback", (0, 8.3, 0)), ("Neck", "LowerNeck", (0, 3.1, -1.6))]
    legs = [("{}femur", "=pelvis", (4, 0, 0)), ("{}tibia", "{}femur", (0, -16, 0)), ("{}foot", "{}tibia", (0, -15.8, 0)),
            ("{}toes", "{}foot", (0, -1.3, 4))]
    arms = [("{}clavicle", "=upperback", (0, 8.3, 0)), ("{}humerus", "{}clavicle", (5.5, -0.5, 0)),
            ("{}radius", "{}humerus", arm), ("{}hand", "{}radius", tuple(0.8 * np.array(arm)))]
    return rig(j + sided(legs, "l", "r") + sided(arms, "l", "r"), z_up=True)


@pytest.mark.parametrize("arms_down", [True, False])
def test_no_head_joint_the_head_is_the_top_of_the_neck(arms_down):
    names, par, off = cmu_without_head(arms_down)
    r = find_roles(names, par, offsets=off, end_site_parents=[])
    assert r["head"] == "Neck" and r["neck"] == "LowerNeck" and r["chest"] == "upperback"
    assert r["left_elbow"] == "lradius" and r["right_knee"] == "rtibia"


# ------------------------------------------------------------------ the real files, when staged
def _realrig(name):
    p = Path(os.environ.get("REPRO_DATA_DIR") or "/nonexistent") / "mocap" / "formats" / "realrigs" / name
    if not p.is_file():
        pytest.skip(f"{p} not staged (set REPRO_DATA_DIR)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_bvh(p)


@pytest.mark.parametrize("name, want", [
    ("makehuman_default_rig_tpose.bvh", {"pelvis": "root", "chest": "spine01", "head": "head",
                                         "left_shoulder": "upperarm01.L", "left_elbow": "lowerarm01.L",
                                         "left_wrist": "wrist.L", "right_hip": "upperleg01.R",
                                         "right_knee": "lowerleg01.R", "right_ankle": "foot.R",
                                         "right_toe": "metatarsal3.R",  # the middle of the five toes
                                         "right_clavicle": "clavicle.R", "right_fist": "wrist.R"}),
    ("makehuman_game_rig_zombiewalk.bvh", {"pelvis": "Root", "chest": "Spine3", "head": "Head",
                                           "left_elbow": "LoArm_L", "right_knee": "LoLeg_R"}),
    ("emretanirgan_jump_no_end_sites.bvh", {"head": "Neck", "neck": "LowerNeck", "left_elbow": "lradius"}),
])  # fmt: skip
def test_real_rigs(name, want):
    m = _realrig(name)
    r = find_roles(m.joint_names, m.parents, offsets=m.offsets, end_site_parents=m.end_site_parents)
    assert {k: r[k] for k in want} == want
