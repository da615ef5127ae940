"""The other feet during the Section 3.4.2 edit: pinned where planted, lifted above the floor, measured.

:func:`solve_feet` keeps each foot that does not strike planted over its contact phases
(``"pin"``: those overlapping the edit; ``"plant"``: every phase after ``t0``, the
kicking foot up to its lift-off) or on its original trajectory (``"track"``), by the limb
step on the leg with the foot's world orientation kept; :func:`lift_to_floor` raises an
ankle goal so that the whole foot (the ankle, the joints below it, their End Sites) stays
above the floor (:func:`floor_heights`: a foot already through it at ``t0``, the current pose,
is raised over ``foot_blend``, not in one frame), on every frame after ``t0`` where the foot
is not striking; :func:`floor_offset` does the same for the kicking foot's hit goals (a
target below the clip's kick lowers ``d(t)`` while the foot is still low);
:func:`liftoff_offset` eases the kicking foot's pin into ``d(t)``; :func:`foot_slides`
measures how far the pinned ankles slide.
"""

from __future__ import annotations

import numpy as np

from repro.errors import MotionError
from repro.motion.adaptation.limb import solve_limb
from repro.motion.adaptation.offset import offset_curve
from repro.motion.adaptation.rig import Chain, Rig

__all__ = [
    "SIDE_INDEX",
    "contact_phases",
    "start_frame",
    "liftoff_offset",
    "feet_independent",
    "solve_feet",
    "floor_heights",
    "lift_to_floor",
    "floor_offset",
    "foot_slides",
]

#: the column of a side in the (F, 2) contacts and pins
SIDE_INDEX = {"left": 0, "right": 1}


def contact_phases(c: np.ndarray) -> list[tuple[int, int]]:
    """The planted runs of one foot's (F,) contacts, as ``(first, past-the-last)`` frames."""
    m = np.concatenate([[0], c.astype(int), [0]])
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def start_frame(contacts: np.ndarray, ch: Chain, t0: int, tc: int) -> int:
    """``t0``, or for a foot effector planted in ``[t0, tc)`` its last planted frame (lift-off)."""
    if ch.kind == "leg":
        planted = np.flatnonzero(contacts[t0:tc, SIDE_INDEX[ch.side]]) + t0
        if planted.size:
            return int(planted.max())
    return t0


def floor_heights(rig, side: str, gp: np.ndarray, t0: int, floor: float, n_blend: int) -> np.ndarray:
    """(F,) the height the ``side`` foot keeps above on each frame: ``floor``, eased in after ``t0``.

    Frame ``t0`` (the current pose) never changes: when its foot already reaches ``sink``
    below the floor, the floor starts there and rises linearly to ``floor`` over the
    ``n_blend`` frames after ``t0`` (as a pin is released), so the foot is not popped up in
    one frame.  ``gp`` are the input's joint positions.
    """
    F = gp.shape[0]
    h = np.full(F, float(floor))
    ank = rig.sk.index(f"{side}_ankle")
    sink = float(floor - (gp[t0, ank, 1] + rig.foot_drop(side)[t0]))
    if sink > 0.0:
        k = np.arange(0, min(n_blend, F - 1 - t0) + 1)
        h[t0 + k] -= sink * (1.0 - k / (n_blend + 1.0))
    return h


