"""Body-part roles read from joint names: the side and the bone a name speaks of.

Pronost et al. (Section 3.4.1) retarget with the limbs of any skeleton; the names of its
joints tell them when the naming convention is known.  A name is read case-insensitively
with any namespace (``mixamorig:``), ``joint_`` prefix or 3ds Max ``Bip01`` prefix
removed; its *side* is a prefix or suffix (``l``/``r`` glued to a bone name as in CMU
``lfemur``, ``Left``/``Right`` as in Mixamo ``LeftUpLeg``, ``_L``/``_R`` as in Bandai
``UpperLeg_L``, Blender ``.L``) and its *base* the rest, without separators, looked up in
:data:`SIDE_BASES` and :data:`CENTER_BASES`.  :func:`is_helper_name` sets aside the joints
that carry no body role (twist bones, fingers, face joints, props).  The finder of
:mod:`repro.motion.body.roles` uses these readings to confirm the roles found from the
tree's structure (:mod:`repro.motion.body.role_structure`) and, when the structure cannot be
read, to find the roles by name alone (:func:`limbs_by_name`, :func:`trunk_by_name`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from functools import lru_cache

from repro.checks import describe
from repro.errors import MotionError

__all__ = ["CENTER_BASES", "SIDE_BASES", "is_clavicle_name", "is_head_name", "is_helper_name", "is_neck_name", "limbs_by_name", "name_side",
           "side_and_base", "stem_votes", "trunk_by_name"]

#: Base names (lower case, alphanumerics only, side removed) of each per-side role stem,
#: best first (``uparm``/``loarm``: the MakeHuman game rig's ``UpArm_L``/``LoArm_L``).  "hand"
#: is the wrist of Mixamo / Bandai skeletons, and the fist (end of the hand bone) of CMU
#: ones, where a separate "wrist" joint exists.
SIDE_BASES: dict[str, tuple[str, ...]] = {
    "clavicle": ("clavicle", "collarbone", "collar", "shoulder"),
    "shoulder": ("humerus", "upperarm", "uparm", "arm", "shldr"),
    "elbow": ("radius", "forearm", "lowerarm", "lowarm", "loarm", "elbow"),
    "wrist": ("wrist", "hand"),
    "hip": ("femur", "upleg", "upperleg", "thigh", "hip"),
    "knee": ("tibia", "lowerleg", "lowleg", "loleg", "leg", "shin", "calf", "knee"),
    "ankle": ("foot", "ankle"),
    "toe": ("toes", "toebase", "toe", "ball"),
}
#: Base names of the trunk roles (a whole name, no side), best first.
CENTER_BASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("hips", "pelvis", "hip", "root"),
    "head": ("head",),
    "neck": ("neck", "lowerneck", "neck1", "upperneck"),
    "spine": ("lowerback", "spine", "abdomen", "spine1", "waist"),
    "chest": ("thorax", "chest", "upperchest", "spine3", "spine2", "spine1", "upperback"),
}
_SEP = r"[_\-. ]"
_LEFT = (re.compile(rf"^(?:left{_SEP}?|l{_SEP}?)(.+)$"), re.compile(rf"^(.+?)(?:{_SEP}?left|{_SEP}l)$"))
_RIGHT = (re.compile(rf"^(?:right{_SEP}?|r{_SEP}?)(.+)$"), re.compile(rf"^(.+?)(?:{_SEP}?right|{_SEP}r)$"))
#: bases that name a bone of another role in other conventions (a stem vote against is no veto)
_AMBIGUOUS_BASES = {"shoulder", "hand", "hip"}

# Joints that never carry a body role: twist / roll / helper bones, fingers, face, props.
_SKIP_PARTS = (
    "twist", "roll", "helper", "nub", "prop", "weapon", "sword", "thumb", "index", "pinky", "pinkie",
    "finger", "carpal", "wing", "tail", "hind", "face", "eye", "jaw", "tongue", "brow", "teeth", "cheek",
    "skirt", "hair", "cape", "breast", "skull", "headtop", "headend", "ik", "pole", "target", "bow",
    "oculi", "orbicularis", "levator", "risorius", "temporalis", "special",  # MakeHuman's face muscles
)  # fmt: skip
# (Rigify's fingers: ``f_ring.01.L``, ``f_middle.01.L``, ``f_index.01.L`` -> ``fring01``, ...)
_SKIP_WHOLE = re.compile(r"^(f?(ring|middle|mid|little)\d*|lip|lid|ear|nose|nostril|oris\d*|hand[a-z]+\d*|fingers?\d*)$")
_SKIP_END = re.compile(r"(end|nub|site|tip)\d*$")


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
def side_and_base(name: str) -> tuple[tuple[str, str], ...]:
    """Possible (side, base) readings of a joint name; base stripped of separators."""
    n = _strip(name)
    out = []
    for side, pats in (("left", _LEFT), ("right", _RIGHT)):
        for p in pats:
            m = p.match(n)
            if m:
                out.append((side, _alnum(m.group(1))))
    return tuple(out)


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
    bases = [b for _, b in side_and_base(name)] or [_alnum(n)]
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
def name_side(name: str) -> str | None:
    """Side read from a name (``Left``/``L_``/``_l``/``.L``/``l`` prefix, ``mShoulderLeft``), or None."""
    n = _strip(name)
    a = _alnum(n)
    if re.search(r"(?<![a-z])left|left$", n) or a.endswith("left") or a.startswith("left"):
        return "left"
    if re.search(r"(?<![a-z])right|right$", n) or a.endswith("right") or a.startswith("right"):
        return "right"
    # a glued l/r prefix or suffix (CMU lfemur) counts only before a body-part word: "lXqT" is no left
    sides = {s for s, b in side_and_base(name) if any(w in b for w in _BODY_WORDS)}
    if re.search(rf"(^|{_SEP})l({_SEP}|$)", n):
        sides.add("left")
    if re.search(rf"(^|{_SEP})r({_SEP}|$)", n):
        sides.add("right")
    return sides.pop() if len(sides) == 1 else None


_BODY_WORDS = tuple(
    sorted({b for bs in SIDE_BASES.values() for b in bs} | {b for bs in CENTER_BASES.values() for b in bs}
           | {"collar", "shldr", "calf", "ball", "clav", "upper", "lower", "fore", "thigh", "abdomen", "torso"})
)


def is_clavicle_name(name: str) -> bool:
    """True for a sided joint named a clavicle (``clavicle.L``, ``LeftCollar``, ``Bip01 L Clavicle``);
    not ``shoulder``, which names the upper arm in other conventions."""
    return any(b in ("clavicle", "collarbone", "collar") for b in _bases(name))


def is_neck_name(name: str) -> bool:
    """True for a joint named a neck (``Neck``, ``LowerNeck``, ``neck_01``, ``mNeck``)."""
    return _alnum(_strip(name)).lstrip("m") in CENTER_BASES["neck"] + ("neck01", "neck2", "neck02")


def is_head_name(name: str) -> bool:
    """True for a joint named the head (``Head``, ``mHead``, ``head1``, ``HeadBone``)."""
    return _alnum(_strip(name)).lstrip("m") in ("head", "head1", "headbone")


@lru_cache(maxsize=8192)
def _bases(name: str) -> frozenset[str]:
    """Side-stripped bases of a name (also without a Second Life ``m`` prefix or a digit suffix)."""
    out = set()
    for _, b in side_and_base(name):
        for c in (b, b.removeprefix("m")):
            out.add(c)
            out.add(c.rstrip("0123456789"))
    return frozenset(out)


@lru_cache(maxsize=8192)
def stem_votes(name: str, stem: str) -> tuple[int, int]:
    """(1 if the name reads as ``stem``, 1 if it reads unambiguously as another limb stem)."""
    bs = _bases(name)
    vote = int(any(b in SIDE_BASES[stem] for b in bs))
    other = int(
        not vote
        and any(b in bases and b not in _AMBIGUOUS_BASES for s, bases in SIDE_BASES.items() if s != stem for b in bs)
    )
    return vote, other


def limbs_by_name(names: list[str], index: dict[str, int], par, roles: dict[str, str], used: set[str]) -> None:
    """Limb joints by name (in place); a "hand" after a separate "wrist" is the fist (CMU lhand).

    ``roles`` already found are kept and ``used`` joints not taken again; with parents
    ``par`` a hand joint must be the child of the wrist."""
    read_as: dict[tuple[str, str], list[str]] = {}  # (side, base) -> the names read so, in joint order
    for n in names:
        for reading in dict.fromkeys(side_and_base(n)):
            read_as.setdefault(reading, []).append(n)
    for side in ("left", "right"):
        for stem, bases in SIDE_BASES.items():
            role = f"{side}_{stem}"
            if role in roles:
                continue
            for base in bases:
                hit = next((n for n in read_as.get((side, base), ()) if n not in used and not n.startswith("__")),
                           None)  # a MakeHuman "__UpLeg_L" is the helper above the bone
                if hit is not None:
                    roles[role] = hit
                    used.add(hit)
                    break
        wrist = roles.get(f"{side}_wrist")
        if f"{side}_hand" not in roles and wrist is not None:
            for n in read_as.get((side, "hand"), ()):
                if n not in used and (par is None or par[index[n]] == index[wrist]):
                    roles[f"{side}_hand"] = n
                    used.add(n)
                    break


def trunk_by_name(role: str, names: Sequence[str], exclude: set[str]) -> str | None:
    """The joint whose whole name is a base of the trunk ``role`` (best base first), or None.

    Joints in ``exclude`` and names that read as a sided limb joint are not taken."""
    for base in CENTER_BASES[role]:
        for n in names:
            if n not in exclude and _alnum(_strip(n)) == base and not _is_limb_name(n):
                return n
    return None


def _is_limb_name(name: str) -> bool:
    """True when ``name`` reads as a sided limb joint (so it is no trunk joint)."""
    return any(base in b for _, base in side_and_base(name) for b in SIDE_BASES.values())
