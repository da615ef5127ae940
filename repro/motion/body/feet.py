"""Foot contacts and foot metrics of a motion (Section 3.4: "correcting the feet artifacts").

:func:`foot_contacts` detects planted ankles with thresholds relative to the leg length;
:func:`foot_metrics` measures foot skating and floor contact over given contact frames;
:func:`foot_goals` gives the planted-foot goals the decoding of
:mod:`repro.motion.retargeting.morphology` pins the feet to.
"""

from __future__ import annotations

import numpy as np

from repro.checks import as_int, as_real, as_real_array, describe
from repro.errors import MotionError
from repro.motion.core.motion import Motion
from repro.motion.body.skeleton import Skeleton

__all__ = ["UP_AXIS", "foot_contacts", "foot_metrics", "foot_goals", "foot_scale", "max_foot_slide", "min_toe_height"]

#: Vertical axis of the world (BVH files are Y-up; the floor is the plane y = 0).
UP_AXIS: int = 1


def foot_contacts(
    motion: Motion,
    *,
    height_tol: float = 0.04,
    speed_tol: float = 0.5,
    up_axis: int = 1,
    roles=None,
    global_positions: np.ndarray | None = None,
    skeleton: Skeleton | None = None,
) -> np.ndarray:
    """(F, 2) bool: frames where the left / right ankle is planted.

    An ankle is planted when it is within ``height_tol * leg_length`` of its lowest
    height in the clip and its horizontal speed is below ``speed_tol * leg_length`` per
    second (defaults: about 3.5 cm and 0.4 m/s for a 0.85 m leg).  Thresholds are relative
    to the leg length, so the same call works in any unit.  ``global_positions`` (F, J, 3)
    and ``skeleton`` may be passed when the caller already has them.  Every argument is
    checked at entry (:class:`~repro.errors.MotionError` naming it).
    """
    up_axis = _check_motion_axis(motion, up_axis)
    height_tol = as_real(height_tol, "height_tol (fraction of the leg length)", lo=0.0, error=MotionError)
    speed_tol = as_real(speed_tol, "speed_tol (leg lengths per second)", lo=0.0, error=MotionError)
    if skeleton is not None and not isinstance(skeleton, Skeleton):
        raise MotionError(f"skeleton must be a Skeleton of the motion or None, got {describe(skeleton)}")
    if global_positions is not None:
        global_positions = as_real_array(global_positions, "global_positions", error=MotionError,
                                         shape=(motion.n_frames, len(motion.joint_names), 3))
    sk = Skeleton.from_motion(motion, roles=roles) if skeleton is None else skeleton
    ank = [sk.index("left_ankle"), sk.index("right_ankle")]
    g = (motion.global_positions() if global_positions is None else global_positions)[:, ank]
    h = g[..., up_axis]
    horiz = np.delete(g, up_axis, axis=-1)
    vel = np.zeros(h.shape)
    if motion.n_frames > 1:
        sp = np.linalg.norm(np.diff(horiz, axis=0), axis=-1) / motion.frame_time
        vel[1:-1] = 0.5 * (sp[1:] + sp[:-1])
        vel[0], vel[-1] = sp[0], sp[-1]
    L = sk.leg_length
    return (h <= h.min(axis=0) + height_tol * L) & (vel <= speed_tol * L)


