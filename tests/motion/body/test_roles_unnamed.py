"""Roles from the structure alone: joints named j0..jN or random strings (issue 11, item 1).

The synthetic skeleton, restructured as other tools' rigs are (extra spine joints, twist
bones, fingers, a head-top marker joint, face leaves, zero-length helpers, a zero-length
root above the pelvis), in A-pose and T-pose, Y-up and Z-up, with every joint renamed to a
meaningless name: :func:`find_roles` (given the rest offsets and the End Sites, as
:class:`~repro.motion.body.skeleton.Skeleton` passes them) finds every role on the joint the
synthetic table names, and the stature (then the unit) follows.
"""

from __future__ import annotations

import dataclasses
import random
import string
import zlib

import numpy as np
import pytest

from repro.errors import MotionError, UnitWarning
from repro.motion.body.roles import find_roles
from repro.motion.body.skeleton import Skeleton, infer_unit
from repro.motion.database.synthetic.conventions import (
    SYNTHETIC_ROLES,
    Z_UP,
    RigConvention,
    a_pose,
    build,
    expected_roles,
)


def restructured(pose: str, up: str, height: float = 1.75) -> tuple[RigConvention, dict[str, str]]:
    """The synthetic rig with every kind of extra joint; (rig, expected role -> joint name)."""
    r = RigConvention.synthetic(height)
    r.split("Spine1", ["SpineA", "SpineB"])  # extra spine joints: the chest stays the top one
    r.insert_above("Hips", "RootHelper", 1.0)  # a root carrying the rest height, pelvis at zero length below
    r.insert_above("LeftForeArm", "LeftArmHelper", 0.0)  # zero-length helper below the shoulder: not the shoulder
    for s, x in (("Left", 1), ("Right", -1)):
        r.add_leaf(f"{s}Arm", f"{s}ArmTwist", (x * 0.1, 0, 0))
        r.add_leaf(f"{s}ForeArm", f"{s}ForeArmTwist", (x * 0.12, 0, 0))
        r.add_leaf(f"{s}UpLeg", f"{s}UpLegTwist", (0, -0.2, 0))
        r.fingers(f"{s}Hand", s + "Hand{f}{k}", x)
    r.add_leaf("Head", "HeadTop", (0, 0.17, 0))
    r.end_sites.pop("Head")  # the head-top marker joint ends the head chain (Mixamo HeadTop_End)
    r.add_leaf("Head", "EyeL", (0.03, 0.05, 0.08)).add_leaf("Head", "EyeR", (-0.03, 0.05, 0.08))
    if pose == "A":
        a_pose(r, "LeftArm", "RightArm", 40.0)
    if up == "z":
        r.transform(Z_UP)
    return r, dict(SYNTHETIC_ROLES)


def renamed(m, how: str, seed: int = 0):
    if how == "index":
        new = [f"j{i}" for i in range(m.n_joints)]
    else:
        rng = random.Random(seed)
        new = ["".join(rng.choice(string.ascii_letters + string.digits) for _ in range(10)) for _ in range(m.n_joints)]
    return dataclasses.replace(m, joint_names=new), dict(zip(m.joint_names, new))


@pytest.mark.parametrize("how", ["index", "random"])
@pytest.mark.parametrize("up", ["y", "z"])
@pytest.mark.parametrize("pose", ["T", "A"])
def test_roles_from_structure_with_meaningless_names(pose, up, how):
    rig, exp = restructured(pose, up)
    m0 = rig.motion(unit_m=1.0)
    named = find_roles(m0.joint_names, m0.parents, offsets=m0.offsets, end_site_parents=m0.end_site_parents)
    assert named == exp  # the names agree with the structure
    m, table = renamed(m0, how, seed=zlib.crc32(f"{pose}{up}".encode()) % 1000)  # str hash() is salted per process
    roles = find_roles(m.joint_names, m.parents, offsets=m.offsets, end_site_parents=m.end_site_parents)
    assert roles == {k: table[v] for k, v in exp.items()}
    with pytest.warns(UnitWarning, match="centimetres"):
        sk = Skeleton.from_motion(dataclasses.replace(m, unit_m=None).scaled(100.0))  # centimetres, unit unknown
    assert sk.roles == roles
    assert infer_unit(sk.height)[0] == pytest.approx(0.01)
    assert sk.height * 0.01 == pytest.approx(Skeleton.from_motion(m0).height, rel=1e-12)