def liftoff_offset(rig, ch, contacts, gp, t0: int, t_start: int, tc: int, floor, kind: str) -> np.ndarray:
    """(F, 3) the kicking foot's pin at its lift-off, eased out by ``tc``: no jump when the pin lets go.

    The planted kicking foot is pinned up to its lift-off ``t_start`` where it was at the
    start of the phase (:func:`solve_feet`); the input's foot has moved meanwhile (the
    blend with the current pose), so the hit goal starts from the pinned place and eases
    (``kind``) to the input's by ``tc``, where ``d(tc)`` takes over.  0 for an arm, an
    unpinned foot or ``t_start == t0``.  ``floor``: None or the kicking foot's (F,)
    :func:`floor_heights`.
    """
    F = gp.shape[0]
    out = np.zeros((F, 3))
    if ch.kind != "leg" or t_start <= t0:
        return out
    s = SIDE_INDEX[ch.side]
    phase = [(a, b) for a, b in contact_phases(contacts[:, s]) if b == t_start + 1 and b > t0 + 1]
    if not phase:
        return out
    ank = ch.dist
    goal = np.repeat(gp[max(phase[0][0], t0), ank][None], F, axis=0)
    if floor is not None:  # the pin's own floor lift (as solve_feet lifts it)
        on = np.zeros(F, dtype=bool)
        on[t_start] = True
        lift_to_floor(rig, ch.side, goal, on, floor)
    delta = goal[t_start] - gp[t_start, ank]  # the foot keeps its world orientation: the hit point moves with the ankle
    w = offset_curve(t_start, tc, np.ones(3), F, kind=kind, release=None)[:, 0]
    r = np.zeros(F)
    r[t_start + 1: tc + 1] = 1.0 - w[t_start + 1: tc + 1]
    return r[:, None] * delta[None, :]


def feet_independent(rig: Rig, ch: Chain, spec) -> bool:
    """Whether the foot pass cannot depend on the hit solve (nor the hit solve on it).

    True for an arm effector when no joint the hit solve may turn (the CCD chain, the
    limb's three joints) lies on either leg's path root .. ankle: the passes then read and
    write disjoint joints (both only read the root).
    """
    if ch.kind != "arm":
        return False
    turned = {int(ch.path[k]) for k, _, _ in spec} | {ch.prox, ch.mid, ch.dist}
    for side in ("left", "right"):
        try:
            leg = rig.chain(f"{side}_ankle")
        except MotionError:
            return False
        if turned & {int(j) for j in leg.path[: leg.k_dist + 1]}:
            return False
    return True


def solve_feet(rig, ch, motion, rot, feet, foot_blend, t0, stop, pinned, anchors, *, contacts, ref_gp,
                shifted, floor, t_start, only=None, foot_offsets=None) -> tuple[float, int]:
    """Keep the other feet planted (``"pin"``, ``"plant"``) or on their trajectories (in place).

    Goals come from ``ref_gp`` (the input's joint positions, before a root shift); with a
    ``floor`` (a height) they are raised so that the whole foot stays above it
    (:func:`floor_heights`) on every frame after ``t0`` but the strike's.
    ``only`` (F,) bool: solve on those frames alone (a probe of
    :func:`~repro.motion.adaptation.adapt`'s bound).
    Returns the largest ankle error and the number of solved frames.
    """
    gq = rig.globals[0]
    gp = ref_gp
    F = motion.n_frames
    foot_err = 0.0
    n_feet = 0
    n_blend = int(round(foot_blend / motion.frame_time))
    for side in ("left", "right"):
        striking = ch.kind == "leg" and side == ch.side
        if striking and feet != "plant":
            continue
        s = SIDE_INDEX[side]
        leg = rig.chain(f"{side}_ankle")
        ank = leg.dist
        anc = [int(j) for j in leg.path[: leg.k_prox]]  # root .. hip's parent
        orig = gp[:, ank]
        goal = orig.copy()
        w = np.zeros(F)
        need = np.zeros(F, dtype=bool)
        if feet in ("pin", "plant"):
            for a, b in contact_phases(contacts[:, s]):
                if b <= t0 + 1 or (a >= stop and feet == "pin") or (striking and b - 1 > t_start and a < stop):
                    continue  # the striking foot: up to its lift-off and after the edit (it lands)
                a = max(a, t0)
                anchors.append((s, a, b))
                goal[a:b] = orig[a]
                pinned[a:b, s] = True
                w[a:b] = 1.0
                delta = orig[a] - orig[b - 1]
                for k in range(1, n_blend + 1):
                    f = b - 1 + k
                    if f >= F or pinned[f, s] or (striking and t_start < f < stop):
                        break
                    wk = 1.0 - k / (n_blend + 1.0)
                    goal[f] = orig[f] + wk * delta
                    w[f] = max(w[f], wk)
            if foot_offsets is not None:  # a step: the goals move with the stepping foot
                goal += foot_offsets[:, s]
                w = np.maximum(w, np.any(foot_offsets[:, s] != 0.0, axis=1))
            need |= w > 0
        if floor is not None:  # the whole foot above the floor after t0, but over the strike itself
            on = np.ones(F, dtype=bool)
            on[: t0 + 1] = False
            if striking:
                on[t_start + 1:stop] = False
            need |= lift_to_floor(rig, side, goal, on, floor_heights(rig, side, gp, t0, floor, n_blend))
        if striking:  # never over the strike itself
            need[t_start + 1:stop] = False
        else:
            need |= shifted
            need |= np.any(rot[:, anc] != np.asarray(motion.rotations)[:, anc], axis=(1, 2))
        need[: t0 + 1] = False
        if only is not None:
            need &= only
        fr = np.flatnonzero(need)
        if fr.size:
            n_feet += fr.size
            rf = rot[fr]
            hit, res = solve_limb(leg, rf, rig.trans[fr], goal[fr], distal_world=gq[fr, ank])
            rot[fr] = rf
            foot_err = max(foot_err, float(res.max(initial=0.0)))
    return foot_err, n_feet


