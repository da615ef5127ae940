"""Body-part roles read from the joint tree and the rest pose: legs, arms and head chains.

The retargeting of Pronost et al. (Section 3.4.1) follows Kulpa et al. (2005), which needs
the limbs of any skeleton, whatever its joints are called.  :func:`roles_from_structure`
finds them from the structure (the finder of :mod:`repro.motion.body.roles` calls it
first when it has the rest offsets):

* twist / roll / helper bones, fingers, face joints, props and ``_End`` leaves are set
  aside by name (:func:`repro.motion.body.role_names.is_helper_name`); the remaining leaves
  are the *tips*;
* the legs are the two branches of the first joint branching three ways (the pelvis hub)
  whose tips lie lowest besides the trunk (the branch of three or more tips spread the
  widest: two hands apart), the head the highest tip of the trunk and the
  arms its most lateral tips on either side (fingers of one hand are all on one side, so
  they are not taken for the two arms); a root branching only into the trunk and a joint
  carrying the two legs (MakeHuman's game rig: ``Root`` the spine base, ``Hips`` beside the
  spine) is the hub as well;
* runs of co-located joints (zero-length helpers) are collapsed to their first joint
  (Rigify ``upper_arm_helper.L`` does not take ``upper_arm.L``'s shoulder role, named or not);
  twist joints inside a bone, which the bone runs straight through, are not counted
  (Rigify-style ``upper_arm_twist.L``, named so, and MakeHuman's numbered segments
  ``upperarm02.L`` after ``upperarm01.L``: :func:`_without_twist_joints`), so the limb's
  roles land on the anatomical joints with the twist joints between them;
  in each limb chain the two longest consecutive bones are the upper arm and forearm
  (thigh and shin), so a joint before them is the clavicle and one after them the hand
  (toe); an arm's shoulder lies off the trunk's midline (CMU's
  clavicle joints lie on it); a wrist that branches into fingers has no ``hand`` joint (CMU's, branching into
  the hand and a one-joint thumb, has), an ankle that branches into toes has the middle
  one as its ``toe`` (:func:`_toe`);
* the names confirm: a limb name contradicting every reading of the chain makes the names
  decide, and the side comes from the names (``Left``/``L_``/``_l``/``l``/``.L``), else
  from the rest pose (the toes point forward, left = up x forward);
* the head is a joint named head on the head chain, else the tip (or, for a leaf without
  an End Site such as Mixamo ``HeadTop_End``, its parent); a skeleton without a head joint
  (CMU-style ``LowerNeck`` -> ``Neck`` ending the trunk) has its head role at the top of the
  neck, the neck chain's last joint, and its neck role at the joint before.

A rest pose that cannot be read this way (every bone along one line, as Bandai Namco's)
raises :class:`~repro.errors.MotionError`, and the finder lets the names decide.
:func:`trunk_from_tree` finds the trunk joints between the limbs (pelvis, chest, spine,
neck, clavicles) from the tree.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from repro.errors import MotionError
from repro.motion.body.role_names import (is_clavicle_name, is_head_name, is_helper_name, is_neck_name, name_side,
                                         side_and_base, stem_votes)
from repro.motion.core.kinematics import children_of, rest_positions

__all__ = ["AmbiguousLimbs", "roles_from_structure", "trunk_from_tree"]

_ARM_STEMS = ("shoulder", "elbow", "wrist")
_LEG_STEMS = ("hip", "knee", "ankle")


class AmbiguousLimbs(MotionError):
    """Two candidate limbs on one side: an error even when the names would decide otherwise."""


@dataclass(frozen=True)
class _Body:
    """The chains' ends found in the tree: rest positions ``P``, co-location tolerance, unit up
    direction, pelvis hub, head tip, arm and leg tips, and which joints lead to a tip."""

    P: np.ndarray
    tol: float
    up: np.ndarray
    hub: int
    head: int
    arms: list[int]
    legs: list[int]
    has_cand: np.ndarray


def _ancestors(j: int, parents: np.ndarray) -> list[int]:
    out = [j]
    while parents[j] >= 0:
        j = int(parents[j])
        out.append(j)
    return out


def _lca(a: int, b: int, parents: np.ndarray) -> int:
    anc = set(_ancestors(a, parents))
    for j in _ancestors(b, parents):
        if j in anc:
            return j
    return 0  # unreachable for a tree with one root


# ---------------------------------------------------------------- the chains' ends in the tree
def _rest_pose(par: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, float]:
    """Rest positions and their extent (MotionError when the rest pose has none)."""
    P = rest_positions(par, off)
    scale = float(np.ptp(P, axis=0).max()) if len(P) > 1 else 0.0
    if scale <= 0 or not np.isfinite(scale):
        raise MotionError("the rest pose has no extent; cannot find body parts from the structure")
    return P, scale


def _candidate_tree(names: list[str], par: np.ndarray) -> tuple[list[list[int]], np.ndarray, set[int]]:
    """Children of every joint, which joints lead to a candidate (unskipped) joint, and the tips."""
    J = len(names)
    skip = np.array([is_helper_name(n) for n in names])
    children = children_of(par)
    # a skipped joint's subtree is kept only when it holds unskipped joints (in-chain helpers)
    has_cand = ~skip.copy()
    for j in range(J - 1, 0, -1):
        if has_cand[j]:
            has_cand[par[j]] = True
    tips = {j for j in range(J) if not skip[j] and not any(has_cand[c] for c in children[j])}
    return children, has_cand, tips


def _tips_under(j: int, children: list[list[int]], has_cand: np.ndarray, tips: set[int]) -> list[int]:
    out, stack = [], [j]
    while stack:
        k = stack.pop()
        if k in tips:
            out.append(k)
        stack.extend(c for c in children[k] if has_cand[c])
    return out


def _first_branching(j: int, children: list[list[int]], has_cand: np.ndarray) -> tuple[int, list[int]]:
    """The first joint from ``j`` down with other than one tip-bearing branch, and its branches."""
    br = [c for c in children[j] if has_cand[c]]
    while len(br) == 1:
        j = br[0]
        br = [c for c in children[j] if has_cand[c]]
    return j, br


def _pelvis_hub(names: list[str], children: list[list[int]], has_cand: np.ndarray) -> tuple[int, list[int]]:
    """The first joint from the root with >= 3 tip-bearing branches, and those branches.

    A root branching in two, the trunk and a hips joint branching into the two legs (the
    MakeHuman game rig: ``Root`` the spine base, ``Hips`` its child carrying the legs), is
    the hub too: its branches are the trunk and the two legs."""
    hub, br = _first_branching(0, children, has_cand)
    if len(br) == 2:
        split = [_first_branching(b, children, has_cand)[1] for b in br]
        two = [k for k in (0, 1) if len(split[k]) == 2]
        if len(two) == 1:
            br = [br[1 - two[0]]] + split[two[0]]
    if len(br) < 3:
        raise MotionError(
            f"no joint of the tree branches into two legs and a trunk (first branching joint "
            f"{names[hub]!r} has {len(br)} branches); not a humanoid skeleton"
        )
    return hub, br


def _height(t: int, P: np.ndarray, hub: int, mean_upper: np.ndarray) -> float:
    """How far tip ``t`` lies from the hub towards the upper body's tips."""
    return float((P[t] - P[hub]) @ (mean_upper - P[hub]))


