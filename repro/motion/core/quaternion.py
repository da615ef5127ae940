"""Quaternion primitives of the motion library (scalar-last ``(x, y, z, w)``), the bottom layer.

Imports nothing from :mod:`repro`: :mod:`~repro.motion.core.motion`, the file formats,
:mod:`~repro.motion.core.kinematics` and the solvers build on these.  Quaternions follow
:class:`scipy.spatial.transform.Rotation`'s convention; these component-wise versions
exist (rather than ``Rotation`` objects) because they broadcast over (frames, joints)
arrays without building objects, which dominates the cost of the short clips the online
retargeting and adaptation of Pronost et al. (Section 3.4) work on.  They are checked
against ``Rotation`` in ``tests/motion/core/test_kinematics.py`` and
``tests/motion/core/test_motion.py``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "cross",
    "quat_multiply",
    "quat_rotate",
    "quat_conjugate",
    "slerp",
    "min_rotation",
    "axis_angle_quat",
    "quat_power",
    "quat_to_matrix",
    "matrix_to_quat",
    "euler_to_quat",
]

_AXIS = {"X": 0, "Y": 1, "Z": 2}


def _lead_shape(a: np.ndarray, b: np.ndarray) -> tuple:
    """The broadcast leading shape of two (..., k) arrays (the common case, equal shapes, without numpy's helper)."""
    return a.shape[:-1] if a.shape == b.shape else np.broadcast_shapes(a.shape[:-1], b.shape[:-1])


def vector_norm(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """``|v|`` over the last axis: the same numbers as ``np.linalg.norm(v, axis=-1)`` (real ``v``).

    numpy's own formula (``sqrt(add.reduce(v * v))``) without its argument handling, which
    dominates the cost on the few frames the adaptation solves at once.
    """
    return np.sqrt(np.add.reduce(v * v, axis=-1, keepdims=keepdims))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis, broadcast; the same numbers as :func:`numpy.cross`.

    Component-wise, without ``np.cross``'s axis juggling, which dominates the cost of
    short (online) clips.
    """
    a, b = np.asarray(a), np.asarray(b)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    # filled in place (not np.stack): the same numbers, a third of the calls' overhead
    out = np.empty(_lead_shape(a, b) + (3,), dtype=np.result_type(a, b))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


#: quat_multiply on few quaternions: component k is sum_t _QM_SIGN[k, t] a[_QM_A[k, t]] b[_QM_B[k, t]], the
#: terms in the order of the component-wise formulas
_QM_A = np.array([[3, 0, 1, 2]] * 4)
_QM_B = np.array([[0, 3, 2, 1], [1, 2, 3, 0], [2, 1, 0, 3], [3, 0, 1, 2]])
_QM_SIGN = np.array([[1, 1, 1, -1], [1, -1, 1, 1], [1, 1, -1, 1], [1, -1, -1, -1]], dtype=float)
#: largest array (elements) quat_multiply takes the one-call path for (above, gathering costs more than it saves)
_SMALL = 512


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of scalar-last quaternions, broadcast over leading axes.

    Parameters
    ----------
    a, b : (..., 4) array
        Quaternions ``(x, y, z, w)``.

    Returns
    -------
    (..., 4) array
        The quaternion of the rotation "first ``b``, then ``a``" (matrix ``R(a) R(b)``).
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.size <= _SMALL and b.size <= _SMALL and a.dtype == np.float64 and b.dtype == np.float64:
        # few quaternions (one pose): the 16 products in one call, signed (exact), summed in the
        # order below (a - b is a + (-b) in IEEE arithmetic): the same numbers in 7 calls, not 28
        p = a[..., _QM_A] * b[..., _QM_B] * _QM_SIGN
        return ((p[..., 0] + p[..., 1]) + p[..., 2]) + p[..., 3]
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    # filled in place (not moveaxis + np.stack): the same numbers, less per-call overhead,
    # which dominates the short clips the adaptation solves (repro.bench.adaptation)
    out = np.empty(_lead_shape(a, b) + (4,), dtype=np.result_type(a, b))
    out[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` by unit quaternions ``q`` (scalar-last), broadcast.

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions ``(x, y, z, w)``.
    v : (..., 3) array
        Vectors.

    Returns
    -------
    (..., 3) array
        ``R(q) v = v + w t + u x t`` with ``u = q[:3]``, ``t = 2 u x v``.
    """
    u = q[..., :3]
    t = 2.0 * cross(u, v)
    return v + q[..., 3:4] * t + cross(u, t)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """``(-x, -y, -z, w)``: the inverse of a unit quaternion, broadcast."""
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def slerp(q0: np.ndarray, q1: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Vectorised slerp of unit quaternions (..., 4) with weights a (..., 1), along the shorter arc."""
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


def min_rotation(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Quaternion of the smallest rotation taking direction ``u`` to direction ``v`` (broadcast).

    ``q = normalise(u x v, |u||v| + u.v)``; for (nearly) opposite vectors, a half turn
    about an axis perpendicular to ``u``.  Zero vectors give the identity.
    """
    if u.shape != v.shape:
        u, v = np.broadcast_arrays(u, v)
    nu = vector_norm(u)
    nv = vector_norm(v)
    q = np.concatenate([cross(u, v), (nu * nv + np.sum(u * v, axis=-1))[..., None]], axis=-1)
    qn = vector_norm(q)
    scale = nu * nv
    bad = qn <= 1e-12 * np.maximum(scale, 1e-300)
    if np.any(bad):
        ub = u[bad]
        # axis perpendicular to u: cross with the basis vector least aligned with u
        k = np.argmin(np.abs(ub), axis=-1)
        e = np.zeros_like(ub)
        e[np.arange(len(k)), k] = 1.0
        ax = cross(ub, e)
        ax = ax / np.maximum(np.linalg.norm(ax, axis=-1, keepdims=True), 1e-300)
        qb = np.concatenate([ax, np.zeros(ax.shape[:-1] + (1,))], axis=-1)
        zero = scale[bad] <= 1e-300
        qb[zero] = [0.0, 0.0, 0.0, 1.0]
        q[bad] = qb
        qn = vector_norm(q)
    return q / qn[..., None]


def axis_angle_quat(axis, angle) -> np.ndarray:
    """Quaternions of rotations by ``angle`` (radians, (F,)) about a fixed unit ``axis``."""
    angle = np.asarray(angle, dtype=float)
    axis = np.asarray(axis, dtype=float)
    h = 0.5 * angle[..., None]
    return np.concatenate([np.sin(h) * axis, np.cos(h)], axis=-1)


def quat_power(q: np.ndarray, k: float) -> np.ndarray:
    """``q^k``: the rotation of ``q`` with its angle multiplied by ``k`` (same axis)."""
    from scipy.spatial.transform import Rotation

    r = Rotation.from_quat(q)
    return Rotation.from_rotvec(r.as_rotvec() * k).as_quat()


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
    """Unit quaternions ``(x, y, z, w)`` of rotation matrices, (..., 3, 3) -> (..., 4) (scipy).

    Raises :class:`repro.errors.MotionError` for a matrix that is not finite or not a proper frame
    (determinant <= 0: a degenerate frame, e.g. built on a zero-length bone), where scipy would
    raise its own ValueError or fail to converge.
    """
    from scipy.spatial.transform import Rotation

    from repro.errors import MotionError

    m = np.asarray(m, dtype=float)
    shape = m.shape[:-2]
    flat = m.reshape(-1, 3, 3)
    if not np.isfinite(flat).all():
        raise MotionError("matrix_to_quat: a rotation matrix is not finite (a degenerate frame?)")
    with np.errstate(all="ignore"):
        bad = np.flatnonzero(~(np.linalg.det(flat) > 0))
    if bad.size:
        raise MotionError(f"matrix_to_quat: rotation matrix {int(bad[0])} of {flat.shape[0]} is not a proper frame "
                          "(determinant <= 0: a left-handed or degenerate frame, e.g. on a zero-length bone)")
    return Rotation.from_matrix(flat).as_quat().reshape(shape + (4,))


def euler_to_quat(seq: str, angles, degrees: bool = True) -> np.ndarray:
    """Quaternions of Euler-angle rotations, with scipy's ``from_euler`` conventions.

    Same result as ``scipy.spatial.transform.Rotation.from_euler(seq, angles,
    degrees).as_quat()`` (checked in the tests), computed with plain numpy products of
    single-axis quaternions: in this scipy version ``from_euler`` costs about 1 us per
    rotation, i.e. most of the time of reading a CMU clip.

    Parameters
    ----------
    seq : str
        1 to 3 axis letters, all uppercase (intrinsic: ``"ZXY"`` is ``Rz Rx Ry``, the
        BVH convention for channels listed Z, X, Y) or all lowercase (extrinsic:
        ``"xyz"`` is ``Rz Ry Rx``, the Acclaim ASF convention for ``axis ... XYZ``).
    angles : (..., len(seq)) array
        Angles, one column per letter of ``seq``.
    degrees : bool, default True
        Whether ``angles`` are in degrees (else radians).

    Returns
    -------
    (..., 4) array
        Unit quaternions ``(x, y, z, w)``.
    """
    if not seq or len(seq) > 3 or not (seq.isupper() or seq.islower()) or set(seq.upper()) - set("XYZ"):
        raise ValueError(f"Euler sequence must be 1-3 letters of XYZ, all upper or all lower case; got {seq!r}")
    angles = np.asarray(angles, dtype=float)
    if angles.shape[-1:] != (len(seq),):
        raise ValueError(f"angles must end with an axis of length {len(seq)}, got shape {angles.shape}")
    half = (np.radians(angles) if degrees else angles) * 0.5
    s, c = np.sin(half), np.cos(half)
    q = None
    for k, letter in enumerate(seq):
        qk = np.zeros(angles.shape[:-1] + (4,))
        qk[..., _AXIS[letter.upper()]] = s[..., k]
        qk[..., 3] = c[..., k]
        if q is None:
            q = qk
        elif seq.isupper():  # intrinsic: R = R1 R2 R3
            q = quat_multiply(q, qk)
        else:  # extrinsic: R = R3 R2 R1
            q = quat_multiply(qk, q)
    return q