@pytest.mark.parametrize("convention", ["mixamo", "motionbuilder", "poser", "secondlife", "biped", "smpl", "unreal",
                                        "unity", "blender"])
def test_every_convention_renamed_to_meaningless_names(convention):
    m0 = build(convention)[0].motion(unit_m=1.0)
    m, table = renamed(m0, "random", seed=len(convention))
    roles = find_roles(m.joint_names, m.parents, offsets=m.offsets, end_site_parents=m.end_site_parents)
    assert roles == {k: table[v] for k, v in expected_roles(convention).items()}


def test_random_names_do_not_read_as_sides():
    # "lq3Xz" or "rT7" are no left / right: a mirrored rest pose swaps the sides
    rig, exp = restructured("T", "y")
    m0 = rig.motion(unit_m=1.0)
    m, table = renamed(m0, "random", seed=3)
    m = dataclasses.replace(m, joint_names=[("l" if i % 2 else "r") + n for i, n in enumerate(m.joint_names)])
    table = {k: ("l" if i % 2 else "r") + v for i, (k, v) in enumerate(table.items())}
    roles = find_roles(m.joint_names, m.parents, offsets=m.offsets, end_site_parents=m.end_site_parents)
    assert roles == {k: table[v] for k, v in exp.items()}
    mirrored = find_roles(m.joint_names, m.parents, offsets=m.offsets * np.array([-1.0, 1.0, 1.0]),
                          end_site_parents=m.end_site_parents)
    assert mirrored["left_wrist"] == roles["right_wrist"] and mirrored["left_knee"] == roles["right_knee"]


def test_a_partial_meaningless_skeleton_is_refused_naming_the_roles():
    rig, _ = restructured("T", "y")
    m0 = rig.motion(unit_m=1.0)
    m, _ = renamed(m0, "index")
    keep = [j for j in range(m.n_joints) if not any(
        m0.joint_names[k].startswith("Left") for k in _ancestry(m0, j))]
    sub = _subset(m, keep)
    with pytest.raises(MotionError, match="left_"):
        find_roles(sub.joint_names, sub.parents, offsets=sub.offsets, end_site_parents=sub.end_site_parents)


def _ancestry(m, j):
    out = [j]
    while m.parents[out[-1]] >= 0:
        out.append(int(m.parents[out[-1]]))
    return out


def _subset(m, keep):
    new = {o: n for n, o in enumerate(keep)}
    esp = [e for e, p in enumerate(m.end_site_parents) if int(p) in new]
    return dataclasses.replace(
        m, joint_names=[m.joint_names[j] for j in keep],
        parents=np.array([-1 if m.parents[j] < 0 else new[int(m.parents[j])] for j in keep]),
        offsets=m.offsets[keep], channels=[m.channels[j] for j in keep], rotations=m.rotations[:, keep],
        positions=m.positions[:, keep],
        end_site_parents=np.array([new[int(m.end_site_parents[e])] for e in esp], dtype=np.intp),
        end_site_offsets=m.end_site_offsets[esp].reshape(-1, 3))


@pytest.mark.data("cmu-bvh")
@pytest.mark.parametrize("rel", ["mocap/cmu/135_04.bvh", "mocap/cmu/07_05.bvh", "mocap/formats/pybvh/bvh_test1.bvh",
                                 "mocap/formats/pybvh/bvh_test2.bvh", "mocap/formats/pybvh/bvh_test3.bvh"])
def test_real_files_renamed_keep_their_roles(rel):
    """Real rigs (CMU: clavicle joints on the trunk's midline, a wrist branching into hand and
    thumb; other tools' Z-up, MotionBuilder-named and 60-joint files) renamed j0..jN: the
    structure finds the roles their names give."""
    import warnings

    from repro import data
    from repro.motion import read_bvh

    path = data.data_dir() / rel
    if not path.is_file():
        pytest.skip(f"{rel} not staged")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = read_bvh(path)
    named = find_roles(m.joint_names, m.parents, offsets=m.offsets, end_site_parents=m.end_site_parents)
    r, table = renamed(m, "index")
    roles = find_roles(r.joint_names, r.parents, offsets=r.offsets, end_site_parents=r.end_site_parents)
    assert roles == {k: table[v] for k, v in named.items()}