def _spread(P: np.ndarray, tips: list[int]) -> float:
    """Largest distance between two of ``tips``."""
    Q = P[tips]
    return float(np.linalg.norm(Q[:, None] - Q[None], axis=-1).max()) if len(tips) > 1 else 0.0


def _legs(names: list[str], P: np.ndarray, hub: int, groups: list) -> list[int]:
    """The lowest tip of each of the two lowest branches besides the trunk (``groups[0]``)."""
    mean_upper = P[groups[0][0]].mean(axis=0)
    leg_cands = [g for g in groups[1:] if len(g[0]) >= 1]
    leg_cands.sort(key=lambda g: min(_height(t, P, hub, mean_upper) for t in g[0]))
    if len(leg_cands) < 2:
        raise MotionError(f"found fewer than two legs under {names[hub]!r}; not a humanoid skeleton")
    return [min(g, key=lambda t: _height(t, P, hub, mean_upper)) for g, _ in leg_cands[:2]]


def _up(P: np.ndarray, upper_tips: list[int], legs: list[int], scale: float) -> np.ndarray:
    """Unit direction from the feet to the upper body's tips."""
    up = P[upper_tips].mean(axis=0) - P[legs].mean(axis=0)
    nu = np.linalg.norm(up)
    if nu <= 1e-3 * scale:
        raise MotionError("the rest pose does not tell up from down (legs and trunk end at the same height)")
    return up / nu


