"""Stature: measured one way on every rig, and the length unit it tells.

The paper's size (Pronost et al., Section 3.3, Eq. 1: ``c_r = c * size_a / size_c``) is the
stature: "a constraint placed at 1-meter in front of the virtual fighter does not have the
same influence if the latter is 2m or 1.5m tall".  Eq. 1 divides the statures of two
different rigs (a CMU actor and a Bandai Namco character, say), so both must be measured the
same way, whatever the rig's rest posture (T, A, N, arms down, or every bone along +X as in
Bandai Namco's files), its helper joints (twist bones halfway along a limb, Second Life's
folded spine bones that go up and come back) and what it marks (a head End Site or a head-top
joint, or nothing above the head joint).  :func:`measure_stature` measures, from the floor to
the top of the head of the body standing straight:

1. sole -> ankle: the lowest point of the foot (the ankle's descendant joints and End Sites)
   below the ankle along the rest shin (knee -> ankle), when the rest foot leaves the shin at
   45 degrees or more (a standing rest pose); else, when the foot continues the shin (a rig
   lying along an axis), estimated as :data:`ANKLE_PER_LEG` times the leg;
2. ankle -> knee -> hip: the rest-pose distances between these joints (so twist joints in the
   chain count once), mean of the two legs;
3. hips -> head joint: the rest-pose distance from the midpoint of the hip joints to the head
   joint (the trunk as the rig holds it; folded helper bones cancel; whatever joint the
   pelvis role is does not matter);
4. head joint -> top of the head: the rise, along the hips -> head direction, of the head's
   End Site, else of the highest of the head's descendant joints and End Sites (Mixamo's
   ``HeadTop_End``, Second Life's ``mSkull``), counting only points within 35 degrees of that
   direction (not the eyes or the jaw, in front of the head joint); when there is none, or it
   rises less than half the estimate (a zero-length or stub End Site), estimated from the
   height of the head joint: the head joint stands at :data:`HEAD_JOINT_FRACTION` of the
   stature.

The anthropometric fractions are those of Winter, *Biomechanics and Motor Control of Human
Movement* (4th ed., 2009), Fig. 4.1 (after Drillis & Contini, 1966): heights above the floor
as fractions of the stature ``H``, ankle 0.039 H, hip (greater trochanter) 0.530 H, chin
0.870 H, eye 0.936 H, top of the head 1.000 H.  :class:`Stature` records each part and how
it was found (:attr:`Stature.method`).

Units: a BVH file does not say its unit.  :func:`infer_unit` picks, among :data:`UNITS`, the
unit whose stature in metres lies in :data:`STATURE_RANGE_M` and is closest on a log scale to
:data:`TYPICAL_STATURE_M`; when another candidate is nearly as close (within
:data:`AMBIGUOUS_LOG_RATIO`) the one listed first in :data:`UNITS` (the more conventional)
is chosen and the name says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.checks import as_real
from repro.errors import MotionError
from repro.motion.core.motion import CMU_UNIT_M

__all__ = [
    "ANKLE_PER_LEG",
    "AMBIGUOUS_LOG_RATIO",
    "HEAD_JOINT_FRACTION",
    "STATURE_RANGE_M",
    "TYPICAL_STATURE_M",
    "UNITS",
    "Stature",
    "infer_unit",
    "measure_stature",
]

#: Ankle height over leg length (hip -> ankle) of Winter (2009), Fig. 4.1: 0.039 H / (0.530 H - 0.039 H).
ANKLE_PER_LEG: float = 0.039 / (0.530 - 0.039)
#: Height of a rig's head joint as a fraction of the stature, for a rig without a head top.
#: Between the chin (0.870 H) and the eyes (0.936 H) of Winter (2009), Fig. 4.1; the rigs that
#: mark their head top put the head joint at 0.90 H (Mixamo, the synthetic actor) to 0.95 H (CMU,
#: DAZ, Unity), Bandai Namco's own bow take (the one with a head End Site) at 0.932 H.
HEAD_JOINT_FRACTION: float = 0.93
#: Below this share of the estimated head top, a head End Site is a stub: the estimate is used.
_MIN_TOP_SHARE: float = 0.5
#: A head point counts for the head top when it is within this angle of the hips -> head direction (degrees).
_TOP_ANGLE_DEG: float = 35.0
#: A foot point counts for the sole when it leaves the shin at this angle or more (degrees).
_FOOT_ANGLE_DEG: float = 45.0

#: Candidate units: (name, metres per unit), the conventional ones first (the order breaks
#: ambiguous choices).  Centimetres are also Mixamo's and Unreal's 100 units per metre;
#: decimetres are MakeHuman's; the CMU unit is 1/0.45 inch (the ASF files' length scale).
UNITS: tuple[tuple[str, float], ...] = (
    ("metres", 1.0),
    ("centimetres", 0.01),
    ("millimetres", 0.001),
    ("inches", 0.0254),
    ("CMU units (1/0.45 inch)", CMU_UNIT_M),
    ("feet", 0.3048),
    ("decimetres", 0.1),
)
#: Statures a human skeleton may have, metres.
STATURE_RANGE_M: tuple[float, float] = (0.5, 2.5)
#: The stature the choice between units favours, metres.
TYPICAL_STATURE_M: float = 1.7
#: Two units whose statures are this close to :data:`TYPICAL_STATURE_M` (difference of their
#: ``|log(stature / typical)|``) are ambiguous: the one listed first in :data:`UNITS` is chosen.
AMBIGUOUS_LOG_RATIO: float = float(np.log(1.2))


@dataclass(frozen=True)
class Stature:
    """A stature and its parts, in the skeleton's file units (see the module docstring).

    Attributes
    ----------
    height : float
        ``sole_to_ankle + leg + hips_to_head + head_top``.
    sole_to_ankle, leg, hips_to_head, head_top : float
        The parts, floor to top.
    foot, top : str
        Where the sole and the head top came from: ``"the foot's lowest point"`` or
        ``"estimated"``; ``"End Site"``, ``"joint <name>"`` or ``"estimated"``.
    """

    height: float
    sole_to_ankle: float
    leg: float
    hips_to_head: float
    head_top: float
    foot: str
    top: str

    @property
    def method(self) -> str:
        """How the stature was measured, one line (for warnings and reports)."""
        foot = ("sole from the foot's lowest point" if self.foot != "estimated"
                else f"ankle height estimated ({ANKLE_PER_LEG:.3f} x leg, Winter 2009)")
        top = (f"head top from the {self.top}" if self.top != "estimated"
               else f"head top estimated (head joint at {HEAD_JOINT_FRACTION:g} of the stature)")
        return f"floor to head top of the body standing straight: {foot}; legs hip-knee-ankle; hips to head; {top}"


def _descendants(parents: np.ndarray, j: int) -> np.ndarray:
    """Joint ``j`` and every joint below it (parents precede children)."""
    below = np.zeros(len(parents), dtype=bool)
    below[j] = True
    for k in range(j + 1, len(parents)):
        below[k] = below[parents[k]]
    return below


def _points_below(skeleton, p: np.ndarray, j: int) -> tuple[list[str], np.ndarray]:
    """Names and rest positions (``p``: the joints') of the End Sites of joint ``j``, then of the
    joints and End Sites under it (``j`` excluded); End Sites are named ``"End Site"``."""
    below = _descendants(skeleton.parents, j)
    es = np.asarray(skeleton.end_site_parents, dtype=int)
    own = es == j
    deeper = below[es] & ~own if es.size else np.zeros(0, bool)
    names = ["End Site"] * int(own.sum()) + [skeleton.joint_names[k] for k in np.flatnonzero(below)[1:]]
    names += ["End Site"] * int(deeper.sum())
    pts = np.concatenate([p[es[own]] + skeleton.end_site_offsets[own], p[below][1:],
                          p[es[deeper]] + skeleton.end_site_offsets[deeper]])
    return names, pts.reshape(-1, 3)


def _sole_to_ankle(skeleton, p: np.ndarray, side: str) -> float | None:
    """Height of the ankle above the foot's lowest point along the rest shin, or None."""
    ank = skeleton.index(f"{side}_ankle")
    shin = p[ank] - p[skeleton.index(f"{side}_knee")]
    n = np.linalg.norm(shin)
    _, pts = _points_below(skeleton, p, ank)
    if n <= 0 or not len(pts):
        return None
    v = pts - p[ank]
    d = np.linalg.norm(v, axis=1)
    down = v @ (shin / n)
    ok = (d > 0) & (down < np.cos(np.radians(_FOOT_ANGLE_DEG)) * d)
    return max(0.0, float(down[ok].max())) if ok.any() else None


def measure_stature(skeleton) -> Stature:
    """The :class:`Stature` of a :class:`~repro.motion.body.skeleton.Skeleton` (file units).

    One measure for every rig (module docstring): floor to the top of the head of the body
    standing straight, from the rest offsets and the roles ``left_/right_hip, _knee, _ankle``
    and ``head``.  A uniform scaling of the skeleton scales it by the same factor.
    """
    p = skeleton.rest_positions()
    hips = [skeleton.index(f"{s}_hip") for s in ("left", "right")]
    head = skeleton.index("head")
    legs, soles = [], []
    for s in ("left", "right"):
        h, k, a = (skeleton.index(f"{s}_{r}") for r in ("hip", "knee", "ankle"))
        legs.append(np.linalg.norm(p[k] - p[h]) + np.linalg.norm(p[a] - p[k]))
        soles.append(_sole_to_ankle(skeleton, p, s))
    leg = float(np.mean(legs))
    measured = [x for x in soles if x is not None]
    sole = float(np.mean(measured)) if measured else ANKLE_PER_LEG * leg
    trunk = p[head] - p[hips].mean(axis=0)
    hips_to_head = float(np.linalg.norm(trunk))
    below_head = sole + leg + hips_to_head
    estimate = below_head * (1.0 / HEAD_JOINT_FRACTION - 1.0)
    top, where = estimate, "estimated"
    names, pts = _points_below(skeleton, p, head)
    if hips_to_head > 0 and len(pts):
        v = pts - p[head]
        rise = v @ (trunk / hips_to_head)
        # the top is above the head joint, not the eyes or the jaw in front of it
        ok = (rise >= np.cos(np.radians(_TOP_ANGLE_DEG)) * np.linalg.norm(v, axis=1)) & (
            rise >= _MIN_TOP_SHARE * estimate)
        n_own = int(np.sum(np.asarray(skeleton.end_site_parents) == head))
        if ok[:n_own].any():  # the head's own End Site first, else the highest head-top joint
            ok[n_own:] = False
        if ok.any():
            i = int(np.argmax(np.where(ok, rise, -np.inf)))
            top, where = float(rise[i]), names[i] if names[i] == "End Site" else f"joint {names[i]}"
    return Stature(height=below_head + top, sole_to_ankle=sole, leg=leg, hips_to_head=hips_to_head, head_top=top,
                   foot="the foot's lowest point" if measured else "estimated", top=where)


def infer_unit(stature: float) -> tuple[float, str]:
    """``(unit_m, unit name)`` of a skeleton whose stature is ``stature`` file units.

    The unit of :data:`UNITS` whose stature in metres lies in :data:`STATURE_RANGE_M` and is
    closest on a log scale to :data:`TYPICAL_STATURE_M`.  When another candidate is within
    :data:`AMBIGUOUS_LOG_RATIO` of it, the one listed first in :data:`UNITS` is chosen and the
    name says so (e.g. 21.3 units: CMU units give 1.20 m, decimetres 2.13 m; CMU units are
    chosen).

    Raises
    ------
    repro.errors.MotionError
        If the stature is not finite and positive, or no unit of :data:`UNITS` makes it
        a human stature (:data:`STATURE_RANGE_M`).
    """
    h = as_real(stature, "stature (file units, finite and > 0 to infer the unit)", error=MotionError, lo=0.0,
                lo_open=True)
    lo, hi = STATURE_RANGE_M
    fits = [(abs(np.log(h * u / TYPICAL_STATURE_M)), rank, u, n) for rank, (n, u) in enumerate(UNITS)
            if lo <= h * u <= hi]
    if not fits:
        raise MotionError(
            f"cannot infer the length unit: a stature of {h:.4g} file units is no human stature "
            f"({lo}-{hi} m) in any of {[n for n, _ in UNITS]}; pass unit_m= explicitly"
        )
    best = min(fits)
    close = sorted((f for f in fits if f[0] - best[0] <= AMBIGUOUS_LOG_RATIO), key=lambda f: f[1])
    _, _, u, name = close[0]
    if len(close) > 1:
        others = ", ".join(f"{n} {h * v:.2f} m" for _, _, v, n in close[1:])
        name = f"{name} (ambiguous: {h * u:.2f} m, or {others}; the more conventional unit chosen)"
    return u, name

