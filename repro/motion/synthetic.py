"""A synthetic kung-fu motion database, generated without any downloaded data.

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.2 ("Design of the database"), build their motion database
from about 75 motion-captured kung-fu moves (punches and kicks) stored as BVH files,
each annotated with the hit segment (e.g. the right hand or the left foot), the
semantics (punching or kicking), the hit time and the trajectory of the hit point with
its bounding box.  Those captures are not available, so this module *synthesises* a
database of the same shape: an actor performing straight punches and front, side and
round kicks with either side at three target heights, plus a few idle fighting-stance
clips, written as BVH files with a ``manifest.csv`` holding the annotations.

What is synthetic
-----------------
Everything.  The clips are procedural keyframe animation, not motion capture: a
hand-designed timeline (fighting stance, wind-up or knee chamber, strike, hit, recoil,
back to the stance) whose timing, amplitudes, stance dimensions, guard, target height
and hit flexion are drawn from a seeded :class:`numpy.random.Generator`, so the same
seed gives byte-identical files.  The clips have none of the subtleties of captured
motion (no noise, no secondary motion, no balance dynamics).  They exist so that the
BVH -> annotated database -> retrieval -> adaptation pipeline of the paper runs end to
end without data, and so that its tests have data with *known* ground truth (hit frame,
hit joint, target height, planted feet).

What "plausible" means here (each property is checked by the tests)
-------------------------------------------------------------------
* **Skeleton**: 21 joints with Mixamo/cgspeed names (:data:`JOINT_NAMES`), metres,
  Y up, the actor facing +Z in the rest pose (a T-pose) with +X on the actor's left;
  human proportions scaled uniformly with the actor height (:func:`synthetic_skeleton`).
* **Smoothness**: every degree of freedom is a keyframe track interpolated with
  ease curves whose slope vanishes at the keys (quintic smootherstep, C2; the strike
  segment uses ``5u^4 - 4u^5``, C1), so positions and rotations are continuous with
  continuous velocity; directions are slerped, rotations blended by quaternion slerp.
* **Joint limits**: elbows and knees are hinges: their local rotation is a single
  rotation about a fixed axis (:data:`HINGE_AXES`) by a flexion angle within
  :data:`ELBOW_FLEXION_LIMITS_DEG` / :data:`KNEE_FLEXION_LIMITS_DEG` (3 to 150
  degrees): they bend one way only and never hyperextend.  Limbs are posed by analytic
  two-bone inverse kinematics that clamps the flexion to those limits.  Other joints
  (hips, shoulders, spine, ankles, toes) are *not* range-limited; see Limitations.
* **Planted feet**: a foot on the ground is solved by leg IK to a fixed world position
  and orientation, so it does not slide at all (to rounding).  Around a kick's lift-off
  and touch-down the kicking foot pivots on the ball of the foot (heel raised, ball and
  toes fixed on the ground), as real kickers do.  The root height is chosen per frame,
  smoothly, so that every planted leg reaches its foot with the knee bent by at least
  about 16 degrees (20 in double support); :func:`synthetic_clip` raises
  :class:`~repro.errors.MotionError` if a planted foot would miss its place by more
  than a micrometre.  The feet and toes stay above the ground (to about 2 mm).
* **Clear hit**: at the annotated hit frame the striking limb is extended (elbow
  flexion 6-14 degrees for punches, knee flexion 5-10 for kicks), the hit point
  (:data:`HIT_POINTS`) is at the target height of the level
  (:data:`TARGET_HEIGHT_FRACTION` of the actor height, to a micrometre) and at its
  largest distance from the shoulder or hip joint over the clip; the strike accelerates
  then decelerates into the hit, so the hit point's speed peaks a few frames (2-5 at
  60 fps) before the hit frame, at about 6-12 m/s for punches and 6-17 m/s for kicks.
  (At 30 fps a strike lasts only 4-7 frames and the sampled peak can be missed.)

Limitations
-----------
No physics: the centre of mass is moved over the support foot by design, not by a
balance model.  No hand, finger or forearm-twist animation; the head is turned 80 %
of the way towards the target.  The support foot never pivots, so in side and round
kicks the support hip twists by up to about 60 degrees relative to the foot.  Shoulder,
hip, spine and ankle rotations are not range-limited (only designed to stay moderate).
Near full extension the two-bone IK makes the knee or elbow angle change fast in the
last frames before the hit (up to about 40 degrees per frame at 60 fps).  Kicks use the
rear leg, punches the rear hand; every clip starts and ends in the same stance, and the
target is always straight ahead (+Z).

Example
-------
>>> motion, ann = synthetic_clip("kick_round", "right", "high", actor_height=1.8, seed=3)
>>> ann["semantics"], ann["hit_joint"]
('kick', 'RightFoot')
"""

from __future__ import annotations

import csv
import dataclasses
import errno
import hashlib
import io
import math
import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from repro.errors import MotionError
from repro.motion.bvh import write_bvh
from repro.motion.motion import Motion, euler_to_quat, quat_multiply, quat_rotate

__all__ = [
    "KINDS",
    "STRIKE_KINDS",
    "SIDES",
    "LEVELS",
    "SEMANTICS",
    "JOINT_NAMES",
    "HINGE_AXES",
    "HIT_POINTS",
    "ELBOW_FLEXION_LIMITS_DEG",
    "KNEE_FLEXION_LIMITS_DEG",
    "TARGET_HEIGHT_FRACTION",
    "REFERENCE_HEIGHT_M",
    "DEFAULT_FPS",
    "MANIFEST_NAME",
    "MANIFEST_COLUMNS",
    "SyntheticDatabase",
    "synthetic_skeleton",
    "synthetic_clip",
    "synthetic_database",
    "database_actor_heights",
    "read_manifest",
    "hit_point_trajectory",
]

# ---------------------------------------------------------------- public constants
#: Motion kinds; the four strikes, then the idle fighting stance.
KINDS: tuple[str, ...] = ("punch", "kick_front", "kick_side", "kick_round", "stance")
#: The kinds that have a hit.
STRIKE_KINDS: tuple[str, ...] = KINDS[:4]
#: Striking side (the hand or foot that hits); for ``"stance"``, the side held back.
SIDES: tuple[str, ...] = ("left", "right")
#: Target heights; see :data:`TARGET_HEIGHT_FRACTION`.
LEVELS: tuple[str, ...] = ("high", "middle", "low")
#: Semantics of each kind, as annotated in the paper (Section 3.2.1).
SEMANTICS: dict[str, str] = {
    "punch": "punch",
    "kick_front": "kick",
    "kick_side": "kick",
    "kick_round": "kick",
    "stance": "other",
}
#: Height of the reference skeleton; every length scales with ``actor_height / 1.75``.
REFERENCE_HEIGHT_M: float = 1.75
#: Default frame rate (the paper's tracking cameras run at 60 Hz).
DEFAULT_FPS: float = 60.0

#: Joint names in file (depth-first) order; parents are listed in :data:`_PARENTS`.
JOINT_NAMES: tuple[str, ...] = (
    "Hips",
    "Spine", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
)  # fmt: skip
_PARENTS = np.array([-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19])
_J = {name: j for j, name in enumerate(JOINT_NAMES)}
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

#: Hit point of each strike kind: ``(joint suffix, where)``; ``where`` is
#: ``"end_site"`` (the joint's End Site: the fist) or ``"joint"`` (the joint itself:
#: the ball of the foot for front kicks, the ankle for side kicks (heel) and round
#: kicks (instep)).  The joint name is ``"Left"`` or ``"Right"`` + suffix.
HIT_POINTS: dict[str, tuple[str, str]] = {
    "punch": ("Hand", "end_site"),
    "kick_front": ("ToeBase", "joint"),
    "kick_side": ("Foot", "joint"),
    "kick_round": ("Foot", "joint"),
}
#: Target height of the hit point, as a fraction of the actor height, per semantics and
#: level (face, chest, belly for punches; head, ribs, thigh for kicks).  Each clip adds
#: a uniform jitter of +-0.02 of the height.
TARGET_HEIGHT_FRACTION: dict[str, dict[str, float]] = {
    "punch": {"high": 0.90, "middle": 0.72, "low": 0.56},
    "kick": {"high": 0.86, "middle": 0.60, "low": 0.32},
}

