"""The synthetic actor's skeleton: 21 Mixamo-named joints, metres, Y up, facing +Z.

Human proportions for a 1.75 m actor (:data:`REF_LENGTHS`), scaled uniformly with the
actor height (:func:`synthetic_skeleton`); elbows and knees are hinges
(:data:`HINGE_AXES`) within the flexion limits below.
"""

from __future__ import annotations

import numpy as np

from repro.checks import as_real
from repro.errors import MotionError
from repro.motion.core.motion import Motion

__all__ = [
    "REFERENCE_HEIGHT_M",
    "DEFAULT_FPS",
    "JOINT_NAMES",
    "PARENTS",
    "JOINT_INDEX",
    "HINGE_AXES",
    "ELBOW_FLEXION_LIMITS_DEG",
    "KNEE_FLEXION_LIMITS_DEG",
    "REF_LENGTHS",
    "synthetic_skeleton",
    "scale_of",
]

#: Height of the reference skeleton; every length scales with ``actor_height / 1.75``.
REFERENCE_HEIGHT_M: float = 1.75
#: Default frame rate (the paper's tracking cameras run at 60 Hz).
DEFAULT_FPS: float = 60.0

#: Joint names in file (depth-first) order; parents are listed in :data:`PARENTS`.
JOINT_NAMES: tuple[str, ...] = (
    "Hips",
    "Spine", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
)  # fmt: skip
PARENTS = np.array([-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19])
JOINT_INDEX = {name: j for j, name in enumerate(JOINT_NAMES)}
#: Joints carrying an End Site (head top, fist tips, toe tips), in file order.
_END_SITE_JOINTS = ("Head", "LeftHand", "RightHand", "LeftToeBase", "RightToeBase")
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
_JOINT_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")

#: Hinge joints: the local rotation axis of each elbow and knee.  The local rotation of
#: these joints is always ``Rotation.from_rotvec(theta * axis)`` with the flexion
#: ``theta`` inside the limits below; positive flexion bends the forearm forward
#: (towards +Z of the rest T-pose) and the shin backwards.
HINGE_AXES: dict[str, tuple[float, float, float]] = {
    "LeftForeArm": (0.0, -1.0, 0.0),
    "RightForeArm": (0.0, 1.0, 0.0),
    "LeftLeg": (1.0, 0.0, 0.0),
    "RightLeg": (1.0, 0.0, 0.0),
}
#: Elbow flexion range enforced by the arm IK (degrees; 0 = straight arm).
ELBOW_FLEXION_LIMITS_DEG: tuple[float, float] = (3.0, 150.0)
#: Knee flexion range enforced by the leg IK (degrees; 0 = straight leg).
KNEE_FLEXION_LIMITS_DEG: tuple[float, float] = (3.0, 150.0)

# ---------------------------------------------------------------- skeleton geometry
# Reference lengths (metres) for a 1.75 m actor.  Hips height at rest = 0.06 + 0.42 +
# 0.41 + 0.075 = 0.965; head top = 0.965 + 0.10 + 0.16 + 0.25 + 0.10 + 0.175 = 1.75.
REF_LENGTHS = {
    "hip_height": 0.965,
    "thigh": 0.42,
    "shin": 0.41,
    "ankle": 0.075,  # ankle height above the sole
    "foot": 0.13,  # ankle -> ball of the foot, forward
    "toe": 0.06,
    "upper_arm": 0.30,
    "forearm": 0.26,
    "fist": 0.09,
}
_REF_OFFSETS = {
    "Hips": (0.0, 0.965, 0.0),
    "Spine": (0.0, 0.10, 0.0),
    "Spine1": (0.0, 0.16, 0.0),
    "Neck": (0.0, 0.25, 0.0),
    "Head": (0.0, 0.10, 0.0),
    "LeftShoulder": (0.02, 0.21, 0.0),
    "LeftArm": (0.16, 0.0, 0.0),
    "LeftForeArm": (0.30, 0.0, 0.0),
    "LeftHand": (0.26, 0.0, 0.0),
    "LeftUpLeg": (0.09, -0.06, 0.0),
    "LeftLeg": (0.0, -0.42, 0.0),
    "LeftFoot": (0.0, -0.41, 0.0),
    "LeftToeBase": (0.0, -0.075, 0.13),
}
_REF_END_SITES = {
    "Head": (0.0, 0.175, 0.0),
    "LeftHand": (0.09, 0.0, 0.0),
    "LeftToeBase": (0.0, 0.0, 0.06),
}


def _ref_offset(table: dict, name: str) -> np.ndarray:
    if name in table:
        return np.array(table[name], dtype=float)
    left = "Left" + name[5:]
    v = np.array(table[left], dtype=float)
    v[0] = -v[0]
    return v


def synthetic_skeleton(actor_height: float = REFERENCE_HEIGHT_M) -> Motion:
    """The rest pose (T-pose) of the synthetic actor, as a one-frame :class:`Motion`.

    Parameters
    ----------
    actor_height : float, default 1.75
        Height of the actor in metres (head top in the rest pose), in (0.5, 3].  All
        offsets scale with ``actor_height / 1.75``: proportions are the same for
        every actor.

    Returns
    -------
    Motion
        One frame, identity rotations, the root at its rest height; ``unit_m = 1``.
        Joint names :data:`JOINT_NAMES`; the root has the channels ``Xposition
        Yposition Zposition Zrotation Xrotation Yrotation``, every other joint
        ``Zrotation Xrotation Yrotation`` (Euler order ZXY, intrinsic).  End Sites:
        head top, both fist tips, both toe tips.
    """
    s = scale_of(actor_height)
    offsets = np.stack([_ref_offset(_REF_OFFSETS, n) for n in JOINT_NAMES]) * s
    offsets[JOINT_INDEX["RightShoulder"]] = _ref_offset(_REF_OFFSETS, "RightShoulder") * s
    esp = np.array([JOINT_INDEX[n] for n in _END_SITE_JOINTS])
    eso = np.stack([_ref_offset(_REF_END_SITES, n) for n in _END_SITE_JOINTS]) * s
    channels = [_ROOT_CHANNELS] + [_JOINT_CHANNELS] * (len(JOINT_NAMES) - 1)
    rot = np.zeros((1, len(JOINT_NAMES), 4))
    rot[..., 3] = 1.0
    pos = offsets[None].copy()
    return Motion(
        joint_names=list(JOINT_NAMES),
        parents=PARENTS.copy(),
        offsets=offsets,
        channels=channels,
        frame_time=1.0 / DEFAULT_FPS,
        rotations=rot,
        positions=pos,
        end_site_parents=esp,
        end_site_offsets=eso,
        unit_m=1.0,
        source=f"synthetic rest pose (height {actor_height:g} m)",
    )


def scale_of(actor_height: float) -> float:
    """``actor_height`` (metres, in (0.5, 3]) over :data:`REFERENCE_HEIGHT_M`, else :class:`MotionError`."""
    h = as_real(actor_height, "actor_height (metres)", lo=0.5, lo_open=True, hi=3.0, error=MotionError)
    return h / REFERENCE_HEIGHT_M
