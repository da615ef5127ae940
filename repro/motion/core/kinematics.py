"""Vector helpers and **the** forward kinematics of the motion library, on raw arrays.

Quaternion maths lives in :mod:`repro.motion.core.quaternion`; this module adds the vector
operations the solvers use (:func:`dot`, :func:`normalize`, :func:`transport`,
:func:`matvec`) and every form of forward kinematics ``G_j = G_parent(j) T(t_j) R(q_j)``
(the world transform of each joint of a BVH/ASF hierarchy, Kovar et al. 2002, Sec. 2):

* :func:`forward_kinematics`, the entry point for a whole tree (what
  :meth:`repro.motion.core.motion.Motion.global_transforms` runs): :func:`fk_arrays`, one
  vectorised step per :func:`depth_levels` level, for trees up to
  :data:`LEVEL_LOOP_MAX_DEPTH` deep (every real skeleton), else :func:`fk_doubling`,
  pointer doubling in ``ceil(log2(depth))`` rounds (deep chains from files);
* :func:`rest_positions`, the rest pose (all rotations identity): sums of offsets by levels;
* :func:`chain_fk` / :func:`chain_fk_from`, rotation matrices along one root -> joint
  path, recomputed in place from a changed joint on: the IK solvers' inner loop.

Checked against :class:`scipy.spatial.transform.Rotation` and against each other in
``tests/motion/core/test_kinematics.py``.
"""

from __future__ import annotations

import numpy as np

from repro.checks import abs_max, as_real_array, describe
from repro.errors import MotionError
from repro.motion.core.quaternion import cross, quat_multiply, quat_rotate, vector_norm

__all__ = [
    "dot",
    "normalize",
    "transport",
    "forward_kinematics",
    "fk_arrays",
    "fk_doubling",
    "rest_positions",
    "chain_fk",
    "chain_fk_from",
    "chain_positions",
    "depth_levels",
    "children_of",
    "LEVEL_LOOP_MAX_DEPTH",
    "world_of",
    "check_pose_arrays",
    "check_joint_names",
    "check_indices",
    "MAX_JOINTS",
    "MAX_COORDINATE",
    "matvec",
    "matvec_t",
]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis, broadcast."""
    return np.einsum("...i,...i->...", a, b)


def normalize(v: np.ndarray, eps: float = 1e-300) -> tuple[np.ndarray, np.ndarray]:
    """``(v / |v|, |v|)`` over the last axis (``|v|`` floored at ``eps`` in the division)."""
    n = vector_norm(v, keepdims=True)
    return v / np.maximum(n, eps), n[..., 0]


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


def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-vector product ``m v`` broadcast over leading axes."""
    return np.matmul(m, v[..., None])[..., 0]


