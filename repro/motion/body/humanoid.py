"""Humanoid or not: a skeleton's proportions, symmetry and stance checked before it is retargeted.

Pronost et al. retarget human motion onto human characters (Section 3.4.1, after Kulpa et
al. 2005: a normalised *humanoid* skeleton).  A skeleton that is not one (a quadruped named
like a 3ds Max Biped, a VR tracker set) can still receive body-part roles by name and only
fail later, on the unit or the up axis.  :func:`check_humanoid`, called by
:func:`repro.motion.body.roles.find_roles` once the roles are found, refuses it up front
with a :class:`~repro.errors.MotionError` saying which test failed, with its numbers:

* **limbs**: the tree is deep enough to hold a limb below the trunk, three bones (a tracker
  set, a dummy root with a head and two hands, is one bone deep);
* **symmetry**: the left and right arms (legs) are of equal length within
  :data:`SYMMETRY_TOLERANCE`;
* **proportions**: the arm-to-leg ratio (the *intermembral index* of physical
  anthropology) and the trunk-to-leg ratio lie within :data:`ARM_TO_LEG` and
  :data:`TRUNK_TO_LEG`, generous bands around the human values;
* **stance**, along the body's own up direction (the legs' ankles -> pelvis, never the
  file's axes): the head lies above the pelvis, the two legs reach the lowest point of the
  rest pose (within :data:`FLOOR_TOLERANCE` of the body's height) and the hands do not
  (each wrist at least :data:`MIN_HAND_HEIGHT` leg lengths above the ankles: only two
  limbs stand on the floor).

So the tests hold for Y-up and Z-up files and for T-, A- and N-pose rests.  Limb lengths
are path lengths along the tree (shoulder -> wrist, hip -> ankle): the bend of the rest
pose does not change them.  A rest pose that shows no stance -- the legs pointing apart, or
nearly every bone along one line (each bone along its own local axis, as Bandai Namco's,
or a lying skeleton) -- is judged on its lengths alone.  Real files' rest poses need not
be a pose at all (an ACCAD export's spine and arms all point forward), so the stance tests
ask no more than a standing body on two legs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from repro.errors import MotionError
from repro.motion.body.role_names import is_helper_name
from repro.motion.core.kinematics import rest_positions

__all__ = ["ARM_TO_LEG", "FLOOR_TOLERANCE", "MIN_HAND_HEIGHT", "SYMMETRY_TOLERANCE", "TRUNK_TO_LEG",
           "check_humanoid"]

#: Human segment lengths as fractions of stature H (Winter, *Biomechanics and Motor Control of
#: Human Movement*, 4th ed. 2009, Fig. 4.1, after Drillis & Contini 1966): upper arm 0.186 H,
#: forearm 0.146 H, thigh 0.245 H, shank 0.246 H; hip (greater trochanter) at 0.530 H, chin at
#: 0.870 H.  Arm / leg = 0.332 / 0.491 = 0.68: the intermembral index of humans, 68-72 (Napier &
#: Napier, *A Handbook of Living Primates*, 1967), 0.54-0.67 on the real rigs here.  The band
#: is wide: it takes stylised characters and the library's own scaled ones
#: (:func:`~repro.motion.body.skeleton.scale_skeleton` with arm and leg scales 0.75-1.25 and
#: forearm and shin scales 0.7-1.4 give 0.26-1.41), and refuses only what is far outside.
ARM_TO_LEG: tuple[float, float] = (0.2, 1.6)
#: Trunk (path length pelvis -> head joint) over leg (path length pelvis -> ankle, the hip
#: offset included): about (0.870 - 0.530) / (0.491 + 0.05) = 0.63 for the human figures
#: above, 0.52-0.95 on the real and generated rigs here; a quadruped's spine runs the length
#: of its body (an elephant's about twice its leg).
TRUNK_TO_LEG: tuple[float, float] = (0.25, 1.4)
#: Largest relative difference between the left and right arm (leg) lengths.  Human limbs
#: are mirror images to a few per cent (0-5 % on the real rigs here); the library's own
#: characters scale one bone of one side by up to 1.5 (about 25 % on the limb); a limb twice
#: the length of its mirror (a crab's claw) is 50 %.
SYMMETRY_TOLERANCE: float = 0.4
#: Lowest a wrist may stand above the ankles in the rest pose, along the legs' up, in leg
#: lengths: a person's hands hang at about 0.9 leg lengths (wrist at 0.485 H, ankle at
#: 0.039 H, leg 0.491 H in Winter's figures) in an N-pose and higher in A- and T-poses; a
#: quadruped's fore feet stand on the floor (0).
MIN_HAND_HEIGHT: float = 0.3
#: How far above the lowest point of the rest pose (along the legs' up, as a fraction of the
#: body's height along it) a leg's lowest joint may end and still reach the floor.
FLOOR_TOLERANCE: float = 0.1
#: Largest angle between the two legs (pelvis -> ankle) for the rest pose to show a stance.
_MAX_LEG_SPREAD_DEG: float = 90.0
#: Share of the bone length along one line beyond which the rest pose shows no stance.
_LINE_POSE_SHARE: float = 0.9

_ARMS = {s: (f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist") for s in ("left", "right")}
_LEGS = {s: (f"{s}_hip", f"{s}_knee", f"{s}_ankle") for s in ("left", "right")}


def _path_length(index: Mapping[str, int], par: np.ndarray, lengths: np.ndarray, top: str, bottom: str) -> float:
    """Sum of the bone lengths from joint ``top`` down to ``bottom`` (nan when not a descendant)."""
    a, d = index[top], index[bottom]
    total = 0.0
    while d != a:
        if d < 0:
            return float("nan")
        total += float(lengths[d])
        d = int(par[d])
    return total


def _limb_lengths(index, par, lengths, roles, limbs) -> dict[str, float]:
    """Length of each limb of ``limbs`` (side -> (proximal, middle, distal) roles) that ``roles``
    holds with two bones of some length (a zero-length one is the Skeleton's to name)."""
    out = {}
    for side, (a, b, c) in limbs.items():
        if all(r in roles for r in (a, b, c)):
            upper = _path_length(index, par, lengths, roles[a], roles[b])
            lower = _path_length(index, par, lengths, roles[b], roles[c])
            if upper > 0 and lower > 0:
                out[side] = upper + lower
    return out


def _depth(par: np.ndarray) -> int:
    """Bones on the longest chain from the root (parents precede children)."""
    d = np.zeros(len(par), dtype=int)
    for j in range(1, len(par)):
        d[j] = d[par[j]] + 1
    return int(d.max(initial=0))


def _not_humanoid(why: str, names: Sequence[str]) -> MotionError:
    return MotionError(f"not a humanoid skeleton: {why}; joints: {list(names)}. A humanoid has two arms and two "
                       "legs of human proportions, mirror images of each other, and stands on its two legs with "
                       "its head over its pelvis (repro.motion.body.humanoid)")


def check_humanoid(names: Sequence[str], par: np.ndarray, offsets: np.ndarray, roles: Mapping[str, str]) -> None:
    """Refuse a skeleton that is not a humanoid (see the module docstring for the tests).

    Parameters
    ----------
    names : sequence of str
        Joint names.
    par : (J,) int array
        Parent indices (``-1`` for the root).
    offsets : (J, 3) array
        Rest offsets, in any unit and any up axis.
    roles : mapping role -> joint name
        The roles found (:func:`repro.motion.body.roles.find_roles`); a test runs only when
        the roles it needs are there (a partial skeleton is named for what it lacks, not here).

    Raises
    ------
    repro.errors.MotionError
        "not a humanoid skeleton: ..." naming the test that failed and its numbers.
    """
    index = {n: i for i, n in enumerate(names)}
    lengths = np.linalg.norm(np.asarray(offsets, dtype=float), axis=1)
    arms = _limb_lengths(index, par, lengths, roles, _ARMS)
    legs = _limb_lengths(index, par, lengths, roles, _LEGS)
    depth = _depth(par)
    if depth < 3:
        raise _not_humanoid(
            f"its tree is {depth} bone(s) deep: no room for a limb below the trunk (hip -> knee -> ankle are three "
            f"bones); roles found: {sorted(roles)}", names)
    _check_symmetry(arms, legs, names)
    _check_proportions(index, par, lengths, roles, arms, legs, names)
    _check_stance(index, par, offsets, roles, float(np.mean(list(legs.values()))) if len(legs) == 2 else None, names)


def _check_symmetry(arms: dict[str, float], legs: dict[str, float], names) -> None:
    for kind, pair in (("arms", arms), ("legs", legs)):
        if len(pair) == 2:
            left, right = pair["left"], pair["right"]
            diff = abs(left - right) / max(left, right, 1e-300)
            if not diff <= SYMMETRY_TOLERANCE:
                raise _not_humanoid(
                    f"its {kind} are not mirror images: left {left:.4g}, right {right:.4g} units long, "
                    f"{100 * diff:.0f} % apart (at most {100 * SYMMETRY_TOLERANCE:.0f} %)", names)


def _check_proportions(index, par, lengths, roles, arms, legs, names) -> None:
    if not legs:
        return
    leg = float(np.mean(list(legs.values())))
    if arms:
        arm = float(np.mean(list(arms.values())))
        lo, hi = ARM_TO_LEG
        if not lo <= arm / leg <= hi:
            raise _not_humanoid(
                f"its arms are {arm / leg:.2f} times as long as its legs ({arm:.4g} and {leg:.4g} units, shoulder "
                f"to wrist and hip to ankle); a human's are about 0.7 times (accepted {lo:g}-{hi:g})", names)
    if "pelvis" in roles and "head" in roles:
        trunk = _path_length(index, par, lengths, roles["pelvis"], roles["head"])
        full_legs = [_path_length(index, par, lengths, roles["pelvis"], roles[f"{s}_ankle"]) for s in legs]
        full = float(np.nanmean(full_legs)) if not np.all(np.isnan(full_legs)) else float("nan")
        lo, hi = TRUNK_TO_LEG
        if np.isfinite(trunk) and np.isfinite(full) and full > 0 and not lo <= trunk / full <= hi:
            raise _not_humanoid(
                f"its trunk (pelvis to head, {trunk:.4g} units) is {trunk / full:.2f} times its legs (pelvis to "
                f"ankle, {full:.4g} units); a human's is about 0.6 times (accepted {lo:g}-{hi:g})", names)


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else None


def _check_stance(index, par, offsets, roles, leg: float | None, names) -> None:
    """The head above the pelvis, both legs reaching the lowest point, the hands off the floor,
    along the legs' up (ankles -> pelvis); skipped for a rest pose that shows no stance and
    without two legs of some length (``leg`` their mean, None without)."""
    need = ("pelvis", "head", "left_hip", "right_hip", "left_ankle", "right_ankle")
    off = np.asarray(offsets, dtype=float)
    if leg is None or not all(r in roles for r in need) or _line_pose(off):
        return
    P = rest_positions(par, off)
    pel, head = P[index[roles["pelvis"]]], P[index[roles["head"]]]
    ankles = [P[index[roles[f"{s}_ankle"]]] for s in ("left", "right")]
    legs = [_unit(pel - a) for a in ankles]
    if legs[0] is None or legs[1] is None or \
            np.degrees(np.arccos(np.clip(legs[0] @ legs[1], -1.0, 1.0))) > _MAX_LEG_SPREAD_DEG:
        return  # the legs point apart: the rest pose shows no stance (Bandai Namco's)
    up = _unit(legs[0] + legs[1])
    if up is None:
        return
    rise = float((head - pel) @ up) / leg
    if not rise > 0:
        raise _not_humanoid(
            f"its head is not above its pelvis: along the legs' up (ankles -> pelvis) it lies {-rise:.2f} leg lengths "
            "below it in the rest pose", names)
    h = P @ up
    body = np.array([not is_helper_name(n) for n in names])
    lowest, extent = float(h[body].min()), float(np.ptp(h[body]))
    for side in ("left", "right"):
        reach = float(h[_subtree(index[roles[f"{side}_hip"]], par)].min())
        if reach - lowest > FLOOR_TOLERANCE * extent:
            low = names[int(np.flatnonzero(body)[np.argmin(h[body])])]
            raise _not_humanoid(
                f"its {side} leg does not reach the lowest point of the rest pose: it ends {(reach - lowest) / extent:.2f} "
                f"of the body's height above {low!r} (at most {FLOOR_TOLERANCE:g})", names)
    foot = min(float(a @ up) for a in ankles)
    for side in ("left", "right"):
        if f"{side}_wrist" in roles:
            hand = (float(P[index[roles[f"{side}_wrist"]]] @ up) - foot) / leg
            if hand < MIN_HAND_HEIGHT:
                raise _not_humanoid(
                    f"its {side} arm stands on the floor like a leg: the wrist is {hand:.2f} leg lengths above the "
                    f"ankles in the rest pose (at least {MIN_HAND_HEIGHT:g}: a person's hands hang at about 0.9 leg "
                    "lengths, a quadruped stands on its fore legs)", names)


def _line_pose(off: np.ndarray) -> bool:
    """True when nearly all the bone length lies along one line (a rest pose with every bone
    along one axis, Bandai Namco's or a lying skeleton's): it shows no stance."""
    bones = off[1:]
    lengths = np.linalg.norm(bones, axis=1)
    if lengths.sum() <= 0:
        return True
    axis = np.linalg.svd(bones, full_matrices=False)[2][0]  # the main direction of the bones
    along = np.abs(bones @ axis)
    return float(along.sum() / lengths.sum()) > _LINE_POSE_SHARE


def _subtree(j: int, par: np.ndarray) -> np.ndarray:
    """Joint indices of ``j`` and its descendants (parents precede children)."""
    inside = np.zeros(len(par), dtype=bool)
    inside[j] = True
    for k in range(j + 1, len(par)):
        if par[k] >= 0 and inside[par[k]]:
            inside[k] = True
    return np.flatnonzero(inside)
