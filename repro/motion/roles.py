"""Body-part roles of any skeleton: which joints are the shoulders, elbows, wrists, hips ...

Pronost et al. (Section 3.4.1) retarget with the representation of Kulpa et al. (2005),
which needs the limbs of any skeleton; :func:`find_roles` finds them by name patterns
and tree structure (:class:`repro.motion.skeleton.Skeleton` keeps the table).

Roles
-----
A *role* names a body part independently of the naming convention of a file.  Limb
joints are found by name (case-insensitive, side from prefixes/suffixes ``l``/``r``,
``Left``/``Right``, ``_L``/``_R``); the trunk joints are found from the tree when the
parents are known (pelvis = lowest common ancestor of the two hips, chest = lowest
common ancestor of the two shoulders), else by name.  Joint-to-role tables for the three
skeletons used in this project (a joint named after bone *b* sits at the start of *b*
in CMU files, ``mocap/cmu/PROVENANCE.md``):

============== ============ ============= =============
role           CMU          Bandai Namco  Mixamo-style
============== ============ ============= =============
pelvis         root         Hips          Hips
spine          lowerback    Spine         Spine
chest          thorax       Chest         Spine1
neck           lowerneck    Neck          Neck
head           head         Head          Head
left_clavicle  lclavicle    Shoulder_L    LeftShoulder
left_shoulder  lhumerus     UpperArm_L    LeftArm
left_elbow     lradius      LowerArm_L    LeftForeArm
left_wrist     lwrist       Hand_L        LeftHand
left_hand      lhand        --            --
left_hip       lfemur       UpperLeg_L    LeftUpLeg
left_knee      ltibia       LowerLeg_L    LeftLeg
left_ankle     lfoot        Foot_L        LeftFoot
left_toe       ltoes        Toes_L        LeftToeBase
left_fist      lhand        Hand_L        LeftHand
left_foot      ltoes        Toes_L        LeftToeBase
============== ============ ============= =============

(right side likewise).  ``left_fist`` and ``left_foot`` are the *hit points* of the paper
(Section 3.2.1: "the name of the hit segment (such as the right hand or the left
foot)"): the end of the hand bone when the skeleton has one (CMU ``lhand``), else the
wrist; the toe joint (ball of the foot) when present, else the ankle.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np

from repro.errors import MotionError

__all__ = ["ROLES", "REQUIRED_ROLES", "SIDE_ROLES", "LIMBS", "find_roles", "effector_role"]

#: Per-side role stems, in proximal-to-distal order (``left_`` / ``right_`` prefixed).
SIDE_ROLES: tuple[str, ...] = (
    "clavicle",
    "shoulder",
    "elbow",
    "wrist",
    "hand",
    "hip",
    "knee",
    "ankle",
    "toe",
    "fist",
    "foot",
)

#: Every role :func:`find_roles` may return.
ROLES: tuple[str, ...] = ("pelvis", "spine", "chest", "neck", "head") + tuple(
    f"{side}_{stem}" for side in ("left", "right") for stem in SIDE_ROLES
)

#: Roles without which a skeleton cannot be encoded / retargeted (:class:`MotionError`).
REQUIRED_ROLES: tuple[str, ...] = ("pelvis", "chest", "head") + tuple(
    f"{side}_{stem}"
    for side in ("left", "right")
    for stem in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "fist", "foot")
)

#: The four limbs of Kulpa et al. (2005): (proximal, middle, distal) roles.
LIMBS: dict[str, tuple[str, str, str]] = {
    "left_arm": ("left_shoulder", "left_elbow", "left_wrist"),
    "right_arm": ("right_shoulder", "right_elbow", "right_wrist"),
    "left_leg": ("left_hip", "left_knee", "left_ankle"),
    "right_leg": ("right_hip", "right_knee", "right_ankle"),
}

# Base names (lower case, alphanumerics only, side removed) of each per-side role stem,
# best first.  "hand" is the wrist of Mixamo / Bandai skeletons, and the fist (end of the
# hand bone) of CMU ones, where a separate "wrist" joint exists.
_SIDE_BASES: dict[str, tuple[str, ...]] = {
    "clavicle": ("clavicle", "collarbone", "collar", "shoulder"),
    "shoulder": ("humerus", "upperarm", "uparm", "arm"),
    "elbow": ("radius", "forearm", "lowerarm", "lowarm", "elbow"),
    "wrist": ("wrist", "hand"),
    "hip": ("femur", "upleg", "upperleg", "thigh", "hip"),
    "knee": ("tibia", "lowerleg", "lowleg", "leg", "shin", "calf", "knee"),
    "ankle": ("foot", "ankle"),
    "toe": ("toes", "toebase", "toe", "ball"),
}
_CENTER_BASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("hips", "pelvis", "hip", "root"),
    "head": ("head",),
    "neck": ("neck", "lowerneck", "neck1", "upperneck"),
    "spine": ("lowerback", "spine", "abdomen", "spine1", "waist"),
    "chest": ("thorax", "chest", "upperchest", "spine3", "spine2", "spine1", "upperback"),
}
_SEP = r"[_\-. ]"
_LEFT = (re.compile(rf"^(?:left{_SEP}?|l{_SEP}?)(.+)$"), re.compile(rf"^(.+?)(?:{_SEP}?left|{_SEP}l)$"))
_RIGHT = (re.compile(rf"^(?:right{_SEP}?|r{_SEP}?)(.+)$"), re.compile(rf"^(.+?)(?:{_SEP}?right|{_SEP}r)$"))


def _strip(name: str) -> str:
    """Lower case, namespace (``mixamorig:``) and ``joint_`` prefix removed."""
    n = name.lower().rsplit(":", 1)[-1].strip()
    if n.startswith("joint_"):
        n = n[len("joint_"):]
    return n


def _alnum(s: str) -> str:
    return re.sub(r"[^a-z0-9]", "", s)


def _side_and_base(name: str) -> list[tuple[str, str]]:
    """Possible (side, base) readings of a joint name; base stripped of separators."""
    n = _strip(name)
    out = []
    for side, pats in (("left", _LEFT), ("right", _RIGHT)):
        for p in pats:
            m = p.match(n)
            if m:
                out.append((side, _alnum(m.group(1))))
    return out


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


def find_roles(
    joint_names: Sequence[str],
    parents: Sequence[int] | np.ndarray | None = None,
    *,
    overrides: Mapping[str, str] | None = None,
    required: Sequence[str] = REQUIRED_ROLES,
) -> dict[str, str]:
    """Map body-part roles to the joints of a skeleton, by name patterns and tree structure.

    Limb joints are recognised by name: the side is read from a prefix or suffix
    (``l``/``r`` glued to a known bone name as in CMU ``lfemur``; ``Left``/``Right`` as
    in Mixamo ``LeftUpLeg``; ``_L``/``_R`` as in Bandai ``UpperLeg_L``; any namespace
    such as ``mixamorig:`` is ignored), the role from the rest of the name (see
    :data:`_SIDE_BASES` in the source: ``humerus``/``upperarm``/``arm`` = shoulder,
    ``radius``/``forearm``/``lowerarm`` = elbow, ``wrist`` else ``hand`` = wrist,
    ``femur``/``upleg``/``upperleg``/``thigh`` = hip, ``tibia``/``leg``/``lowerleg`` =
    knee, ``foot``/``ankle`` = ankle, ``toes``/``toebase`` = toe, ``clavicle``/``shoulder``
    = clavicle).  When ``parents`` is given the trunk is found from the tree: pelvis =
    lowest common ancestor of the two hips, chest = lowest common ancestor of the two
    shoulders, spine = first joint after the pelvis on the way to the chest, neck = first
    joint after the chest on the way to the head; and each limb is checked to be a
    parent-child chain (shoulder -> elbow -> wrist, hip -> knee -> ankle), which the
    analytic two-bone IK of :mod:`repro.motion.morphology` needs.  Without ``parents``
    the trunk joints are found by name too (``hips``/``pelvis``/``root``, ``thorax``/
    ``chest``/highest ``spineN`` ...).

    Parameters
    ----------
    joint_names : sequence of str
        The skeleton's joints (e.g. :attr:`repro.motion.Motion.joint_names`).
    parents : (J,) int array, optional
        Parent index of each joint (``-1`` for the root).  Strongly recommended.
    overrides : mapping role -> joint name, optional
        Explicit assignments, applied before anything is inferred (e.g. for a skeleton
        with unusual names: ``{"left_wrist": "L_Hand_jnt"}``).
    required : sequence of str
        Roles that must be found (default :data:`REQUIRED_ROLES`).

    Returns
    -------
    dict[str, str]
        Role -> joint name, for every role found (a subset of :data:`ROLES`).  The
        effector roles ``left_fist``/``right_fist`` (hand tip when the skeleton has a
        separate hand joint after the wrist, else the wrist) and
        ``left_foot``/``right_foot`` (toe joint, else ankle) are always derived when the
        limbs are found.

    Raises
    ------
    repro.errors.MotionError
        If a required role is missing (the message names the missing roles and lists
        the joints), an override names an unknown joint or role, or a limb is not a
        parent-child chain.
    """
    names = [str(n) for n in joint_names]
    index = {n: i for i, n in enumerate(names)}
    par = None if parents is None else np.asarray(parents, dtype=np.intp)
    if par is not None and par.shape != (len(names),):
        raise MotionError(f"parents must have one entry per joint ({len(names)}), got shape {par.shape}")
    roles: dict[str, str] = {}
    for role, joint in (overrides or {}).items():
        if role not in ROLES:
            raise MotionError(f"unknown role {role!r} in overrides; roles are {list(ROLES)}")
        if joint not in index:
            raise MotionError(f"override {role!r} -> {joint!r}: no such joint; joints: {names}")
        roles[role] = joint
    used = set(roles.values())
    _limbs_by_name(names, index, par, roles, used)
    if "head" not in roles:
        h = _trunk_by_name("head", names, used)
        if h is not None:
            roles["head"] = h
            used.add(h)
    if par is not None:
        _trunk_from_tree(names, index, par, roles)
    else:
        for role in ("pelvis", "chest", "spine", "neck"):
            if role not in roles:
                n = _trunk_by_name(role, names, set(roles.values()))
                if n is not None:
                    roles[role] = n
    _hit_points(roles)
    missing = [r for r in required if r not in roles]
    if missing:
        raise MotionError(
            f"skeleton lacks the roles {missing} (found {sorted(roles)}); joints: {names}. "
            "Pass overrides={'role': 'joint name'} to name them."
        )
    if par is not None:
        _check_limb_chains(index, par, roles)
    return roles


def _limbs_by_name(names: list[str], index: dict[str, int], par, roles: dict[str, str], used: set[str]) -> None:
    """Limb joints by name (in place); a "hand" after a separate "wrist" is the fist (CMU lhand)."""
    readings = {n: _side_and_base(n) for n in names}
    for side in ("left", "right"):
        for stem, bases in _SIDE_BASES.items():
            role = f"{side}_{stem}"
            if role in roles:
                continue
            for base in bases:
                hits = [n for n in names if n not in used and (side, base) in readings[n]]
                if hits:
                    roles[role] = hits[0]
                    used.add(hits[0])
                    break
        wrist = roles.get(f"{side}_wrist")
        if f"{side}_hand" not in roles and wrist is not None:
            for n in names:
                if n not in used and (side, "hand") in readings[n]:
                    if par is None or par[index[n]] == index[wrist]:
                        roles[f"{side}_hand"] = n
                        used.add(n)
                        break


def _trunk_by_name(role: str, names: list[str], exclude: set[str]) -> str | None:
    for base in _CENTER_BASES[role]:
        for n in names:
            if n not in exclude and _alnum(_strip(n)) == base and not _side_and_base_is_limb(n):
                return n
    return None


def _trunk_from_tree(names: list[str], index: dict[str, int], par: np.ndarray, roles: dict[str, str]) -> None:
    """Pelvis, chest, spine, neck and clavicles from the tree (in place)."""
    lh, rh = roles.get("left_hip"), roles.get("right_hip")
    if "pelvis" not in roles and lh and rh:
        roles["pelvis"] = names[_lca(index[lh], index[rh], par)]
    ls, rs = roles.get("left_shoulder"), roles.get("right_shoulder")
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


def _hit_points(roles: dict[str, str]) -> None:
    """The effector roles: fist = hand tip, else wrist; foot = toe, else ankle (in place)."""
    for side in ("left", "right"):
        if f"{side}_fist" not in roles:
            src = roles.get(f"{side}_hand") or roles.get(f"{side}_wrist")
            if src:
                roles[f"{side}_fist"] = src
        if f"{side}_foot" not in roles:
            src = roles.get(f"{side}_toe") or roles.get(f"{side}_ankle")
            if src:
                roles[f"{side}_foot"] = src


def _check_limb_chains(index: dict[str, int], par: np.ndarray, roles: dict[str, str]) -> None:
    for limb, (a, b, c) in LIMBS.items():
        if a in roles and b in roles and c in roles:
            ia, ib, ic = index[roles[a]], index[roles[b]], index[roles[c]]
            if par[ib] != ia or par[ic] != ib:
                raise MotionError(
                    f"{limb}: {roles[a]!r} -> {roles[b]!r} -> {roles[c]!r} is not a parent-child "
                    "chain; two-bone IK needs the middle joint to be the child of the proximal "
                    "one and the parent of the distal one"
                )


def _side_and_base_is_limb(name: str) -> bool:
    """True when ``name`` reads as a sided limb joint (so it is no trunk joint)."""
    return any(base in b for _, base in _side_and_base(name) for b in _SIDE_BASES.values())


def effector_role(roles: Mapping[str, str], hit_role: str, hit_joint: str) -> str:
    """The role (of a skeleton's ``roles``) whose joint is a clip's hit joint: the effector to adapt.

    A clip's ``hit_role`` names its striking limb's default hit point (``left_foot`` is
    the toe joint), but its ``hit_joint`` can be another joint of that limb: the
    synthetic side and round kicks strike with the heel (``LeftFoot``, the ankle).
    Driving the role's own joint onto the target would put the toe there instead.
    """
    side, _, stem = hit_role.partition("_")
    stems = ("fist", "hand", "wrist") if stem in ("fist", "hand", "wrist") else ("foot", "toe", "ankle")
    for role in (hit_role,) + tuple(f"{side}_{s}" for s in stems):
        if roles.get(role) == hit_joint:
            return role
    raise MotionError(f"no {side} effector role maps to the hit joint {hit_joint!r} (hit role {hit_role!r})")
