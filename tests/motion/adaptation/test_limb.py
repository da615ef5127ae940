"""The limb step of Section 3.4.2 (repro.motion.adaptation.limb): reachable targets reached to rounding,
hand orientation kept, bone lengths unchanged, elbow kept in its plane, one-frame scalar path == numpy
batch path; unreachable targets give the exact excess distance, not an exception."""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.adaptation import reach_limb
from tests.motion_fixtures import MIXAMO
from tests.motion.adaptation.fixture import IDX, OFFSETS, PARENTS, fixture_motion, quat_angle, with_rotations


def test_reach_limb_reaches_keeps_hand_and_bone_lengths():
    m = fixture_motion()
    gq, gp = m.global_transforms()
    w = IDX["RightHand"]
    goal = gp[:, w] + np.array([0.05, -0.08, 0.03])
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert sol.reached.all() and sol.residual.max() < 1e-12
    m2 = with_rotations(m, slice(None), sol.rotations)
    gq2, gp2 = m2.global_transforms()
    np.testing.assert_allclose(gp2[:, w], goal, atol=1e-12)
    np.testing.assert_allclose(sol.hit_positions, goal, atol=1e-12)
    assert quat_angle(gq2[:, w], gq[:, w]).max() < 1e-9  # hand keeps its world orientation
    # only the arm's three joints changed, bone lengths are the offsets'
    changed = np.any(np.abs(sol.rotations - m.rotations) > 1e-12, axis=(0, 2))
    assert set(np.flatnonzero(changed)) <= {IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]}
    lengths = np.linalg.norm(gp2[:, 1:] - gp2[:, PARENTS[1:]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(np.linalg.norm(OFFSETS[1:], axis=1), lengths.shape), atol=1e-12)


def test_reach_limb_identity_and_swivel_plane_kept():
    m = fixture_motion()
    gq, gp = m.global_transforms()
    s, e, w = IDX["RightArm"], IDX["RightForeArm"], IDX["RightHand"]
    same = reach_limb(m, np.arange(m.n_frames), "right_wrist", gp[:, w])
    assert quat_angle(same.rotations, np.asarray(m.rotations)).max() < 1e-7
    # moving the wrist within the arm's plane keeps the elbow in that plane
    n = np.cross(gp[:, e] - gp[:, s], gp[:, w] - gp[:, s])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    toward = gp[:, s] - gp[:, w]
    goal = gp[:, w] + 0.2 * toward
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    gp2 = with_rotations(m, slice(None), sol.rotations).global_positions()
    assert np.abs(np.sum((gp2[:, e] - gp[:, s]) * n, axis=1)).max() < 1e-9
    # and on the same side of the shoulder->wrist axis (the elbow bends the same way)
    side0 = np.sum(np.cross(gp[:, w] - gp[:, s], gp[:, e] - gp[:, s]) * n, axis=1)
    side1 = np.sum(np.cross(gp2[:, w] - gp[:, s], gp2[:, e] - gp[:, s]) * n, axis=1)
    assert np.all(np.sign(side0) == np.sign(side1))


def test_reach_limb_scalar_path_equals_batch():
    m = fixture_motion(n_frames=8, seed=3)
    gp = m.global_positions()
    goal = gp[:, IDX["LeftHand"]] + np.array([-0.1, 0.12, 0.2])  # partly out of reach
    batch = reach_limb(m, np.arange(8), "left_fist", goal, hit_point="end_site")
    assert not batch.reached.all()
    for f in range(8):
        one = reach_limb(m, f, "left_fist", goal[f], hit_point="end_site")
        # 1e-7 rad, not rounding: a fully extended arm is the singular pose of two-bone IK
        # (sin of the elbow angle ~ sqrt(rounding)), where both paths are equally right
        assert quat_angle(one.rotations[0], batch.rotations[f]).max() < 1e-7
        g1 = with_rotations(m, [f], one.rotations).global_positions()[f]
        g2 = with_rotations(m, [f], batch.rotations[[f]]).global_positions()[f]
        np.testing.assert_allclose(g1, g2, atol=1e-8)
        np.testing.assert_allclose(one.residual[0], batch.residual[f], atol=1e-12)
        np.testing.assert_allclose(one.hit_positions[0], batch.hit_positions[f], atol=1e-12)
    for ext in (1.0, 0.9):  # also with a reach limit
        b = reach_limb(m, np.arange(8), "left_fist", goal, max_extension=ext)
        o = reach_limb(m, 5, "left_fist", goal[5], max_extension=ext)
        assert quat_angle(o.rotations[0], b.rotations[5]).max() < 1e-9


def test_reach_limb_unreachable_gives_excess_distance():
    m = fixture_motion()
    gp = m.global_positions()
    s, w = IDX["RightArm"], IDX["RightHand"]
    L = np.linalg.norm(OFFSETS[IDX["RightForeArm"]]) + np.linalg.norm(OFFSETS[w])
    direction = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    goal = gp[:, s] + (L + 0.25) * direction
    sol = reach_limb(m, np.arange(m.n_frames), "right_wrist", goal)
    assert not sol.reached.any()
    np.testing.assert_allclose(sol.residual, 0.25, atol=1e-9)
    gp2 = with_rotations(m, slice(None), sol.rotations).global_positions()
    np.testing.assert_allclose(gp2[:, w], gp[:, s] + L * direction, atol=1e-9)  # fully extended towards it
    # too close (closer than |upper - forearm|): folded as far as it goes, no NaN
    close = reach_limb(m, 0, "right_wrist", gp[0, s] + 1e-3 * direction)
    assert np.all(np.isfinite(close.rotations)) and not close.reached[0]


def test_the_tip_of_a_joint_without_an_end_site_is_its_knuckles_or_itself():
    """hit_point="end_site" on a joint with no End Site (issue 25: a hand with fingers): the knuckles of the
    joints below it, else the joint itself (repro.motion.body.hit_points), never a refusal."""
    from repro.motion.body.hit_points import hit_offset
    from repro.motion.body.skeleton import skeleton_of
    from repro.motion.core.quaternion import quat_rotate

    m = fixture_motion()
    sk = skeleton_of(m)
    foot = sk.index("right_foot")
    off, src = hit_offset(sk, foot)
    assert not np.any(sk.end_site_parents == foot) and src in ("knuckles", "joint")
    gp = m.global_positions()
    target = gp[0, foot] + np.array([0.0, 0.05, 0.1])
    tip = reach_limb(m, 0, "right_foot", target, hit_point="end_site")
    assert tip.reached[0]
    g = with_rotations(m, slice(0, 1), tip.rotations).global_transforms()
    np.testing.assert_allclose(g[1][0, foot] + quat_rotate(g[0][0, foot], off), target, atol=1e-6)


def test_reach_limb_bad_inputs():
    m = fixture_motion()
    with pytest.raises(MotionError, match="out of range"):
        reach_limb(m, [0, 12], "right_fist", [0, 1, 0])
    with pytest.raises(MotionError, match="NaN"):
        reach_limb(m, [0, 1], "right_fist", [[0, 1, 0], [np.inf, 0, 0]])
    with pytest.raises(MotionError, match="targets must be"):
        reach_limb(m, [0, 1, 2], "right_fist", np.zeros((2, 3)))
    with pytest.raises(MotionError, match="hit_point"):
        reach_limb(m, 0, "right_foot", [0, 0, 0], hit_point="tip")
    with pytest.raises(MotionError, match="rotations must be"):
        reach_limb(m, [0, 1], "right_fist", [0, 1, 0], rotations=np.zeros((3, len(MIXAMO), 4)))
    with pytest.raises(MotionError, match="Motion"):
        reach_limb("not a motion", 0, "right_fist", [0, 1, 0])


# ------------------------------------------------------------------ twist joints inside the chain
def _with_twist_joints(m, bones, twist_deg):
    """``m`` with a joint halfway along each bone ending at a joint of ``bones`` (a twist segment,
    MakeHuman ``upperarm02.L``), turned ``twist_deg`` about the bone per frame: the same body
    (the joint below it keeps its offset and its world rotation)."""
    from repro.motion.core.quaternion import axis_angle_quat, quat_multiply

    names, par, off = list(m.joint_names), list(m.parents), list(np.asarray(m.offsets, float))
    rot = list(np.swapaxes(np.asarray(m.rotations), 0, 1))
    for bone in bones:
        j = names.index(bone)
        axis = off[j] / np.linalg.norm(off[j])
        t = np.array([axis_angle_quat(axis, a) for a in np.radians(twist_deg)])  # (F, 4), about the bone
        names.insert(j, bone + "Twist")
        par = [p + (p >= j) for p in par]
        par.insert(j, par[j])
        par[j + 1] = j
        off.insert(j, 0.5 * off[j])
        off[j + 1] = 0.5 * off[j + 1]
        rot[j] = quat_multiply(t * np.array([-1, -1, -1, 1.0]), rot[j])  # the joint below: same world rotation
        rot.insert(j, t)
    J = len(names)
    esp = [names.index(m.joint_names[p]) for p in m.end_site_parents]
    rot_ch = ("Zrotation", "Xrotation", "Yrotation")
    from repro.motion import Motion

    return Motion(joint_names=names, parents=np.array(par), offsets=np.array(off),
                  channels=[m.channels[0]] + [rot_ch] * (J - 1), frame_time=m.frame_time,
                  rotations=np.swapaxes(np.array(rot), 0, 1), positions=np.broadcast_to(np.array(off), (m.n_frames, J, 3)).copy(),
                  end_site_parents=np.array(esp), end_site_offsets=m.end_site_offsets, unit_m=1.0)  # fmt: skip


@pytest.mark.parametrize("twist_deg", [0.0, 35.0])
def test_twist_joints_inside_the_limb_are_carried_along(twist_deg):
    """Twist segments between the shoulder and elbow and between the elbow and wrist (MakeHuman's
    ``upperarm02``, ``lowerarm02``; issue 25): the limb step turns the shoulder, elbow and wrist only,
    the twist joints keep their local rotations, and the arm ends where it ends without them."""
    import dataclasses

    from repro.motion.adaptation.limb import _limb_scalar, limb_dmax, solve_limb
    from repro.motion.adaptation.rig import rig_of

    m = fixture_motion(n_frames=6, seed=5)
    twisted = _with_twist_joints(m, ["RightForeArm", "RightHand"], twist_deg * np.arange(1, 7) / 6)
    gp = m.global_positions()
    np.testing.assert_allclose(twisted.global_positions()[:, [twisted.joint_names.index(n) for n in m.joint_names]],
                               gp, atol=1e-12)  # the same body
    ch0 = rig_of(m).chain("right_wrist", "joint")
    idx = {n: i for i, n in enumerate(twisted.joint_names)}
    path = [idx[m.joint_names[j]] for j in ch0.path]
    for k, b in ((ch0.k_dist, "RightHand"), (ch0.k_mid, "RightForeArm")):  # the twist joint above each
        path.insert(k, idx[b + "Twist"])
    ch = dataclasses.replace(ch0, path=np.array(path), hit=idx["RightHand"], prox=idx["RightArm"], mid=idx["RightForeArm"],
                             dist=idx["RightHand"], k_prox=path.index(idx["RightArm"]),
                             k_mid=path.index(idx["RightForeArm"]), k_dist=path.index(idx["RightHand"]))  # fmt: skip
    goal = gp[:, IDX["RightHand"]] + np.array([0.05, -0.08, 0.03])
    rot0, rot = np.array(m.rotations), np.array(twisted.rotations)
    trans0, trans = m.local_translations(), twisted.local_translations()
    hit0, _ = solve_limb(ch0, rot0, trans0, goal)
    hit, res = solve_limb(ch, rot, trans, goal)
    assert res.max() < 1e-12
    np.testing.assert_allclose(hit, goal, atol=1e-12)
    np.testing.assert_allclose(hit, hit0, atol=1e-12)
    after = dataclasses.replace(twisted, rotations=rot)
    before = dataclasses.replace(m, rotations=rot0).global_transforms()
    gq, gp2 = after.global_transforms()
    keep = [idx[n] for n in m.joint_names]
    np.testing.assert_allclose(gp2[:, keep], before[1], atol=1e-12)  # the arm ends where it ends without them
    assert quat_angle(gq[:, keep], before[0]).max() < 1e-9  # and every joint turns as it does there
    changed = np.any(np.abs(rot - np.asarray(twisted.rotations)) > 1e-12, axis=(0, 2))
    assert set(np.flatnonzero(changed)) <= {idx["RightArm"], idx["RightForeArm"], idx["RightHand"]}
    np.testing.assert_allclose(limb_dmax(ch, np.asarray(twisted.rotations), trans, 1.0),
                               limb_dmax(ch0, np.asarray(m.rotations), trans0, 1.0), atol=1e-12)
    for f in (0, 3):  # the one-frame path agrees
        one = np.array(twisted.rotations[f])
        h1, r1 = _limb_scalar(ch, one, trans[f], goal[f].tolist())
        np.testing.assert_allclose(h1, goal[f], atol=1e-12)
        assert quat_angle(one, rot[f]).max() < 1e-9
