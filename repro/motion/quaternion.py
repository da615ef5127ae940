"""Quaternion primitives of the motion library (scalar-last ``(x, y, z, w)``), the bottom layer.

Imports nothing from :mod:`repro`: :mod:`~repro.motion.motion`, the file formats,
:mod:`~repro.motion.kinematics` and the solvers build on these.
"""

from __future__ import annotations

import numpy as np

__all__ = ["quat_multiply", "quat_rotate", "euler_to_quat"]

_AXIS = {"X": 0, "Y": 1, "Z": 2}


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
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


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
        ``R(q) v``.
    """
    u = q[..., :3]
    w = q[..., 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


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
