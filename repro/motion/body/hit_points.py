"""Where a strike lands on the body: the hit point of an effector joint, the same way on every rig.

The paper annotates each clip with its hit segment, and "the system automatically calculates the
trajectory of the hit point" (Section 3.1).  A fist lands on its knuckles and a kick on the ball
or the tip of the foot, so the hit point is a fixed point in the frame of the effector joint (the
``{side}_fist`` or ``{side}_foot`` role), found in the rest pose (where every rotation is the
identity, so that a descendant's position in the joint's frame is the sum of the offsets below it):

* the joint's **End Site** when it has one (the hand or toe tip a BVH exporter wrote);
* else the **knuckles** of the fingers below it (a hand with fingers: Mixamo, Unity, DAZ,
  MakeHuman, MotionBuilder, Second Life bento ...; a foot with a toe joint): per path from the
  joint down to a leaf, the end of its longest segment -- the palm's bone, longer than any
  phalanx, whether the rig splits it with short metacarpal joints (MakeHuman, MotionBuilder's
  ``RightHandRing`` carrying the ring and pinky fingers) or not (Mixamo's ``HandIndex1`` sits a
  palm's length from the wrist); the thumb left out (a path through a joint named like a thumb,
  else, among five paths or more, the one whose knuckle is farthest from the others'); the mean
  of the rest;
* else the joint itself (a bare leaf: nothing says where its tip is).

:func:`hit_offset` gives the offset and how it was found.
"""

from __future__ import annotations

import numpy as np

from repro.checks import as_int, describe
from repro.errors import MotionError
from repro.motion.core.kinematics import children_of

__all__ = ["HIT_POINT_SOURCES", "THUMB_NAMES", "hit_offset"]

#: How :func:`hit_offset` found the point: the joint's End Site, its fingers' knuckles, the joint.
HIT_POINT_SOURCES = ("end_site", "knuckles", "joint")
#: Joint names of a thumb (lower case, a part of the name): Mixamo, Unity, DAZ, MotionBuilder, Second Life, CMU.
THUMB_NAMES = ("thumb", "pollex")

def hit_offset(skeleton, joint) -> tuple[np.ndarray, str]:
    """The hit point of ``joint`` in its own frame, ``(offset (3,), source)`` (module docstring).

    Parameters
    ----------
    skeleton : Skeleton or Motion
        Anything with ``parents``, ``offsets``, ``end_site_parents``, ``end_site_offsets``
        (and ``joint_names`` for a joint given by name).
    joint : int or str
        The effector joint (index or name).

    Raises
    ------
    repro.errors.MotionError
        Not a skeleton, an unknown joint.
    """
    try:
        parents = np.asarray(skeleton.parents)
        offsets = np.asarray(skeleton.offsets, dtype=float)
        esp = np.asarray(skeleton.end_site_parents)
        eso = np.asarray(skeleton.end_site_offsets, dtype=float)
    except (AttributeError, TypeError, ValueError):
        raise MotionError(f"skeleton must be a Skeleton or a Motion, got {describe(skeleton)}") from None
    J = parents.shape[0]
    if isinstance(joint, str):
        names = list(getattr(skeleton, "joint_names", ()))
        if joint not in names:
            raise MotionError(f"unknown joint {joint!r}")
        j = names.index(joint)
    else:
        j = as_int(joint, "joint (an index)", 0, J - 1, error=MotionError)
    mine = np.flatnonzero(esp == j)
    if mine.size:
        return eso[mine[0]].copy(), "end_site"
    names = [str(n).lower() for n in getattr(skeleton, "joint_names", [""] * J)]
    knuckles = _knuckles(parents, offsets, j, names)
    if knuckles is not None:
        return knuckles, "knuckles"
    return np.zeros(3), "joint"


def _knuckles(parents: np.ndarray, offsets: np.ndarray, j: int, names: list[str]) -> np.ndarray | None:
    """Mean knuckle (rest position in ``j``'s frame) of the paths below ``j``, thumb left out; None if none."""
    paths = _paths(children_of(parents), j)
    named = [p for p in paths if not any(any(t in names[k] for t in THUMB_NAMES) for k in p)]
    thumb_named = len(named) < len(paths)
    points = [p for p in (_path_knuckle(offsets, path) for path in (named or paths)) if p is not None]
    if not points:
        return None
    P = np.array(points)
    if not thumb_named and len(P) >= 5:  # an unnamed thumb: the knuckle farthest from the mean of the others
        others = [(float(np.linalg.norm(P[i] - np.delete(P, i, axis=0).mean(axis=0))), i) for i in range(len(P))]
        P = np.delete(P, max(others)[1], axis=0)
    return P.mean(axis=0)


def _paths(kids: list[list[int]], j: int) -> list[list[int]]:
    """Every path from a child of ``j`` down to a leaf (one per finger, or per toe)."""
    out, stack = [], [[c] for c in reversed(kids[j])]
    while stack:
        path = stack.pop()
        below = kids[path[-1]]
        if not below:
            out.append(path)
        stack.extend(path + [c] for c in reversed(below))
    return out


def _path_knuckle(offsets: np.ndarray, path: list[int]) -> np.ndarray | None:
    """The knuckle of one finger: the end of the longest segment of its path (the palm's bone, whether
    the rig splits it with a short metacarpal joint or not); None for a path of zero-length helpers."""
    seg = np.linalg.norm(offsets[path], axis=1)
    k = int(np.argmax(seg))
    if seg[k] <= 0:
        return None
    return offsets[path[:k + 1]].sum(axis=0)
