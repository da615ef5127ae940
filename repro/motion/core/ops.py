"""Operations on motions: resampling, cutting, mirroring.

Motions are :class:`~repro.motion.core.motion.Motion` objects; every operation returns a
new motion on the same (or the mirrored) skeleton.  :func:`resample` interpolates
rotations with slerp and position channels linearly; :func:`mirror_motion` reflects
through the plane x = 0 with left and right swapped (:func:`mirror_joint_map`);
:func:`variant_motion` combines them for the database's augmented clips.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence

import numpy as np

from repro.errors import MotionError
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import slerp

__all__ = ["resample", "cut", "mirror_joint_map", "mirror_motion", "variant_motion"]


#: the easing curves ``s`` of :func:`ease` (by name, for options and panels)
EASINGS = ("linear", "smoothstep", "smootherstep")


def ease(u, kind: str = "smootherstep") -> np.ndarray:
    """An easing curve ``s(u)``: ``s(0) = 0``, ``s(1) = 1``, increasing, ``u`` clipped to [0, 1] first.

    ``"linear"``; ``"smoothstep"`` ``3u^2 - 2u^3`` (zero speed at both ends); ``"smootherstep"``
    ``6u^5 - 15u^4 + 10u^3`` (zero speed and acceleration at both ends).  The one easing of the
    library: the offset ``d(t)`` of Section 3.4.2, blends between clips, the synthetic tracks.
    """
    u = np.clip(u, 0.0, 1.0)
    if kind == "linear":
        return u
    if kind == "smoothstep":
        return u * u * (3.0 - 2.0 * u)
    if kind == "smootherstep":
        return u * u * u * (u * (6.0 * u - 15.0) + 10.0)
    raise MotionError(f"kind must be one of {EASINGS}, got {kind!r}")


def resample(motion: Motion, fps: float | None = None, *, frames: Sequence[float] | np.ndarray | None = None,
             frame_time: float | None = None) -> Motion:
    """A motion sampled at other times: slerp of rotations, linear position channels.

    Parameters
    ----------
    motion : Motion
    fps : float, optional
        New rate; samples at ``0, 1/fps, ...`` up to the last frame's time.
    frames : (n,) array, optional
        Instead of ``fps``: the (fractional) source frame index of every new frame,
        within ``[0, F-1]``.
    frame_time : float, optional
        Frame time of the result with ``frames`` (default the source's).

    Returns
    -------
    Motion
        Same skeleton; sample times that fall on source frames reproduce them exactly.
    """
    F = motion.n_frames
    if frames is None:
        if fps is None or not np.isfinite(fps) or fps <= 0:
            raise MotionError(f"fps must be finite and > 0, got {fps!r}")
        n = int(math.floor((F - 1) * motion.frame_time * fps + 1e-9)) + 1
        u = np.arange(n) / fps / motion.frame_time
        frame_time = 1.0 / fps
    else:
        u = np.asarray(frames, dtype=float).reshape(-1)
        frame_time = motion.frame_time if frame_time is None else float(frame_time)
    if u.size == 0 or not np.all(np.isfinite(u)) or u.min() < -1e-9 or u.max() > F - 1 + 1e-9:
        raise MotionError(f"sample frames must be finite and inside [0, {F - 1}]")
    u = np.clip(u, 0, F - 1)
    i0 = np.clip(np.floor(u + 1e-9).astype(np.intp), 0, F - 1)
    a = u - i0
    a[np.abs(a) < 1e-9] = 0.0
    i1 = np.minimum(i0 + 1, F - 1)
    rot = slerp(motion.rotations[i0], motion.rotations[i1], a[:, None, None])
    exact = a == 0.0
    rot[exact] = motion.rotations[i0[exact]]
    pos = motion.positions[i0] * (1 - a)[:, None, None] + motion.positions[i1] * a[:, None, None]
    return dataclasses.replace(motion, rotations=rot, positions=pos, frame_time=frame_time)


def cut(motion: Motion, start: int, stop: int) -> Motion:
    """Frames ``[start, stop)`` of a motion."""
    if not 0 <= start < stop <= motion.n_frames:
        raise MotionError(f"cannot cut frames [{start}, {stop}) of a {motion.n_frames}-frame motion")
    return dataclasses.replace(motion, rotations=motion.rotations[start:stop], positions=motion.positions[start:stop])


_SWAPS = (("Left", "Right"), ("left", "right"), ("LEFT", "RIGHT"))


def _mirror_candidates(name: str) -> list[str]:
    out = []
    for a, b in _SWAPS:
        if a in name:
            out.append(name.replace(a, b))
        if b in name:
            out.append(name.replace(b, a))
    for a, b in (("_L", "_R"), ("_l", "_r"), (".L", ".R"), (".l", ".r")):
        if name.endswith(a):
            out.append(name[: -len(a)] + b)
        if name.endswith(b):
            out.append(name[: -len(b)] + a)
        if a + "_" in name:
            out.append(name.replace(a + "_", b + "_"))
        if b + "_" in name:
            out.append(name.replace(b + "_", a + "_"))
    m = re.match(r"^([A-Za-z]*:)?([lLrR])([a-z].*)$", name)  # CMU lhumerus / rhumerus
    if m:
        ns, s, rest = m.group(1) or "", m.group(2), m.group(3)
        out.append(ns + {"l": "r", "r": "l", "L": "R", "R": "L"}[s] + rest)
    return out


def mirror_joint_map(joint_names: Sequence[str], parents: Sequence[int] | np.ndarray) -> np.ndarray:
    """Left/right partner of every joint (itself for central joints), from the names.

    Recognises ``Left``/``Right`` anywhere in the name (Mixamo), ``_L``/``_R`` suffixes
    (Bandai Namco) and a leading ``l``/``r`` (CMU ``lhumerus``).  The map must be an
    involution compatible with the tree (the partner of a joint's parent is the parent of
    its partner), else :class:`~repro.errors.MotionError`.
    """
    names = list(joint_names)
    index = {n: i for i, n in enumerate(names)}
    par = np.asarray(parents, dtype=np.intp)
    pi = np.arange(len(names))
    for i, n in enumerate(names):
        for c in _mirror_candidates(n):
            if c != n and c in index:
                pi[i] = index[c]
                break
    if not np.array_equal(pi[pi], np.arange(len(names))):
        raise MotionError("left/right joint names do not pair up; cannot mirror this skeleton")
    for j in range(1, len(names)):
        if par[pi[j]] != pi[par[j]]:
            raise MotionError(f"mirror partner of {names[j]!r} has another parent; cannot mirror this skeleton")
    return pi


def mirror_motion(motion: Motion) -> Motion:
    """The motion reflected through the plane x = 0, with left and right swapped.

    Joint ``j`` of the result carries the data of its partner ``pi(j)``
    (:func:`mirror_joint_map`) reflected by ``M = diag(-1, 1, 1)``: offsets and positions
    ``M t``, rotations ``M R M`` (quaternion ``(x, -y, -z, w)``); End Sites likewise.
    Forward kinematics of the result is ``M p_{pi(j)}`` exactly.  For a left/right
    symmetric skeleton (the synthetic actor) the skeleton is unchanged; for a captured one
    (CMU) the mirrored skeleton has the other side's bone lengths.
    """
    pi = mirror_joint_map(motion.joint_names, motion.parents)
    M = np.array([-1.0, 1.0, 1.0])
    rot = motion.rotations[:, pi] * np.array([1.0, -1.0, -1.0, 1.0])
    pos = motion.positions[:, pi] * M
    off = motion.offsets[pi] * M
    esp = motion.end_site_parents
    eso = motion.end_site_offsets.copy()
    for e, p in enumerate(esp):
        mine = np.flatnonzero(esp == p)
        theirs = np.flatnonzero(esp == pi[p])
        k = int(np.flatnonzero(mine == e)[0])
        if theirs.size != mine.size:
            raise MotionError("End Sites are not symmetric; cannot mirror this skeleton")
        eso[e] = motion.end_site_offsets[theirs[k]] * M
    # position channels: a component is only meaningful where the mask says so; the mask
    # of joint j and of its partner must agree for the mirror to be expressible
    if not np.array_equal(motion.position_mask, motion.position_mask[pi]):
        raise MotionError("position channels differ between left and right joints; cannot mirror")
    return dataclasses.replace(motion, rotations=rot, positions=pos, offsets=off, end_site_offsets=eso,
                               source=(motion.source or "") + " (mirrored)")


def variant_motion(m: Motion, n_frames: int, scale: float, mirror: bool) -> Motion:
    """A variant of a motion: ``n_frames`` frames resampled uniformly, rescaled by ``scale`` (to metres), mirrored.

    The motion of a clip made by :func:`repro.motion.database.augment.augment`, rebuilt from its source clip.
    """
    if n_frames != m.n_frames:
        m = resample(m, frames=np.linspace(0.0, m.n_frames - 1, n_frames))
    if scale != 1.0:
        m = m.scaled(scale, unit_m=1.0)
    if mirror:
        m = mirror_motion(m)
    return m
