"""Vectorised vector and quaternion kinematics shared by the motion library.

Quaternions are scalar-last ``(x, y, z, w)`` like :class:`scipy.spatial.transform.Rotation`
and :mod:`repro.motion.motion`.  These component-wise helpers exist (rather than
``Rotation`` objects) because they broadcast over (frames, joints) arrays without
building objects, which dominates the cost of the short clips the online
retargeting and adaptation of Pronost et al. (Section 3.4) work on.  They are
checked against :class:`scipy.spatial.transform.Rotation` in
``tests/motion/test_kinematics.py`` (and, through FK, in the tests of their users).
"""

from __future__ import annotations

import numpy as np

from repro.motion.quaternion import quat_multiply

__all__ = [
    "cross",
    "dot",
    "qrot",
    "qinv",
    "normalize",
    "min_rotation",
    "transport",
    "fk_arrays",
    "depth_levels",
    "slerp",
    "quat_to_matrix",
    "matrix_to_quat",
    "matvec",
    "matvec_t",
]


# Component-wise versions of np.cross / quat_rotate: same results, but
# without np.cross's axis juggling, which dominates the cost of short (online) clips.
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis, broadcast."""
    return np.einsum("...i,...i->...", a, b)


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q) v`` for unit quaternions ``(x, y, z, w)`` (as :func:`quat_rotate`)."""
    u = q[..., :3]
    t = 2.0 * cross(u, v)
    return v + q[..., 3:4] * t + cross(u, t)


def qinv(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def normalize(v: np.ndarray, eps: float = 1e-300) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps), n[..., 0]


def min_rotation(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Quaternion of the smallest rotation taking direction ``u`` to direction ``v`` (broadcast).

    ``q = normalise(u x v, |u||v| + u.v)``; for (nearly) opposite vectors, a half turn
    about an axis perpendicular to ``u``.  Zero vectors give the identity.
    """
    u, v = np.broadcast_arrays(u, v)
    nu = np.linalg.norm(u, axis=-1)
    nv = np.linalg.norm(v, axis=-1)
    q = np.concatenate([cross(u, v), (nu * nv + np.sum(u * v, axis=-1))[..., None]], axis=-1)
    qn = np.linalg.norm(q, axis=-1)
    scale = nu * nv
    bad = qn <= 1e-12 * np.maximum(scale, 1e-300)
    if np.any(bad):
        ub = u[bad]
        # axis perpendicular to u: cross with the basis vector least aligned with u
        k = np.argmin(np.abs(ub), axis=-1)
        e = np.zeros_like(ub)
        e[np.arange(len(k)), k] = 1.0
        ax, _ = normalize(cross(ub, e))
        qb = np.concatenate([ax, np.zeros(ax.shape[:-1] + (1,))], axis=-1)
        zero = scale[bad] <= 1e-300
        qb[zero] = [0.0, 0.0, 0.0, 1.0]
        q[bad] = qb
        qn = np.linalg.norm(q, axis=-1)
    return q / qn[..., None]


def transport(a0: np.ndarray, r0: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Reference direction ``R(a0 -> a) r0`` (unit, perpendicular to unit ``a``), broadcast.

    ``R v = v + w x v + w x (w x v) / (1 + c)`` with ``w = a0 x a``, ``c = a0 . a`` is
    the smallest rotation taking ``a0`` to ``a``; the last term has norm at most
    ``1 - c``, so it is stable everywhere but at ``c = -1`` exactly, where ``r0`` itself
    (perpendicular to ``a0 = -a``) is used.
    """
    w = cross(a0, a)
    c = np.sum(a0 * a, axis=-1, keepdims=True)
    opp = c[..., 0] <= -1.0 + 1e-12
    denom = np.where(opp[..., None], 1.0, 1.0 + c)
    wr = cross(w, r0)
    r = r0 + wr + cross(w, wr) / denom
    r = np.where(opp[..., None], r0, r)
    r = r - np.sum(r * a, axis=-1, keepdims=True) * a  # clean rounding
    return normalize(r)[0]


def fk_arrays(levels, rotations: np.ndarray, translations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics as :meth:`Motion.global_transforms` on raw arrays."""
    gq = np.empty_like(rotations)
    gp = translations.copy()
    gq[:, 0] = rotations[:, 0]
    for idx, par in levels:
        pq = gq[:, par]
        gp[:, idx] = gp[:, par] + qrot(pq, gp[:, idx])
        gq[:, idx] = quat_multiply(pq, rotations[:, idx])
    return gq, gp


def depth_levels(parents: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    J = len(parents)
    depth = np.zeros(J, dtype=np.intp)
    for j in range(1, J):
        depth[j] = depth[parents[j]] + 1
    return [(np.flatnonzero(depth == d), parents[depth == d]) for d in range(1, int(depth.max(initial=0)) + 1)]


def slerp(q0: np.ndarray, q1: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Vectorised slerp of unit quaternions (..., 4) with weights a (..., 1)."""
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    so = np.sin(omega)
    small = so < 1e-8
    so_safe = np.where(small, 1.0, so)
    w0 = np.where(small, 1.0 - a, np.sin((1.0 - a) * omega) / so_safe)
    w1 = np.where(small, a, np.sin(a * omega) / so_safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# Rotation matrices: the limb and CCD solvers of repro.motion.adaptation chain many
# rotations along one path, which is cheaper with 3x3 matrices than with quaternions.
def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions ``(x, y, z, w)``, (..., 4) -> (..., 3, 3)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    x2, y2, z2 = x + x, y + y, z + z
    xx, yy, zz = x * x2, y * y2, z * z2
    xy, xz, yz = x * y2, x * z2, y * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1.0 - (yy + zz)
    m[..., 0, 1] = xy - wz
    m[..., 0, 2] = xz + wy
    m[..., 1, 0] = xy + wz
    m[..., 1, 1] = 1.0 - (xx + zz)
    m[..., 1, 2] = yz - wx
    m[..., 2, 0] = xz - wy
    m[..., 2, 1] = yz + wx
    m[..., 2, 2] = 1.0 - (xx + yy)
    return m


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(x, y, z, w)`` of rotation matrices, (..., 3, 3) -> (..., 4) (scipy)."""
    from scipy.spatial.transform import Rotation

    shape = m.shape[:-2]
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat().reshape(shape + (4,))


def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-vector product ``m v`` broadcast over leading axes."""
    return np.matmul(m, v[..., None])[..., 0]


def matvec_t(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transposed-matrix-vector product ``m^T v`` broadcast over leading axes."""
    return np.matmul(v[..., None, :], m)[..., 0, :]
