"""Pose representation, the aligned pose distance of Kovar et al. and k-means of poses.

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.2.2 (Clustering):

    "In order to compare the similarity of the poses, a distance is introduced. Since
    the frames of the motion clips have variety of orientation and absolute positions on
    the horizontal plane, defining this distance is not obvious. A solution that we use,
    proposed by Kovar et al. [10] consists of minimizing the distance between the two
    poses by tuning the alignment parameters of the two motions."

and "we choose the K-mean clustering algorithm [...] to gather poses of various motions
into clusters in order to minimize the total intra-cluster variance."

Pose representation
-------------------
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
statures can share clusters (the same normalisation as Eq. 1 for targets).

Aligned distance (Kovar, Gleicher and Pighin, "Motion Graphs", SIGGRAPH 2002, Sec. 3.1)
------------------------------------------------------------------------------------
For point clouds ``a_i`` and ``b_i`` (i = 1..P) with weights ``w_i`` (normalised here to
sum to 1), the distance is

    ``D(a, b)^2 = min over theta, x0, z0 of  sum_i w_i |a_i - T(b_i)|^2``,

where ``T`` rotates about the vertical axis by ``theta`` and translates by
``(x0, 0, z0)``: ``T(x, y, z) = (c x + s z + x0, y, -s x + c z + z0)`` with
``c = cos theta``, ``s = sin theta`` (the right-handed rotation about +y).  Derivation:
for fixed ``theta`` the optimal translation matches the weighted centroids,
``x0 = X - (c X' + s Z')``, ``z0 = Z - (-s X' + c Z')`` with ``X = sum w x``,
``X' = sum w x'`` and so on (``sum w = 1``).  With centred clouds the cost becomes
``sum w (y - y')^2 + H_a + H_b - 2 (c A + s B)`` where

    ``A = sum w (x x' + z z') - (X X' + Z Z')``,
    ``B = sum w (x z' - z x') - (X Z' - Z X')``,
    ``H_a = sum w (x^2 + z^2) - (X^2 + Z^2)``   (likewise ``H_b``),

which is minimal for ``(c, s)`` proportional to ``(A, B)``: ``theta = atan2(B, A)``
(Kovar et al.'s formula), and the minimum is

    ``D^2 = sum w (y - y')^2 + H_a + H_b - 2 sqrt(A^2 + B^2)``.

This closed form needs only dot products between the query and each candidate, so
:class:`AlignedPoseIndex` evaluates it for many candidate poses with one matrix product
(the per-candidate sums are precomputed).  ``D`` is the weighted root-mean-square
distance between the aligned clouds (metres for clouds in metres).  It is symmetric,
zero for identical poses, and invariant to rotating either pose about y and translating
it on the floor (checked by the tests).

k-means and the aligned distance
--------------------------------
:func:`cluster_poses` runs :func:`scipy.cluster.vq.kmeans2` (k-means++ seeding, a fixed
seed, so the result is deterministic) on the poses in their canonical root frame
(flattened and multiplied by ``sqrt(w)``, so that squared Euclidean distance is the
weighted squared distance *without* alignment).  Because the identity is one of the
transformations the aligned distance minimises over, ``D(p, q) <= |p - q|_w`` for poses
in canonical frames: k-means minimises an upper bound of the aligned intra-cluster
variance, and each centroid (the weighted mean cloud of its members in the canonical
frame) is itself a pose cloud that the aligned distance can compare with a query; the
retrieval (:mod:`repro.motion.search.retrieval`) picks the cluster whose centroid is nearest
to the query in the aligned distance.  Putting poses in the canonical heading frame
before k-means removes most of what the alignment would remove (the residual is the
heading-estimation error), which is why the bound is tight in practice.
"""

from __future__ import annotations

import math
import operator
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.sparse import csr_matrix

from repro.checks import abs_max, as_bool, as_int, as_real_array, check_alloc, describe
from repro.errors import MotionError, ReproWarning

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
    "aligned_distance",
    "AlignedPoseIndex",
    "PoseClusters",
    "cluster_poses",
    "default_k",
    "real_array",
    "float_poses",
    "CHUNK",
    "MAX_ITERATIONS",
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

#: Most k-means iterations :func:`cluster_poses` accepts (each is one pass over the poses).
MAX_ITERATIONS: int = 10_000


