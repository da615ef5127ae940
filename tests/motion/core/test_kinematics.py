"""The shared kinematics helpers against scipy's Rotation and the Motion type's FK."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from repro.errors import MotionError
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
