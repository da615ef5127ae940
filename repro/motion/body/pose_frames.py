"""Pose clouds in the root frame: the pose representation of Pronost et al., Section 3.2.2.

"In order to compare the similarity of the poses, a distance is introduced. Since the frames
of the motion clips have variety of orientation and absolute positions on the horizontal
plane, defining this distance is not obvious."  The distance (:mod:`repro.motion.search.distance`)
compares poses represented here.

A pose is the point cloud of a few key joints (:data:`POSE_ROLES`: pelvis, chest,
head, shoulders, elbows, wrists, hips, knees, ankles, feet; 17 points), optionally over
a short window of frames, *expressed in the root frame of the pose*
(:func:`root_frames`): the origin is the point of the floor below the pelvis, the
y axis is up (BVH convention), the z axis is the body's heading (the horizontal
direction perpendicular to the left-hip minus right-hip vector, pointing forward) and
x points to the body's left.  Heights (y) stay absolute heights above the floor
(y = 0), as in Kovar et al. (a crouched pose differs from a standing one).  The
database (:mod:`repro.motion.database.clips`) divides these coordinates by the actor's
:attr:`~repro.motion.body.skeleton.Skeleton.size`, so that poses of actors of different
statures can share clusters (the same normalisation as Eq. 1 for targets).  The same root
frame carries the targets of the retrieval (Section 3.3) and the annotation's headings.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from repro.checks import abs_max, as_int, as_real_array, check_alloc, describe
from repro.errors import MotionError
from repro.motion.core.kinematics import MAX_COORDINATE

__all__ = [
    "POSE_ROLES",
    "UP_AXIS",
    "heading_from_hips",
    "root_frames",
    "to_root_frame",
    "from_root_frame",
    "rotate_y",
    "pose_points",
    "pose_weights",
    "float_poses",
    "check_magnitude",
    "CHUNK",
    "MAX_WINDOW",
]

#: Vertical axis of the world (BVH is Y-up; the floor is y = 0).
UP_AXIS: int = 1

#: Roles whose positions make a pose (see :func:`repro.motion.body.roles.find_roles`).
POSE_ROLES: tuple[str, ...] = (
    "pelvis", "chest", "head",
    "left_shoulder", "left_elbow", "left_wrist",
    "right_shoulder", "right_elbow", "right_wrist",
    "left_hip", "left_knee", "left_ankle", "left_foot",
    "right_hip", "right_knee", "right_ankle", "right_foot",
)  # fmt: skip


#: Most frames in a pose cloud's window, and largest spacing between them (:func:`pose_points`):
#: Kovar et al. use a few frames; 1,000 is 33 s at 30 Hz.
MAX_WINDOW: int = 1000

#: Most joints in a pose cloud (:func:`pose_points`).
MAX_JOINTS: int = 10_000


def check_magnitude(a: np.ndarray, name: str, error=MotionError) -> np.ndarray:
    """``a`` (finite) if no entry exceeds :data:`~repro.motion.core.kinematics.MAX_COORDINATE` in magnitude,
    else ``error`` naming ``name``: squares and weighted sums of larger ones overflow float64 (1e308 gave inf
    distances); pose clouds are in units of the actor's size (about 1), world points in metres."""
    if a.size and abs_max(a) > MAX_COORDINATE:
        raise error(f"{name} has values of magnitude {abs_max(a):.3g}, beyond {MAX_COORDINATE:g} (they would overflow)")
    return a


#: Rows per chunk of the passes over all poses (index build, k-means assignment): bounds the
#: temporaries to a few tens of MB whatever the database size.
CHUNK: int = 65536


def float_poses(value, name: str, error=MotionError, *, allow_empty: bool = False) -> np.ndarray:
    """Pose clouds (N, P, 3) as a float32 or float64 array (kept as given: no copy of a large database), checked.

    Other real dtypes become float64; non-finite values, an empty array or another shape raise
    ``error`` naming ``name``.  Finiteness is checked by chunks (no (N, P, 3) boolean temporary).
    """
    p = value if isinstance(value, np.ndarray) and value.dtype in (np.float32, np.float64) else as_real_array(
        value, name, error=error, finite=False)
    if p.ndim != 3 or p.shape[-1] != 3 or (p.shape[0] == 0 and not allow_empty):
        raise error(f"{name} must be a {'' if allow_empty else 'non-empty '}(N, P, 3) array, got shape {p.shape}")
    p = np.ascontiguousarray(p)
    for a in range(0, p.shape[0], CHUNK):
        if not np.isfinite(p[a:a + CHUNK]).all():
            raise error(f"{name} contain NaN or inf")
        check_magnitude(p[a:a + CHUNK], name, error)
    return p


