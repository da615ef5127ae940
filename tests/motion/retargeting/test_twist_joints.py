"""Twist joints inside the limb bones (issue 25: MakeHuman ``upperarm02.L``, Rigify-style
``upper_arm_twist.L``): Section 3.4.1's retargeting measures a limb between its joints as
positions and carries the twist joints along.

What is asserted: a character with a joint halfway along every upper arm, forearm, thigh and
shin (the same body as without them) gets the roles on its anatomical joints, and a clip
retargeted onto it puts every other joint where it goes on the character without them, by
both paths (another joint tree: :func:`~repro.motion.retargeting.trees.retarget_across`; the
same tree: :func:`~repro.motion.retargeting.morphology.retarget`, Kulpa's decode), with the
twist joints on their bones.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.motion.body.skeleton import Skeleton
from repro.motion.core.quaternion import quat_multiply
from repro.motion.database.synthetic import synthetic_clip
from repro.motion.database.synthetic.conventions import RigConvention
from repro.motion.retargeting.morphology import retarget
from repro.motion.retargeting.trees import retarget_across

#: the bones that get a twist joint halfway: (joint the bone ends at, its parent)
BONES = [(f"{s}{b}", f"{s}{a}") for s in ("Left", "Right")
         for a, b in (("Arm", "ForeArm"), ("ForeArm", "Hand"), ("UpLeg", "Leg"), ("Leg", "Foot"))]


def characters(arm: float, leg: float):
    """(plain, twisted): a body of the given proportions, without and with the twist joints."""
    plain = RigConvention.synthetic(1.6).proportions(arm, leg, 1.0)
    twisted = RigConvention.synthetic(1.6).proportions(arm, leg, 1.0)
    for end, start in BONES:
        twisted.insert_above(end, start + "Twist", 0.5)
    return plain.motion(unit_m=1.0), twisted.motion(unit_m=1.0)


def positions(m, names):
    return m.global_positions()[:, [m.joint_names.index(n) for n in names]]


@pytest.fixture(scope="module")
def clip():
    return synthetic_clip("kick_front", "right", "high", seed=3)[0]


def test_the_roles_are_the_anatomical_joints():
    plain, twisted = characters(1.1, 0.9)
    a, b = Skeleton.from_motion(plain), Skeleton.from_motion(twisted)
    assert a.roles == b.roles  # no twist joint takes a role
    assert b.limb_lengths == pytest.approx(a.limb_lengths, rel=1e-12)


def test_another_tree_puts_the_joints_where_they_go_without_twist_joints(clip):
    plain, twisted = characters(1.1, 0.9)
    a, b = retarget_across(clip, plain), retarget_across(clip, twisted)
    names = list(plain.joint_names)
    np.testing.assert_allclose(positions(b, names), positions(a, names), atol=1e-9)
    for end, start in BONES:  # halfway along the bone
        mid = 0.5 * (positions(b, [start])[:, 0] + positions(b, [end])[:, 0])
        np.testing.assert_allclose(positions(b, [start + "Twist"])[:, 0], mid, atol=1e-9)


def twisting(m, deg: float):
    """``m`` with each twist joint turned about its bone by up to ``deg`` (varying over the frames) and
    the joint below it turned back: the same world rotations and positions below it."""
    rot = np.array(m.rotations)
    ang = np.radians(deg) * np.sin(np.linspace(0.0, 3.0, m.n_frames))
    for end, start in BONES:
        t, e = m.joint_names.index(start + "Twist"), m.joint_names.index(end)
        axis = m.offsets[e] / np.linalg.norm(m.offsets[e])
        q = np.concatenate([np.sin(0.5 * ang)[:, None] * axis, np.cos(0.5 * ang)[:, None]], axis=1)
        rot[:, t] = quat_multiply(q, rot[:, t])
        rot[:, e] = quat_multiply(q * np.array([-1.0, -1.0, -1.0, 1.0]), rot[:, e])
    return dataclasses.replace(m, rotations=rot)


@pytest.mark.parametrize("fix_feet", [False, True])
def test_the_same_tree_decodes_as_without_twist_joints(clip, fix_feet):
    """Kulpa's decode onto a twisted tree of other proportions (the upper / lower ratios change, so
    the two-bone IK places the elbows and knees), the source's twist joints turned about their
    bones: the joints where the plain tree has them."""
    src_plain, src_twisted = (retarget_across(clip, c) for c in characters(1.1, 0.9))
    src_twisted = twisting(src_twisted, 40.0)
    names = list(src_plain.joint_names)
    np.testing.assert_allclose(positions(src_twisted, names), positions(src_plain, names), atol=1e-9)
    plain, twisted = characters(0.85, 1.2)
    a = retarget(src_plain, plain, fix_feet=fix_feet)
    b = retarget(src_twisted, twisted, fix_feet=fix_feet)
    np.testing.assert_allclose(positions(b, names), positions(a, names), atol=1e-9)
    for end, start in BONES:
        mid = 0.5 * (positions(b, [start])[:, 0] + positions(b, [end])[:, 0])
        np.testing.assert_allclose(positions(b, [start + "Twist"])[:, 0], mid, atol=1e-9)