#: File name of the database manifest.
MANIFEST_NAME = "manifest.csv"
#: Columns of the manifest, in order.  ``hit_frame`` is -1 and the ``hit_*`` fields are
#: empty for stance clips; ``hit_x_m``... is the hit point's world position at the hit
#: frame; ``clip_seed`` regenerates the clip with :func:`synthetic_clip`; ``unit_m`` is
#: the metres per BVH length unit (always 1).
MANIFEST_COLUMNS: tuple[str, ...] = (
    "file", "kind", "semantics", "side", "level", "hit_joint", "hit_frame",
    "actor_height_m", "frames", "frame_time", "sha256",
    "hit_point", "hit_x_m", "hit_y_m", "hit_z_m", "clip_seed", "unit_m",
)  # fmt: skip

# ---------------------------------------------------------------- skeleton geometry
# Reference lengths (metres) for a 1.75 m actor.  Hips height at rest = 0.06 + 0.42 +
# 0.41 + 0.075 = 0.965; head top = 0.965 + 0.10 + 0.16 + 0.25 + 0.10 + 0.175 = 1.75.
_REF = {
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
    s = _scale(actor_height)
    offsets = np.stack([_ref_offset(_REF_OFFSETS, n) for n in JOINT_NAMES]) * s
    offsets[_J["RightShoulder"]] = _ref_offset(_REF_OFFSETS, "RightShoulder") * s
    esp = np.array([_J[n] for n in _END_SITE_JOINTS])
    eso = np.stack([_ref_offset(_REF_END_SITES, n) for n in _END_SITE_JOINTS]) * s
    channels = [_ROOT_CHANNELS] + [_JOINT_CHANNELS] * (len(JOINT_NAMES) - 1)
    rot = np.zeros((1, len(JOINT_NAMES), 4))
    rot[..., 3] = 1.0
    pos = offsets[None].copy()
    return Motion(
        joint_names=list(JOINT_NAMES),
        parents=_PARENTS.copy(),
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


def _scale(actor_height: float) -> float:
    h = float(actor_height)
    if not np.isfinite(h) or not 0.5 < h <= 3.0:
        raise MotionError(f"actor_height must be a height in metres in (0.5, 3], got {actor_height!r}")
    return h / REFERENCE_HEIGHT_M


# ---------------------------------------------------------------- small maths helpers
_X, _Y, _Z = np.eye(3)


def _ease_smooth(u):
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def _ease_strike(u):  # speed 20 u^3 (1 - u): peaks at u = 0.75, zero at both ends
    return u**4 * (5.0 - 4.0 * u)


_EASES = {"smooth": _ease_smooth, "strike": _ease_strike}


def _track(t: np.ndarray, keys: Sequence[tuple[float, object]], eases: Sequence[str] | None = None) -> np.ndarray:
    """Evaluate a keyframe track at frames ``t``: ``v_i + (v_{i+1} - v_i) ease(u)`` per segment.

    Constant before the first and after the last key.  Every ease has zero slope at both
    ends, so the track is C1 with zero velocity at the keys.
    """
    kt = np.array([k[0] for k in keys], dtype=float)
    kv = np.array([np.asarray(k[1], dtype=float) for k in keys])
    if np.any(np.diff(kt) <= 0):
        raise MotionError(f"internal error: key frames not increasing: {kt}")
    eases = eases or ["smooth"] * (len(keys) - 1)
    out = np.empty((len(t),) + kv.shape[1:])
    out[t <= kt[0]] = kv[0]
    out[t >= kt[-1]] = kv[-1]
    for i in range(len(kt) - 1):
        m = (t > kt[i]) & (t < kt[i + 1])
        u = (t[m] - kt[i]) / (kt[i + 1] - kt[i])
        s = _EASES[eases[i]](u).reshape((-1,) + (1,) * (kv.ndim - 1))
        out[m] = kv[i] + (kv[i + 1] - kv[i]) * s
    # exact values at the keys themselves (t == kt[i] for interior keys)
    for i in range(1, len(kt) - 1):
        out[t == kt[i]] = kv[i]
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _slerp_vec(d0: np.ndarray, d1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit vectors (broadcast), along the shorter great circle."""
    c = np.clip(np.sum(d0 * d1, axis=-1, keepdims=True), -1.0, 1.0)
    om = np.arccos(c)
    so = np.sin(om)
    small = so < 1e-9
    so_safe = np.where(small, 1.0, so)
    s = np.asarray(s, dtype=float)[..., None] if np.ndim(s) == np.ndim(om) - 1 else np.asarray(s, float)
    a = np.where(small, 1.0 - s, np.sin((1.0 - s) * om) / so_safe)
    b = np.where(small, s, np.sin(s * om) / so_safe)
    return _unit(a * d0 + b * d1)


def _dir_track(t: np.ndarray, keys: Sequence[tuple[float, np.ndarray]], eases: Sequence[str]) -> np.ndarray:
    """Keyframed unit vectors, slerped per segment with the given eases."""
    kt = np.array([k[0] for k in keys], dtype=float)
    kv = _unit(np.array([k[1] for k in keys], dtype=float))
    out = np.empty((len(t), 3))
    out[t <= kt[0]] = kv[0]
    out[t >= kt[-1]] = kv[-1]
    for i in range(len(kt) - 1):
        m = (t > kt[i]) & (t < kt[i + 1])
        u = (t[m] - kt[i]) / (kt[i + 1] - kt[i])
        out[m] = _slerp_vec(kv[i][None], kv[i + 1][None], _EASES[eases[i]](u)[:, None])
    for i in range(1, len(kt) - 1):
        out[t == kt[i]] = kv[i]
    return out


def _qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def _qaxis(axis, angle) -> np.ndarray:
    """Quaternions of rotations by ``angle`` (radians, (F,)) about a fixed unit ``axis``."""
    angle = np.asarray(angle, dtype=float)
    axis = np.asarray(axis, dtype=float)
    h = 0.5 * angle[..., None]
    return np.concatenate([np.sin(h) * axis, np.cos(h)], axis=-1)


def _qslerp(q0: np.ndarray, q1: np.ndarray, s) -> np.ndarray:
    """Per-row quaternion slerp (shorter arc), ``s`` in [0, 1] broadcast over rows."""
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    return _slerp_vec(_unit(q0), _unit(q1), np.asarray(s, float).reshape(-1, 1) if np.ndim(s) else s)


def _qpow(q: np.ndarray, k: float) -> np.ndarray:
    r = Rotation.from_quat(q)
    return Rotation.from_rotvec(r.as_rotvec() * k).as_quat()


def _sph(az, el) -> np.ndarray:
    """Unit vector with azimuth ``az`` (from +Z towards +X) and elevation ``el`` (radians)."""
    az, el = np.asarray(az, float), np.asarray(el, float)
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)


def _rad(deg) -> float:
    return math.radians(float(deg))


# ---------------------------------------------------------------- two-bone IK
class _Limb(NamedTuple):
    upper: str  # joint rotated to aim the limb (LeftArm / LeftUpLeg)
    middle: str  # hinge joint (LeftForeArm / LeftLeg)
    end: str  # joint at the target (LeftHand / LeftFoot)
    l1: float
    l2: float
    u: np.ndarray  # rest direction of both bones in the parent's frame
    h: np.ndarray  # hinge axis
    limits: tuple[float, float]  # flexion range, radians


def _limb(prefix: str, kind: str, s: float) -> _Limb:
    if kind == "arm":
        names = (prefix + "Arm", prefix + "ForeArm", prefix + "Hand")
        l1, l2 = _REF["upper_arm"] * s, _REF["forearm"] * s
        u = _X if prefix == "Left" else -_X
        lim = ELBOW_FLEXION_LIMITS_DEG
    else:
        names = (prefix + "UpLeg", prefix + "Leg", prefix + "Foot")
        l1, l2 = _REF["thigh"] * s, _REF["shin"] * s
        u = -_Y
        lim = KNEE_FLEXION_LIMITS_DEG
    h = np.array(HINGE_AXES[names[1]])
    return _Limb(*names, l1, l2, u, h, (math.radians(lim[0]), math.radians(lim[1])))


def _reach(limb: _Limb, flexion: float) -> float:
    """Distance from the upper joint to the end joint at a given flexion (radians)."""
    return math.sqrt(limb.l1**2 + limb.l2**2 + 2 * limb.l1 * limb.l2 * math.cos(flexion))


def _flexion(limb: _Limb, distance: float) -> float:
    """Flexion (radians) at which the limb's end is ``distance`` from its root (clamped)."""
    c = (distance**2 - limb.l1**2 - limb.l2**2) / (2 * limb.l1 * limb.l2)
    return float(np.clip(math.acos(float(np.clip(c, -1.0, 1.0))), *limb.limits))


class _IK(NamedTuple):
    q_upper_world: np.ndarray  # (F, 4)
    q_middle_local: np.ndarray  # (F, 4) hinge rotation
    q_lower_world: np.ndarray  # (F, 4) world rotation of the middle joint's frame
    end: np.ndarray  # (F, 3) position reached by the end joint
    flexion: np.ndarray  # (F,) radians
    miss: np.ndarray  # (F,) distance between target and reached end


def _two_bone(limb: _Limb, root: np.ndarray, target: np.ndarray, pole: np.ndarray) -> _IK:
    """Analytic two-bone IK with the elbow/knee towards ``pole`` and clamped flexion.

    The hinge plane contains the root->target line and the pole direction; the flexion
    is clamped to the limb's limits (the end then misses the target, reported in
    ``miss``).  The upper bone's world rotation maps the rest bone direction ``u`` to the
    solved bone and the local hinge axis ``h`` to the plane normal, so the middle joint's
    local rotation is exactly a rotation about ``h``.
    """
    l1, l2 = limb.l1, limb.l2
    d = target - root
    D = np.linalg.norm(d, axis=-1)
    if np.any(D < 1e-9):
        raise MotionError("internal error: IK target on the limb's root")
    n = d / D[:, None]
    tmin, tmax = limb.limits
    dmax = _reach(limb, tmin)
    dmin = _reach(limb, tmax)
    Dc = np.clip(D, dmin, dmax)
    theta = math.pi - np.arccos(np.clip((l1 * l1 + l2 * l2 - Dc * Dc) / (2 * l1 * l2), -1.0, 1.0))
    alpha = np.arccos(np.clip((l1 * l1 + Dc * Dc - l2 * l2) / (2 * l1 * Dc), -1.0, 1.0))
    b = pole - np.sum(pole * n, axis=-1, keepdims=True) * n
    nb = np.linalg.norm(b, axis=-1)
    if np.any(nb < 1e-6):
        raise MotionError("internal error: IK pole parallel to the limb")
    b = b / nb[:, None]
    a = np.cos(alpha)[:, None] * n + np.sin(alpha)[:, None] * b
    hw = np.cross(b, n)
    g = (theta - alpha)[:, None]
    f = np.cos(g) * n - np.sin(g) * b
    m_world = np.stack([a, hw, np.cross(a, hw)], axis=-1)
    m_local = np.stack([limb.u, limb.h, np.cross(limb.u, limb.h)], axis=-1)
    q_up = Rotation.from_matrix(m_world @ m_local.T).as_quat()
    q_mid = _qaxis(limb.h, theta)
    q_low = quat_multiply(q_up, q_mid)
    end = root + l1 * a + l2 * f
    return _IK(q_up, q_mid, q_low, end, theta, np.linalg.norm(end - target, axis=-1))


# ---------------------------------------------------------------- clip design
class _Leg(NamedTuple):
    """Ground contact design of one leg.

    On the ground the foot is either flat or, around a kick's lift-off and landing,
    pivoting on the ball of the foot (heel raised by ``heel``, toes kept flat by
    bending the toe joint); ``w_pos`` blends from that ground pose (0) to the flight
    design (1).
    """

    yaw: float  # foot yaw on the ground (radians, about +Y)
    ankle: np.ndarray  # (3,) ankle position of the flat foot
    ground_ankle: np.ndarray  # (F, 3) ankle target on the ground (moves only with a raised heel)
    ground_q: np.ndarray  # (F, 4) world rotation of the foot on the ground
    heel: np.ndarray  # (F,) heel-raise angle, radians
    w_pos: np.ndarray  # (F,) 0 = on the ground, 1 = following the flight design


class _Builder:
    """Designs one clip: trunk tracks, then root height, trunk FK, hit target, limb IK."""

    def __init__(self, kind: str, side: str, level: str, actor_height: float, rng: np.random.Generator, fps: float):
        self.kind, self.side, self.level = kind, side, level
        self.height = float(actor_height)
        self.s = _scale(actor_height)
        self.rng = rng
        self.fps = float(fps)
        self.sg = 1.0 if side == "left" else -1.0  # +1: the striking limb is on +X
        self.hit_side = "Left" if self.sg > 0 else "Right"
        self.lead_side = "Right" if self.sg > 0 else "Left"
        self.skel = synthetic_skeleton(actor_height)
        s, sg, r = self.s, self.sg, rng
        # fighting stance: lead foot on the side opposite to the striking limb
        w = r.uniform(0.12, 0.16) * s
        d = r.uniform(0.19, 0.25) * s
        ah = _REF["ankle"] * s
        self.feet = {
            self.lead_side: (np.array([-sg * w, ah, d]), -sg * _rad(r.uniform(10, 20))),
            self.hit_side: (np.array([sg * w, ah, -d]), sg * _rad(r.uniform(35, 50))),
        }
        self.center0 = np.array([r.uniform(-0.01, 0.01) * s, r.uniform(-0.04, -0.01) * s])
        self.yaw0 = sg * _rad(r.uniform(20, 30))
        self.pitch0 = _rad(r.uniform(1, 4))
        self.twist0 = sg * _rad(r.uniform(3, 8))
        self.guard = {  # wrist position and elbow pole in the chest (Spine1) frame
            self.hit_side: (np.array([sg * r.uniform(0.08, 0.12), r.uniform(0.18, 0.22), r.uniform(0.24, 0.28)]) * s,
                            np.array([sg * 0.35, -1.0, -0.1])),
            self.lead_side: (np.array([-sg * r.uniform(0.06, 0.10), r.uniform(0.22, 0.26), r.uniform(0.34, 0.38)]) * s,
                             np.array([-sg * 0.35, -1.0, 0.0])),
        }  # fmt: skip
        self.target_height = None
        self.hit_frame = None
        self.arm_keys: dict[str, tuple[list, list, list]] = {}

    # ------------------------------------------------------------ timeline helpers
    def sec(self, lo: float, hi: float) -> float:
        """A random duration in frames."""
        return self.rng.uniform(lo, hi) * self.fps

    def set_frames(self, last_key: float) -> None:
        self.F = int(math.ceil(last_key)) + 1
        self.t = np.arange(self.F, dtype=float)

    # ------------------------------------------------------------ the three designs
    def design_punch(self) -> None:
        r, s, sg, lv = self.rng, self.s, self.sg, self.level
        f_w = self.sec(0.15, 0.30)
        f_c = f_w + self.sec(0.20, 0.30)
        f_h = float(round(f_c + self.sec(0.20, 0.26)))
        f_r = f_h + self.sec(0.30, 0.40)
        end = f_r + self.sec(0.15, 0.30)
        self.set_frames(end)
        self.hit_frame = int(f_h)
        self.phases = {"windup": f_w, "chamber": f_c, "hit": f_h, "recovered": f_r}
        t = self.t
        y0, p0, tw0 = self.yaw0, self.pitch0, self.twist0
        lean = {"high": (0, 4), "middle": (4, 8), "low": (12, 18)}[lv]
        drop = {"high": 0.0, "middle": 0.03, "low": 0.10}[lv] * s
        keys = [0.0, f_w, f_c, f_h, f_r, end]
        ez = ["smooth", "smooth", "smooth", "smooth", "smooth"]
        yaw_c, yaw_h = y0 + sg * _rad(r.uniform(3, 8)), -sg * _rad(r.uniform(0, 10))  # wind back, turn through
        self.yaw = _track(t, list(zip(keys, [y0, y0, yaw_c, yaw_h, y0, y0])), ez)
        self.pitch = _track(t, list(zip(keys, [p0, p0, p0, _rad(r.uniform(*lean)), p0, p0])), ez)
        self.roll = np.zeros(self.F)
        ez_s = ["smooth", "smooth", "strike", "smooth", "smooth"]
        tw_c, tw_h = sg * _rad(r.uniform(10, 18)), -sg * _rad(r.uniform(12, 22))  # shoulders lag the hips
        twist = _track(t, list(zip(keys, [tw0, tw0, tw_c, tw_h, tw0, tw0])), ez_s)
        lean_h = _rad(r.uniform(5, 10)) if lv == "low" else _rad(r.uniform(0, 3))
        slean = _track(t, list(zip(keys, [0, 0, 0, lean_h, 0, 0])), ez)
        self.spine = np.stack([twist, slean, np.zeros(self.F)], axis=1)
        c0 = self.center0
        lunge = np.array([-sg * 0.03 * s, r.uniform(0.05, 0.09) * s])
        self.root_xz = _track(t, list(zip(keys, [c0, c0, c0 + [0, -0.02 * s], c0 + lunge, c0, c0])), ez)
        self.dy = _track(t, list(zip(keys, [0, 0, -0.01 * s, -drop, 0, 0])), ez)
        prot = _track(t, list(zip(keys, [0, 0, -0.10, _rad(r.uniform(12, 20)), 0, 0])), ez_s)
        self.clav = {self.hit_side: np.stack([prot, np.zeros(self.F)], 1), self.lead_side: np.zeros((self.F, 2))}
        # arms: the striking fist goes guard -> chamber at the hip -> target -> guard;
        # the lead hand reaches out while the other chambers, then pulls back
        g, gp = self.guard[self.hit_side]
        chamber = np.array([sg * r.uniform(0.18, 0.21), r.uniform(-0.12, -0.08), r.uniform(-0.06, -0.02)]) * s
        self.arm_keys[self.hit_side] = (
            [(0.0, g), (f_w, g), (f_c, chamber), (f_h, None), (f_r, g), (end, g)],
            [(0.0, gp), (f_w, gp), (f_c, np.array([sg * 0.3, -0.2, -1.0])), (f_h, np.array([sg * 0.3, -1.0, -0.3])),
             (f_r, gp), (end, gp)],
            ez_s,
        )  # fmt: skip
        lg, lgp = self.guard[self.lead_side]
        reach = lg + np.array([sg * 0.03, -0.02, r.uniform(0.06, 0.12)]) * s
        pulled = np.array([-sg * r.uniform(0.08, 0.12), r.uniform(0.08, 0.14), r.uniform(0.10, 0.16)]) * s
        self.arm_keys[self.lead_side] = (
            [(0.0, lg), (f_w, lg), (f_c, reach), (f_h, pulled), (f_r, lg), (end, lg)],
            [(0.0, lgp), (f_w, lgp), (f_c, lgp), (f_h, np.array([-sg * 0.4, -1.0, -0.6])), (f_r, lgp), (end, lgp)],
            ez,
        )
        self.legs_planted()
        self.flex_hit = _rad(r.uniform(6, 14))
        self.target_height = (TARGET_HEIGHT_FRACTION["punch"][lv] + r.uniform(-0.02, 0.02)) * self.height
        self.target_x = self.center0[0]

    def design_kick(self) -> None:
        r, s, sg, lv, kind = self.rng, self.s, self.sg, self.level, self.kind
        f_ws = self.sec(0.15, 0.30)  # weight starts moving onto the support foot
        shift = self.sec(0.28, 0.36)  # duration of the weight shift (mirrored at the landing)
        heel_lag = self.sec(0.08, 0.14)  # the heel rises that long after the shift starts
        f_ho = f_ws + heel_lag  # the kicking heel starts to rise
        f_l = float(round(f_ws + shift))  # lift-off from the ball of the foot
        li = {"high": 0, "middle": 1, "low": 2}[lv]
        f_c = f_l + self.sec(0.33, 0.43) + (0.12, 0.06, 0.0)[li] * self.fps  # knee chambered
        strike = {"kick_front": (0.19, 0.24), "kick_side": (0.12, 0.16), "kick_round": (0.16, 0.21)}[kind]
        f_h = float(round(f_c + self.sec(*strike)))
        f_r = f_h + self.sec(0.20, 0.28)  # rechambered
        f_d = float(round(f_r + self.sec(0.35, 0.45) + (0.12, 0.06, 0.0)[li] * self.fps))  # touch-down on the ball
        f_e = f_d + shift  # weight back in stance
        f_hd = f_e - heel_lag  # heel down (the lift-off, time-reversed)
        end = f_e + self.sec(0.10, 0.25)
        self.set_frames(end)
        self.hit_frame = int(f_h)
        self.phases = {"weight_shift": f_ws, "heel_off": f_ho, "lift_off": f_l, "chamber": f_c, "hit": f_h,
                       "rechamber": f_r, "touch_down": f_d, "heel_down": f_hd, "recovered": f_e}  # fmt: skip
        t = self.t
        keys = [0.0, f_ws, f_l, f_c, f_h, f_r, f_d, f_e, end]
        ez = ["smooth"] * 8
        y0, p0 = self.yaw0, self.pitch0
        if kind == "kick_front":
            y_h = sg * _rad(r.uniform(-5, 5))
            yc, yr = y_h, y_h
            pitch_h = -_rad(r.uniform(*[(15, 22), (6, 12), (0, 4)][li]))
            roll_h = sg * _rad(r.uniform(0, 4))
            back = np.array([0.0, -0.04 * s])
            kfac = 0.3
        elif kind == "kick_round":
            y_h = -sg * _rad(r.uniform(55, 70))
            yc, yr = -sg * _rad(r.uniform(20, 30)), -sg * _rad(r.uniform(35, 45))
            pitch_h = -_rad(r.uniform(*[(8, 14), (4, 8), (0, 2)][li]))
            roll_h = sg * _rad(r.uniform(*[(15, 22), (8, 12), (2, 6)][li]))
            back = np.array([0.0, -0.03 * s])
            kfac = 0.35
        else:  # kick_side
            y_h = -sg * _rad(r.uniform(65, 75))
            yc, yr = -sg * _rad(r.uniform(55, 62)), -sg * _rad(r.uniform(55, 62))
            pitch_h = -_rad(r.uniform(*[(4, 8), (2, 5), (0, 2)][li]))
            roll_h = sg * _rad(r.uniform(*[(28, 35), (16, 22), (6, 12)][li]))
            back = np.array([0.0, -0.06 * s])
            kfac = 0.3
        yaws = [y0, y0, y0 + 0.3 * (yc - y0), yc, y_h, yr, y0 + 0.4 * (yr - y0), y0, y0]
        self.yaw = _track(t, list(zip(keys, yaws)), ez)
        self.pitch = _track(t, list(zip(keys, [p0, p0, p0, p0 + 0.6 * (pitch_h - p0), pitch_h,
                                               p0 + 0.6 * (pitch_h - p0), p0, p0, p0])), ez)  # fmt: skip
        self.roll = _track(t, list(zip(keys, [0, 0, 0, 0.6 * roll_h, roll_h, 0.6 * roll_h, 0, 0, 0])), ez)
        twist = np.array([self.twist0 - kfac * (y - y0) for y in yaws])
        crunch = _rad(r.uniform(3, 8)) if kind == "kick_front" else 0.0
        self.spine = np.stack([
            _track(t, list(zip(keys, twist)), ez),
            _track(t, list(zip(keys, [0, 0, 0, crunch, 0.3 * crunch, crunch, 0, 0, 0])), ez),
            np.zeros(self.F),
        ], axis=1)  # fmt: skip
        sup_ankle = self.feet[self.lead_side][0]
        c0 = self.center0
        c_sup = np.array([sup_ankle[0] + sg * 0.02 * s, sup_ankle[2] - 0.03 * s])
        # the weight moves over the support foot while the kicking heel rises (85 % at lift-off)
        xz = [c0, c0, c0 + 0.85 * (c_sup - c0), c_sup, c_sup + back, c_sup, c0 + 0.85 * (c_sup - c0), c0, c0]
        self.root_xz = _track(t, list(zip(keys, xz)), ez)
        rise = [0, 0, 0.01, 0.03, 0.04, 0.03, 0.01, 0, 0]
        self.dy = _track(t, list(zip(keys, np.array(rise) * s)), ez)
        self.clav = {self.hit_side: np.zeros((self.F, 2)), self.lead_side: np.zeros((self.F, 2))}
        # arms stay in guard; the kicking side's arm swings down and back for balance
        g, gp = self.guard[self.hit_side]
        low = np.array([sg * r.uniform(0.20, 0.26), r.uniform(-0.14, -0.08), r.uniform(-0.04, 0.02)]) * s
        mid = 0.5 * (g + low) + np.array([sg * 0.04, 0, 0]) * s
        p_low = np.array([sg * 0.3, 0.0, -1.0])
        self.arm_keys[self.hit_side] = (
            list(zip(keys, [g, g, g, mid, low, mid, g, g, g])),
            list(zip(keys, [gp, gp, gp, gp + p_low, p_low, gp + p_low, gp, gp, gp])),
            ez,
        )
        lg, lgp = self.guard[self.lead_side]
        lg2 = lg + np.array([sg * 0.03, 0.02, -0.06]) * s
        self.arm_keys[self.lead_side] = (list(zip(keys, [lg, lg, lg, lg2, lg2, lg2, lg, lg, lg])),
                                         list(zip(keys, [lgp] * 9)), ez)  # fmt: skip
        self.flex_hit = _rad(r.uniform(5, 10))
        self.target_height = (TARGET_HEIGHT_FRACTION["kick"][lv] + r.uniform(-0.02, 0.02)) * self.height
        self.target_x = self.center0[0]
        self.kick_keys = (f_l, f_c, f_h, f_r, f_d)
        self.heel_keys = [(f_ho, 0.0), (f_l, _rad(r.uniform(35, 45))), (f_d, None), (f_hd, 0.0)]
        self.toe_design = {"kick_front": -r.uniform(20, 35), "kick_round": 0.0, "kick_side": -r.uniform(5, 15)}[kind]
        # chamber and rechamber shapes, drawn now so the random stream does not depend on FK
        self.chamber = {
            "thigh_el": _rad([r.uniform(15, 25), r.uniform(-2, 8), r.uniform(-30, -20)][li]),
            "flex": _rad(r.uniform(105, 120)),
            "knee_az": sg * _rad(r.uniform(20, 35)),
            "re": r.uniform(0.9, 1.1),
        }
        self.ankle_design = {"kick_front": r.uniform(35, 45), "kick_round": r.uniform(40, 50),
                             "kick_side": -r.uniform(5, 15)}[kind]  # fmt: skip
        self.legs_planted(kick=True)

    def design_stance(self) -> None:
        r, s = self.rng, self.s
        n = int(r.integers(4, 6))
        step = [self.sec(0.35, 0.5) for _ in range(n)]
        keys = np.concatenate([[0.0], np.cumsum(step)])
        self.set_frames(keys[-1])
        self.hit_frame = -1
        self.phases = {}
        t, K = self.t, len(keys)
        ez = ["smooth"] * (K - 1)

        def jitter(base, amp, fixed_ends=True):
            base = np.asarray(base, float)
            vals = [base + r.uniform(-1, 1, size=base.shape) * amp for _ in range(K)]
            if fixed_ends:
                vals[0] = vals[-1] = base
            return vals

        self.yaw = _track(t, list(zip(keys, jitter(self.yaw0, _rad(3)))), ez)
        self.pitch = _track(t, list(zip(keys, jitter(self.pitch0, _rad(1.5)))), ez)
        self.roll = _track(t, list(zip(keys, jitter(0.0, _rad(1.0)))), ez)
        self.spine = np.stack([_track(t, list(zip(keys, jitter(self.twist0, _rad(3)))), ez),
                               _track(t, list(zip(keys, jitter(0.0, _rad(2)))), ez),
                               np.zeros(self.F)], axis=1)  # fmt: skip
        self.root_xz = _track(t, list(zip(keys, jitter(self.center0, 0.015 * s))), ez)
        dys = [-abs(v) for v in jitter(0.0, 0.02 * s)]
        self.dy = _track(t, list(zip(keys, dys)), ez)
        self.clav = {k: np.zeros((self.F, 2)) for k in ("Left", "Right")}
        for side in ("Left", "Right"):
            g, gp = self.guard[side]
            self.arm_keys[side] = (list(zip(keys, jitter(g, 0.02 * s))), list(zip(keys, [gp] * K)), ez)
        self.legs_planted()
        self.flex_hit = None

    def legs_planted(self, kick: bool = False) -> None:
        s = self.s
        foot = np.array([0.0, -_REF["ankle"], _REF["foot"]]) * s  # ankle -> ball of the foot
        self.legs = {}
        for side, (ankle, yaw) in self.feet.items():
            w = np.zeros(self.F)
            heel = np.zeros(self.F)
            if kick and side == self.hit_side:
                f_l, f_c, f_h, f_r, f_d = self.kick_keys
                w = _track(self.t, [(f_l, 0.0), (f_c, 1.0), (f_r, 1.0), (f_d, 0.0)])
                hk = self.heel_keys
                hk[2] = (hk[2][0], hk[1][1])
                heel = _track(self.t, hk)
            q_yaw = _qaxis(_Y, np.full(self.F, yaw))
            ground_q = quat_multiply(q_yaw, _qaxis(_X, heel))
            ball = ankle + quat_rotate(q_yaw[0], foot)
            ground_ankle = ball - quat_rotate(ground_q, foot[None])
            self.legs[side] = _Leg(yaw, ankle, ground_ankle, ground_q, heel, w)

    # ------------------------------------------------------------ solving
    def trunk_rotations(self) -> np.ndarray:
        """(F, J, 4) local rotations of root, spine, neck, head and clavicles; identity elsewhere."""
        F = self.F
        q = np.zeros((F, len(JOINT_NAMES), 4))
        q[..., 3] = 1.0
        q[:, 0] = euler_to_quat("YXZ", np.stack([self.yaw, self.pitch, self.roll], 1), degrees=False)
        half = 0.5 * self.spine
        q_sp = euler_to_quat("YXZ", half, degrees=False)
        q[:, _J["Spine"]] = q_sp
        q[:, _J["Spine1"]] = q_sp
        chest = quat_multiply(q[:, 0], quat_multiply(q_sp, q_sp))
        # head: 80 % of the way back to facing the target (+Z, upright), split over neck and head
        nh = _qpow(_qconj(chest), 0.4)
        q[:, _J["Neck"]] = nh
        q[:, _J["Head"]] = nh
        for side, sgn in (("Left", 1.0), ("Right", -1.0)):
            prot, elev = self.clav[side][:, 0], self.clav[side][:, 1]
            # protraction brings the shoulder forward (+Z), elevation raises it
            q[:, _J[side + "Shoulder"]] = euler_to_quat("YZ", np.stack([-sgn * prot, sgn * elev], 1), degrees=False)
        return q

    def solve_root_height(self, q: np.ndarray) -> np.ndarray:
        """Root height per frame: the design, lowered smoothly where a planted leg could not reach."""
        off = self.skel.offsets
        L = _REF["thigh"] * self.s + _REF["shin"] * self.s
        bound = np.full(self.F, np.inf)
        stance_bound = np.inf
        for side, leg in self.legs.items():
            hip_rel = quat_rotate(q[:, 0], off[_J[side + "UpLeg"]][None])  # (F, 3)
            planted = leg.w_pos == 0.0
            other_flying = np.any([self.legs[o].w_pos > 0.0 for o in self.legs if o != side], axis=0)
            # knee flexion >= 2 acos(r): 16 deg on a single support leg, 20 deg in double support
            r_max = np.where(other_flying, 0.99, 0.985)
            ga = leg.ground_ankle
            horiz = np.hypot(self.root_xz[:, 0] + hip_rel[:, 0] - ga[:, 0],
                             self.root_xz[:, 1] + hip_rel[:, 2] - ga[:, 2])  # fmt: skip
            ymax = ga[:, 1] - hip_rel[:, 1] + np.sqrt(np.maximum((r_max * L) ** 2 - horiz**2, 0.0))
            bound = np.where(planted, np.minimum(bound, ymax), bound)
            # the stance itself: knees bent by about 26 degrees (r = 0.975)
            y_st = ga[0, 1] - hip_rel[0, 1] + math.sqrt(max((0.975 * L) ** 2 - horiz[0] ** 2, 0.0))
            stance_bound = min(stance_bound, y_st)
        y = stance_bound + self.dy
        excess = np.maximum(y - bound + 1e-6 * self.s, 0.0)
        # lower the root where needed: over each run of frames with an excess, by the
        # run's largest excess, easing in and out over 0.1 s outside the run (C2, and
        # exactly zero elsewhere, so the stance at both ends is untouched)
        k = max(2.0, 0.1 * self.fps)
        t = self.t
        for a, b in _runs(excess > 0):
            up = _ease_smooth(np.clip((t - (a - k)) / k, 0.0, 1.0))
            down = _ease_smooth(np.clip(((b - 1 + k) - t) / k, 0.0, 1.0))
            y = y - excess[a:b].max() * np.minimum(up, down)
        return y

    def chest_pose(self, gq, gp):
        j = _J["Spine1"]
        return gq[:, j], gp[:, j]

    def solve(self) -> tuple[Motion, dict]:
        s, F = self.s, self.F
        q = self.trunk_rotations()
        root = np.column_stack([self.root_xz[:, 0], self.solve_root_height(q), self.root_xz[:, 1]])
        pos = np.broadcast_to(self.skel.offsets, (F, len(JOINT_NAMES), 3)).copy()
        pos[:, 0] = root
        trunk = _replace(self.skel, rotations=q, positions=pos)
        gq, gp = trunk.global_transforms()
        cq, cp = self.chest_pose(gq, gp)

        arms = {side: _limb(side, "arm", s) for side in ("Left", "Right")}
        legs = {side: _limb(side, "leg", s) for side in ("Left", "Right")}
        h = self.hit_frame
        hit_world = None
        if self.kind == "punch":
            hit_world = self.aim_punch(arms[self.hit_side], gq, gp, cq, cp)
        elif self.kind != "stance":
            hit_world = self.aim_kick(legs[self.hit_side], gq, gp)

        # ---- arms
        for side, limb in arms.items():
            wkeys, pkeys, ez = self.arm_keys[side]
            if any(v is None for _, v in wkeys):
                w_chest = quat_rotate(_qconj(cq[h]), hit_world["wrist"] - cp[h])
                wkeys = [(k, w_chest if v is None else v) for k, v in wkeys]
            w_local = _track(self.t, wkeys, ez)
            p_local = _dir_track(self.t, pkeys, ez)
            target = cp + quat_rotate(cq, w_local)
            pole = quat_rotate(cq, p_local)
            ik = _two_bone(limb, gp[:, _J[limb.upper]], target, pole)
            parent = gq[:, _PARENTS[_J[limb.upper]]]
            q[:, _J[limb.upper]] = quat_multiply(_qconj(parent), ik.q_upper_world)
            q[:, _J[limb.middle]] = ik.q_middle_local
            if side == self.hit_side and self.kind == "punch":
                self.check_reached(ik, [h], f"{side} arm at the hit")

        # ---- legs
        self.contacts = {}
        for side, limb in legs.items():
            leg = self.legs[side]
            hip = gp[:, _J[limb.upper]]
            fwd = np.array([math.sin(leg.yaw), 0.0, math.cos(leg.yaw)])
            kicking = side == self.hit_side and self.kind.startswith("kick")
            if kicking:
                fl_target, fl_pole, ankle_local = self.kick_flight(limb, hip, hit_world)
                w = leg.w_pos[:, None]
                ga = leg.ground_ankle
                target = self.soft_reach(limb, hip, ga + w * (fl_target - ga), leg.w_pos)
                pole = (1 - w) * fwd + w * fl_pole
            else:
                target = leg.ground_ankle
                pole = np.broadcast_to(fwd, (F, 3))
                ankle_local = None
            ik = _two_bone(limb, hip, target, pole)
            planted = np.flatnonzero(leg.w_pos == 0.0)
            self.check_reached(ik, planted, f"planted {side} foot")
            if side == self.hit_side and self.kind.startswith("kick"):
                self.check_reached(ik, [h], f"{side} leg at the hit")
            q[:, _J[limb.upper]] = quat_multiply(_qconj(gq[:, 0]), ik.q_upper_world)
            q[:, _J[limb.middle]] = ik.q_middle_local
            ground_local = quat_multiply(_qconj(ik.q_lower_world), leg.ground_q)
            toe = -leg.heel  # keeps the toes flat on the ground while the heel is raised
            if ankle_local is None:
                q[:, _J[limb.end]] = ground_local
            else:
                w_foot = leg.w_pos**3  # the foot turns only once it is off the ground
                q[:, _J[limb.end]] = _qslerp(ground_local, ankle_local, w_foot)
                toe = toe * (1.0 - w_foot) + w_foot * _rad(self.toe_design)
            q[:, _J[side + "ToeBase"]] = _qaxis(_X, toe)
            on_ground = leg.w_pos == 0.0
            self.contacts[side + "Foot"] = _runs(on_ground & (leg.heel == 0.0))
            self.contacts[side + "ToeBase"] = _runs(on_ground)
        motion = _replace(self.skel, rotations=q, positions=pos, frame_time=1.0 / self.fps, source=None)
        return motion, hit_world

    def soft_reach(self, limb: _Limb, hip: np.ndarray, target: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Keep the kicking foot's lift-off and landing blend within reach, smoothly.

        While the foot blends between the ground and the flight design (``0 < w < 1``)
        the hip keeps moving and the blended target can end up slightly beyond the leg's
        reach.  Hip-to-target distances above ``d0 = 0.99 L`` (never reached on planted
        frames) are compressed with ``d0 + k tanh((d - d0) / k)`` below the distance at
        the hit, so the IK never clamps and the leg is longest at the hit.
        """
        rel = target - hip
        d = np.linalg.norm(rel, axis=-1)
        d0 = 0.99 * (limb.l1 + limb.l2)
        k = 0.999 * (_reach(limb, self.flex_hit) - d0)
        m = (w > 0.0) & (w < 1.0) & (d > d0)
        out = target.copy()
        out[m] = hip[m] + rel[m] * ((d0 + k * np.tanh((d[m] - d0) / k)) / d[m])[:, None]
        return out

    @staticmethod
    def check_reached(ik: _IK, frames, what: str) -> None:
        frames = np.asarray(frames, dtype=int)
        if frames.size and np.max(ik.miss[frames]) > 1e-6:
            raise MotionError(f"internal error: {what} out of reach by {np.max(ik.miss[frames]):.3g} m")

    # ------------------------------------------------------------ aiming the hit
    def aim(self, limb: _Limb, S: np.ndarray, pole_fn, end_fn, flex: float) -> dict:
        """Direction of the limb at the hit so that the hit point lands at the target height.

        The limb is posed with flexion ``flex`` (so its reach is fixed) and turned about
        its root ``S`` (elevation and azimuth) until the hit point ``end_fn(ik)`` is at
        the target height above the ground and at the target's lateral position.
        """
        D = _reach(limb, flex)
        el, az = 0.0, 0.0
        for _ in range(8):
            W = S + D * _sph(az, el)
            ik = _two_bone(limb, S[None], W[None], pole_fn(_sph(az, el))[None])
            P = end_fn(ik, W)
            v = P - S
            rho = np.linalg.norm(v)
            el_p = math.asin(np.clip(v[1] / rho, -1, 1))
            el_t = math.asin(np.clip((self.target_height - S[1]) / rho, -0.95, 0.95))
            el = float(np.clip(el + el_t - el_p, -1.2, 1.2))
            hz = math.hypot(v[0], v[2])
            az_p = math.atan2(v[0], v[2])
            az_t = math.asin(np.clip((self.target_x - S[0]) / max(hz, 1e-9), -0.6, 0.6))
            az = float(az + az_t - az_p)
        W = S + D * _sph(az, el)
        ik = _two_bone(limb, S[None], W[None], pole_fn(_sph(az, el))[None])
        return {"wrist": W, "dir": _sph(az, el), "hit_point": end_fn(ik, W), "az": az, "el": el}

    def aim_punch(self, limb, gq, gp, cq, cp) -> dict:
        h = self.hit_frame
        S = gp[h, _J[limb.upper]]
        pole_chest = _unit(self.arm_keys[self.hit_side][1][3][1])
        pole = quat_rotate(cq[h], pole_chest)
        fist = _REF["fist"] * self.s

        def end_fn(ik, W):
            return (W + fist * quat_rotate(ik.q_lower_world, limb.u[None]))[0]

        return self.aim(limb, S, lambda d: pole, end_fn, self.flex_hit)

    def kick_pole(self, dirs: np.ndarray, az_hit: float) -> np.ndarray:
        """Knee direction of the kicking leg for hip->ankle directions ``dirs`` (F, 3).

        Front kick: the knee leads upwards in the vertical plane of the kick; round kick:
        it leads horizontally in the direction of the swing; side kick: horizontally
        (the pelvis faces sideways) and upwards (the knee is lifted in the chamber).
        Each is perpendicular to ``dirs`` and vanishes only for vertical ``dirs`` (round
        and side kicks), where the ground pose dominates the blend.
        """
        if self.kind == "kick_front":
            f = np.array([math.sin(az_hit), 0.0, math.cos(az_hit)])
            return np.cross(np.cross(f, _Y), dirs)
        pole = -self.sg * np.cross(_Y, dirs)
        if self.kind == "kick_side":
            up = _Y - np.sum(dirs * _Y, axis=-1, keepdims=True) * dirs
            pole = pole + 0.6 * np.linalg.norm(pole, axis=-1, keepdims=True) * up
        return pole

    def aim_kick(self, limb, gq, gp) -> dict:
        h = self.hit_frame
        S = gp[h, _J[limb.upper]]
        toe = np.array([0.0, -_REF["ankle"], _REF["foot"]]) * self.s
        ankle_q = _qaxis(_X, _rad(self.ankle_design))

        def end_fn(ik, W):
            if self.kind != "kick_front":
                return W
            return (W + quat_rotate(quat_multiply(ik.q_lower_world, ankle_q[None]), toe[None]))[0]

        def pole_fn(d):
            return self.kick_pole(d[None], math.atan2(d[0], d[2]))[0]

        return self.aim(limb, S, pole_fn, end_fn, self.flex_hit)

    def kick_flight(self, limb: _Limb, hip: np.ndarray, hit: dict):
        """Ankle target, pole and ankle rotation of the kicking leg in flight (hip-relative design)."""
        f_l, f_c, f_h, f_r, f_d = self.kick_keys
        sg, ch = self.sg, self.chamber
        ga = self.legs[self.hit_side].ground_ankle
        il, idd = int(f_l), int(f_d)  # integer frames by construction
        rel_l = ga[il] - hip[il]
        rel_d = ga[idd] - hip[idd]
        az_h, el_h = hit["az"], hit["el"]
        if self.kind == "kick_front":
            te, fx = ch["thigh_el"], ch["flex"]
            # thigh raised to elevation te, shin folded back by fx: (forward, up) of the ankle
            p = limb.l1 * np.array([math.cos(te), math.sin(te)])
            p = p + limb.l2 * np.array([math.cos(te - fx), math.sin(te - fx)])
            fwd = np.array([math.sin(az_h), 0.0, math.cos(az_h)])
            rel_c = p[0] * fwd + p[1] * _Y
        elif self.kind == "kick_round":
            # knee up towards the target, shin folded back and nearly horizontal
            e = el_h - _rad(10)
            fx = ch["flex"]
            rel_c = limb.l1 * _sph(ch["knee_az"], e) + limb.l2 * _sph(ch["knee_az"] + sg * fx, 0.3 * e)
        else:  # side kick: knee to the chest, heel towards the target
            rel_c = 0.42 * (limb.l1 + limb.l2) * _sph(az_h + sg * _rad(10), el_h - _rad(20))
        rel_r = rel_c * ch["re"]
        rel_h = hit["wrist"] - hip[self.hit_frame]
        keys = [(f_l, rel_l), (f_c, rel_c), (f_h, rel_h), (f_r, rel_r), (f_d, rel_d)]
        ez = ["smooth", "strike", "smooth", "smooth"]
        dirs = _dir_track(self.t, keys, ez)
        radius = _track(self.t, [(k, np.linalg.norm(v)) for k, v in keys], ez)
        # during the strike the knee flexion, not the hip-ankle distance, is eased: the knee
        # then slows down into the hit instead of snapping through its last degrees (near
        # full extension the distance hardly changes while the angle changes fast)
        flex = _track(self.t, [(k, _flexion(limb, np.linalg.norm(v))) for k, v in keys], ez)
        strike = (self.t > f_c) & (self.t < f_h)
        radius[strike] = np.sqrt(limb.l1**2 + limb.l2**2 + 2 * limb.l1 * limb.l2 * np.cos(flex[strike]))
        target = hip + radius[:, None] * dirs
        pole = self.kick_pole(dirs, az_h)
        design = _qaxis(_X, np.full(self.F, _rad(self.ankle_design)))
        return target, pole, design


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open ``[start, stop)`` frame ranges where ``mask`` is true."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]




def _replace(m: Motion, **kw) -> Motion:
    return dataclasses.replace(m, **kw)


# ---------------------------------------------------------------- public API: one clip
def _check_choice(name: str, value, allowed) -> str:
    if value not in allowed:
        raise MotionError(f"{name} must be one of {list(allowed)}, got {value!r}")
    return value


def synthetic_clip(
    kind: str,
    side: str = "right",
    level: str = "middle",
    actor_height: float = REFERENCE_HEIGHT_M,
    seed: int | Sequence[int] | np.random.Generator = 0,
    fps: float = DEFAULT_FPS,
) -> tuple[Motion, dict]:
    """Generate one synthetic kung-fu clip and its annotation.

    Parameters
    ----------
    kind : {"punch", "kick_front", "kick_side", "kick_round", "stance"}
        A straight punch with the rear hand from a fist chambered at the hip (with hip
        and shoulder rotation and a small lunge); a front kick (ball of the foot), a
        side kick (heel, the body turned sideways and leaning away) or a round kick
        (instep, the body turning over the support foot), each with the rear leg from
        a knee chamber; or an idle fighting stance (small weight shifts and sway).
    side : {"left", "right"}, default "right"
        The striking hand or foot.  The actor stands with the other foot forward; for
        ``"stance"``, the side held back.
    level : {"high", "middle", "low"}, default "middle"
        Target height of the hit point (:data:`TARGET_HEIGHT_FRACTION`); ignored for
        ``"stance"`` (annotated ``"none"``).
    actor_height : float, default 1.75
        Actor height in metres; the skeleton is :func:`synthetic_skeleton`.
    seed : int, sequence of int or numpy.random.Generator, default 0
        Seed of the per-clip variations (timing, stance width and orientation, guard,
        amplitudes, target height jitter, hit flexion).  Equal seeds give equal clips.
    fps : float, default 60
        Frame rate, in [24, 240].

    Returns
    -------
    motion : Motion
        The clip in metres (``unit_m = 1``), Y up, the opponent towards +Z.
    annotation : dict
        ``kind``, ``semantics`` ("punch", "kick" or "other"), ``side``, ``level``,
        ``hit_joint`` (e.g. ``"RightHand"``; ``""`` for stance), ``hit_point``
        (``"end_site"``: the End Site of ``hit_joint``, ``"joint"``: the joint itself;
        ``""`` for stance), ``hit_frame`` (-1 for stance), ``hit_time`` (s),
        ``hit_position`` (world position of the hit point at the hit frame, m),
        ``target_height_m`` (the designed height), ``actor_height_m``, ``fps``,
        ``frame_time``, ``frames``, ``support_foot`` (joint name of the foot planted
        for the whole clip, for kicks), ``contacts`` (half-open frame ranges
        ``[start, stop)``: under ``"LeftFoot"``/``"RightFoot"`` the frames where that
        foot is flat and fixed, under ``"LeftToeBase"``/``"RightToeBase"`` those where
        the ball of the foot is fixed on the ground, flat or heel raised), ``phases``
        (frame of each key of the timeline) and ``flexion_at_hit_deg`` (elbow or knee
        flexion of the striking limb at the hit).

    Raises
    ------
    repro.errors.MotionError
        For an unknown kind, side or level, an actor height outside (0.5, 3] m or a
        frame rate outside [24, 240]; or (an internal error) if a planted foot or the
        hit could not be reached.
    """
    _check_choice("kind", kind, KINDS)
    _check_choice("side", side, SIDES)
    if kind != "stance":
        _check_choice("level", level, LEVELS)
    fps = float(fps)
    if not np.isfinite(fps) or not 24.0 <= fps <= 240.0:
        raise MotionError(f"fps must be in [24, 240], got {fps!r}")
    _scale(actor_height)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    b = _Builder(kind, side, level if kind != "stance" else "none", actor_height, rng, fps)
    if kind == "punch":
        b.design_punch()
    elif kind == "stance":
        b.design_stance()
    else:
        b.design_kick()
    motion, hit = b.solve()
    motion = _replace(motion, source=f"synthetic:{kind}:{side}:{b.level}:{float(actor_height):g}m")
    ann = {
        "kind": kind,
        "semantics": SEMANTICS[kind],
        "side": side,
        "level": b.level,
        "hit_joint": "",
        "hit_point": "",
        "hit_frame": -1,
        "hit_time": None,
        "hit_position": None,
        "target_height_m": None,
        "actor_height_m": float(actor_height),
        "fps": fps,
        "frame_time": motion.frame_time,
        "frames": motion.n_frames,
        "support_foot": None,
        "contacts": b.contacts,
        "phases": {k: float(v) for k, v in b.phases.items()},
        "flexion_at_hit_deg": None,
    }
    if kind != "stance":
        suffix, where = HIT_POINTS[kind]
        joint = b.hit_side + suffix
        h = b.hit_frame
        ann.update(
            hit_joint=joint,
            hit_point=where,
            hit_frame=h,
            hit_time=h * motion.frame_time,
            hit_position=tuple(float(x) for x in hit_point_trajectory(motion, joint, where)[h]),
            target_height_m=float(b.target_height),
            flexion_at_hit_deg=float(np.degrees(b.flex_hit)),
        )
        if kind != "punch":
            ann["support_foot"] = b.lead_side + "Foot"
    return motion, ann


def hit_point_trajectory(motion: Motion, joint: str, where: str = "joint") -> np.ndarray:
    """(F, 3) world trajectory of a hit point: a joint, or the End Site of a joint.

    Parameters
    ----------
    motion : Motion
        Any motion.
    joint : str
        Joint name (e.g. the annotation's ``hit_joint``).
    where : {"joint", "end_site"}
        The joint's own position, or its (first) End Site.
    """
    j = motion.joint_index(joint)
    if where == "joint":
        return motion.global_positions()[:, j]
    if where == "end_site":
        sites = np.flatnonzero(motion.end_site_parents == j)
        if sites.size == 0:
            raise MotionError(f"joint {joint!r} has no End Site")
        return motion.end_site_positions()[:, sites[0]]
    raise MotionError(f"where must be 'joint' or 'end_site', got {where!r}")


# ---------------------------------------------------------------- public API: the database
class SyntheticDatabase(NamedTuple):
    """What :func:`synthetic_database` wrote.

    Attributes
    ----------
    paths : list of pathlib.Path
        The BVH files, in manifest order.
    manifest_path : pathlib.Path
        The ``manifest.csv``.
    records : list of dict
        The manifest rows, typed as by :func:`read_manifest`.
    """

    paths: list[Path]
    manifest_path: Path
    records: list[dict]


def database_actor_heights(n_actors: int) -> list[float]:
    """Actor heights of a database with ``n_actors`` actors: evenly spaced in [1.60, 1.90] m.

    One actor is 1.75 m; three are 1.60, 1.75 and 1.90 m.
    """
    n = _positive_int("n_actors", n_actors)
    if n == 1:
        return [REFERENCE_HEIGHT_M]
    return [round(float(h), 4) for h in np.linspace(1.60, 1.90, n)]


def _positive_int(name: str, value, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise MotionError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _plan(n_actors: int, seed: int) -> list[dict]:
    """The clips of a database: per actor, every strike kind x side x level, plus one stance."""
    plan = []
    for a, height in enumerate(database_actor_heights(n_actors), start=1):
        combos = [(k, s, lv) for k in STRIKE_KINDS for s in SIDES for lv in LEVELS]
        combos.append(("stance", SIDES[(a - 1) % 2], "none"))
        for kind, side, level in combos:
            name = f"actor{a}_{kind}_{side}" + ("" if kind == "stance" else f"_{level}") + ".bvh"
            index = len(plan)
            clip_seed = int(np.random.SeedSequence([seed, index]).generate_state(1, np.uint32)[0])
            plan.append({"file": name, "kind": kind, "side": side, "level": level, "height": height, "seed": clip_seed})
    return plan


def _manifest_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(MANIFEST_COLUMNS)
    for r in rows:
        w.writerow([r[c] for c in MANIFEST_COLUMNS])
    return buf.getvalue()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def synthetic_database(
    out_dir,
    n_actors: int = 3,
    seed: int = 0,
    *,
    fps: float = DEFAULT_FPS,
    overwrite: bool = False,
) -> SyntheticDatabase:
    """Write the synthetic motion database: BVH clips plus ``manifest.csv``.

    Per actor (heights :func:`database_actor_heights`): every strike kind
    (:data:`STRIKE_KINDS`) x side x level, i.e. 24 clips, plus one stance clip; the
    default three actors give 75 clips, the size of the paper's database (Section 3.2).
    Files are named ``actor{a}_{kind}_{side}_{level}.bvh`` (``actor{a}_stance_{side}.bvh``).
    Clip ``i`` is ``synthetic_clip(..., seed=SeedSequence([seed, i]))``, recorded as
    ``clip_seed`` in the manifest, so every file can be regenerated alone.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Folder to write into (created if missing).  Other files in it are left alone.
    n_actors : int, default 3
        Number of actor sizes.
    seed : int, default 0
        Master seed (>= 0).  The same arguments always give byte-identical files.
    fps : float, default 60
        Frame rate of every clip.
    overwrite : bool, default False
        Policy for existing files.  Every file is first generated in a temporary folder
        inside ``out_dir``; a target that already exists **with identical bytes** is kept
        (so re-running with the same arguments is a no-op); if any target exists with
        *different* content, nothing is written and :class:`FileExistsError` is raised,
        unless ``overwrite=True``, in which case those files are replaced.  Each file is
        moved into place atomically (``os.replace``), the manifest last.

    Returns
    -------
    SyntheticDatabase
        ``(paths, manifest_path, records)``.

    Raises
    ------
    FileExistsError
        If ``out_dir`` holds a BVH file or manifest of the same name with other content
        and ``overwrite`` is False.
    repro.errors.MotionError
        For a bad ``n_actors``, ``seed`` or ``fps``.
    """
    n_actors = _positive_int("n_actors", n_actors)
    seed = _positive_int("seed", seed, minimum=0)
    out_dir = Path(out_dir)
    plan = _plan(n_actors, seed)
    clips = [synthetic_clip(p["kind"], p["side"], p["level"], p["height"], seed=p["seed"], fps=fps) for p in plan]
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".synthetic-", dir=out_dir))
    try:
        rows = []
        for p, (motion, ann) in zip(plan, clips):
            staged = write_bvh(motion, stage / p["file"])
            hp = ann["hit_position"]
            rows.append({
                "file": p["file"], "kind": ann["kind"], "semantics": ann["semantics"], "side": ann["side"],
                "level": ann["level"], "hit_joint": ann["hit_joint"], "hit_frame": ann["hit_frame"],
                "actor_height_m": f"{ann['actor_height_m']:.6g}", "frames": motion.n_frames,
                "frame_time": f"{motion.frame_time:.12g}", "sha256": _sha256(staged),
                "hit_point": ann["hit_point"],
                "hit_x_m": "" if hp is None else f"{hp[0]:.6f}",
                "hit_y_m": "" if hp is None else f"{hp[1]:.6f}",
                "hit_z_m": "" if hp is None else f"{hp[2]:.6f}",
                "clip_seed": p["seed"],
                "unit_m": "1",
            })  # fmt: skip
        (stage / MANIFEST_NAME).write_text(_manifest_text(rows), encoding="utf-8", newline="")
        names = [p["file"] for p in plan] + [MANIFEST_NAME]
        same, conflicts = set(), []
        for name in names:
            target = out_dir / name
            if target.is_file() and _sha256(target) == _sha256(stage / name):
                same.add(name)
            elif target.exists() or target.is_symlink():
                conflicts.append(name)
        if conflicts and not overwrite:
            raise FileExistsError(
                errno.EEXIST,
                f"{len(conflicts)} file(s) of the synthetic database already exist with other content "
                f"(e.g. {conflicts[0]!r}); nothing was written; pass overwrite=True to replace them",
                str(out_dir / conflicts[0]),
            )
        for name in names:  # the manifest last: it is complete only once every clip is in place
            if name not in same:
                os.chmod(stage / name, 0o644)
                os.replace(stage / name, out_dir / name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    manifest_path = out_dir / MANIFEST_NAME
    return SyntheticDatabase([out_dir / p["file"] for p in plan], manifest_path, read_manifest(manifest_path))


_INT_COLUMNS = ("hit_frame", "frames", "clip_seed")
_FLOAT_COLUMNS = ("actor_height_m", "frame_time", "hit_x_m", "hit_y_m", "hit_z_m", "unit_m")


def read_manifest(path, *, verify: bool = False) -> list[dict]:
    """Read a ``manifest.csv`` written by :func:`synthetic_database`.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest.
    verify : bool, default False
        Also check the sha256 of every listed BVH file (in the manifest's folder).

    Returns
    -------
    list of dict
        One dict per clip with the :data:`MANIFEST_COLUMNS` as keys: ``hit_frame``,
        ``frames`` and ``clip_seed`` as int, ``actor_height_m``, ``frame_time``,
        ``unit_m`` and ``hit_x_m``/``hit_y_m``/``hit_z_m`` as float (None when empty, i.e. for stance
        clips), the rest as str.

    Raises
    ------
    repro.errors.MotionError
        If a column is missing or a value does not parse, or (``verify``) a file is
        missing or its sha256 differs.
    """
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in MANIFEST_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise MotionError(f"{path}: manifest lacks column(s) {missing}")
        rows = []
        for lineno, raw in enumerate(reader, start=2):
            row = dict(raw)
            try:
                for c in _INT_COLUMNS:
                    row[c] = int(row[c])
                for c in _FLOAT_COLUMNS:
                    row[c] = None if row[c] in ("", None) else float(row[c])
            except (TypeError, ValueError) as e:
                raise MotionError(f"{path}, line {lineno}: {e}") from None
            rows.append(row)
    if verify:
        for row in rows:
            f = path.parent / row["file"]
            if not f.is_file():
                raise MotionError(f"{path}: listed file {row['file']!r} is missing")
            if _sha256(f) != row["sha256"]:
                raise MotionError(f"{path}: sha256 of {row['file']!r} differs from the manifest")
    return rows
