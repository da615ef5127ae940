"""Body-part roles of any skeleton: which joints are the shoulders, elbows, wrists, hips ...

Pronost et al. (Section 3.4.1) retarget with the representation of Kulpa et al. (2005),
which needs the limbs of any skeleton; :func:`find_roles` finds them by name patterns
and tree structure (:class:`repro.motion.body.skeleton.Skeleton` keeps the table).

Roles
-----
A *role* names a body part independently of the naming convention of a file.  Given the
rest offsets (``find_roles(..., offsets=...)``, which :class:`~repro.motion.body.skeleton.Skeleton`
always passes), roles come from the **structure first**: legs, arms and head from the
joint tree and the rest pose (twist / roll / helper bones, fingers, face joints, props
and zero-length joints set aside), the names only confirming and disambiguating (which
of ``RightCollar``/``RightShoulder`` is the upper arm, the side when the rest pose cannot
tell it); this recognises MotionBuilder/Biovision, Poser/DAZ, Second Life (``m``-prefixed
bento), 3ds Max Biped, SMPL, Unreal, Unity/HumanIK and Blender ``.L`` names besides the
three tables below.  :func:`check_roles` names what a use lacks (a punch needs an arm).
Without offsets, limb joints are found by name (case-insensitive, side from prefixes/suffixes ``l``/``r``,
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
from functools import lru_cache

import numpy as np

from repro.checks import as_real_array, describe
from repro.errors import MotionError
from repro.motion.core.cache import LRUCache
from repro.motion.core.kinematics import check_joint_names

__all__ = ["LIMBS", "REQUIRED_ROLES", "ROLES", "ROLES_FOR", "SIDE_ROLES", "bone_lengths_of", "check_roles",
           "effector_role", "find_roles", "is_helper_name"]

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
    "shoulder": ("humerus", "upperarm", "uparm", "arm", "shldr"),
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


class _AmbiguousLimbs(MotionError):
    """Two candidate limbs on one side: an error even when the names would decide otherwise."""


@lru_cache(maxsize=8192)
def _strip(name: str) -> str:
    """Lower case, namespace (``mixamorig:``) and ``joint_`` prefix removed."""
    n = name.lower().rsplit(":", 1)[-1].strip()
    n = n.removeprefix("joint_")
    n = re.sub(r"^bip\d*[ _]", "", n)  # 3ds Max Biped "Bip01 L Thigh"
    return n


def _alnum(s: str) -> str:
    return re.sub(r"[^a-z0-9]", "", s)


@lru_cache(maxsize=8192)
def _side_and_base(name: str) -> tuple[tuple[str, str], ...]:
    """Possible (side, base) readings of a joint name; base stripped of separators."""
    n = _strip(name)
    out = []
    for side, pats in (("left", _LEFT), ("right", _RIGHT)):
        for p in pats:
            m = p.match(n)
            if m:
                out.append((side, _alnum(m.group(1))))
    return tuple(out)


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
    offsets: Sequence | np.ndarray | None = None,
    end_site_parents: Sequence[int] | np.ndarray | None = None,
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
    analytic two-bone IK of :mod:`repro.motion.retargeting.morphology` needs.  Without ``parents``
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
    offsets : (J, 3) array, optional
        Rest offsets.  With ``parents`` they switch on *roles from structure first*:
        the legs are the two branches of the first three-way branching joint (the
        pelvis hub) whose end joints lie lowest, the head the highest end of the third
        branch (the trunk) and the arms its two most lateral ends, once twist / roll /
        helper bones, fingers, face joints, props and ``_End`` leaves are set aside by
        name (:func:`is_helper_name`) and runs of co-located joints (zero-length
        helpers) are collapsed to their deepest joint.  In each limb chain the two
        longest consecutive bones are the upper arm and forearm (thigh and shin), so
        a joint before them is the clavicle and one after them the hand (toe).  The
        side comes from the names (``Left``/``L_``/``_l``/``l``/``.L``/``...Left``)
        and, when the names say nothing, from the rest pose (the toes point forward,
        left = up x forward).  Names are not needed (joints named ``j0 .. jN`` or random
        strings get their roles from the structure: the arms are the most lateral tips on
        either side of the trunk, so fingers and twist leaves are not taken for arms; a
        wrist that branches into fingers has no ``hand`` joint (CMU's, branching into the
        hand and a one-joint thumb, has); an arm's shoulder lies off the trunk's midline
        (CMU's clavicle joints lie on it); the joint before the upper arm is the clavicle); a name contradicting the structure makes the names decide,
        and a glued ``l``/``r`` prefix is a side only before a body-part word.  When the structure cannot be read (a rest pose with
        every bone along one line, as Bandai Namco's), the names decide as without
        ``offsets``.
    end_site_parents : (E,) int array, optional
        Joints carrying an End Site.  With meaningless names, a head chain ending in a
        leaf joint *without* an End Site (a head-top marker joint, Mixamo
        ``HeadTop_End``) has its head at that joint's parent.

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
    # the arguments checked at the entry (a string is no list of joint names, a float no parent index)
    names = check_joint_names(joint_names)
    par = None if parents is None else as_real_array(parents, "parents", error=MotionError, integer=True,
                                                     shape=(len(names),)).astype(np.intp)
    if par is not None and par.size and (par[0] != -1 or np.any(par[1:] < 0) or
                                         np.any(par[1:] >= np.arange(1, par.size))):
        raise MotionError("parents must be -1 for joint 0 and parents[j] < j for the others")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise MotionError(f"overrides must be a mapping role -> joint name, got {describe(overrides)}")
    if isinstance(required, (str, bytes)) or not isinstance(required, Sequence | np.ndarray) or \
            not all(isinstance(r, str) for r in required):
        raise MotionError(f"required must be a sequence of role names, got {describe(required)}")
    if offsets is not None:
        offsets = as_real_array(offsets, "offsets", error=MotionError, shape=(len(names), 3))
        bone_lengths_of(offsets)  # a skeleton too large or small to compute with, named as such
    if end_site_parents is not None:
        esp = as_real_array(end_site_parents, "end_site_parents", error=MotionError, integer=True).reshape(-1)
        if np.any((esp < 0) | (esp >= len(names))):
            raise MotionError(f"end_site_parents must be joint indices in [0, {len(names)})")
        end_site_parents = esp
    key = None
    try:
        off_key = None if offsets is None else np.asarray(offsets, dtype=float).tobytes()
        es = None if end_site_parents is None else tuple(int(e) for e in np.asarray(end_site_parents).reshape(-1))
        key = (tuple(names), None if par is None else par.tobytes(), off_key,
               tuple(sorted((overrides or {}).items())), tuple(required), es)
        hash(key)
    except (TypeError, ValueError):
        key = None
    es_set = None if end_site_parents is None else {int(e) for e in np.asarray(end_site_parents).reshape(-1)}
    if key is None:
        return _find_roles(names, par, overrides, required, offsets, es_set)
    return dict(_CACHE.get(key, lambda: _find_roles(names, par, overrides, required, offsets, es_set)))


#: Largest / smallest sum of a skeleton's bone lengths (its units): beyond them squared lengths
#: (distances, IK) overflow or underflow float64 (1.8e308, 2.2e-308), so such a skeleton is refused.
MAX_LENGTH_SUM: float = 1e100
MIN_LENGTH_SUM: float = 1e-100


def _check_role_map(roles) -> None:
    if not isinstance(roles, Mapping):
        raise MotionError(f"roles must be a mapping role -> joint name, got {describe(roles)}")


def bone_lengths_of(offsets: np.ndarray) -> np.ndarray:
    """``|offsets[j]|`` (J,) of finite (J, 3) offsets, measured without overflow or underflow.

    MotionError when their sum is beyond :data:`MAX_LENGTH_SUM` or below
    :data:`MIN_LENGTH_SUM`: such a skeleton is too large (or small) to compute with, and
    is named as such rather than, say, as having zero-length bones.
    """
    big = float(np.abs(offsets).max(initial=0.0))
    # scaled by the largest component first: the squares of 1e300 (or 1e-300) would overflow (underflow)
    lengths = big * np.linalg.norm(offsets / big, axis=1) if big > 0 else np.zeros(len(offsets))
    total = float(lengths.sum())
    if not total <= MAX_LENGTH_SUM:
        raise MotionError(
            f"skeleton bone lengths add up to {total:.3g} units (largest offset component {big:.3g}): beyond "
            f"{MAX_LENGTH_SUM:g} their squares and products overflow float64 (to inf); rescale the offsets")
    if 0 < total < MIN_LENGTH_SUM:
        raise MotionError(
            f"skeleton bone lengths add up to {total:.3g} units: below {MIN_LENGTH_SUM:g} their squares "
            "underflow float64 (to 0); rescale the offsets")
    return lengths


#: Role tables of the 256 most recent skeletons (the same skeleton is encoded once per clip).
_CACHE: LRUCache[dict[str, str]] = LRUCache(256)


def _find_roles(names, par, overrides, required, offsets, end_sites=None) -> dict[str, str]:
    index = {n: i for i, n in enumerate(names)}
    if par is not None and par.shape != (len(names),):
        raise MotionError(f"parents must have one entry per joint ({len(names)}), got shape {par.shape}")
    roles: dict[str, str] = {}
    for role, joint in (overrides or {}).items():
        if role not in ROLES:
            raise MotionError(f"unknown role {role!r} in overrides; roles are {list(ROLES)}")
        if joint not in index:
            raise MotionError(f"override {role!r} -> {joint!r}: no such joint; joints: {names}")
        roles[role] = joint
    seen: dict[str, str] = {}
    for role, joint in roles.items():
        stem = role.split("_", 1)[-1]
        if joint in seen and stem not in ("fist", "foot", "hand", "toe", "wrist", "ankle"):
            raise MotionError(f"conflicting overrides: {seen[joint]!r} and {role!r} both name joint {joint!r}")
        seen.setdefault(joint, role)
    if par is not None and offsets is not None:
        off = np.asarray(offsets, dtype=float)
        if off.shape != (len(names), 3) or not np.all(np.isfinite(off)):
            raise MotionError(f"offsets must be a finite ({len(names)}, 3) array, got shape {off.shape}")
        try:
            found = _roles_from_structure(names, par, off, end_sites)
        except _AmbiguousLimbs:
            raise
        except MotionError:
            found = None  # e.g. every bone along one line: the names decide
        if found is not None:
            used0 = set(roles.values())
            for role, joint in found.items():
                if role not in roles and joint not in used0:
                    roles[role] = joint
                    used0.add(joint)
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
            f"skeleton lacks the roles {missing} needed for retargeting (found {sorted(roles)}); joints: {names}. "
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
    _check_role_map(roles)
    for name, v in (("hit_role", hit_role), ("hit_joint", hit_joint)):
        if not isinstance(v, str):
            raise MotionError(f"{name} must be a string, got {describe(v)}")
    side, _, stem = hit_role.partition("_")
    stems = ("fist", "hand", "wrist") if stem in ("fist", "hand", "wrist") else ("foot", "toe", "ankle")
    for role in (hit_role,) + tuple(f"{side}_{s}" for s in stems):
        if roles.get(role) == hit_joint:
            return role
    raise MotionError(f"no {side} effector role maps to the hit joint {hit_joint!r} (hit role {hit_role!r})")


# ---------------------------------------------------------------- roles from structure
#: Roles each use of a skeleton needs (for :func:`check_roles` messages).
ROLES_FOR: dict[str, tuple[str, ...]] = {
    "a punch": ("pelvis", "chest", "right_shoulder", "right_elbow", "right_wrist", "right_fist"),
    "a kick": ("pelvis", "right_hip", "right_knee", "right_ankle", "right_foot"),
    "retargeting": REQUIRED_ROLES,
}

# Joints that never carry a body role: twist / roll / helper bones, fingers, face, props.
_SKIP_PARTS = (
    "twist", "roll", "helper", "nub", "prop", "weapon", "sword", "thumb", "index", "pinky", "pinkie",
    "finger", "carpal", "wing", "tail", "hind", "face", "eye", "jaw", "tongue", "brow", "teeth", "cheek",
    "skirt", "hair", "cape", "breast", "skull", "headtop", "headend", "ik", "pole", "target", "bow",
)  # fmt: skip
_SKIP_WHOLE = re.compile(r"^(ring|middle|mid|little|lip|lid|ear|nose|nostril|hand[a-z]+\d*|fingers?\d*)$")
_SKIP_END = re.compile(r"(end|nub|site|tip)\d*$")


def is_helper_name(name: str) -> bool:
    """True for joints that carry no body role by name: twist/roll/helper bones, fingers,
    face joints, props and ``..._End`` leaves (``Unreal upperarm_twist_01_l``, ``mixamorig:
    LeftHandIndex1``, ``mFaceJaw``, ``HeadTop_End``)."""
    if not isinstance(name, str):  # checked before the cache, which needs a hashable name
        raise MotionError(f"a joint name must be a string, got {describe(name)}")
    return _is_helper_name(name)


@lru_cache(maxsize=8192)
def _is_helper_name(name: str) -> bool:
    n = _strip(name)
    bases = [b for _, b in _side_and_base(name)] or [_alnum(n)]
    for b in bases:
        b2 = b[1:] if b.startswith("m") and len(b) > 1 and b[1:2].isalpha() else b
        for s in (b, b2):
            if any(p in s for p in _SKIP_PARTS if p not in ("ik", "bow", "pole", "target")):
                return True
            if s.startswith(("ik", "pole", "target")) or s == "bow":
                return True
            if _SKIP_WHOLE.match(s) or (_SKIP_END.search(s) and not s.endswith(("spine", "hand", "head"))):
                return True
    return False


@lru_cache(maxsize=8192)
def _name_side(name: str) -> str | None:
    """Side read from a name (``Left``/``L_``/``_l``/``.L``/``l`` prefix, ``mShoulderLeft``), or None."""
    n = _strip(name)
    a = _alnum(n)
    if re.search(r"(?<![a-z])left|left$", n) or a.endswith("left") or a.startswith("left"):
        return "left"
    if re.search(r"(?<![a-z])right|right$", n) or a.endswith("right") or a.startswith("right"):
        return "right"
    # a glued l/r prefix or suffix (CMU lfemur) counts only before a body-part word: "lXqT" is no left
    sides = {s for s, b in _side_and_base(name) if any(w in b for w in _BODY_WORDS)}
    if re.search(rf"(^|{_SEP})l({_SEP}|$)", n):
        sides.add("left")
    if re.search(rf"(^|{_SEP})r({_SEP}|$)", n):
        sides.add("right")
    return sides.pop() if len(sides) == 1 else None


_BODY_WORDS = tuple(
    sorted({b for bs in _SIDE_BASES.values() for b in bs} | {b for bs in _CENTER_BASES.values() for b in bs}
           | {"collar", "shldr", "calf", "ball", "clav", "upper", "lower", "fore", "thigh", "abdomen", "torso"})
)


def _rest_positions(parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    p = np.array(offsets, dtype=float)
    for j in range(1, len(p)):
        p[j] = p[parents[j]] + offsets[j]
    return p


def _structure(names: list[str], par: np.ndarray, off: np.ndarray) -> dict:
    """Legs, arms and head chains from the tree and the rest pose (see :func:`find_roles`)."""
    J = len(names)
    P = _rest_positions(par, off)
    bl = np.linalg.norm(off, axis=1)
    scale = float(np.ptp(P, axis=0).max()) if J > 1 else 0.0
    if scale <= 0 or not np.isfinite(scale):
        raise MotionError("the rest pose has no extent; cannot find body parts from the structure")
    tol = 1e-6 * scale
    skip = np.array([is_helper_name(n) for n in names])
    children: list[list[int]] = [[] for _ in range(J)]
    for j in range(1, J):
        children[par[j]].append(j)
    # a skipped joint's subtree is kept only when it holds unskipped joints (in-chain helpers)
    has_cand = ~skip.copy()
    for j in range(J - 1, 0, -1):
        if has_cand[j]:
            has_cand[par[j]] = True
    tips = [j for j in range(J) if not skip[j] and not any(has_cand[c] for c in children[j])]

    def tips_under(j):
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            if k in tipset:
                out.append(k)
            stack.extend(c for c in children[k] if has_cand[c])
        return out

    tipset = set(tips)
    # pelvis hub: first joint from the root with >= 3 tip-bearing branches
    hub = 0
    while True:
        br = [c for c in children[hub] if has_cand[c]]
        if len(br) >= 3 or len(br) == 0:
            break
        if len(br) == 1:
            hub = br[0]
            continue
        break
    br = [c for c in children[hub] if has_cand[c]]
    if len(br) < 3:
        raise MotionError(
            f"no joint of the tree branches into two legs and a trunk (first branching joint "
            f"{names[hub]!r} has {len(br)} branches); not a humanoid skeleton"
        )
    groups = sorted(((tips_under(c), c) for c in br), key=lambda g: -len(g[0]))
    upper_tips, _upper_root = groups[0]
    if len(upper_tips) < 3:
        raise MotionError(
            f"the branches of {names[hub]!r} hold at most {len(upper_tips)} end joints each; "
            "expected a trunk ending in two arms and a head"
        )
    leg_cands = [g for g in groups[1:] if len(g[0]) >= 1]
    mean_upper = P[upper_tips].mean(axis=0)
    # lowest leg tips relative to the hub
    def low(g):
        return min(float((P[t] - P[hub]) @ (mean_upper - P[hub])) for t in g[0])

    leg_cands.sort(key=low)
    if len(leg_cands) < 2:
        raise MotionError(f"found fewer than two legs under {names[hub]!r}; not a humanoid skeleton")
    legs = []
    for g, _ in leg_cands[:2]:
        legs.append(min(g, key=lambda t: float((P[t] - P[hub]) @ (mean_upper - P[hub]))))
    up = mean_upper - P[legs].mean(axis=0)
    nu = np.linalg.norm(up)
    if nu <= 1e-3 * scale:
        raise MotionError("the rest pose does not tell up from down (legs and trunk end at the same height)")
    up = up / nu
    # head: the upper tip highest along up; arms: the two most lateral of the others
    head = max(upper_tips, key=lambda t: float(P[t] @ up))
    others = [t for t in upper_tips if t != head]
    chest_ref = P[hub] + up * float((P[head] - P[hub]) @ up) * 0.7

    def lateral(t):
        v = P[t] - chest_ref
        return float(np.linalg.norm(v - (v @ up) * up))

    others.sort(key=lateral, reverse=True)
    if len(others) < 2:
        raise MotionError("the upper body has fewer than two arms")

    def lat_vec(t):
        v = P[t] - chest_ref
        return v - (v @ up) * up

    # the second arm: the most lateral tip on the other side (fingers of one hand are all lateral)
    first = others[0]
    opposite = [t for t in others[1:] if float(lat_vec(t) @ lat_vec(first)) < 0]
    if not opposite:
        raise MotionError(f"the upper body has no arm on the other side of {names[first]!r}")
    arms = [first, opposite[0]]
    return {"P": P, "bl": bl, "tol": tol, "up": up, "hub": hub, "head": head, "arms": arms, "legs": legs,
            "has_cand": has_cand}


def _points(chain: list[int], P: np.ndarray, tol: float) -> list[int]:
    """Collapse runs of co-located joints to their deepest one."""
    out: list[int] = []
    for j in chain:
        if out and np.linalg.norm(P[j] - P[out[-1]]) <= tol:
            out[-1] = j
        else:
            out.append(j)
    return out


def _path_down(a: int, d: int, par: np.ndarray) -> list[int]:
    """Joints from ``a`` (excluded) down to ``d`` (included)."""
    out = []
    while d != a and d >= 0:
        out.append(d)
        d = int(par[d])
    return out[::-1]


_ARM_STEMS = ("shoulder", "elbow", "wrist")
_LEG_STEMS = ("hip", "knee", "ankle")
_AMBIGUOUS_BASES = {"shoulder", "hand", "hip"}


@lru_cache(maxsize=8192)
def _bases(name: str) -> frozenset[str]:
    """Side-stripped bases of a name (also without a Second Life ``m`` prefix or a digit suffix)."""
    out = set()
    for _, b in _side_and_base(name):
        for c in (b, b.removeprefix("m")):
            out.add(c)
            out.add(c.rstrip("0123456789"))
    return frozenset(out)


@lru_cache(maxsize=8192)
def _stem_votes(name: str, stem: str) -> tuple[int, int]:
    """(1 if the name reads as ``stem``, 1 if it reads unambiguously as another limb stem)."""
    bs = _bases(name)
    vote = int(any(b in _SIDE_BASES[stem] for b in bs))
    other = int(
        not vote
        and any(b in bases and b not in _AMBIGUOUS_BASES for s, bases in _SIDE_BASES.items() if s != stem for b in bs)
    )
    return vote, other


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
        votes = [_stem_votes(names[j], st) for j, st in zip(trio, stems)]
        k = (sum(v for v, _ in votes) - sum(c for _, c in votes), seg[i - 1] + seg[i])
        if key is None or k > key:
            best, key = i, k
            bad = any(c for _, c in votes)
    if bad:
        return None  # the names contradict every reading of the structure: let the names decide
    return {"before": pts[: best - 1], "prox": pts[best - 1], "mid": pts[best], "dist": pts[best + 1],
            "after": pts[best + 2:]}


def _roles_from_structure(names: list[str], par: np.ndarray, off: np.ndarray, end_sites=None) -> dict[str, str]:
    st = _structure(names, par, off)
    P, tol, up, hub = st["P"], st["tol"], st["up"], st["hub"]
    cand = st["has_cand"]
    n_cand_children = np.zeros(len(names), dtype=int)
    for j in range(1, len(names)):
        if cand[j]:
            n_cand_children[par[j]] += 1
    roles: dict[str, str] = {}
    # legs
    legs = {}
    for t in st["legs"]:
        pts = _points(_path_down(hub, t, par), P, tol)
        legs[t] = _limb_from_chain(pts, names, P, "leg")
    arms = {}
    head = st["head"]
    chest = _lca(st["arms"][0], st["arms"][1], par)
    for t in st["arms"]:
        pts = _points(_path_down(chest, t, par), P, tol)
        v = P[pts] - P[hub]
        lat = np.linalg.norm(v - np.outer(v @ up, up), axis=1)
        arms[t] = _limb_from_chain(pts, names, P, "arm", prox_ok=lat >= 0.1 * lat[-1])
    # facing: toes point forward; else names must tell the sides
    fwd = np.zeros(3)
    for lg in legs.values():
        if lg is not None and lg["after"]:
            v = P[lg["after"][0]] - P[lg["dist"]]
            fwd += v - (v @ up) * up
    sides: dict[int, str] = {}
    for group in (legs, arms):
        (t1, g1), (t2, g2) = group.items()
        if g1 is None or g2 is None:
            # one chain's names disagree with the structure: sides from the tips' names
            for t, g in ((t1, g1), (t2, g2)):
                side = None if g is None else _name_side(names[g["prox"]]) or _name_side(names[t])
                if side is None:
                    group[t] = None
                else:
                    sides[t] = side
            continue
        by_name = [_name_side(names[g["prox"]]) or _name_side(names[g["mid"]]) or _name_side(names[t]) for t, g in ((t1, g1), (t2, g2))]
        if by_name[0] and by_name[1] and by_name[0] != by_name[1]:
            sides[t1], sides[t2] = by_name
            continue
        if by_name[0] and by_name[0] == by_name[1]:
            raise _AmbiguousLimbs(
                f"two candidate {'legs' if group is legs else 'arms'} on the {by_name[0]} side: "
                f"{names[g1['prox']]!r} and {names[g2['prox']]!r}"
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
    for t, lg in legs.items():
        if lg is None:
            continue
        s = sides[t]
        roles[f"{s}_hip"], roles[f"{s}_knee"], roles[f"{s}_ankle"] = (names[lg[k]] for k in ("prox", "mid", "dist"))
        if lg["after"]:
            roles[f"{s}_toe"] = names[lg["after"][0]]
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
            roles[f"{s}_clavicle"] = names[am["before"][-1]]
    # head: a joint named head on the head chain, else the tip
    hchain = _path_down(hub, head, par)
    named = [j for j in hchain if _alnum(_strip(names[j])).lstrip("m") in ("head", "head1", "headbone")]
    if not named and end_sites is not None and head not in end_sites and not np.any(par == head) \
            and len(hchain) >= 3:
        head = int(par[head])  # a head-top marker joint (no End Site, no child): the head is its parent
    roles["head"] = names[named[-1] if named else head]
    return roles


def check_roles(roles: Mapping[str, str], purpose: str, joint_names: Sequence[str] = ()) -> None:
    """Raise :class:`MotionError` naming the roles ``purpose`` needs and the skeleton lacks.

    ``purpose`` is a key of :data:`ROLES_FOR` (``"a punch"``, ``"a kick"``, ``"retargeting"``)."""
    _check_role_map(roles)
    joint_names = check_joint_names(joint_names)
    if not isinstance(purpose, str) or purpose not in ROLES_FOR:
        raise MotionError(f"unknown purpose {purpose!r}; one of {list(ROLES_FOR)}")
    need = ROLES_FOR[purpose]
    if purpose in ("a punch", "a kick"):
        side_need = [r for r in need if r.startswith("right_")]
        ok_side = [
            s for s in ("left", "right") if all(r.replace("right_", f"{s}_") in roles for r in side_need)
        ]
        missing = [r for r in need if not r.startswith("right_") and r not in roles]
        if not ok_side:
            limb = "arm" if purpose == "a punch" else "leg"
            missing += [f"{'an' if limb == 'arm' else 'a'} {limb} (" + ", ".join(r.replace("right_", "left_/right_") for r in side_need) + ")"]
    else:
        missing = [r for r in need if r not in roles]
    if missing:
        raise MotionError(
            f"{purpose} needs {missing}, which this skeleton lacks (found {sorted(roles)}); joints: "
            f"{list(joint_names)}"
        )
