"""Skeletons of other tools' conventions, generated from the synthetic actor (no third-party file).

Two kinds, both deterministic, every joint and offset from
:func:`repro.motion.database.synthetic.synthetic_skeleton`:

* :func:`build`: the synthetic actor renamed and restructured in a naming convention
  (:data:`CONVENTIONS`: extra spine joints, twist bones, fingers, face joints, zero-length
  helpers, Z-up, A-pose) -- *the same body*, so retargeting onto it must give the source's
  joint positions.  Used by the roles / units / retargeting tests.
* :func:`build_character`: characters whose *bodies* differ from the source actor's too
  (:data:`CHARACTERS`), for the cross-skeleton figure
  (:mod:`repro.experiments.pronost.cross_skeleton`):

  ================ ============= ==================== ===== ===== ======= ===== ===== ======= ====
  character        names         arm / leg / torso    rest  spine fingers toes  twist helpers up, unit
  ================ ============= ==================== ===== ===== ======= ===== ===== ======= ====
  mixamo_cm        Mixamo        0.90 / 1.12 / 1.00   T     3     3       yes   --    0       Y, cm
  unreal_cm        Unreal (UE5)  1.20 / 1.00 / 0.90   A 45  5     3       yes   leaf  1       Z, cm
  biped_inch       3ds Max Biped 1.00 / 0.85 / 1.15   T     1     2       yes   --    1       Z, inch
  rigify_n         Blender .L/.R 1.15 / 0.90 / 1.10   N 85  4     3       yes   chain 1       Z, m
  motionbuilder_mm MotionBuilder 1.10 / 1.20 / 1.00   T     4     --      no    --    0       Y, mm
  secondlife_inch  Second Life   0.85 / 0.90 / 1.20   T     4     3       yes   --    2       Y, inch
  smpl_a           SMPL          1.05 / 0.88 / 1.20   A 45  3     --      yes   --    0       Y, m
  unity_a          Unity         0.80 / 1.00 / 1.10   A 30  3     2       yes   --    0       Y, m
  poser_n_cm       Poser / DAZ   1.15 / 1.10 / 0.85   N 85  2     3       yes   --    0       Y, cm
  ================ ============= ==================== ===== ===== ======= ===== ===== ======= ====

  (arm / leg / torso: length factors against the actor's, before the stature is set; rest:
  degrees the arms hang below horizontal; spine: joints from the pelvis to the neck, the chest
  included; fingers: segments, and then no hand End Site; twist: bones hanging off the limb
  bones, or joints halfway along them, in the chain.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from repro.checks import as_choice
from repro.errors import MotionError
from repro.motion.core.motion import Motion
from repro.motion.database.synthetic.skeleton import JOINT_NAMES, synthetic_skeleton

#: The prefixes of the synthetic actor's side joints.
SIDE_PREFIXES = ("Left", "Right")


@dataclass
class RigConvention:
    """An editable joint list: names, parent names and offsets (metres, Y up, facing +Z)."""

    names: list[str]
    parents: list[str | None]
    offsets: list[np.ndarray]
    end_sites: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def synthetic(cls, height: float = 1.75) -> RigConvention:
        m = synthetic_skeleton(height)
        par = [None if p < 0 else m.joint_names[p] for p in m.parents]
        es = {m.joint_names[p]: np.array(o) for p, o in zip(m.end_site_parents, m.end_site_offsets)}
        return cls(list(m.joint_names), par, [np.array(o, float) for o in m.offsets], es)

    def i(self, name: str) -> int:
        return self.names.index(name)

    def rename(self, table: dict[str, str]) -> RigConvention:
        self.names = [table.get(n, n) for n in self.names]
        self.parents = [None if p is None else table.get(p, p) for p in self.parents]
        self.end_sites = {table.get(k, k): v for k, v in self.end_sites.items()}
        return self

    def insert_above(self, joint: str, new: str, fraction: float = 0.0) -> RigConvention:
        """A new joint between ``joint`` and its parent, ``fraction`` of the bone along (0: zero-length helper)."""
        j = self.i(joint)
        off = self.offsets[j]
        self.names.insert(j, new)
        self.parents.insert(j, self.parents[j])
        self.offsets.insert(j, off * fraction)
        self.parents[j + 1] = new
        self.offsets[j + 1] = off * (1.0 - fraction)
        return self

    def split(self, joint: str, new_names: list[str]) -> RigConvention:
        """Split the bone ending at ``joint`` into len(new_names)+1 equal bones (extra spine joints)."""
        k = len(new_names) + 1
        for n, name in enumerate(new_names):
            self.insert_above(joint, name, 1.0 / (k - n))
        return self

    def add_leaf(self, parent: str, name: str, offset) -> RigConvention:
        j = self.i(parent)
        # after the parent's subtree
        end = j + 1
        while end < len(self.names) and self._is_below(end, parent):
            end += 1
        self.names.insert(end, name)
        self.parents.insert(end, parent)
        self.offsets.insert(end, np.asarray(offset, float))
        return self

    def _is_below(self, j: int, anc: str) -> bool:
        p = self.parents[j]
        while p is not None:
            if p == anc:
                return True
            p = self.parents[self.i(p)]
        return False

    def fingers(self, hand: str, fmt: str, side_x: float, segments: int = 3) -> RigConvention:
        """Five fingers of ``segments`` joints on ``hand``; ``fmt`` names them from ``{f}`` (Thumb ..
        Pinky), ``{lf}`` (thumb .. pinky), ``{i}`` (0 .. 4), ``{k}`` (1 ..) and ``{seg}`` (Proximal,
        Intermediate, Distal)."""
        for i, (f, z) in enumerate((("Thumb", 0.03), ("Index", 0.015), ("Middle", 0.0), ("Ring", -0.015), ("Pinky", -0.03))):
            prev = hand
            for k in range(1, segments + 1):
                name = fmt.format(f=f, lf=f.lower(), i=i, k=k, seg=("Proximal", "Intermediate", "Distal")[k - 1])
                self.add_leaf(prev, name, (side_x * 0.03, 0.0, z if k == 1 else 0.0))
                prev = name
        return self

    def remove(self, joint: str, end_site: bool = False) -> RigConvention:
        """Take ``joint`` out: its children hang from its parent (their offsets lengthened by its
        own).  With ``end_site`` its bone becomes the parent's End Site (no toes: the ankle's
        End Site at the ball of the foot)."""
        j = self.i(joint)
        parent, off = self.parents[j], self.offsets[j]
        for c, p in enumerate(self.parents):
            if p == joint:
                self.parents[c], self.offsets[c] = parent, self.offsets[c] + off
        self.end_sites.pop(joint, None)
        if end_site:
            self.end_sites[parent] = off.copy()
        del self.names[j], self.parents[j], self.offsets[j]
        return self

    def scale_bones(self, joints, k: float, end_sites=()) -> RigConvention:
        """The bones ending at ``joints`` (and the End Sites of ``end_sites``) ``k`` times as long."""
        for n in joints:
            self.offsets[self.i(n)] = self.offsets[self.i(n)] * k
        for n in end_sites:
            self.end_sites[n] = self.end_sites[n] * k
        return self

    def proportions(self, arm: float, leg: float, torso: float) -> RigConvention:
        """Synthetic names: upper arms, forearms and fists ``arm`` times as long, thighs and shins
        ``leg`` times, the spine, neck and clavicle rise ``torso`` times (head and feet kept)."""
        for s in SIDE_PREFIXES:
            self.scale_bones((f"{s}ForeArm", f"{s}Hand"), arm, (f"{s}Hand",))
            self.scale_bones((f"{s}Leg", f"{s}Foot"), leg)
            self.scale_bones((f"{s}Shoulder",), torso)
        return self.scale_bones(("Spine", "Spine1", "Neck"), torso)

    def rest_points(self) -> np.ndarray:
        """(J + E, 3) rest positions of the joints, then of the End Sites."""
        pos: dict[str, np.ndarray] = {}
        for n, p, o in zip(self.names, self.parents, self.offsets):
            pos[n] = o if p is None else pos[p] + o
        return np.array(list(pos.values()) + [pos[k] + v for k, v in self.end_sites.items()])

    def stand(self, height: float) -> RigConvention:
        """Y up: the lowest rest point on the floor (the root lifted, or the joint below it when
        it is a zero-length helper at the origin, Unreal's ``root``), the highest at ``height``
        (scaled uniformly)."""
        y = self.rest_points()[:, 1]
        j = 0 if np.any(self.offsets[0]) else 1
        self.offsets[j] = self.offsets[j] - np.array([0.0, y.min(), 0.0])
        return self.scale(height / float(y.max() - y.min()))

    def scale(self, k: float) -> RigConvention:
        """Every offset ``k`` times as long (another unit, another stature)."""
        self.offsets = [o * k for o in self.offsets]
        self.end_sites = {n: v * k for n, v in self.end_sites.items()}
        return self

    def rotate_subtree(self, joint: str, rot: Rotation) -> RigConvention:
        """Rest-pose change: the offsets of ``joint``'s descendants turned by ``rot`` (A-pose)."""
        for j, n in enumerate(self.names):
            if self._is_below(j, joint):
                self.offsets[j] = rot.apply(self.offsets[j])
        for k in list(self.end_sites):
            if k == joint or self._is_below(self.i(k), joint):
                self.end_sites[k] = rot.apply(self.end_sites[k])
        return self

    def transform(self, rot: Rotation | None = None, scale: float = 1.0) -> RigConvention:
        rot = rot or Rotation.identity()
        self.offsets = [rot.apply(o) * scale for o in self.offsets]
        self.end_sites = {k: rot.apply(v) * scale for k, v in self.end_sites.items()}
        return self

    def motion(self, unit_m: float | None = None, frames: int = 1) -> Motion:
        J = len(self.names)
        parents = np.array([-1 if p is None else self.i(p) for p in self.parents])
        off = np.array(self.offsets)
        rot6 = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
        channels = [rot6] + [("Zrotation", "Xrotation", "Yrotation")] * (J - 1)
        rot = np.zeros((frames, J, 4))
        rot[..., 3] = 1
        esp = np.array([self.i(k) for k in self.end_sites], dtype=int)
        eso = np.array(list(self.end_sites.values())).reshape(-1, 3)
        return Motion(self.names, parents, off, channels, 1 / 60, rot, np.broadcast_to(off, (frames, J, 3)),
                      esp, eso, unit_m=unit_m)


def _sided(fmt_left: str, fmt_right: str, stems: dict[str, str]) -> dict[str, str]:
    out = {}
    for syn, stem in stems.items():
        out["Left" + syn] = fmt_left.format(stem)
        out["Right" + syn] = fmt_right.format(stem)
    return out


_SIDE_STEMS = ("Shoulder", "Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot", "ToeBase")
Z_UP = Rotation.from_euler("x", 90, degrees=True)  # +Y -> +Z, +Z -> -Y (facing -Y)


def a_pose(rig: RigConvention, left_arm: str, right_arm: str, deg: float = 45.0) -> RigConvention:
    rig.rotate_subtree(left_arm, Rotation.from_euler("z", -deg, degrees=True))
    rig.rotate_subtree(right_arm, Rotation.from_euler("z", deg, degrees=True))
    return rig


def build(convention: str, height: float = 1.75) -> tuple[RigConvention, dict[str, str]]:
    """(rig in metres, expected roles) of a naming convention; roles map the synthetic ones.

    The synthetic actor of stature ``height``, renamed and restructured: the same body."""
    as_choice(convention, "convention", CONVENTIONS, error=MotionError)
    r, t, up = _named(convention, RigConvention.synthetic(height))
    if up == "z":
        r.transform(Z_UP)
    return r, t


def _named(convention: str, r: RigConvention) -> tuple[RigConvention, dict[str, str], str]:
    """``r`` (synthetic names, Y up) in a naming convention: (rig, synthetic -> convention names,
    the convention's up axis, applied by the caller)."""
    t: dict[str, str]
    up = "y"
    if convention == "mixamo":
        t = {n: "mixamorig:" + n for n in r.names}
        r.rename(t)
        for s, x in (("Left", 1), ("Right", -1)):
            r.fingers(f"mixamorig:{s}Hand", "mixamorig:" + s + "Hand{f}{k}", x)
        r.add_leaf("mixamorig:Head", "mixamorig:HeadTop_End", (0, 0.17, 0))
        r.add_leaf("mixamorig:LeftToeBase", "mixamorig:LeftToe_End", (0, 0, 0.06))
        r.add_leaf("mixamorig:RightToeBase", "mixamorig:RightToe_End", (0, 0, 0.06))
    elif convention == "motionbuilder":
        t = {"Spine": "Chest", "Spine1": "Chest4"}
        t.update(_sided("Left{}", "Right{}", dict(zip(_SIDE_STEMS, ("Collar", "Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle", "Toe")))))
        r.rename(t).split("Chest4", ["Chest2", "Chest3"])
    elif convention == "poser":
        t = {"Hips": "hip", "Spine": "abdomen", "Spine1": "chest", "Neck": "neck", "Head": "head"}
        t.update(_sided("l{}", "r{}", dict(zip(_SIDE_STEMS, ("Collar", "Shldr", "ForeArm", "Hand", "Thigh", "Shin", "Foot", "Toe")))))
        r.rename(t).fingers("lHand", "l{f}{k}", 1).fingers("rHand", "r{f}{k}", -1)
        r.add_leaf("head", "leftEye", (0.03, 0.05, 0.08)).add_leaf("head", "rightEye", (-0.03, 0.05, 0.08))
    elif convention == "secondlife":
        t = {"Hips": "mPelvis", "Spine": "mTorso", "Spine1": "mChest", "Neck": "mNeck", "Head": "mHead"}
        t.update(_sided("m{}Left", "m{}Right", dict(zip(_SIDE_STEMS, ("Collar", "Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle", "Toe")))))
        r.rename(t).insert_above("mTorso", "mSpine1", 0.0).insert_above("mTorso", "mSpine2", 0.0)
        r.add_leaf("mHead", "mSkull", (0, 0.12, 0)).add_leaf("mHead", "mFaceRoot", (0, 0.05, 0.05))
        r.add_leaf("mFaceRoot", "mFaceJaw", (0, -0.05, 0.02)).add_leaf("mFaceRoot", "mFaceEyeAltLeft", (0.03, 0.03, 0.04))
        r.fingers("mWristLeft", "mHand{f}{k}Left", 1).fingers("mWristRight", "mHand{f}{k}Right", -1)
    elif convention == "biped":
        t = {"Hips": "Bip01 Pelvis", "Spine": "Bip01 Spine", "Spine1": "Bip01 Spine1", "Neck": "Bip01 Neck", "Head": "Bip01 Head"}
        t.update(_sided("Bip01 L {}", "Bip01 R {}", dict(zip(_SIDE_STEMS, ("Clavicle", "UpperArm", "Forearm", "Hand", "Thigh", "Calf", "Foot", "Toe0")))))
        r.rename(t).insert_above("Bip01 Pelvis", "Bip01", 1.0)  # root carries the rest height
        up = "z"
    elif convention == "smpl":
        t = {"Hips": "Pelvis", "Spine": "Spine1", "Spine1": "Spine3", "Neck": "Neck", "Head": "Head"}
        t.update(_sided("L_{}", "R_{}", dict(zip(_SIDE_STEMS, ("Collar", "Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle", "Foot")))))
        r.rename(t).split("Spine3", ["Spine2"])
        r.add_leaf("L_Wrist", "L_Hand", (0.08, 0, 0)).add_leaf("R_Wrist", "R_Hand", (-0.08, 0, 0))
        a_pose(r, "L_Shoulder", "R_Shoulder")
    elif convention == "unreal":
        t = {"Hips": "pelvis", "Spine": "spine_01", "Spine1": "spine_03", "Neck": "neck_01", "Head": "head"}
        t.update(_sided("{}_l", "{}_r", dict(zip(_SIDE_STEMS, ("clavicle", "upperarm", "lowerarm", "hand", "thigh", "calf", "foot", "ball")))))
        r.rename(t).split("spine_03", ["spine_02"]).insert_above("pelvis", "root", 0.0)
        for s, x in (("l", 1), ("r", -1)):
            r.add_leaf(f"upperarm_{s}", f"upperarm_twist_01_{s}", (x * 0.1, 0, 0))
            r.add_leaf(f"lowerarm_{s}", f"lowerarm_twist_01_{s}", (x * 0.15, 0, 0))
            r.add_leaf(f"thigh_{s}", f"thigh_twist_01_{s}", (0, -0.2, 0))
            r.add_leaf(f"calf_{s}", f"calf_twist_01_{s}", (0, -0.2, 0))
        up = "z"
    elif convention == "unity":
        t = {"Spine1": "Chest"}
        t.update(_sided("Left{}", "Right{}", dict(zip(_SIDE_STEMS, ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot", "Toes")))))
        r.rename(t)
        a_pose(r, "LeftUpperArm", "RightUpperArm", 30.0)
    elif convention == "blender":
        t = {"Hips": "hips", "Spine": "spine", "Spine1": "chest", "Neck": "neck", "Head": "head"}
        t.update(_sided("{}.L", "{}.R", dict(zip(_SIDE_STEMS, ("shoulder", "upper_arm", "forearm", "hand", "thigh", "shin", "foot", "toe")))))
        r.rename(t).insert_above("forearm.L", "upper_arm_helper.L", 0.0)
    elif convention == "unsided":
        # no side in the names: left/right from the rest pose (toes forward, left = up x forward)
        t = {n: n.replace("Left", "A_").replace("Right", "B_") for n in r.names if n.startswith(("Left", "Right"))}
        r.rename(t)
    else:
        raise KeyError(convention)
    return r, t, up


CONVENTIONS = ("mixamo", "motionbuilder", "poser", "secondlife", "biped", "smpl", "unreal", "unity", "blender", "unsided")

#: Roles of the synthetic skeleton (Mixamo names).
SYNTHETIC_ROLES = {
    "pelvis": "Hips", "spine": "Spine", "chest": "Spine1", "neck": "Neck", "head": "Head",
    **{f"{s.lower()}_{k}": f"{s}{v}" for s in SIDE_PREFIXES for k, v in (
        ("clavicle", "Shoulder"), ("shoulder", "Arm"), ("elbow", "ForeArm"), ("wrist", "Hand"), ("hip", "UpLeg"),
        ("knee", "Leg"), ("ankle", "Foot"), ("toe", "ToeBase"), ("fist", "Hand"), ("foot", "ToeBase"))},
}  # fmt: skip


def expected_roles(convention: str) -> dict[str, str]:
    _r, t = build(convention)
    exp = {k: t.get(v, v) for k, v in SYNTHETIC_ROLES.items()}
    if convention == "smpl":
        exp.update(left_hand="L_Hand", right_hand="R_Hand", left_fist="L_Hand", right_fist="R_Hand")
    if convention == "secondlife":
        exp["spine"] = "mSpine1"  # first joint after the pelvis (zero-length, like CMU's lowerback)
    return exp


# ---------------------------------------------------------------- characters of other bodies
#: Metres per file unit of the characters' units.
UNITS_M = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}
#: The roles of the body a character is compared on (trunk and the joints of the four limbs).
LIMB_ROLES = ("pelvis", "chest", "neck", "head") + tuple(
    f"{s}_{k}" for s in ("left", "right") for k in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe"))
#: Degrees the arms hang below horizontal in each rest pose (T, A, N).
REST_POSE_DEG = {"T": 0.0, "A": 45.0, "N": 85.0}


@dataclass(frozen=True)
class Character:
    """A generated character: a naming convention (:func:`build`) and how its body differs from
    the synthetic actor's.  The fields say what :func:`build_character` makes (a test checks them).

    Attributes
    ----------
    convention : str
        The naming convention (its restructuring included: extra joints, face, fingers).
    arm, leg, torso : float
        Length factors of the upper arms, forearms and fists; thighs and shins; spine, neck
        and clavicles (:meth:`RigConvention.proportions`), before the stature is set.
    rest_pose : str
        ``"T"`` (arms horizontal), ``"A"`` (arms 45 deg down; Unity's 30) or ``"N"`` (85 deg down).
    spine : int
        Joints between the pelvis and the neck (the chest, where the clavicles hang, included).
    fingers : int
        Segments per finger (0: none); a hand with fingers has no End Site.
    toes : bool
        False: no toe joints, the ankle's End Site at the ball of the foot.
    twist : str
        ``"none"``, ``"leaf"`` (twist bones hanging off the limb bones, Unreal) or ``"chain"``
        (a twist joint halfway along each upper arm, forearm, thigh and shin).
    helpers : int
        Zero-length helper joints.
    up, unit : str
        Up axis (``"y"``, ``"z"``) and file unit (:data:`UNITS_M`).
    """

    convention: str
    arm: float
    leg: float
    torso: float
    rest_pose: str
    spine: int
    fingers: int
    toes: bool
    twist: str
    helpers: int
    up: str
    unit: str

    def describe(self) -> str:
        """One line: what differs from the source actor."""
        fingers = f"{self.fingers}-segment fingers" if self.fingers else "no fingers"
        twist = {"none": "no twist bones", "leaf": "twist bones off the limbs", "chain": "twist joints in the limb chains"}
        return (f"{self.convention} names; arm x{self.arm:g}, leg x{self.leg:g}, torso x{self.torso:g}; "
                f"{self.rest_pose}-pose; {_count(self.spine, 'spine joint')}; {fingers}; {'toes' if self.toes else 'no toes'}; "
                f"{twist[self.twist]}; {_count(self.helpers, 'zero-length helper')}; {self.up.upper()} up, {self.unit}")


def _count(n: int, what: str) -> str:
    return f"{n} {what}" + ("" if n == 1 else "s")


#: The characters of the cross-skeleton figure: each convention's tree on a body whose arm, leg
#: and torso proportions differ from the source actor's by 10-25 %.
CHARACTERS: dict[str, Character] = {
    "mixamo_cm": Character("mixamo", 0.90, 1.12, 1.00, "T", 3, 3, True, "none", 0, "y", "cm"),
    "unreal_cm": Character("unreal", 1.20, 1.00, 0.90, "A", 5, 3, True, "leaf", 1, "z", "cm"),
    "biped_inch": Character("biped", 1.00, 0.85, 1.15, "T", 1, 2, True, "none", 1, "z", "inch"),
    "rigify_n": Character("blender", 1.15, 0.90, 1.10, "N", 4, 3, True, "chain", 1, "z", "m"),
    "motionbuilder_mm": Character("motionbuilder", 1.10, 1.20, 1.00, "T", 4, 0, False, "none", 0, "y", "mm"),
    "secondlife_inch": Character("secondlife", 0.85, 0.90, 1.20, "T", 4, 3, True, "none", 2, "y", "inch"),
    "smpl_a": Character("smpl", 1.05, 0.88, 1.20, "A", 3, 0, True, "none", 0, "y", "m"),
    "unity_a": Character("unity", 0.80, 1.00, 1.10, "A", 3, 2, True, "none", 0, "y", "m"),
    "poser_n_cm": Character("poser", 1.15, 1.10, 0.85, "N", 2, 3, True, "none", 0, "y", "cm"),
}  # fmt: skip


def _chain_twists(r: RigConvention, bones: list[tuple[str, str]]) -> None:
    """A twist joint halfway along each (bone start ``x.L``, bone end) pair, named ``x_twist.L``."""
    for start, end in bones:
        r.insert_above(end, start[:-2] + "_twist" + start[-2:], 0.5)


def _restructure(name: str, r: RigConvention, n) -> dict[str, str]:
    """The per-character changes of the named rig ``r`` (Y up, metres); ``n`` maps a synthetic
    joint name to the convention's.  Returns the joints renamed (old -> new name)."""
    sides = (("Left", 1.0), ("Right", -1.0))
    renamed: dict[str, str] = {}
    if name == "mixamo_cm":  # Spine, Spine1, Spine2 (chest); fingertips instead of a hand End Site
        renamed = {"mixamorig:Spine1": "mixamorig:Spine2"}
        r.rename(renamed).split("mixamorig:Spine2", ["mixamorig:Spine1"])
    elif name == "unreal_cm":  # UE5's spine_01 .. spine_05, fingers index_01_l ..
        renamed = {"spine_03": "spine_05"}
        r.rename(renamed).split("spine_05", ["spine_03", "spine_04"])
        for (s, x), k in zip(sides, "lr"):
            r.fingers(f"hand_{k}", "{lf}_0{k}_" + k, x)
    elif name == "biped_inch":  # one spine link; Biped's two-segment fingers
        r.remove("Bip01 Spine1")
        for (s, x), k in zip(sides, "LR"):
            r.fingers(f"Bip01 {k} Hand", f"Bip01 {k} Finger{{i}}{{k}}", x, segments=2)
    elif name == "rigify_n":  # spine .. spine.003; fingers f_index.01.L ..; twist joints in the limb chains
        renamed = {"chest": "spine.003"}
        r.rename(renamed).split("spine.003", ["spine.001", "spine.002"])
        for s in "LR":
            r.fingers(f"hand.{s}", "f_{lf}.0{k}." + s, 1.0 if s == "L" else -1.0)
            _chain_twists(r, [(f"upper_arm.{s}", f"forearm.{s}"), (f"forearm.{s}", f"hand.{s}"),
                              (f"thigh.{s}", f"shin.{s}"), (f"shin.{s}", f"foot.{s}")])
    elif name == "motionbuilder_mm":  # no toe joints
        r.remove("LeftToe", end_site=True).remove("RightToe", end_site=True)
    elif name == "unity_a":  # Spine, Chest, UpperChest; two-segment fingers (LeftIndexProximal ..)
        renamed = {"Chest": "UpperChest"}
        r.rename(renamed).split("UpperChest", ["Chest"])
        for s, x in sides:
            r.fingers(f"{s}Hand", s + "{f}{seg}", x, segments=2)
    spec = CHARACTERS[name]
    if spec.fingers:
        for s, _x in sides:
            r.end_sites.pop(n(f"{s}Hand"), None)
    if spec.rest_pose != "T" and spec.convention not in ("smpl", "unity"):  # those two are A-posed already
        a_pose(r, n("LeftArm"), n("RightArm"), REST_POSE_DEG[spec.rest_pose])
    return renamed


def build_character(name: str, height: float = 1.75) -> tuple[Motion, dict[str, str]]:
    """(rest pose, expected roles) of a generated character (:data:`CHARACTERS`), ``height`` m tall.

    The synthetic actor with the character's proportions, in its naming convention and
    restructured, standing on the floor with the top of its head at ``height``, then turned
    to its up axis and written in its unit (``unit_m`` set).  Deterministic; no file read.
    The expected roles are the body roles of :data:`LIMB_ROLES` on the joints of the synthetic
    actor's (the chest: where the clavicles hang; no toe role without toes).
    """
    as_choice(name, "character", tuple(CHARACTERS), error=MotionError)
    spec = CHARACTERS[name]
    r = RigConvention.synthetic().proportions(spec.arm, spec.leg, spec.torso)
    r, t, _up = _named(spec.convention, r)
    renamed = _restructure(name, r, lambda s: t.get(s, s))
    names = {syn: renamed.get(t.get(syn, syn), t.get(syn, syn)) for syn in JOINT_NAMES}
    exp = {k: names[SYNTHETIC_ROLES[k]] for k in LIMB_ROLES if names[SYNTHETIC_ROLES[k]] in r.names}
    exp["chest"] = r.parents[r.i(names["LeftShoulder"])]
    r.stand(height)
    unit_m = UNITS_M[spec.unit]
    if spec.up == "z":
        r.transform(Z_UP)
    return r.scale(1.0 / unit_m).motion(unit_m=unit_m), exp
