"""Hinge-clamped analytic two-bone IK that poses the synthetic limbs (:func:`two_bone`).

Not the limb solver of :mod:`repro.motion.adaptation.limb`: that one edits an existing
pose (it keeps the swivel and twist of the input with the smallest rotations), this one
builds a pose from nothing (elbow / knee towards a pole direction, the middle joint's
local rotation exactly a rotation about its hinge axis, flexion clamped to the joint
limits), which is what makes the generated elbows and knees hinges.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from repro.errors import MotionError
from repro.motion.core.quaternion import axis_angle_quat, quat_multiply
from repro.motion.database.synthetic.skeleton import ELBOW_FLEXION_LIMITS_DEG, HINGE_AXES, KNEE_FLEXION_LIMITS_DEG, REF_LENGTHS
from repro.motion.database.synthetic.tracks import UNIT_X, UNIT_Y

__all__ = ["Limb", "limb_of", "limb_reach", "flexion_at", "IKSolution", "two_bone"]


# ---------------------------------------------------------------- two-bone IK
class Limb(NamedTuple):
    upper: str  # joint rotated to aim the limb (LeftArm / LeftUpLeg)
    middle: str  # hinge joint (LeftForeArm / LeftLeg)
    end: str  # joint at the target (LeftHand / LeftFoot)
    l1: float
    l2: float
    u: np.ndarray  # rest direction of both bones in the parent's frame
    h: np.ndarray  # hinge axis
    limits: tuple[float, float]  # flexion range, radians


def limb_of(prefix: str, kind: str, s: float) -> Limb:
    if kind == "arm":
        names = (prefix + "Arm", prefix + "ForeArm", prefix + "Hand")
        l1, l2 = REF_LENGTHS["upper_arm"] * s, REF_LENGTHS["forearm"] * s
        u = UNIT_X if prefix == "Left" else -UNIT_X
        lim = ELBOW_FLEXION_LIMITS_DEG
    else:
        names = (prefix + "UpLeg", prefix + "Leg", prefix + "Foot")
        l1, l2 = REF_LENGTHS["thigh"] * s, REF_LENGTHS["shin"] * s
        u = -UNIT_Y
        lim = KNEE_FLEXION_LIMITS_DEG
    h = np.array(HINGE_AXES[names[1]])
    return Limb(*names, l1, l2, u, h, (math.radians(lim[0]), math.radians(lim[1])))


def limb_reach(limb: Limb, flexion: float) -> float:
    """Distance from the upper joint to the end joint at a given flexion (radians)."""
    return math.sqrt(limb.l1**2 + limb.l2**2 + 2 * limb.l1 * limb.l2 * math.cos(flexion))


def flexion_at(limb: Limb, distance: float) -> float:
    """Flexion (radians) at which the limb's end is ``distance`` from its root (clamped)."""
    c = (distance**2 - limb.l1**2 - limb.l2**2) / (2 * limb.l1 * limb.l2)
    return float(np.clip(math.acos(float(np.clip(c, -1.0, 1.0))), *limb.limits))


class IKSolution(NamedTuple):
    q_upper_world: np.ndarray  # (F, 4)
    q_middle_local: np.ndarray  # (F, 4) hinge rotation
    q_lower_world: np.ndarray  # (F, 4) world rotation of the middle joint's frame
    end: np.ndarray  # (F, 3) position reached by the end joint
    flexion: np.ndarray  # (F,) radians
    miss: np.ndarray  # (F,) distance between target and reached end


def two_bone(limb: Limb, root: np.ndarray, target: np.ndarray, pole: np.ndarray) -> IKSolution:
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
    dmax = limb_reach(limb, tmin)
    dmin = limb_reach(limb, tmax)
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
    q_mid = axis_angle_quat(limb.h, theta)
    q_low = quat_multiply(q_up, q_mid)
    end = root + l1 * a + l2 * f
    return IKSolution(q_up, q_mid, q_low, end, theta, np.linalg.norm(end - target, axis=-1))