# ------------------------------------------------------------------ root frames
def _points3(x, name: str) -> np.ndarray:
    """``x`` as a finite float64 (..., 3) array (at least 1-D), else :class:`MotionError` naming ``name``."""
    a = check_magnitude(as_real_array(x, name, error=MotionError), name)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise MotionError(f"{name} must be an array of 3-D points (..., 3), got shape {a.shape}")
    return a


def _broadcast(what: str, *shapes) -> tuple:
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError:
        raise MotionError(f"{what}: shapes {', '.join(map(str, shapes))} do not broadcast together") from None


def rotate_y(points: np.ndarray, theta) -> np.ndarray:
    """Rotate ``points`` (..., 3) about +y by ``theta`` (radians; broadcast over leading axes).

    ``(x, y, z) -> (c x + s z, y, -s x + c z)``: +z turns towards +x for ``theta > 0``
    (a heading ``theta`` is the direction ``(sin theta, 0, cos theta)``).  Points and
    angles must be finite real numbers whose shapes broadcast (:class:`MotionError`).
    """
    p = _points3(points, "points")
    th = as_real_array(theta, "theta (radians)", error=MotionError)[..., None]
    c, s = np.cos(th)[..., 0], np.sin(th)[..., 0]
    out = np.empty(_broadcast("rotate_y points and theta", p.shape, th.shape[:-1] + (3,)))
    out[..., 0] = c * p[..., 0] + s * p[..., 2]
    out[..., 1] = p[..., 1]
    out[..., 2] = -s * p[..., 0] + c * p[..., 2]
    return out


def heading_from_hips(left_hip: np.ndarray, right_hip: np.ndarray) -> np.ndarray:
    """Heading angle (radians) of the body from its hip joints, (...,) from (..., 3).

    Forward is ``(left - right) x up`` projected on the floor (a body whose left hip is at
    +x faces +z): the heading ``theta`` is such that forward = ``(sin theta, 0, cos
    theta)``.  A degenerate hip vector (vertical or zero) gives heading 0.
    """
    left, right = _points3(left_hip, "left_hip"), _points3(right_hip, "right_hip")
    _broadcast("heading_from_hips left_hip and right_hip", left.shape, right.shape)
    lat = left - right
    fx, fz = -lat[..., 2], lat[..., 0]
    bad = np.hypot(fx, fz) <= 1e-12
    fz = np.where(bad, 1.0, fz)
    fx = np.where(bad, 0.0, fx)
    return np.arctan2(fx, fz)


def root_frames(global_positions: np.ndarray, pelvis: int, left_hip: int, right_hip: int):
    """Root reference frame of every frame: heading angle and origin on the floor.

    The paper expresses targets "in the root reference frame" (Section 3.3).  Here that
    frame has its origin on the floor below the pelvis joint, its y axis up and its z
    axis along the body's heading (:func:`heading_from_hips`).

    Parameters
    ----------
    global_positions : (F, J, 3) array
        World joint positions (e.g. :meth:`repro.motion.Motion.global_positions`).
    pelvis, left_hip, right_hip : int
        Joint indices.

    Returns
    -------
    theta : (F,) array
        Heading angles (radians).
    origin : (F, 3) array
        ``(pelvis_x, 0, pelvis_z)``.
    """
    g = _points3(global_positions, "global_positions")
    if g.ndim != 3 or g.shape[0] == 0:
        raise MotionError(f"global_positions must be a non-empty (F, J, 3) array, got shape {g.shape}")
    J = g.shape[1]
    pelvis, left_hip, right_hip = (as_int(j, name, 0, J - 1, error=MotionError) for j, name in
                                   ((pelvis, "pelvis"), (left_hip, "left_hip"), (right_hip, "right_hip")))
    theta = heading_from_hips(g[:, left_hip], g[:, right_hip])
    origin = g[:, pelvis].copy()
    origin[:, UP_AXIS] = 0.0
    return theta, origin


def to_root_frame(points: np.ndarray, theta, origin) -> np.ndarray:
    """World points -> coordinates in a root frame ``(theta, origin)``: ``R_y(-theta)(p - o)``."""
    p, o = _points3(points, "points"), _points3(origin, "origin")
    _broadcast("to_root_frame points and origin", p.shape, o.shape)
    return rotate_y(p - o, -as_real_array(theta, "theta (radians)", error=MotionError))


def from_root_frame(points: np.ndarray, theta, origin) -> np.ndarray:
    """Inverse of :func:`to_root_frame`: ``R_y(theta) p + o``."""
    r, o = rotate_y(points, theta), _points3(origin, "origin")
    _broadcast("from_root_frame points and origin", r.shape, o.shape)
    return r + o