def _lateral(t: int, P: np.ndarray, chest_ref: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The offset of tip ``t`` from the trunk's axis, across ``up``."""
    v = P[t] - chest_ref
    return v - (v @ up) * up


def _head_and_arms(names: list[str], P: np.ndarray, hub: int, upper_tips: list[int],
                   up: np.ndarray) -> tuple[int, list[int]]:
    """The upper tip highest along up, and the most lateral tip on either side of the trunk."""
    head = max(upper_tips, key=lambda t: float(P[t] @ up))
    others = [t for t in upper_tips if t != head]
    chest_ref = P[hub] + up * float((P[head] - P[hub]) @ up) * 0.7
    others.sort(key=lambda t: float(np.linalg.norm(_lateral(t, P, chest_ref, up))), reverse=True)
    if len(others) < 2:
        raise MotionError("the upper body has fewer than two arms")
    # the second arm: the most lateral tip on the other side (fingers of one hand are all lateral)
    first = others[0]
    side = _lateral(first, P, chest_ref, up)
    opposite = [t for t in others[1:] if float(_lateral(t, P, chest_ref, up) @ side) < 0]
    if not opposite:
        raise MotionError(f"the upper body has no arm on the other side of {names[first]!r}")
    return head, [first, opposite[0]]


def _structure(names: list[str], par: np.ndarray, off: np.ndarray) -> _Body:
    """Legs, arms and head tips from the tree and the rest pose (see the module docstring)."""
    P, scale = _rest_pose(par, off)
    children, has_cand, tips = _candidate_tree(names, par)
    hub, br = _pelvis_hub(names, children, has_cand)
    # the trunk: the branch of three or more tips spread the widest (two hands apart; a foot's
    # toes, five tips on MakeHuman's, lie close together)
    groups = sorted(((_tips_under(c, children, has_cand, tips), c) for c in br),
                    key=lambda g: (len(g[0]) >= 3, _spread(P, g[0])), reverse=True)
    upper_tips = groups[0][0]
    if len(upper_tips) < 3:
        raise MotionError(
            f"the branches of {names[hub]!r} hold at most {len(upper_tips)} end joints each; "
            "expected a trunk ending in two arms and a head"
        )
    legs = _legs(names, P, hub, groups)
    up = _up(P, upper_tips, legs, scale)
    head, arms = _head_and_arms(names, P, hub, upper_tips, up)
    return _Body(P=P, tol=1e-6 * scale, up=up, hub=hub, head=head, arms=arms, legs=legs, has_cand=has_cand)


# ---------------------------------------------------------------- the limbs along the chains
def _points(chain: list[int], P: np.ndarray, tol: float) -> list[int]:
    """Collapse runs of co-located joints to their first one: the joints below it at zero length
    are helpers (Rigify ``upper_arm_helper.L`` under ``upper_arm.L``), carried along between the
    limb's joints like twist joints."""
    out: list[int] = []
    for j in chain:
        if not out or np.linalg.norm(P[j] - P[out[-1]]) > tol:
            out.append(j)
    return out


#: Largest angle (degrees) between the two segments meeting at a twist joint inside a limb bone:
#: the bone runs straight through it (MakeHuman's thigh bends 5 degrees at ``upperleg02``).
TWIST_COLLINEAR_DEG = 15.0


def _bone_segment(name: str, before: str) -> bool:
    """True when ``name`` reads as a later numbered segment of the bone ``before`` starts
    (MakeHuman ``upperarm02.L`` after ``upperarm01.L``: one bone in two twist segments)."""
    def parts(n):
        out = set()
        for _side, base in side_and_base(n):
            m = re.fullmatch(r"([a-z]+?)(\d+)", base)
            if m:
                out.add((m.group(1), int(m.group(2))))
        return out
    return any(s == s0 and k > k0 for s, k in parts(name) for s0, k0 in parts(before))


def _without_twist_joints(pts: list[int], names: list[str], P: np.ndarray) -> list[int]:
    """The chain's points without the twist joints inside its bones: a point the bone runs
    straight through (within :data:`TWIST_COLLINEAR_DEG`) that is named a twist / roll /
    helper bone (Rigify-style ``upper_arm_twist.L``) or a later numbered segment of the bone
    before it (MakeHuman ``upperarm02.L``, ``lowerleg02.L``).  The limb's joints are then the
    anatomical ones (shoulder, elbow, wrist; hip, knee, ankle) with the twist joints between
    them, carried along by the limb IK (:mod:`repro.motion.adaptation.limb`)."""
    out = list(pts[:1])
    for i in range(1, len(pts) - 1):
        q, nxt = pts[i], pts[i + 1]
        a, b = P[q] - P[out[-1]], P[nxt] - P[q]
        na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
        straight = na > 0 and nb > 0 and float(a @ b) >= na * nb * np.cos(np.radians(TWIST_COLLINEAR_DEG))
        if straight and (is_helper_name(names[q]) or _bone_segment(names[q], names[out[-1]])):
            continue
        out.append(q)
    return out + pts[-1:] if len(pts) > 1 else out


def _path_down(a: int, d: int, par: np.ndarray) -> list[int]:
    """Joints from ``a`` (excluded) down to ``d`` (included)."""
    out = []
    while d != a and d >= 0:
        out.append(d)
        d = int(par[d])
    return out[::-1]


def _limb_from_chain(pts: list[int], names: list[str], P: np.ndarray, kind: str, prox_ok=None) -> dict | None:
    """Proximal, middle, distal joints of an arm or leg chain of points (None: names disagree).

    ``prox_ok``: per point of the chain, whether it may be the proximal joint (an arm's
    shoulder is off the trunk's midline; CMU's clavicle joint is on it)."""
    if len(pts) < 3:
        raise MotionError(f"{kind} chain ending at {names[pts[-1]]!r} has fewer than three joints")
    stems = _ARM_STEMS if kind == "arm" else _LEG_STEMS
    seg = [float(np.linalg.norm(P[pts[i]] - P[pts[i - 1]])) for i in range(1, len(pts))]
    best, key = None, None
    for i in range(1, len(seg)):
        if prox_ok is not None and not prox_ok[i - 1] and any(prox_ok[: len(seg) - 1]):
            continue
        trio = (pts[i - 1], pts[i], pts[i + 1])
        votes = [stem_votes(names[j], st) for j, st in zip(trio, stems)]
        if votes[1][0] and stem_votes(names[trio[2]], stems[1])[0]:
            votes[2] = (0, 0)  # the middle bone's second, twist segment (MakeHuman lowerarm02): on the bone
        k = (sum(v for v, _ in votes) - sum(c for _, c in votes), seg[i - 1] + seg[i])
        if key is None or k > key:
            best, key = i, k
            bad = any(c for _, c in votes)
    if bad:
        return None  # the names contradict every reading of the structure: let the names decide
    return {"before": pts[: best - 1], "prox": pts[best - 1], "mid": pts[best], "dist": pts[best + 1],
            "after": pts[best + 2:]}


def _limbs(names: list[str], par: np.ndarray, body: _Body) -> tuple[dict, dict]:
    """Leg and arm chains (tip -> :func:`_limb_from_chain` reading), legs from the hub, arms from the chest."""
    P, tol, up, hub = body.P, body.tol, body.up, body.hub
    legs = {}
    for t in body.legs:
        pts = _without_twist_joints(_points(_path_down(hub, t, par), P, tol), names, P)
        legs[t] = _limb_from_chain(pts, names, P, "leg")
    arms = {}
    chest = _lca(body.arms[0], body.arms[1], par)
    for t in body.arms:
        pts = _without_twist_joints(_points(_path_down(chest, t, par), P, tol), names, P)
        v = P[pts] - P[hub]
        lat = np.linalg.norm(v - np.outer(v @ up, up), axis=1)
        arms[t] = _limb_from_chain(pts, names, P, "arm", prox_ok=lat >= 0.1 * lat[-1])
    return legs, arms


# ---------------------------------------------------------------- left and right
def _forward(legs: dict, P: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The facing direction across ``up``: where the toes point (zero without toes)."""
    fwd = np.zeros(3)
    for lg in legs.values():
        if lg is not None and lg["after"]:
            v = P[lg["after"][0]] - P[lg["dist"]]
            fwd += v - (v @ up) * up
    return fwd


def _sides_by_tip_names(names: list[str], group: dict, sides: dict[int, str]) -> None:
    """Sides from the names when a chain's names disagree with the structure (in place; a
    chain without a side in its names is dropped from ``group``)."""
    for t, g in list(group.items()):
        side = None if g is None else name_side(names[g["prox"]]) or name_side(names[t])
        if side is None:
            group[t] = None
        else:
            sides[t] = side


def _group_sides(names: list[str], group: dict, what: str, P: np.ndarray, up: np.ndarray, fwd: np.ndarray,
                 sides: dict[int, str]) -> None:
    """Left and right of the two chains of ``group`` (``what``: legs or arms), by name else by
    the rest pose (in place)."""
    (t1, g1), (t2, g2) = group.items()
    if g1 is None or g2 is None:
        _sides_by_tip_names(names, group, sides)
        return
    by_name = [name_side(names[g["prox"]]) or name_side(names[g["mid"]]) or name_side(names[t])
               for t, g in ((t1, g1), (t2, g2))]
    if by_name[0] and by_name[1] and by_name[0] != by_name[1]:
        sides[t1], sides[t2] = by_name
        return
    if by_name[0] and by_name[0] == by_name[1]:
        raise AmbiguousLimbs(
            f"two candidate {what} on the {by_name[0]} side: {names[g1['prox']]!r} and {names[g2['prox']]!r}"
        )
    nf = np.linalg.norm(fwd)
    if nf <= 1e-9 * np.linalg.norm(P[g1["prox"]] - P[g2["prox"]] + 1e-300):
        raise MotionError(
            f"cannot tell left from right for {names[g1['prox']]!r} / {names[g2['prox']]!r}: no side in "
            "the names and no toes to tell the facing direction"
        )
    left = np.cross(up, fwd / nf)
    s1 = float((P[g1["prox"]] - P[g2["prox"]]) @ left)
    sides[t1], sides[t2] = ("left", "right") if s1 > 0 else ("right", "left")


# ---------------------------------------------------------------- the role table
def _toe(lg: dict, par: np.ndarray, cand: np.ndarray, P: np.ndarray) -> int:
    """The toe joint after the ankle: the first joint on the way to the leg's lowest tip; of an
    ankle branching into several toes (MakeHuman ``metatarsal1.L`` .. ``metatarsal5.L``) the
    middle one, whose direction from the ankle is nearest the toes' mean direction (the foot's)."""
    kids = np.flatnonzero((par == lg["dist"]) & cand)
    if len(kids) < 2:
        return lg["after"][0]
    d = P[kids] - P[lg["dist"]]
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    return int(kids[int(np.argmax(d @ d.mean(axis=0)))])


def _leg_roles(names: list[str], par: np.ndarray, cand: np.ndarray, P: np.ndarray, legs: dict,
               sides: dict[int, str], roles: dict[str, str]) -> None:
    for t, lg in legs.items():
        if lg is None:
            continue
        s = sides[t]
        roles[f"{s}_hip"], roles[f"{s}_knee"], roles[f"{s}_ankle"] = (names[lg[k]] for k in ("prox", "mid", "dist"))
        if lg["after"]:
            roles[f"{s}_toe"] = names[_toe(lg, par, cand, P)]


def _arm_roles(names: list[str], par: np.ndarray, cand: np.ndarray, arms: dict, sides: dict[int, str],
               roles: dict[str, str]) -> None:
    n_cand_children = np.zeros(len(names), dtype=int)
    for j in range(1, len(names)):
        if cand[j]:
            n_cand_children[par[j]] += 1
    for t, am in arms.items():
        if am is None:
            continue
        s = sides[t]
        roles[f"{s}_shoulder"], roles[f"{s}_elbow"], roles[f"{s}_wrist"] = (names[am[k]] for k in ("prox", "mid", "dist"))
        # a hand joint after the wrist (CMU lhand, beside a one-joint thumb), not the first
        # finger of a wrist that branches into fingers
        if am["after"]:
            kids = [c for c in range(len(names)) if par[c] == am["dist"] and cand[c]]
            inner = [c for c in kids if n_cand_children[c] > 0]
            if len(kids) == 1 or (len(inner) == 1 and inner[0] == am["after"][0]):
                roles[f"{s}_hand"] = names[am["after"][0]]
        if am["before"]:
            # a joint named the clavicle before the arm (MakeHuman clavicle.L, then shoulder01.L and
            # the upper arm's first segment upperarm01.L), else the joint just before the shoulder
            named = [j for j in am["before"] if is_clavicle_name(names[j])]
            roles[f"{s}_clavicle"] = names[(named or am["before"])[-1]]


def _head_role(names: list[str], par: np.ndarray, hub: int, head: int, end_sites) -> str:
    """A joint named head on the head chain, else the tip (a head-top marker's parent); a tip
    named neck (no head joint: CMU-style ``LowerNeck``, ``Neck``) is the head, the top of the neck."""
    hchain = _path_down(hub, head, par)
    named = [j for j in hchain if is_head_name(names[j])]
    if not named and end_sites is not None and head not in end_sites and not np.any(par == head) \
            and len(hchain) >= 3 and not is_neck_name(names[head]):
        head = int(par[head])  # a head-top marker joint (no End Site, no child): the head is its parent
    return names[named[-1] if named else head]


def roles_from_structure(names: list[str], par: np.ndarray, off: np.ndarray, end_sites=None) -> dict[str, str]:
    """Role -> joint name of the legs, arms and head, from the tree and the rest pose.

    ``par`` (J,) parent indices, ``off`` (J, 3) finite rest offsets, ``end_sites`` the set
    of joints carrying an End Site (or None).  See the module docstring for the method.

    Raises
    ------
    AmbiguousLimbs
        Both legs (or arms) named on one side.
    repro.errors.MotionError
        When the structure cannot be read (no pelvis hub, no extent, no up, too short a
        chain, no side).
    """
    body = _structure(names, par, off)
    legs, arms = _limbs(names, par, body)
    fwd = _forward(legs, body.P, body.up)
    sides: dict[int, str] = {}
    _group_sides(names, legs, "legs", body.P, body.up, fwd, sides)
    _group_sides(names, arms, "arms", body.P, body.up, fwd, sides)
    roles: dict[str, str] = {}
    _leg_roles(names, par, body.has_cand, body.P, legs, sides, roles)
    _arm_roles(names, par, body.has_cand, arms, sides, roles)
    roles["head"] = _head_role(names, par, body.hub, body.head, end_sites)
    return roles


def trunk_from_tree(names: list[str], index: dict[str, int], par: np.ndarray, roles: dict[str, str]) -> None:
    """Pelvis, chest, spine, neck and clavicles from the tree (in place).

    Pelvis = lowest common ancestor of the two hips (or of them and the chest, when the hips
    hang off a joint beside the trunk), chest = that of the two shoulders,
    spine = first joint after the pelvis on the way to the chest, neck = first joint after
    the chest on the way to the head, clavicle = a shoulder's parent other than the chest.
    """
    lh, rh = roles.get("left_hip"), roles.get("right_hip")
    ls, rs = roles.get("left_shoulder"), roles.get("right_shoulder")
    if "pelvis" not in roles and lh and rh:
        p = _lca(index[lh], index[rh], par)
        if ls and rs and "chest" not in roles:
            c = _lca(index[ls], index[rs], par)
            if p not in _ancestors(c, par):  # the legs' joint beside the trunk (MakeHuman game rig Hips)
                p = _lca(p, c, par)
        roles["pelvis"] = names[p]
    if "chest" not in roles and ls and rs:
        c = _lca(index[ls], index[rs], par)
        if "pelvis" not in roles or names[c] != roles["pelvis"]:
            roles["chest"] = names[c]
    if "pelvis" in roles and "chest" in roles and "spine" not in roles:
        path = _ancestors(index[roles["chest"]], par)
        p = index[roles["pelvis"]]
        if p in path:
            below = path[: path.index(p)]  # chest ... first joint after pelvis
            if below:
                roles["spine"] = names[below[-1]]
    if "chest" in roles and "head" in roles and "neck" not in roles:
        path = _ancestors(index[roles["head"]], par)
        c = index[roles["chest"]]
        if c in path:
            between = path[1: path.index(c)]  # joints strictly between head and chest
            if between:
                roles["neck"] = names[between[-1]]
    for side in ("left", "right"):
        cl, sh = f"{side}_clavicle", roles.get(f"{side}_shoulder")
        if cl not in roles and sh and "chest" in roles:
            p = par[index[sh]]
            if p >= 0 and names[p] != roles["chest"]:
                roles[cl] = names[p]
