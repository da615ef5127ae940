"""Skeletons of other tools' naming conventions, built from the synthetic actor by renaming and
restructuring (extra spine joints, twist bones, fingers, face joints, zero-length helpers, Z-up,
A-pose).  No third-party file is used: every joint and offset comes from
:func:`repro.motion.database.synthetic.synthetic_skeleton`.  Used by the roles / units / retargeting tests and the cross_skeleton figure."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from repro.checks import as_choice
from repro.errors import MotionError
from repro.motion.core.motion import Motion
from repro.motion.database.synthetic.skeleton import synthetic_skeleton

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

    def fingers(self, hand: str, fmt: str, side_x: float) -> RigConvention:
        for f, z in (("Thumb", 0.03), ("Index", 0.015), ("Middle", 0.0), ("Ring", -0.015), ("Pinky", -0.03)):
            prev = hand
            for k in (1, 2, 3):
                name = fmt.format(f=f, k=k)
                self.add_leaf(prev, name, (side_x * 0.03, 0.0, z if k == 1 else 0.0))
                prev = name
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
    """(rig in metres, expected roles) of a naming convention; roles map the synthetic ones."""
    as_choice(convention, "convention", CONVENTIONS, error=MotionError)
    r = RigConvention.synthetic(height)
    t: dict[str, str]
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
        r.transform(Z_UP)
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
        r.transform(Z_UP)
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
    return r, t


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
    if convention == "blender":
        exp["left_shoulder"] = "upper_arm_helper.L"  # the deepest of the co-located shoulder joints
    return exp
