"""Body-part roles of any skeleton: which joints are the shoulders, elbows, wrists, hips ...

Pronost et al. (Section 3.4.1) retarget with the representation of Kulpa et al. (2005),
which needs the limbs of any skeleton; :func:`find_roles` finds them by name patterns
and tree structure (:class:`repro.motion.body.skeleton.Skeleton` keeps the table).

Roles
-----
A *role* names a body part independently of the naming convention of a file.  Given the
rest offsets (``find_roles(..., offsets=...)``, which :class:`~repro.motion.body.skeleton.Skeleton`
always passes), roles come from the **structure first**: legs, arms and head from the
joint tree and the rest pose (:mod:`repro.motion.body.role_structure`: twist / roll /
helper bones, fingers, face joints, props and zero-length joints set aside), the names
(:mod:`repro.motion.body.role_names`) only confirming and disambiguating (which
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

from collections.abc import Mapping, Sequence

import numpy as np

from repro.checks import as_real_array, describe
from repro.errors import MotionError
from repro.motion.body.humanoid import check_humanoid
from repro.motion.body.role_names import is_helper_name, limbs_by_name, trunk_by_name
from repro.motion.body.role_structure import AmbiguousLimbs, roles_from_structure, trunk_from_tree
from repro.motion.core.cache import LRUCache
from repro.motion.core.kinematics import check_joint_names

__all__ = ["LIMBS", "MAX_LENGTH_SUM", "MIN_LENGTH_SUM", "REQUIRED_ROLES", "ROLES", "ROLES_FOR", "SIDE_ROLES",
           "bone_lengths_of", "check_roles", "effector_role", "find_roles", "is_helper_name"]

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

#: Roles each use of a skeleton needs (for :func:`check_roles` messages).
ROLES_FOR: dict[str, tuple[str, ...]] = {
    "a punch": ("pelvis", "chest", "right_shoulder", "right_elbow", "right_wrist", "right_fist"),
    "a kick": ("pelvis", "right_hip", "right_knee", "right_ankle", "right_foot"),
    "retargeting": REQUIRED_ROLES,
}

#: Largest / smallest sum of a skeleton's bone lengths (its units): beyond them squared lengths
#: (distances, IK) overflow or underflow float64 (1.8e308, 2.2e-308), so such a skeleton is refused.
MAX_LENGTH_SUM: float = 1e100
MIN_LENGTH_SUM: float = 1e-100

#: Role tables of the 256 most recent skeletons (the same skeleton is encoded once per clip).
_CACHE: LRUCache[dict[str, str]] = LRUCache(256)


def find_roles(
    joint_names: Sequence[str],
    parents: Sequence[int] | np.ndarray | None = None,
    *,
    overrides: Mapping[str, str] | None = None,
    required: Sequence[str] = REQUIRED_ROLES,
    offsets: Sequence | np.ndarray | None = None,
    end_site_parents: Sequence[int] | np.ndarray | None = None,
) -> dict[str, str]:
    """Map body-part roles to the joints of a skeleton, by tree structure and name patterns.

    With ``parents`` and ``offsets`` the legs, arms and head come from the structure first
    (:mod:`repro.motion.body.role_structure`: the pelvis hub, the lowest and most lateral
    tips, the two longest bones of each limb chain, twist joints inside the bones not
    counted; helper bones, fingers, face joints and props set aside), the names only confirming them and telling the sides; names are not
    needed (``j0 .. jN`` will do).  Joints the structure leaves open (or all of them, when
    the rest pose cannot be read, e.g. every bone along one line as Bandai Namco's) are
    found by name (:mod:`repro.motion.body.role_names`: side from a prefix or suffix such
    as CMU ``lfemur``, Mixamo ``LeftUpLeg``, Bandai ``UpperLeg_L``, any ``mixamorig:``
    namespace ignored; role from the rest, e.g. ``humerus``/``upperarm``/``arm`` =
    shoulder).  With ``parents`` the trunk comes from the tree (pelvis = lowest common
    ancestor of the two hips, chest = that of the two shoulders, spine and neck the first
    joints after them) and each limb must be a chain down the tree (shoulder -> elbow ->
    wrist, hip -> knee -> ankle; twist joints inside the bones, MakeHuman ``upperarm02.L``,
    may sit between them), which the analytic two-bone IK of
    :mod:`repro.motion.retargeting.morphology` needs; without, the trunk is found by name
    too (``hips``/``pelvis``/``root``, ``thorax``/``chest``/highest ``spineN`` ...).

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
        Rest offsets; with ``parents`` they switch on the roles from structure first.
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
        If the skeleton is not a humanoid (with ``parents`` and ``offsets``:
        :func:`repro.motion.body.humanoid.check_humanoid` -- no arm or leg, limbs that are
        not mirror images, proportions far from a human's, a rest pose standing on four
        limbs; the message says which test failed, with its numbers), a required role is
        missing (the message names the missing roles and lists the joints), an override
        names an unknown joint or role, or a limb is not a chain down the tree.
    """
    names, par, offsets, end_site_parents = _checked_arguments(joint_names, parents, overrides, required,
                                                               offsets, end_site_parents)
    key = _cache_key(names, par, overrides, required, offsets, end_site_parents)
    es_set = None if end_site_parents is None else set(end_site_parents.tolist())
    if key is None:
        return _find_roles(names, par, overrides, required, offsets, es_set)
    return dict(_CACHE.get(key, lambda: _find_roles(names, par, overrides, required, offsets, es_set)))


def _checked_arguments(joint_names, parents, overrides, required, offsets, end_site_parents):
    """The arguments of :func:`find_roles` checked (a string is no list of joint names, a float
    no parent index): names, parents, offsets and End Site parents as arrays."""
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
    return names, par, offsets, end_site_parents


def _cache_key(names, par, overrides, required, offsets, end_site_parents) -> tuple | None:
    """The key of a call in :data:`_CACHE`, or None when an argument cannot be hashed."""
    try:
        off_key = None if offsets is None else np.asarray(offsets, dtype=float).tobytes()
        es = None if end_site_parents is None else tuple(end_site_parents.tolist())
        key = (tuple(names), None if par is None else par.tobytes(), off_key,
               tuple(sorted((overrides or {}).items())), tuple(required), es)
        hash(key)
    except (TypeError, ValueError):
        return None
    return key


def _find_roles(names, par, overrides, required, offsets, end_sites=None) -> dict[str, str]:
    """The role table of checked arguments: overrides, then structure, then names, then the trunk."""
    index = {n: i for i, n in enumerate(names)}
    roles = _roles_of_overrides(names, index, overrides)
    if par is not None and offsets is not None:
        _add_roles_from_structure(roles, names, par, np.asarray(offsets, dtype=float), end_sites)
    used = set(roles.values())
    limbs_by_name(names, index, par, roles, used)
    if "head" not in roles:
        h = trunk_by_name("head", names, used)
        if h is not None:
            roles["head"] = h
            used.add(h)
    if par is not None:
        trunk_from_tree(names, index, par, roles)
    else:
        for role in ("pelvis", "chest", "spine", "neck"):
            if role not in roles:
                n = trunk_by_name(role, names, set(roles.values()))
                if n is not None:
                    roles[role] = n
    _hit_points(roles)
    if par is not None and offsets is not None:
        check_humanoid(names, par, offsets, roles)
    missing = [r for r in required if r not in roles]
    if missing:
        raise MotionError(
            f"skeleton lacks the roles {missing} needed for retargeting (found {sorted(roles)}); joints: {names}. "
            "Pass overrides={'role': 'joint name'} to name them."
        )
    if par is not None:
        _check_limb_chains(index, par, roles)
    return roles


def _roles_of_overrides(names: list[str], index: dict[str, int], overrides) -> dict[str, str]:
    """The explicit assignments, checked: known roles, known joints, no joint for two roles
    (but a wrist may be the fist, an ankle the foot ...)."""
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
    return roles


def _add_roles_from_structure(roles: dict[str, str], names: list[str], par: np.ndarray, off: np.ndarray,
                              end_sites) -> None:
    """The roles the structure finds, for roles and joints not yet taken (in place); a
    structure that cannot be read adds nothing, but two limbs named on one side are an error."""
    try:
        found = roles_from_structure(names, par, off, end_sites)
    except AmbiguousLimbs:
        raise
    except MotionError:
        return  # e.g. every bone along one line: the names decide
    used = set(roles.values())
    for role, joint in found.items():
        if role not in roles and joint not in used:
            roles[role] = joint
            used.add(joint)


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


def _below(j: int, top: int, par: np.ndarray) -> bool:
    """True when joint ``j`` is a descendant of ``top`` (not ``top`` itself)."""
    while j >= 0:
        j = int(par[j])
        if j == top:
            return True
    return False


def _check_limb_chains(index: dict[str, int], par: np.ndarray, roles: dict[str, str]) -> None:
    """Each limb a chain down the tree: the middle joint below the proximal one, the distal one
    below the middle one (twist joints between them, MakeHuman ``upperarm02.L``, are carried
    along by the two-bone IK)."""
    for limb, (a, b, c) in LIMBS.items():
        if a in roles and b in roles and c in roles:
            ia, ib, ic = index[roles[a]], index[roles[b]], index[roles[c]]
            if not _below(ib, ia, par) or not _below(ic, ib, par):
                raise MotionError(
                    f"{limb}: {roles[a]!r} -> {roles[b]!r} -> {roles[c]!r} is not a chain down the tree; "
                    "two-bone IK needs the middle joint below the proximal one and the distal one below "
                    "the middle one"
                )


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


def _check_role_map(roles) -> None:
    if not isinstance(roles, Mapping):
        raise MotionError(f"roles must be a mapping role -> joint name, got {describe(roles)}")


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