def lift_to_floor(rig, side: str, goal: np.ndarray, on: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Raise the ankle goals on ``on`` frames so that no point of the foot is below ``floor`` (F,) (in place).

    The foot keeps its world orientation at its goal (the limb step and the pins keep it),
    so its lowest point is ``goal[1] + rig.foot_drop(side)``.  Returns the (F,) frames raised.
    """
    lift = np.where(on, np.maximum(0.0, floor - (goal[:, 1] + rig.foot_drop(side))), 0.0)
    goal[:, 1] += lift
    return lift > 0.0


def floor_offset(rig, ch, gp: np.ndarray, p: np.ndarray, goals: np.ndarray, on: np.ndarray,
                 floor: np.ndarray) -> np.ndarray:
    """(F, 3) the raise of a kicking foot's hit goals that keeps the whole foot at or above ``floor`` (F,).

    ``d(t)`` reaches ``X - p(tc)`` from the lift-off on: a target lower than the clip's kick
    lowers the foot while it is still near the ground, through the floor.  The foot keeps
    its world orientation (the limb step, and CCD's last limb step, keep it), so at the hit
    goal its lowest point is ``goals[1] + foot_drop - (p[1] - ankle[1])`` (``gp`` the input's
    joint positions, ``p`` its hit trajectory).  0 off ``on`` and for an arm.
    """
    out = np.zeros_like(goals)
    if ch.kind != "leg":
        return out
    low = goals[:, 1] + rig.foot_drop(ch.side) - (p[:, 1] - gp[:, ch.dist, 1])
    out[:, 1] = np.where(on, np.maximum(0.0, floor - low), 0.0)
    return out


def foot_slides(rig: Rig, anchors, gp2: np.ndarray, gp: np.ndarray) -> tuple[dict, dict]:
    """Largest horizontal ankle distance from its anchor over the pinned frames: adapted, original."""
    slide = {"left": 0.0, "right": 0.0}
    slide_o = {"left": 0.0, "right": 0.0}
    horiz = [0, 2]
    for s, a, b in anchors:
        side = ("left", "right")[s]
        ank = rig.sk.index(f"{side}_ankle")
        for g, dct in ((gp2, slide), (gp, slide_o)):
            dd = np.linalg.norm(g[a:b, ank][:, horiz] - g[a, ank][horiz], axis=-1).max()
            dct[side] = max(dct[side], float(dd))
    return slide, slide_o
