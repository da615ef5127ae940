"""The shared kinematics helpers against scipy's Rotation and the Motion type's FK."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from repro.errors import MotionError
from repro.motion import Motion
from repro.motion.core import kinematics as K
from repro.motion.core.kinematics import depth_levels, fk_arrays
from repro.motion.core import quaternion as Q4
from repro.motion.core.quaternion import quat_multiply

rng = np.random.default_rng(0)
Q = Rotation.random(50, random_state=1).as_quat()
V = rng.normal(size=(50, 3))


def test_qrot_and_qinv_match_scipy():
    np.testing.assert_allclose(Q4.quat_rotate(Q, V), Rotation.from_quat(Q).apply(V), atol=1e-12)
    np.testing.assert_allclose(Q4.quat_rotate(Q4.quat_conjugate(Q), Q4.quat_rotate(Q, V)), V, atol=1e-12)
    np.testing.assert_allclose(Q4.cross(V, V[::-1]), np.cross(V, V[::-1]), atol=1e-12)


def test_min_rotation_takes_u_to_v_including_opposite_and_zero():
    U = np.vstack([V, V[:3], np.zeros((1, 3))])
    W = np.vstack([V[::-1], -V[:3], V[:1]])
    q = Q4.min_rotation(U, W)
    un, _ = K.normalize(U)
    wn, _ = K.normalize(W)
    moved = Q4.quat_rotate(q, un)
    np.testing.assert_allclose(moved[:-1], wn[:-1], atol=1e-9)  # opposite vectors too
    np.testing.assert_allclose(q[-1], [0, 0, 0, 1])  # zero vector: identity
    # smallest: the angle equals the angle between u and v
    ang = Rotation.from_quat(q[:50]).magnitude()
    np.testing.assert_allclose(ang, np.arccos(np.clip(np.sum(un[:50] * wn[:50], -1), -1, 1)), atol=1e-9)


def test_transport_keeps_the_reference_perpendicular_and_unit():
    a0, _ = K.normalize(V)
    r0, _ = K.normalize(Q4.cross(a0, rng.normal(size=(50, 3))))
    a, _ = K.normalize(V[::-1])
    r = K.transport(a0, r0, a)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), 1, atol=1e-12)
    np.testing.assert_allclose(np.sum(r * a, axis=-1), 0, atol=1e-12)


def test_slerp_matches_scipy():
    q0, q1 = Q[:20], Q[20:40]
    t = np.linspace(0, 1, 20)[:, None]
    ours = Q4.slerp(q0, q1, t)
    for i in range(20):
        ref = Slerp([0, 1], Rotation.from_quat([q0[i], q1[i]]))([t[i, 0]]).as_quat()[0]
        assert min(np.abs(ours[i] - ref).max(), np.abs(ours[i] + ref).max()) < 1e-9


def test_fk_arrays_matches_an_explicit_chain():
    parents = np.array([-1, 0, 1, 1])
    rot = Rotation.random(3 * 4, random_state=2).as_quat().reshape(3, 4, 4)
    tr = rng.normal(size=(3, 4, 3))
    gq, gp = K.fk_arrays(K.depth_levels(parents), rot, tr)
    for f in range(3):
        for j in range(1, 4):
            p = parents[j]
            np.testing.assert_allclose(gp[f, j], gp[f, p] + Rotation.from_quat(gq[f, p]).apply(tr[f, j]), atol=1e-12)
            np.testing.assert_allclose(gq[f, j], quat_multiply(gq[f, p], rot[f, j]), atol=1e-12)


def test_matrix_helpers_match_scipy():
    M = Rotation.from_quat(Q).as_matrix()
    np.testing.assert_allclose(Q4.quat_to_matrix(Q), M, atol=1e-12)
    back = Q4.matrix_to_quat(M.reshape(5, 10, 3, 3)).reshape(50, 4)
    same_sign = np.sign(np.sum(back * Q, axis=-1))[:, None]
    np.testing.assert_allclose(back * same_sign, Q / np.linalg.norm(Q, axis=-1, keepdims=True), atol=1e-12)
    np.testing.assert_allclose(K.matvec(M, V), Rotation.from_quat(Q).apply(V), atol=1e-12)
    np.testing.assert_allclose(K.matvec_t(M, V), Rotation.from_quat(Q).inv().apply(V), atol=1e-12)
    np.testing.assert_allclose(K.dot(V, V[::-1]), np.sum(V * V[::-1], axis=-1), atol=1e-12)


# ------------------------------------------------------------------ hostile arguments (issue 23)
@pytest.mark.parametrize("parents", ["ab", [0.5, 0], [[-1, 0]], [-1, 1], [0, 0], [], None])
def test_depth_levels_refuses_what_is_not_a_joint_tree(parents):
    with pytest.raises(MotionError, match="parents"):
        depth_levels(parents)


def test_fk_arrays_refuses_mismatched_shapes():
    lv = depth_levels([-1, 0, 1])
    with pytest.raises(MotionError, match="fk_arrays"):
        fk_arrays(lv, np.zeros((2, 3, 4)), np.zeros((2, 2, 3)))
    with pytest.raises(MotionError, match="fk_arrays"):
        fk_arrays(lv, "q", np.zeros((2, 3, 3)))


# ------------------------------------------------------------------ rest pose (issue 24)
def _random_tree(n: int, seed: int) -> np.ndarray:
    r = np.random.default_rng(seed)
    return np.array([-1] + [int(r.integers(0, j)) for j in range(1, n)])


def _rest_by_joint(parents, offsets):
    p = np.array(offsets, dtype=float)
    for j in range(1, len(p)):
        p[j] = p[parents[j]] + offsets[j]
    return p


@pytest.mark.parametrize("parents", [np.array([-1]), _random_tree(40, 3), _random_tree(300, 4),
                                     np.arange(-1, 2999)], ids=["root", "tree40", "tree300", "chain3000"])
def test_rest_positions_is_the_joint_by_joint_sum_and_fk_with_identity_rotations(parents):
    J = parents.size
    off = np.random.default_rng(J).normal(size=(J, 3))
    p = K.rest_positions(parents, off)
    np.testing.assert_array_equal(p, _rest_by_joint(parents, off))  # bit for bit
    ident = np.zeros((1, J, 4))
    ident[..., 3] = 1.0
    np.testing.assert_array_equal(p, K.fk_arrays(depth_levels(parents), ident, off[None])[1][0])


def test_rest_positions_refuses_what_is_not_a_tree_with_offsets():
    with pytest.raises(MotionError, match="parents"):
        K.rest_positions([-1, 2, 0], np.zeros((3, 3)))
    with pytest.raises(MotionError, match="offsets"):
        K.rest_positions([-1, 0, 1], np.zeros((2, 3)))


# ------------------------------------------------------------------ the forms of forward kinematics agree (issue 24)
def _random_pose(parents, F: int, seed: int):
    J = parents.size
    rot = Rotation.random(F * J, random_state=seed).as_quat().reshape(F, J, 4)
    tr = np.random.default_rng(seed).normal(size=(F, J, 3))
    return rot, tr


@pytest.mark.parametrize("parents", [np.array([-1]), _random_tree(40, 5), _random_tree(300, 6),
                                     np.arange(-1, 999)], ids=["root", "tree40", "tree300", "chain1000"])
def test_level_loop_and_pointer_doubling_agree(parents):
    rot, tr = _random_pose(parents, 3, parents.size)
    lq, lp = K.fk_arrays(depth_levels(parents), rot, tr)
    dq, dp = K.fk_doubling(parents, rot, tr)
    scale = 1.0 + np.abs(lp).max()
    np.testing.assert_allclose(dp, lp, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(Q4.quat_rotate(dq, V[:3, None]), Q4.quat_rotate(lq, V[:3, None]), rtol=0, atol=1e-9)
    # the entry point: the level loop's numbers up to LEVEL_LOOP_MAX_DEPTH levels, doubling's beyond
    fq, fp = K.forward_kinematics(parents, rot, tr)
    deep = len(depth_levels(parents)) > K.LEVEL_LOOP_MAX_DEPTH
    assert deep == (parents.size == 1000)
    assert np.array_equal(fq, dq if deep else lq) and np.array_equal(fp, dp if deep else lp)
    assert np.array_equal(tr, _random_pose(parents, 3, parents.size)[1])  # copy=True left the input alone


def test_motion_global_transforms_is_forward_kinematics_on_a_deep_chain():
    J = 200
    parents = np.arange(-1, J - 1)
    rot, tr = _random_pose(parents, 2, 7)
    m = Motion(joint_names=[f"j{i}" for i in range(J)], parents=parents, offsets=tr[0],
               channels=[["Zrotation", "Yrotation", "Xrotation"]] * J, rotations=rot,
               positions=np.zeros((2, J, 3)), frame_time=0.01)
    assert m.n_depth_levels > K.LEVEL_LOOP_MAX_DEPTH
    gq, gp = m.global_transforms()
    dq, dp = K.fk_doubling(m.parents, m.rotations, m.local_translations())
    assert np.array_equal(gq, dq) and np.array_equal(gp, dp)


def test_chain_fk_is_the_full_fk_on_the_path_joints():
    parents = _random_tree(60, 8)
    rot, tr = _random_pose(parents, 4, 9)
    gq, gp = K.fk_arrays(depth_levels(parents), rot, tr)
    path = [59]
    while parents[path[-1]] >= 0:
        path.append(int(parents[path[-1]]))
    path = np.array(path[::-1])
    assert path.size >= 3
    ml = Q4.quat_to_matrix(rot[:, path])
    rw, pw = K.chain_fk(ml, tr[:, path])
    np.testing.assert_allclose(pw, gp[:, path], rtol=0, atol=1e-12 * (1 + np.abs(gp).max()))
    np.testing.assert_allclose(rw, Q4.quat_to_matrix(gq[:, path]), rtol=0, atol=1e-12)
    # a solver's step: change one joint of the path, recompute from it on, in place
    for k in (0, 1, path.size - 1):
        ml2 = ml.copy()
        ml2[:, k] = Q4.quat_to_matrix(Rotation.random(4, random_state=k).as_quat())
        rw2, pw2 = rw.copy(), pw.copy()
        K.chain_fk_from(ml2, tr[:, path], rw2, pw2, k)
        fresh = K.chain_fk(ml2, tr[:, path])
        assert np.array_equal(rw2, fresh[0]) and np.array_equal(pw2, fresh[1])


def test_fk_doubling_refuses_what_is_not_a_tree_or_a_pose_of_it():
    with pytest.raises(MotionError, match="parents"):
        K.fk_doubling([-1, 2, 0], np.zeros((1, 3, 4)), np.zeros((1, 3, 3)))
    with pytest.raises(MotionError, match="fk_doubling"):
        K.fk_doubling([-1, 0, 1], np.zeros((1, 3, 4)), np.zeros((1, 2, 3)))
    with pytest.raises(MotionError, match="3 parents for 2 joints"):
        K.fk_doubling([-1, 0, 1], np.zeros((1, 2, 4)), np.zeros((1, 2, 3)))


def test_forward_kinematics_of_a_deep_chain_takes_log_depth_rounds(monkeypatch):
    J = 5000
    parents = np.arange(-1, J - 1)
    rot, tr = _random_pose(parents, 2, 10)
    calls, real = [], K.quat_multiply
    monkeypatch.setattr(K, "quat_multiply", lambda a, b: calls.append(1) or real(a, b))
    K.forward_kinematics(parents, rot, tr)
    assert len(calls) == int(np.ceil(np.log2(J)))  # pointer doubling, not one step per level


def test_children_of_lists_each_joints_children_in_joint_order():
    from repro.motion.core.kinematics import children_of

    assert children_of([-1, 0, 1, 0, 3, 3]) == [[1, 3], [2], [], [4, 5], [], []]
    assert children_of(np.array([-1])) == [[]]