def matvec_t(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transposed-matrix-vector product ``m^T v`` broadcast over leading axes."""
    return np.matmul(v[..., None, :], m)[..., 0, :]


#: Largest coordinate of a point or vector the motion library takes (targets, offsets, floors,
#: translations): its squares (distances, norms) stay far inside float64.
MAX_COORDINATE: float = 1e100
#: Largest ``| |q| - 1 |`` of a rotation given as a unit quaternion (as :class:`~repro.motion.Motion`'s).
UNIT_TOLERANCE: float = 1e-6


#: Most joints a skeleton may have: far beyond any rig (film rigs with faces and fingers have about
#: a thousand; the BVH reader is tested on a 20,000-deep chain), short of what takes seconds to name.
MAX_JOINTS: int = 1_000_000


def check_joint_names(joint_names, *, error=MotionError) -> list[str]:
    """``joint_names`` as a list of str: a 1-D sequence of at most :data:`MAX_JOINTS` names (not a string)."""
    if isinstance(joint_names, (str, bytes)) or not isinstance(joint_names, (list, tuple, np.ndarray)) or \
            getattr(joint_names, "ndim", 1) != 1:
        raise error(f"joint_names must be a sequence of joint names, got {describe(joint_names)}")
    if len(joint_names) > MAX_JOINTS:
        raise error(f"{len(joint_names)} joints: more than the {MAX_JOINTS} of any skeleton")
    if any(isinstance(n, (list, tuple, dict, set, np.ndarray)) for n in joint_names):
        raise error(f"joint_names must be a sequence of joint names, got {describe(joint_names)}")
    return [str(n) for n in joint_names]


def check_indices(x, name: str, n: int, *, error=MotionError) -> np.ndarray:
    """``x`` as a 1-D intp array of joint indices in ``[0, n)`` (a range is checked against the budget first)."""
    a = as_real_array(x, name, error=error, integer=True).reshape(-1)
    if np.any((a < 0) | (a >= n)):
        raise error(f"{name} must be joint indices in [0, {n})")
    return a.astype(np.intp)


def check_pose_arrays(rotations, translations, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """``(rotations (F, J, 4), translations (F, J, 3))`` as float64 arrays, or MotionError naming what is wrong.

    The rotations must be unit quaternions (within :data:`UNIT_TOLERANCE`), the translations
    finite and within :data:`MAX_COORDINATE`: what a plan's ``positions`` takes from a Motion,
    checked at its entry (the arithmetic after it would overflow or divide by zero silently).
    """
    rot = as_real_array(rotations, "rotations", error=MotionError)
    tr = as_real_array(translations, "translations", error=MotionError)
    if rot.ndim != 3 or rot.shape[1:] != (n_joints, 4) or tr.shape != rot.shape[:2] + (3,):
        raise MotionError(f"rotations must be (F, {n_joints}, 4) and translations (F, {n_joints}, 3), got "
                          f"{rot.shape} and {tr.shape}")
    if abs_max(tr) > MAX_COORDINATE:
        raise MotionError(f"translations beyond {MAX_COORDINATE:g}: their squares overflow float64")
    if rot.size and (abs_max(rot) > 1.0 + UNIT_TOLERANCE or
                     not np.all(np.abs(vector_norm(rot) - 1.0) <= UNIT_TOLERANCE)):
        raise MotionError(f"rotations must be unit quaternions (| |q| - 1 | <= {UNIT_TOLERANCE:g})")
    return rot, tr


# ------------------------------------------------------------------ forward kinematics
def children_of(parents) -> list[list[int]]:
    """The children of every joint, in joint order (``parents[j] < 0``: a root)."""
    kids: list[list[int]] = [[] for _ in range(len(parents))]
    for c, p in enumerate(np.asarray(parents).tolist()):
        if p >= 0:
            kids[p].append(c)
    return kids


def depth_levels(parents) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(joints, their parents)`` per depth 1, 2, ... of a tree (``parents[j] < j``), index order within a level.

    Linear in the number of joints (a scan per depth level would be quadratic for chains).
    """
    parents, order, bounds = _depth_order(parents)
    p = parents[order]
    return [(order[a:b], p[a:b]) for a, b in zip(bounds[1:-1], bounds[2:])]


def _depth_order(parents) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """``(parents, order, bounds)``: the checked parents, the joints by depth (index order within
    a depth) and where each depth starts in ``order`` (``order[bounds[d]:bounds[d + 1]]`` at depth d)."""
    parents = _tree_parents(parents)
    par = parents.tolist()
    depth = [0] * len(par)
    for j in range(1, len(par)):
        depth[j] = depth[par[j]] + 1
    depth = np.array(depth, dtype=np.intp)
    order = np.argsort(depth, kind="stable")
    return parents, order, [0] + np.cumsum(np.bincount(depth)).tolist()


def _tree_parents(parents) -> np.ndarray:
    """``parents`` as a 1-D intp array of a joint tree (-1 for joint 0, ``parents[j] < j``), or MotionError."""
    parents = as_real_array(parents, "parents", error=MotionError, integer=True, ndim=1).astype(np.intp)
    if parents.size == 0 or parents[0] != -1 or np.any(parents[1:] < 0) or \
            np.any(parents[1:] >= np.arange(1, parents.size)):
        raise MotionError("parents must be -1 for joint 0 and parents[j] < j for the others")
    return parents


#: Trees deeper than this use pointer doubling in forward kinematics (log(depth)
#: vectorised rounds) instead of one round per depth level; real skeletons are far
#: shallower and keep the level loop (and its exact arithmetic).
LEVEL_LOOP_MAX_DEPTH = 64


def forward_kinematics(parents, rotations: np.ndarray, translations: np.ndarray, *, levels=None,
                       copy: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """World rotations and positions of every joint of a tree: :func:`fk_arrays` or :func:`fk_doubling` by depth.

    The level loop (:func:`fk_arrays`) for trees up to :data:`LEVEL_LOOP_MAX_DEPTH` levels
    deep, pointer doubling (:func:`fk_doubling`) beyond: the same transforms, the level
    loop's numbers exactly on every real skeleton.

    Parameters
    ----------
    parents : (J,) int array
        Parent of each joint (-1 for joint 0, ``parents[j] < j``).
    rotations : (F, J, 4) array
        Local rotations (unit quaternions).
    translations : (F, J, 3) array
        Local translations.
    levels : list of (joints, parents) index arrays, optional
        :func:`depth_levels` of ``parents``, when the caller has them cached.
    copy : bool, default True
        False: fill ``translations`` in place with the world positions (a fresh array
        the caller owns).

    Returns
    -------
    (F, J, 4) world rotations, (F, J, 3) world positions
    """
    if levels is None:
        levels = depth_levels(parents)
    if len(levels) > LEVEL_LOOP_MAX_DEPTH:
        return fk_doubling(parents, rotations, translations, copy=copy)
    return fk_arrays(levels, rotations, translations, copy=copy)


def fk_arrays(levels, rotations: np.ndarray, translations: np.ndarray, *,
              copy: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics ``G_j = G_parent(j) T(t_j) R(q_j)`` level by level: one vectorised step per depth.

    The form for real skeletons (a few dozen levels at most): the retargeting and
    adaptation solvers call it with their cached levels; :func:`forward_kinematics`
    chooses it for trees up to :data:`LEVEL_LOOP_MAX_DEPTH` deep.

    Parameters
    ----------
    levels : list of (joints, parents) index arrays
        :func:`depth_levels` of the tree (depth 1, 2, ...).
    rotations : (F, J, 4) array
        Local rotations (unit quaternions).
    translations : (F, J, 3) array
        Local translations.
    copy : bool, default True
        False: fill ``translations`` in place with the world positions (a fresh array
        the caller owns).

    Returns
    -------
    (F, J, 4) world rotations, (F, J, 3) world positions
    """
    _check_pose_shapes("fk_arrays", rotations, translations)
    gq = np.empty_like(rotations)
    gp = translations.copy() if copy else translations
    gq[:, 0] = rotations[:, 0]
    for idx, par in levels:
        gq[:, idx] = quat_multiply(gq[:, par], rotations[:, idx])
    return gq, chain_positions(levels, gq, gp)


def chain_positions(levels, gq: np.ndarray, gp: np.ndarray) -> np.ndarray:
    """World positions from world rotations: ``gp[j] = gp[parent] + R(gq[parent]) t[j]`` over ``levels``.

    ``gp`` holds the local translations ``t`` of the levels' joints and the world positions
    of their parents (above the levels), and is filled in place.  The rotations of all the
    levels run as one call, the sums level by level: the numbers of a level-by-level loop
    (element for element the same arithmetic), with less per-call overhead on few frames.
    """
    if not levels:
        return gp
    joints = np.concatenate([i for i, _ in levels])
    parents = np.concatenate([p for _, p in levels])
    w = quat_rotate(gq[:, parents], gp[:, joints])
    k = 0
    for idx, par in levels:
        gp[:, idx] = gp[:, par] + w[:, k:k + idx.size]
        k += idx.size
    return gp


def fk_doubling(parents, rotations: np.ndarray, translations: np.ndarray, *,
                copy: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics by pointer doubling: ``ceil(log2(depth))`` vectorised rounds, no loop over levels.

    The form for deep trees (a 20,000-joint chain read from a file takes 15 rounds, where
    :func:`fk_arrays` would take 20,000 steps).  Each joint holds the transform from an
    ancestor ``anc[j]`` to itself (at first its local one, from its parent); every round
    composes it with the transform held by ``anc[j]`` and jumps to that joint's ancestor,
    so after the last round every joint holds its world transform.  The products are
    grouped differently from the level loop's, so the numbers agree with it to rounding.

    Parameters and returns as :func:`forward_kinematics` (without ``levels``).
    """
    parents = _tree_parents(parents)
    _check_pose_shapes("fk_doubling", rotations, translations)
    if rotations.shape[1] != parents.size:
        raise MotionError(f"fk_doubling: {parents.size} parents for {rotations.shape[1]} joints")
    gq = rotations.copy()
    gp = translations.copy() if copy else translations
    anc = parents.copy()
    while True:
        live = np.flatnonzero(anc >= 0)
        if not live.size:
            return gq, gp
        a = anc[live]
        pq = gq[:, a]
        gp[:, live] = gp[:, a] + quat_rotate(pq, gp[:, live])
        gq[:, live] = quat_multiply(pq, gq[:, live])
        anc[live] = anc[a]


def _check_pose_shapes(who: str, rotations, translations) -> None:
    """MotionError unless (F, J, 4) rotations and (F, J, 3) translations arrays.

    Shapes only (forward kinematics runs in every solver): what fails here would fail as a
    bare numpy error in the arithmetic.
    """
    if not (isinstance(rotations, np.ndarray) and isinstance(translations, np.ndarray)) or rotations.ndim != 3 or \
            rotations.shape[2:] != (4,) or translations.shape != rotations.shape[:2] + (3,):
        raise MotionError(f"{who} needs (F, J, 4) rotations and (F, J, 3) translations arrays, got "
                          f"{getattr(rotations, 'shape', describe(rotations))} and "
                          f"{getattr(translations, 'shape', describe(translations))}")


def world_of(levels, rotations, translations, source=None) -> tuple[np.ndarray, np.ndarray]:
    """``source`` = world ``(rotations (F, J, 4), positions (F, J, 3))`` checked against ``levels``' J joints,
    or :func:`fk_arrays` of ``rotations`` and ``translations`` when it is None (a plan's ``source=`` argument)."""
    if source is None:
        return fk_arrays(levels, rotations, translations)
    J = 1 + sum(len(i) for i, _ in levels)
    ok = isinstance(source, tuple) and len(source) == 2 and all(isinstance(a, np.ndarray) for a in source)
    if ok:
        gq, gp = source
        ok = gq.ndim == 3 and gq.shape[1:] == (J, 4) and gp.shape == gq.shape[:2] + (3,)
    if not ok:
        raise MotionError(f"source must be a pair of world (F, {J}, 4) rotations and (F, {J}, 3) positions "
                          f"arrays (Motion.global_transforms()), got {describe(source)}")
    return source


def rest_positions(parents, offsets) -> np.ndarray:
    """(J, 3) joint positions of the rest pose: forward kinematics with every rotation identity.

    ``p[j] = p[parent(j)] + offsets[j]`` (``p[0] = offsets[0]``), one vectorised step per
    :func:`depth_levels` level (:func:`fk_arrays`' loop without rotations): element for element
    the sums of a joint-by-joint loop, for any tree the library takes (``parents[j] < j``),
    chains of any depth included.

    Parameters
    ----------
    parents : (J,) int array
        Parent of each joint, -1 for the root.
    offsets : (J, 3) array
        Rest offset of each joint from its parent (the root's: its rest position).
    """
    parents, order, bounds = _depth_order(parents)
    off = np.asarray(offsets, dtype=float)
    if off.shape != (parents.size, 3):
        raise MotionError(f"offsets must be a ({parents.size}, 3) array for {parents.size} joints, got {off.shape}")
    # in depth order each level is a slice (only the parents are gathered): the same sums, fewer copies
    at = np.empty_like(order)
    at[order] = np.arange(order.size)
    p = off[order]
    par = at[parents[order]]
    for a, b in zip(bounds[1:-1], bounds[2:]):
        np.add(p[par[a:b]], p[a:b], out=p[a:b])
    return p[at]


def chain_fk(ml: np.ndarray, tl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (n, P, 3, 3) and positions (n, P, 3) along one root -> joint path.

    Forward kinematics on just the P joints of a path (an effector chain of
    :mod:`repro.motion.adaptation.rig`), with rotation matrices: the form of the IK
    solvers, which change one joint of the path at a time and recompute the joints below
    it with :func:`chain_fk_from`.  Same transforms as :func:`fk_arrays` on those joints.

    Parameters
    ----------
    ml : (n, P, 3, 3) array
        Local rotation matrices of the path's joints, root first.
    tl : (n, P, 3) array
        Their local translations.
    """
    rw = np.empty_like(ml)
    pw = np.empty_like(tl)
    rw[:, 0] = ml[:, 0]
    pw[:, 0] = tl[:, 0]
    chain_fk_from(ml, tl, rw, pw, 1)
    return rw, pw


def chain_fk_from(ml, tl, rw, pw, k: int) -> None:
    """Recompute the world transforms ``rw``, ``pw`` of :func:`chain_fk` at path positions ``>= k`` in place.

    What a solver runs after changing the local rotation ``ml[:, k]`` (and any below it):
    the joints above ``k`` keep their world transforms.
    """
    if k == 0:
        rw[:, 0] = ml[:, 0]
        pw[:, 0] = tl[:, 0]
        k = 1
    for i in range(k, ml.shape[1]):
        pw[:, i] = pw[:, i - 1] + matvec(rw[:, i - 1], tl[:, i])
        rw[:, i] = rw[:, i - 1] @ ml[:, i]