# ------------------------------------------------------------- argument checks
def real_array(value, name: str, error=MotionError) -> np.ndarray:
    """``value`` as a float array, or ``error`` if it is not made of real numbers.

    Refuses strings, None, objects and complex numbers (whose imaginary part numpy would
    otherwise drop); finiteness and shape are the caller's checks.
    """
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be an array of real numbers ({exc})") from None
    if a.dtype.kind not in "biuf":
        if a.dtype.kind == "O":
            try:
                a = a.astype(float)
            except (TypeError, ValueError):
                raise error(f"{name} must be an array of real numbers, got {_short(value)}") from None
        else:
            raise error(f"{name} must be an array of real numbers, got dtype {a.dtype} ({_short(value)})")
    with np.errstate(over="ignore"):  # a longdouble beyond float64 becomes inf, refused by the finiteness checks
        return a.astype(float, copy=False)


#: Largest coordinate magnitude the pose and frame functions accept: squares and weighted sums of
#: larger ones overflow float64 (1e308 gave inf distances and overflow warnings); pose clouds are
#: in units of the actor's size (about 1), world points in metres.
MAX_COORD: float = 1e100


def _check_magnitude(a: np.ndarray, name: str, error=MotionError) -> np.ndarray:
    """``a`` (finite) if no entry exceeds :data:`MAX_COORD` in magnitude, else ``error`` naming ``name``."""
    if a.size and abs_max(a) > MAX_COORD:
        raise error(f"{name} has values of magnitude {abs_max(a):.3g}, beyond {MAX_COORD:g} (they would overflow)")
    return a


def _short(value) -> str:
    r = repr(value)
    return r if len(r) <= 80 else r[:77] + "..."


#: Rows per chunk of the passes over all poses (index build, k-means assignment): bounds the
#: temporaries to a few tens of MB whatever the database size.
CHUNK: int = 65536


def float_poses(value, name: str, error=MotionError, *, allow_empty: bool = False) -> np.ndarray:
    """Pose clouds (N, P, 3) as a float32 or float64 array (kept as given: no copy of a large database), checked.

    Other real dtypes become float64 (:func:`real_array`); non-finite values, an empty
    array or another shape raise ``error`` naming ``name``.  Finiteness is checked by
    chunks (no (N, P, 3) boolean temporary).
    """
    p = value if isinstance(value, np.ndarray) and value.dtype in (np.float32, np.float64) else real_array(value, name,
                                                                                                           error)
    if p.ndim != 3 or p.shape[-1] != 3 or (p.shape[0] == 0 and not allow_empty):
        raise error(f"{name} must be a {'' if allow_empty else 'non-empty '}(N, P, 3) array, got shape {p.shape}")
    p = np.ascontiguousarray(p)
    for a in range(0, p.shape[0], CHUNK):
        if not np.isfinite(p[a:a + CHUNK]).all():
            raise error(f"{name} contain NaN or inf")
        _check_magnitude(p[a:a + CHUNK], name, error)
    return p