def pose_points(global_positions: np.ndarray, joints: Sequence[int], pelvis: int, left_hip: int,
                right_hip: int, *, window: int = 1, step: int = 1, first=None) -> np.ndarray:
    """Pose clouds of every frame, each in its own root frame.

    Parameters
    ----------
    global_positions : (F, J, 3) array
        World joint positions (metres for the database).
    joints : sequence of int
        The P joints of the cloud (:data:`POSE_ROLES` resolved on the skeleton).
    pelvis, left_hip, right_hip : int
        Joints defining the root frame (:func:`root_frames`).
    window : int, default 1
        Number of frames in the cloud (Kovar et al. use a short window so that
        velocities count): frame ``f`` uses frames ``f - (window-1)*step, ..., f``
        (clamped at 0), all expressed in the root frame of frame ``f``.
    step : int, default 1
        Frame spacing inside the window.
    first : (F,) int array, optional
        For frames of several clips laid end to end (:func:`repro.motion.database.augment.augment`
        computes all the variants of a clip at once): the index of the first frame of
        each frame's clip, where its window is clamped (default 0: one clip).

    Returns
    -------
    (F, window * P, 3) array
        Oldest frame first.
    """
    g = _points3(global_positions, "global_positions")
    if g.ndim != 3 or g.shape[0] == 0:
        raise MotionError(f"global_positions must be a non-empty (F, J, 3) array, got {g.shape}")
    window = as_int(window, "window (frames per pose cloud)", 1, MAX_WINDOW, error=MotionError)
    step = as_int(step, "step (frames between the cloud's frames)", 1, MAX_WINDOW, error=MotionError)
    J = g.shape[1]
    for name, j in (("pelvis", pelvis), ("left_hip", left_hip), ("right_hip", right_hip)):
        as_int(j, name, 0, J - 1, error=MotionError)
    if isinstance(joints, range):
        if len(joints) > MAX_JOINTS:  # range(10**12) is not listed to be refused
            raise MotionError(f"joints (pose joint indices) must be at most {MAX_JOINTS} indices, got {describe(joints)}")
        joints = list(joints)
    idx = as_real_array(joints, "joints (pose joint indices)", error=MotionError, integer=True, ndim=1)
    if idx.size == 0 or idx.min() < 0 or idx.max() >= J:
        raise MotionError(f"joints (pose joint indices) must be 1 or more indices in 0..{J - 1}, got {describe(joints)}")
    idx = idx.astype(np.intp)
    F = g.shape[0]
    if first is not None:
        first = as_real_array(first, "first (first frame of each frame's clip)", error=MotionError, integer=True,
                              shape=(F,))
        if first.size and (first.min() < 0 or np.any(first > np.arange(F))):
            raise MotionError("first (first frame of each frame's clip) must be in 0..f for every frame f")
    # what the windows will allocate: (F, window, P, 3) floats, a few copies
    check_alloc(4 * 8 * 3 * F * window * idx.size, f"pose_points window={window} ({F} frames, {idx.size} joints)",
                error=MotionError)
    theta, origin = root_frames(g, pelvis, left_hip, right_hip)
    offs = np.arange(-(window - 1) * step, 1, step)
    lo = 0 if first is None else first.astype(np.intp).reshape(F, 1)
    frames = np.clip(np.arange(F)[:, None] + offs[None, :], lo, F - 1)  # (F, window)
    pts = g[frames][:, :, idx]  # (F, window, P, 3)
    pts = to_root_frame(pts, theta[:, None, None], origin[:, None, None])
    return pts.reshape(F, window * idx.size, 3)


def pose_weights(n_points: int, weights: Sequence[float] | Mapping | None = None) -> np.ndarray:
    """Per-point weights normalised to sum to 1 (uniform by default)."""
    n_points = as_int(n_points, "n_points", 1, None, error=MotionError)
    check_alloc(8 * n_points, f"n_points={n_points} (pose weights)", error=MotionError)
    if weights is None:
        w = np.ones(n_points)
    else:
        if isinstance(weights, Mapping):
            raise MotionError("pose weights must be a sequence of numbers, one per pose point, not a mapping")
        w = as_real_array(weights, "pose weights", error=MotionError, finite=False).reshape(-1)
        if w.size != n_points:
            raise MotionError(f"need {n_points} pose weights, got {w.size}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise MotionError("pose weights must be finite, >= 0 and not all 0")
    check_magnitude(w, "pose weights")
    return w / w.sum()