def foot_metrics(motion: Motion, contacts: np.ndarray, *, up_axis: int = 1, roles=None) -> dict[str, float]:
    """Foot-skating and floor measures of a motion over given contact frames, in metres.

    Parameters
    ----------
    motion : Motion
        Needs ``unit_m``.
    contacts : (F, 2) bool
        Planted frames (left, right ankle), usually :func:`foot_contacts` of the *source*
        motion, so a retargeted motion is judged on the frames where the actor's foot was
        planted.

    Returns
    -------
    dict
        ``slide_speed``: mean horizontal ankle speed (m/s) over consecutive planted frame
        pairs; ``slide_per_contact``: mean over contact phases of the horizontal distance
        between the ankle's first and last position in the phase (m);
        ``planted_height_mean`` / ``planted_height_std``: ankle height above the floor
        plane ``y = 0`` on planted frames (m); ``min_ankle_height``: lowest ankle height
        in the clip (m; negative = below the floor); ``min_toe_height`` likewise for the
        foot effector (toe).  The two planted-height entries are NaN when no frame is
        planted (there is nothing to average).
    """
    up_axis = _check_motion_axis(motion, up_axis)
    c = np.asarray(contacts) if isinstance(contacts, (np.ndarray, list, tuple)) else None
    if c is None or c.dtype.kind != "b":
        raise MotionError(f"contacts must be an (F, 2) boolean array (foot_contacts), got {describe(contacts)}")
    if c.shape != (motion.n_frames, 2):
        raise MotionError(f"contacts must be ({motion.n_frames}, 2), got {c.shape}")
    contacts = c
    sk = Skeleton.from_motion(motion, roles=roles)
    u = sk.to_metres(1.0)
    gp = motion.global_positions() * u
    ank = gp[:, [sk.index("left_ankle"), sk.index("right_ankle")]]
    toe = gp[:, [sk.index("left_foot"), sk.index("right_foot")]]
    h = ank[..., up_axis]
    horiz = np.delete(ank, up_axis, axis=-1)
    both = contacts[1:] & contacts[:-1]
    step = np.linalg.norm(np.diff(horiz, axis=0), axis=-1)
    slide_speed = float(step[both].sum() / max(both.sum(), 1) / motion.frame_time)
    drifts = []
    for s in range(2):
        c = contacts[:, s].astype(int)
        edges = np.diff(np.concatenate([[0], c, [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for a, b in zip(starts, ends):
            if b - a >= 2:
                drifts.append(float(np.linalg.norm(horiz[b - 1, s] - horiz[a, s])))
    return {
        "slide_speed": slide_speed,
        "slide_per_contact": float(np.mean(drifts)) if drifts else 0.0,
        "planted_height_mean": float(h[contacts].mean()) if contacts.any() else float("nan"),
        "planted_height_std": float(h[contacts].std()) if contacts.any() else float("nan"),
        "min_ankle_height": float(h.min()),
        "min_toe_height": float(toe[..., up_axis].min()),
    }


def _check_motion_axis(motion, up_axis) -> int:
    """The checks :func:`foot_contacts` and :func:`foot_metrics` share: a Motion and an axis 0..2."""
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a Motion, got {describe(motion)}")
    return as_int(up_axis, "up_axis (0 = x, 1 = y, 2 = z)", 0, 2, error=MotionError)


def foot_scale(sk: Skeleton) -> float:
    """Mean foot length (ankle -> toe bone), or the leg length without toe joints."""
    ft = [sk.limb_lengths[f"{s}_foot"] for s in ("left", "right")]
    f = float(np.mean(ft))
    return f if min(ft) > 1e-9 * sk.height else sk.leg_length


def _nearest_true(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column of bool (F, K): index of the nearest True frame and the distance to it.

    Columns without any True get index 0 and distance F.
    """
    F = c.shape[0]
    t = np.arange(F)[:, None]
    prev = np.maximum.accumulate(np.where(c, t, -1), axis=0)
    nxt = np.minimum.accumulate(np.where(c, t, 2 * F + 1)[::-1], axis=0)[::-1]
    dprev = np.where(prev >= 0, t - prev, 10 * F)
    dnext = np.where(nxt <= F, nxt - t, 10 * F)
    idx = np.where(dprev <= dnext, prev, nxt)
    dist = np.minimum(dprev, dnext)
    none = ~c.any(axis=0)
    return np.where(none[None], 0, idx), np.where(none[None], F, dist)


def foot_goals(A: np.ndarray, contacts: np.ndarray, heights: np.ndarray, n_blend: int) -> tuple[np.ndarray, np.ndarray]:
    """Planted-foot goals: per contact phase the mean horizontal position of ``A``, at ``heights``.

    Returns the goals (F, 2, 3) and blend weights (F, 2): 1 on contact frames, falling
    linearly to 0 over ``n_blend`` frames on each side.
    """
    F = A.shape[0]
    goal = np.array(A, copy=True)
    w = np.zeros((F, 2))
    if F == 0:
        return goal, w
    idx, dist = _nearest_true(contacts)
    for s in range(2):
        c = contacts[:, s]
        if not c.any():
            continue
        start = c & ~np.concatenate([[False], c[:-1]])
        phase = np.cumsum(start) * c  # 1.. on contact frames, 0 elsewhere
        n = np.bincount(phase, minlength=phase.max() + 1).astype(float)
        anchor = np.empty((phase.max() + 1, 3))
        for k in range(3):
            vals = heights[:, s] if k == UP_AXIS else A[:, s, k]
            anchor[:, k] = np.bincount(phase, weights=vals, minlength=phase.max() + 1) / np.maximum(n, 1)
        goal[:, s] = anchor[phase[idx[:, s]]]
        w[:, s] = np.clip(1.0 - dist[:, s] / (n_blend + 1.0), 0.0, 1.0)
    return goal, w


def max_foot_slide(motion: Motion, contacts: np.ndarray, *, skeleton: Skeleton | None = None,
                   global_positions: np.ndarray | None = None, up_axis: int = UP_AXIS) -> float:
    """Largest horizontal drift of a planted ankle from its position at the start of its contact phase.

    In the motion's units.  ``contacts`` (F, 2): planted frames of the left / right ankle
    (usually those of the *source* motion, :func:`foot_contacts`).
    """
    sk = Skeleton.from_motion(motion) if skeleton is None else skeleton
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.shape != (motion.n_frames, 2):
        raise MotionError(f"contacts must be ({motion.n_frames}, 2), got {contacts.shape}")
    g = motion.global_positions() if global_positions is None else global_positions
    horiz = [a for a in range(3) if a != up_axis]
    ank = g[:, [sk.index("left_ankle"), sk.index("right_ankle")]][..., horiz]
    worst = 0.0
    for s in range(2):
        c = np.concatenate([[0], contacts[:, s].astype(int), [0]])
        d = np.diff(c)
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            worst = max(worst, float(np.linalg.norm(ank[a:b, s] - ank[a, s], axis=-1).max()))
    return worst


def min_toe_height(motion: Motion, contacts: np.ndarray | None = None, *, skeleton: Skeleton | None = None,
                   global_positions: np.ndarray | None = None, up_axis: int = UP_AXIS) -> float:
    """Lowest toe (foot-effector joint) height, over the planted frames of each side (all frames if None)."""
    sk = Skeleton.from_motion(motion) if skeleton is None else skeleton
    g = motion.global_positions() if global_positions is None else global_positions
    h = g[:, [sk.index("left_foot"), sk.index("right_foot")], up_axis]
    if contacts is None:
        return float(h.min())
    c = np.asarray(contacts, dtype=bool)
    if c.shape != h.shape:
        raise MotionError(f"contacts must be {h.shape}, got {c.shape}")
    return float(h[c].min()) if c.any() else float("nan")