# ------------------------------------------------------------------ root frames
def _points3(x, name: str) -> np.ndarray:
    """``x`` as a finite float64 (..., 3) array (at least 1-D), else :class:`MotionError` naming ``name``."""
    a = _check_magnitude(as_real_array(x, name, error=MotionError), name)
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
        w = real_array(weights, "pose weights").reshape(-1)
        if w.size != n_points:
            raise MotionError(f"need {n_points} pose weights, got {w.size}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise MotionError("pose weights must be finite, >= 0 and not all 0")
    _check_magnitude(w, "pose weights")
    return w / w.sum()


# ------------------------------------------------------------ aligned distance
def _moments(p: np.ndarray, w: np.ndarray):
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    X, Z = x @ w, z @ w
    H = (x * x + z * z) @ w - (X * X + Z * Z)
    return x, y, z, X, Z, H


def aligned_distance(a, b, weights=None, *, return_transform: bool = False):
    """Kovar et al.'s aligned pose distance (weighted RMS, see the module docstring).

    Parameters
    ----------
    a, b : (..., P, 3) arrays
        Point clouds, broadcast against each other.
    weights : (P,) array, optional
        Non-negative point weights (normalised to sum 1); default uniform.
    return_transform : bool, default False
        Also return the transformation ``T`` applied to ``b``.

    Returns
    -------
    d : (...) array
        ``sqrt(min sum w |a - T(b)|^2)``.
    theta, x0, z0 : (...) arrays, only with ``return_transform``
        ``T(p) = rotate_y(p, theta) + (x0, 0, z0)`` maps ``b`` onto ``a``.
    """
    return_transform = as_bool(return_transform, "return_transform", error=MotionError)
    a = real_array(a, "pose cloud a")
    b = real_array(b, "pose cloud b")
    try:
        np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    except ValueError:
        raise MotionError(f"pose clouds a {a.shape} and b {b.shape} do not broadcast together") from None
    if a.ndim < 2 or b.ndim < 2 or a.shape[-1] != 3 or b.shape[-1] != 3 or a.shape[-2] != b.shape[-2]:
        raise MotionError(f"pose clouds must be (..., P, 3) with equal P, got {a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise MotionError("pose clouds contain NaN or inf")
    _check_magnitude(a, "pose cloud a")
    _check_magnitude(b, "pose cloud b")
    w = pose_weights(a.shape[-2], weights)
    xa, ya, za, Xa, Za, Ha = _moments(a, w)
    xb, yb, zb, Xb, Zb, Hb = _moments(b, w)
    A = (xa * xb + za * zb) @ w - (Xa * Xb + Za * Zb)
    B = (xa * zb - za * xb) @ w - (Xa * Zb - Za * Xb)
    dy = ((ya - yb) ** 2) @ w
    d2 = np.maximum(dy + Ha + Hb - 2.0 * np.hypot(A, B), 0.0)
    d = np.sqrt(d2)
    if not return_transform:
        return d
    theta = np.arctan2(B, A)
    c, s = np.cos(theta), np.sin(theta)
    x0 = Xa - (c * Xb + s * Zb)
    z0 = Za - (-s * Xb + c * Zb)
    return d, theta, x0, z0


@dataclass(eq=False)
class AlignedPoseIndex:
    """Many candidate poses, ready for one-query-to-all aligned distances.

    Precomputes everything of the closed form that does not depend on the query, so
    that :meth:`distances` costs one ``(N, 3P) @ (3P, 3)`` matrix product plus O(N)
    element-wise work.

    Parameters
    ----------
    points : (N, P, 3) array
        Candidate clouds, float32 or float64 (kept as :attr:`points`, not copied; None in a
        :meth:`subset`).  The closed-form terms are float64 whatever their dtype.
    weights : (P,) array, optional
        Point weights (normalised); default uniform.
    order : (n,) int array, optional
        Store the matrix terms of the poses ``order`` only, in that order (default: every
        pose, in order).  A :meth:`subset` whose rows are a run of consecutive entries of
        ``order`` is then a view, not a copy: the retriever orders the startable poses by
        (semantics, cluster, pose) (:func:`repro.motion.search.index_build.block_order`) so that its
        per-cluster and per-semantics candidate blocks share one array instead of one copy
        each (the 1,000x database: 4.6 M poses).  The terms of a pose outside ``order`` are
        recomputed from :attr:`points` when asked for (same values).
    """

    points: np.ndarray | None
    weights: np.ndarray | None = None
    order: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = float_poses(self.points, "candidate poses", allow_empty=True)
        self.points = p
        N, P, _ = p.shape
        self._P = P
        w = pose_weights(P, self.weights)
        self.weights = w
        self._N = N
        self._perm = None  # (a subset's) row -> stored row, when not the identity
        if self.order is None:
            self._pos = None
            stored = None
        else:
            if hasattr(self.order, "__len__") and not isinstance(self.order, np.ndarray) and len(self.order) > N:
                raise MotionError(f"order must be distinct pose indices in [0, {N}), got {len(self.order)} of them")
            stored = np.asarray(self.order)
            if stored.ndim != 1 or stored.dtype.kind not in "iu" or (stored.size and (
                    stored.min() < 0 or stored.max() >= N)) or np.unique(stored).size != stored.size:
                raise MotionError(f"order must be distinct pose indices in [0, {N}), got {_short(self.order)}")
            self.order = stored = stored.astype(np.intp)
            self._pos = np.full(N, -1, dtype=np.intp)
            self._pos[stored] = np.arange(stored.size)
        n = N if stored is None else stored.size
        # the stored poses' scalar terms X, Z, H, Y2 (4, n) and matrix terms, both in stored order (a subset
        # that is a run of ``order`` is a view of them); columns of M: [w x', w z', w y'] ->
        # M @ [[xa, -za, 0], [za, xa, 0], [0, 0, ya]].  Filled by chunks (float32 points are never copied
        # whole to float64); M is element-wise in each pose, the scalar terms are sums (chunks in pose order).
        self._T = np.empty((4, n))
        for a in range(0, N, CHUNK):  # the scalar terms by chunks of poses in pose order (see _pose_terms)
            t = np.stack(self._terms(p[a:a + CHUNK], want_m=False)[1:])
            if stored is None:
                self._T[:, a:a + CHUNK] = t
            else:
                at = self._pos[a:a + CHUNK]
                self._T[:, at[at >= 0]] = t[:, at >= 0]
        self._X, self._Z, self._H, self._Y2 = self._T
        self._M = np.empty((n, 3 * P))
        for a in range(0, n, CHUNK):
            self._M[a:a + CHUNK] = self._terms(p[a:a + CHUNK] if stored is None else p[stored[a:a + CHUNK]])[0]

    def _pose_terms(self, rows: np.ndarray) -> np.ndarray:
        """(4, r): ``X, Z, H, Y2`` of poses ``rows`` recomputed from :attr:`points` on the same chunks of
        poses as in the constructor (the sums go through BLAS, whose rounding may depend on the rows
        computed together: the same chunks give the same values as stored)."""
        out = np.empty((4, rows.size))
        ch = rows // CHUNK
        for c in np.unique(ch):
            a, sel = int(c) * CHUNK, ch == c
            out[:, sel] = np.stack(self._terms(self.points[a:a + CHUNK], want_m=False)[1:])[:, rows[sel] - a]
        return out

    def _terms(self, pts: np.ndarray, want_m: bool = True):
        """``(M rows or None, X, Z, H, Y2)`` of the clouds ``pts`` (n, P, 3), in float64."""
        w = self.weights
        x, y, z, X, Z, H = _moments(pts.astype(float, copy=False), w)
        M = None
        if want_m:
            P = self._P
            M = np.empty((x.shape[0], 3 * P))
            M[:, :P], M[:, P:2 * P], M[:, 2 * P:] = x * w, z * w, y * w
        return M, X, Z, H, (y * y) @ w

    def _rows_t(self, rows: np.ndarray) -> tuple:
        """``X, Z, H, Y2`` of poses ``rows`` (copies), from the stored ones (in stored order) or recomputed."""
        if self._pos is None:
            at = rows if self._perm is None else self._perm[rows]
            return self._X[at], self._Z[at], self._H[at], self._Y2[at]
        at = self._pos[rows]
        ok = at >= 0
        if ok.all():
            return tuple(self._T[:, at])
        out = np.empty((4, rows.size))
        out[:, ok] = self._T[:, at[ok]]
        out[:, ~ok] = self._pose_terms(rows[~ok])
        return tuple(out)

    def centroids_xz(self, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """``X, Z``: the weighted horizontal centroid of the candidates ``rows`` (default all), in the
        clouds' units (the translation part of the closed form, see the module docstring)."""
        rows = self._check_rows(rows)
        X, Z, _, _ = self._rows_t(rows)
        return X, Z

    def _check_rows(self, rows, name: str = "rows") -> np.ndarray:
        """Candidate rows: ``None`` (all), a boolean mask of length n or indices in ``0..n-1`` (intp), else
        :class:`MotionError` (a float, a string or an index out of range raised numpy's errors)."""
        n = self.n
        if rows is None:
            return np.arange(n)
        if isinstance(rows, np.ndarray) and rows.dtype.kind in "iu" and rows.ndim == 1:
            r = rows  # the retrieval's own gathers: no copy, only the range
        else:
            if isinstance(rows, range) and len(rows) > n:  # range(10**12) is not copied to be refused
                raise MotionError(f"{name} must be candidate indices in 0..{n - 1}, got {describe(rows)}")
            try:
                a = np.asarray(rows) if not isinstance(rows, (str, bytes)) else None
            except (TypeError, ValueError):
                a = None
            if a is None or a.ndim != 1:
                raise MotionError(f"{name} must be a 1-D array of candidate indices or a mask, got {describe(rows)}")
            if a.dtype.kind == "b":
                if a.size != n:
                    raise MotionError(f"{name}: a boolean mask of length {a.size}, not {n}")
                return np.flatnonzero(a)
            r = as_real_array(a, name, error=MotionError, integer=True, ndim=1)
        if r.size and (r.min() < 0 or r.max() >= n):
            raise MotionError(f"{name} must be candidate indices in 0..{n - 1}, got {int(r.min())}..{int(r.max())}")
        return r.astype(np.intp, copy=False)

    def _rows_m(self, rows: np.ndarray) -> np.ndarray:
        """The matrix terms of poses ``rows`` (a copy), from the stored ones or recomputed."""
        if self._pos is None:
            return self._M[rows] if self._perm is None else self._M[self._perm[rows]]
        at = self._pos[rows]
        ok = at >= 0
        if ok.all():
            return self._M[at]
        out = np.empty((rows.size, self._M.shape[1]))
        out[ok] = self._M[at[ok]]
        out[~ok] = self._terms(self.points[rows[~ok]])[0]
        return out

    def subset(self, rows) -> AlignedPoseIndex:
        """An index of the candidates ``rows`` only (``points`` is None).

        A view of the stored terms when ``rows`` are consecutive entries of ``order``
        (see the class), in any order (the subset then keeps the permutation to its rows:
        its distances are in the order of ``rows``); else contiguous copies.
        """
        if rows is None:
            raise MotionError("rows must be candidate indices or a mask, got None")
        rows = self._check_rows(rows)
        out = object.__new__(AlignedPoseIndex)
        out.points = None
        out.order = None
        out._pos = None
        out._perm = None
        out.weights = self.weights
        out._P = self._P
        out._T = None
        out._N = int(rows.size)
        at = None if self._pos is None or rows.size == 0 else self._pos[rows]
        lo = None if at is None else int(at.min())
        if (at is not None and lo >= 0 and int(at.max()) - lo == rows.size - 1
                and np.bincount(at - lo, minlength=rows.size).max() == 1):  # a run of ``order``, permuted
            sl = slice(lo, lo + rows.size)
            out._M = self._M[sl]
            out._X, out._Z, out._H, out._Y2 = self._T[0, sl], self._T[1, sl], self._T[2, sl], self._T[3, sl]
            if np.any(np.diff(at) != 1):
                out._perm = at - lo
        else:
            out._M = np.ascontiguousarray(self._rows_m(rows))
            out._X, out._Z, out._H, out._Y2 = self._rows_t(rows)
        return out

    @property
    def n(self) -> int:
        """Number of candidate poses N."""
        return self._N

    def terms(self) -> tuple[np.ndarray, ...]:
        """``(M, X, Z, H, Y2, perm)``: the closed form's stored terms (views) and the stored entry of each
        candidate (``perm[i]``), for a compiled reader of :meth:`distances` (the exact retrieval's)."""
        if self._pos is not None:
            raise MotionError("terms() needs an index stored in candidate order (a subset, or one built without order)")
        perm = np.arange(self._N, dtype=np.intp) if self._perm is None else self._perm.astype(np.intp, copy=False)
        return self._M, self._X, self._Z, self._H, self._Y2, perm

    def query_matrix(self, q: np.ndarray) -> tuple[np.ndarray, float, float, float, float]:
        """The query-dependent parts: ``(3P, 3)`` matrix and ``X, Z, H, sum w y^2`` of the query."""
        q = self._query(q)
        P = self._P
        w = self.weights
        xa, ya, za = q[:, 0], q[:, 1], q[:, 2]
        Q = np.zeros((3 * P, 3))
        Q[:P, 0], Q[P:2 * P, 0] = xa, za
        Q[:P, 1], Q[P:2 * P, 1] = -za, xa
        Q[2 * P:, 2] = ya
        Xa, Za = float(xa @ w), float(za @ w)
        Ha = float((xa * xa + za * za) @ w) - (Xa * Xa + Za * Za)
        return Q, Xa, Za, Ha, float((ya * ya) @ w)

    def _query(self, q) -> np.ndarray:
        """A query pose: a finite float (P, 3) array, else :class:`MotionError`."""
        q = real_array(q, "query pose")
        if q.shape != (self._P, 3):
            raise MotionError(f"query pose must be ({self._P}, 3), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise MotionError("query pose contains NaN or inf")
        return _check_magnitude(q, "query pose")

    def distances(self, q: np.ndarray, rows: np.ndarray | None = None, *, return_transform: bool = False,
                  prepared=None):
        """Aligned distances from query ``q`` (P, 3) to the candidates ``rows`` (default all).

        Parameters
        ----------
        q : (P, 3) array
        rows : int array, optional
            Candidate subset (gathered: prefer a :meth:`subset` for repeated use).
        return_transform : bool
            Also return ``theta, x0, z0`` (n,) of the transformation mapping each
            candidate onto ``q`` (as in :func:`aligned_distance` with ``a = q``).
        prepared : tuple, optional
            :meth:`query_matrix` of ``q`` when already computed.
        """
        Q, Xa, Za, Ha, Ya2 = self.query_matrix(q) if prepared is None else prepared
        return_transform = as_bool(return_transform, "return_transform", error=MotionError)
        perm = None
        if rows is None and self._pos is None:
            # every candidate, in stored order (a permuted subset's results are permuted at the end:
            # element-wise, so the same values as permuting the terms first)
            X, Z, H, Y2 = self._X, self._Z, self._H, self._Y2
            R = self._M @ Q
            perm = self._perm
        else:
            rows = self._check_rows(rows)
            M = self._rows_m(rows)
            X, Z, H, Y2 = self._rows_t(rows)
            R = M @ Q
        A = R[:, 0] - (Xa * X + Za * Z)
        B = R[:, 1] - (Xa * Z - Za * X)
        d2 = Ya2 - 2.0 * R[:, 2] + Y2 + Ha + H - 2.0 * np.hypot(A, B)
        d = np.sqrt(np.maximum(d2, 0.0))
        if not return_transform:
            return d if perm is None else d[perm]
        theta = np.arctan2(B, A)
        c, s = np.cos(theta), np.sin(theta)
        out = d, theta, Xa - (c * X + s * Z), Za - (-s * X + c * Z)
        return out if perm is None else tuple(o[perm] for o in out)

    def direct_distance(self, q: np.ndarray, row: int) -> tuple[float, float, float, float]:
        """``(d, theta, x0, z0)`` of query ``q`` (P, 3) to stored pose ``row``, ``d`` summed directly.

        The transform is the closed form's (the terms of :meth:`query_matrix` and of the stored
        pose, for this one pair); ``d = sqrt(sum w |q - T(p)|^2)`` is then summed over the
        points instead of expanded, so it keeps full precision where the closed form cancels
        (``d2`` of two near-equal poses is the difference of terms ~``H``: ``d`` off by ~1e-8
        sqrt(H)).  Needs :attr:`points` (not a :meth:`subset`).
        """
        if self.points is None:
            raise MotionError("direct_distance needs the candidate clouds (this index is a subset)")
        # one pair, in plain dot products: :meth:`distances` on one row costs ~5x more (its matrix
        # product and per-array steps, measured ~115 us against ~25 us); the same terms, rounded in
        # another order (a few ulps of theta)
        row = as_int(row, "row (candidate index)", 0, self.n - 1, error=MotionError)
        q = self._query(q)
        p = self.points[row].astype(float)
        w = self.weights
        pw = p * w[:, None]
        S = q.T @ pw  # S[a, b] = sum w q_a p_b
        Xa, _, Za = (w @ q).tolist()
        X, _, Z = pw.sum(axis=0).tolist()
        A = (S[0, 0] + S[2, 2]).item() - (Xa * X + Za * Z)
        B = (S[0, 2] - S[2, 0]).item() - (Xa * Z - Za * X)
        theta = math.atan2(B, A)
        c, s = math.cos(theta), math.sin(theta)
        x0, z0 = Xa - (c * X + s * Z), Za - (-s * X + c * Z)
        # q - T(p), T(p) = rotate_y(p, theta) + (x0, 0, z0) as a row-vector product
        diff = q - (p @ np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]) + [x0, 0.0, z0])
        return float(np.sqrt(np.einsum("pk,pk,p->", diff, diff, w))), theta, x0, z0


# ------------------------------------------------------------------- k-means
@dataclass(eq=False)
class PoseClusters:
    """Result of :func:`cluster_poses`.

    Attributes
    ----------
    centroids : (k, P, 3) array
        Mean cloud of each cluster, in the canonical root frame (same units as the
        poses).
    labels : (N,) int array
        Cluster of each pose.
    members : list of (n_c,) int arrays
        Pose indices of each cluster (sorted).
    weights : (P,) array
        Point weights used.
    seed : int
    inertia : float
        Mean weighted squared distance of the poses to their centroid (unaligned, in the
        canonical frame): the k-means objective, an upper bound of the aligned one.
    """

    centroids: np.ndarray
    labels: np.ndarray
    members: list
    weights: np.ndarray
    seed: int
    inertia: float

    @property
    def k(self) -> int:
        """Number of clusters."""
        return int(self.centroids.shape[0])

    def sizes(self) -> np.ndarray:
        """(k,) number of poses per cluster."""
        return np.array([m.size for m in self.members])


def default_k(n_poses: int) -> int:
    """Default number of clusters: ``round(sqrt(n_poses / 8))``, in [1, 256].

    About 16 clusters for the ~2,000 poses of the CMU database at 30 Hz (a cluster
    holds ~125 poses, so the pruned search scores ~1/16 of the poses).
    """
    n_poses = as_int(n_poses, "n_poses", 0, None, error=MotionError)
    return int(np.clip(round(math.sqrt(max(n_poses, 1) / 8.0)), 1, 256))


def _nearest_centroid(X: np.ndarray, C: np.ndarray, chunk: int = CHUNK) -> np.ndarray:
    """Index of the nearest row of C for every row of X (squared Euclidean, via BLAS).

    ``argmin_c |c|^2 - 2 x.c`` (``|x|^2`` does not change the argmin), one matrix product per
    chunk into a reused buffer.
    """
    c2 = np.einsum("ij,ij->i", C, C)
    out = np.empty(X.shape[0], dtype=np.intp)
    buf = np.empty((min(chunk, X.shape[0]), C.shape[0]), dtype=np.result_type(X, C))
    for a in range(0, X.shape[0], chunk):
        Xa = X[a:a + chunk]
        D = np.matmul(Xa, C.T, out=buf[:Xa.shape[0]])
        D *= -2.0
        D += c2
        out[a:a + Xa.shape[0]] = np.argmin(D, axis=1)
    return out


def _label_sums(labels: np.ndarray, X: np.ndarray, k: int) -> np.ndarray:
    """(k, D) float64 sums of the rows of X per label: one sparse product (the same sums, in the same
    order, as one :func:`numpy.bincount` per column)."""
    n = labels.size
    onehot = csr_matrix((np.ones(n), (labels, np.arange(n))), shape=(k, n))
    return np.asarray(onehot @ X.astype(np.float64, copy=False))


def _kmeans_sample(X: np.ndarray, k: int, iterations: int, rng) -> np.ndarray:
    """k-means++ seeding and Lloyd iterations on a sample, with BLAS distances (float32).

    The seeding keeps every point's squared distance to its nearest chosen centre and
    updates it with one new centre at a time (O(n k), where
    :func:`scipy.cluster.vq.kmeans2`'s ``minit="++"`` recomputes the distances to all
    chosen centres at every step, O(n k^2)).
    """
    n = X.shape[0]
    x2 = np.einsum("ij,ij->i", X, X)
    C = np.empty((k, X.shape[1]), dtype=X.dtype)
    C[0] = X[rng.integers(n)]
    best = np.maximum(x2 - 2.0 * (X @ C[0]) + C[0] @ C[0], 0.0)
    for j in range(1, k):
        tot = float(best.sum(dtype=np.float64))
        i = int(rng.integers(n)) if tot <= 0 else int(np.searchsorted(np.cumsum(best, dtype=np.float64),
                                                                      rng.random() * tot))
        C[j] = X[min(i, n - 1)]
        np.minimum(best, np.maximum(x2 - 2.0 * (X @ C[j]) + C[j] @ C[j], 0.0), out=best)
    for _ in range(iterations):
        lab = _nearest_centroid(X, C)
        C = _means(X, lab, k, C)
    return C


def _means(X: np.ndarray, labels: np.ndarray, k: int, previous: np.ndarray) -> np.ndarray:
    """Mean of every label's rows (one bincount per column); an empty label keeps ``previous``."""
    cnt = np.bincount(labels, minlength=k).astype(np.float64)
    S = _label_sums(labels, X, k)
    out = np.array(previous, dtype=np.float64)
    nz = cnt > 0
    out[nz] = S[nz] / cnt[nz, None]
    return out.astype(X.dtype)


def cluster_poses(points: np.ndarray, k: int | None = None, *, weights=None, seed: int = 0,
                  iterations: int = 20, max_fit: int | None = 20_000) -> PoseClusters:
    """k-means of pose clouds (Section 3.2.2), deterministic for a fixed seed.

    Parameters
    ----------
    points : (N, P, 3) array
        Pose clouds in their canonical root frames (:func:`pose_points`); float32 or
        float64, never copied whole (the passes over all poses work by chunks of
        :data:`CHUNK` rows).
    k : int, optional
        Number of clusters, an int >= 1 (default :func:`default_k`); more than N is cut
        to N with a :class:`~repro.errors.ReproWarning` saying so.
    weights : (P,) array, optional
        Point weights; default uniform.
    seed : int, default 0
        Seed (an int >= 0) of the k-means++ initialisation (:func:`scipy.cluster.vq.kmeans2`).
    iterations : int, default 20
        k-means iterations, in ``[1, MAX_ITERATIONS]`` (10,000).
    max_fit : int or None, default 20,000
        With more poses than this (the 10x / 100x / 1,000x augmented databases), k-means
        runs on a random subset of ``max_fit`` poses (drawn with ``seed``; k-means++
        seeding and Lloyd iterations with BLAS distances in float32, linear in ``k`` per
        seed, :func:`_kmeans_sample`), then every pose is assigned to its nearest
        centroid in chunks and the centroids are recomputed as the means of their
        members (one more Lloyd step on all poses).  Memory: float32 chunks, never a
        second copy of all poses.  Up to ``max_fit`` poses (the paper-size databases)
        :func:`scipy.cluster.vq.kmeans2` runs on all of them.  None: always the latter.

    Returns
    -------
    PoseClusters
        Empty clusters (possible with k-means) are dropped, so ``k`` may be smaller
        than asked.

    Raises
    ------
    repro.errors.MotionError
        Empty, non-numeric or non-finite input; ``k``, ``seed``, ``iterations`` or
        ``max_fit`` not an integer in range (``max_fit`` must be >= ``k``).
    """
    p = float_poses(points, "poses")
    N, P, _ = p.shape
    k = default_k(N) if k is None else as_int(k, "k (number of clusters)", 1, error=MotionError)
    seed = as_int(seed, "seed", 0, error=MotionError)
    iterations = as_int(iterations, "iterations", 1, MAX_ITERATIONS, error=MotionError)
    if k > N:
        warnings.warn(f"k = {k} clusters asked for {N} poses; using k = {N}", ReproWarning, stacklevel=2)
        k = N
    if max_fit is not None:
        max_fit = as_int(max_fit, "max_fit", k, error=MotionError)
    w = pose_weights(P, weights)
    sw = np.sqrt(w)[None, :, None]
    if max_fit is not None and N > max_fit and k > 1:
        return _cluster_large(p, k, w, seed, iterations, int(max_fit))
    X = (p.astype(float, copy=False) * sw).reshape(N, 3 * P)
    if k == 1:
        labels = np.zeros(N, dtype=np.intp)
        C = X.mean(axis=0, keepdims=True)
    else:
        rng = np.random.default_rng(seed)
        C, labels = kmeans2(X, k, iter=iterations, minit="++", rng=rng)
        labels = labels.astype(np.intp)
    used = np.unique(labels)
    remap = np.full(max(k, 1), -1, dtype=np.intp)
    remap[used] = np.arange(used.size)
    labels = remap[labels]
    C = np.stack([X[labels == c].mean(axis=0) for c in range(used.size)])
    inertia = float(np.mean(np.sum((X - C[labels]) ** 2, axis=1)))
    centroids = C.reshape(-1, P, 3) / sw
    members = [np.flatnonzero(labels == c) for c in range(used.size)]
    return PoseClusters(centroids=centroids, labels=labels, members=members, weights=w, seed=int(seed),
                        inertia=inertia)


def _cluster_large(p: np.ndarray, k: int, w: np.ndarray, seed: int, iterations: int, max_fit: int,
                   chunk: int = CHUNK) -> PoseClusters:
    """:func:`cluster_poses` beyond ``max_fit`` poses: k-means of a sample, one pass over all."""
    N, P, _ = p.shape
    sw = np.sqrt(w).astype(np.float32)[None, :, None]
    rng = np.random.default_rng(seed)
    fit = np.sort(rng.choice(N, max_fit, replace=False))
    C = _kmeans_sample((p[fit].astype(np.float32) * sw).reshape(max_fit, 3 * P), k, iterations, rng)
    labels = np.empty(N, dtype=np.intp)
    S = np.zeros((k, 3 * P))
    for a in range(0, N, chunk):
        Xc = (p[a:a + chunk].astype(np.float32) * sw).reshape(-1, 3 * P)
        lab = _nearest_centroid(Xc, C)
        labels[a:a + chunk] = lab
        S += _label_sums(lab, Xc, k)
    cnt = np.bincount(labels, minlength=k)
    used = np.flatnonzero(cnt)
    remap = np.full(k, -1, dtype=np.intp)
    remap[used] = np.arange(used.size)
    labels = remap[labels]
    Cm = S[used] / cnt[used, None]
    inertia = 0.0
    for a in range(0, N, chunk):
        Xc = (p[a:a + chunk].astype(float, copy=False) * sw).reshape(-1, 3 * P)
        inertia += float(np.sum((Xc - Cm[labels[a:a + chunk]]) ** 2))
    order = np.argsort(labels, kind="stable")
    members = np.split(order, np.cumsum(cnt[used])[:-1])
    centroids = Cm.reshape(-1, P, 3) / np.sqrt(w)[None, :, None]
    return PoseClusters(centroids=centroids, labels=labels, members=members, weights=w, seed=int(seed),
                        inertia=inertia / N)
