"""Morphology-independent representation of motion and retargeting (Section 3.4.1).

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.4.1, retarget database motions to fighters of other sizes
with the representation of Kulpa, Multon and Arnaldi, "Morphology-independent
representation of motions for interactive human-like animation" (Eurographics 2005):

    "the arm is modeled as a line between the shoulder and the wrist (denoted l_i for
    limb i) and an angle alpha_i to locate the elbow. Finally, only the relative position
    of the wrist in the shoulder reference frame and the angle are stored. The same way,
    all the intermediate body parts are modeled with relative position of the distal
    point in the proximal reference frame, divided by the total length."

and "retargetting mainly consists of multiplying adimensional data of the skeleton by
the new dimensions of the character" (Section 3.4).  :func:`encode` builds that
adimensional data, :func:`decode` multiplies it by a target skeleton's dimensions,
:func:`retarget` is both; :func:`naive_retarget` is the baseline the paper improves on
("people usually apply joint angles from character#1 to character#2").  Everything is
vectorised over frames (the only Python loops run over the depth of the tree in forward
kinematics).

What is stored (:class:`MorphologyIndependentMotion`), per frame:

* **Root trajectory**: the local translations of the joints from the root down to the
  pelvis (CMU ``root``; Bandai Namco ``joint_Root`` and ``Hips``), divided by the
  source's :attr:`~repro.motion.body.skeleton.Skeleton.hip_height` (the pelvis height of the
  straightened skeleton = ankle height + leg length + pelvis-above-hips).  Hip height
  rather than stature, because it is what the feet need: a character with 25% longer
  legs must carry its pelvis higher, not a head taller.
* **Limbs** (two arms, two legs): the distal point (wrist / ankle) relative to the
  proximal one (shoulder / hip), expressed in the *limb's parent frame* -- the world
  frame of the proximal joint's parent: the clavicle for an arm (the chest when there is
  no clavicle), the pelvis (CMU ``lhipjoint``) for a leg, i.e. the paper's "shoulder
  reference frame" -- divided by the limb length ``l_upper + l_lower``; its norm is
  therefore <= 1 (triangle inequality), and 1 at full extension.  Plus the **swivel
  angle** ``alpha`` of the middle joint (elbow / knee) about the proximal->distal axis,
  and the **orientation of the distal segment** (hand / foot) in the limb's parent frame.
* **All other segments** (pelvis, spine, neck, head, clavicles, hands, toes ...): their
  local rotations.  Kulpa et al. store these as normalised distal-point vectors; a local
  rotation holds the same information (the direction of the normalised vector) plus the
  twist about the segment, and involves no length, so it is morphology independent as
  it stands, and decoding it on any skeleton with the same rest directions places every
  segment's distal point at (normalised vector x target length).  Other translations
  (position channels below the pelvis, e.g. Bandai Namco's constant ones) are divided by
  the source bone length and multiplied by the target's.

Swivel angle
------------
For limb axis ``a = n / |n|`` (in the limb's parent frame) the swivel is measured from a
reference direction ``u(a)`` perpendicular to ``a``: ``alpha = atan2(e . (a x u),
e . u)`` with ``e`` the proximal->middle-joint vector.  ``u(a)`` is *parallel
transported*: ``u(a) = R(a0 -> a) r0``, where ``R(a0 -> a)`` is the smallest rotation
taking a fixed axis ``a0`` to ``a`` and ``r0 _|_ a0`` a fixed bend direction.  This
reference is smooth everywhere except at the single direction ``a = -a0``, which is put
where the limb cannot point (using the rest pose of the source to tell forward ``f``, up
``h`` and the limb's outward side ``o``):

* arm: ``a0 = (o + f)/sqrt(2)`` (forward-outward; the singular direction,
  backward-inward through the trunk, is out of reach), ``r0 = -h`` (elbow down when the
  arm is held forward-outward, forearm bent);
* leg: ``a0 = (f - h)/sqrt(2)`` (forward-down; singular direction backward-up, beyond the
  hip's extension range), ``r0 = (f + h)/sqrt(2)`` (knee forward-up).

``a0`` and ``r0`` are computed once on the source and stored in the representation, so
the target uses exactly the same reference.  They are anatomical when the rest pose is a
T- or A-pose facing along a horizontal axis (CMU, Mixamo); on a rig whose rest pose is
not (Bandai Namco: every bone along +X) they are still a fixed, consistent reference --
the round trip stays exact -- only without anatomical meaning.

At full extension (and when the middle joint lies on the axis for any other reason) the
swivel is undefined: the circle the middle joint lives on has radius 0, any angle gives
the same positions.  :func:`encode` then carries the last defined angle forward (the
first defined one backward), 0 if no frame defines it, so the stored angle never is NaN
and does not jump; :func:`decode` clips the law of cosines to [-1, 1], so a fully
extended (or unreachable) limb is solved without NaN.  A limb whose target proportions
(upper/lower ratio) differ can be asked to fold closer than it can (``n * L <
|l_upper - l_lower|``): the distance is clipped to the reachable range, the middle joint
placed accordingly; :func:`decode_with_report` counts those frames per limb
(:class:`DecodeReport`).

Decoding keeps every source local rotation, then replaces, for each limb, the rotations
of the proximal and middle joints by the smallest corrections that bring the middle and
distal joints onto the analytic two-bone solution (so the twist of the upper arm / thigh
is kept), and sets the distal joint's local rotation so its orientation in the limb's
parent frame is the source's.  On the source skeleton every correction is the identity:
the round trip reproduces the motion to rounding error.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from repro.checks import as_bool, as_real, describe
from repro.errors import MotionError
from repro.motion.core.channels import POSITION_CHANNELS
from repro.motion.body.feet import UP_AXIS, foot_contacts, foot_goals, foot_scale
from repro.motion.core.kinematics import (
    chain_positions,
    check_pose_arrays,
    depth_levels,
    fk_arrays,
    normalize,
    transport,
    world_of,
)
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import cross, min_rotation, quat_multiply, vector_norm
from repro.motion.core.quaternion import quat_conjugate as qinv
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.retargeting.trees import retarget_across
from repro.motion.body.roles import LIMBS
from repro.motion.body.skeleton import Skeleton, check_role_table, skeleton_of

__all__ = [
    "LIMB_NAMES",
    "DecodeReport",
    "MorphologyIndependentMotion",
    "RetargetPlan",
    "decode",
    "decode_with_report",
    "encode",
    "naive_retarget",
    "retarget",
]

LIMB_NAMES: tuple[str, ...] = tuple(LIMBS)  # left_arm, right_arm, left_leg, right_leg


def _position_mask(channels) -> np.ndarray:
    return np.array([[c in ch for c in POSITION_CHANNELS] for ch in channels], dtype=bool).reshape(-1, 3)


# ------------------------------------------------------------- representation
@dataclass(frozen=True, eq=False)
class MorphologyIndependentMotion:
    """A motion in the morphology-independent representation (Kulpa et al. 2005; Section 3.4.1).

    Built by :func:`encode`; :func:`decode` puts it on a skeleton.  All arrays are per
    frame (first axis F); limbs are in the order of :data:`LIMB_NAMES`
    (``left_arm, right_arm, left_leg, right_leg``).  Nothing in it is a length of the
    source skeleton except the informative ``source_*`` fields.

    Attributes
    ----------
    joint_names, parents, channels
        Topology and channel layout of the source (the target must have the same names
        and parents).
    roles : dict
        Role -> joint name (:func:`repro.motion.body.roles.find_roles`).
    frame_time : float
    rotations : (F, J, 4)
        Local rotations of the source, unit quaternions ``(x, y, z, w)``.  Used as is for
        every joint except the limbs' proximal, middle and distal joints.
    translations : (F, J, 3)
        Normalised local translations: for the joints from the root to the pelvis
        (:attr:`root_path`) divided by the source's hip height, for the others divided
        by the source bone length (or by the hip height when that is 0).
    root_path : (P,) int
        Joint indices from the root to the pelvis.
    limb_vectors : (F, 4, 3)
        ``(distal - proximal) / (l_upper + l_lower)`` in the limb's parent frame; norm <= 1.
    limb_swivel : (F, 4)
        Swivel angle of the middle joint in radians, in ``(-pi, pi]`` (see the module
        docstring for the reference direction).
    limb_end_rotations : (F, 4, 4)
        World rotation of the distal joint (hand / foot frame) in the limb's parent frame.
    swivel_axes, swivel_refs : (4, 3)
        ``a0`` and ``r0`` of each limb, in the limb's parent frame.
    rest_directions : (J, 3)
        Unit rest offsets of the source (zero rows for zero offsets): a target must point
        its bones the same way for local rotations to mean the same pose.
    source_hip_height, source_height : float
        Source sizes, file units; ``source_unit_m`` metres per unit (or None).
    contacts : (F, 2) bool
        Frames where the source's left / right ankle is planted (:func:`foot_contacts`).
    ankle_heights : (F, 2)
        Height of the source's ankles above the floor plane ``y = 0`` divided by the
        source's foot length (ankle -> toe bone; the leg length when there is no toe
        joint): the ankle height a planted foot must keep, in foot lengths.
    """

    joint_names: list[str]
    parents: np.ndarray
    channels: list[tuple[str, ...]]
    roles: dict[str, str]
    frame_time: float
    rotations: np.ndarray
    translations: np.ndarray
    root_path: np.ndarray
    limb_vectors: np.ndarray
    limb_swivel: np.ndarray
    limb_end_rotations: np.ndarray
    swivel_axes: np.ndarray
    swivel_refs: np.ndarray
    rest_directions: np.ndarray
    source_hip_height: float
    source_height: float
    contacts: np.ndarray
    ankle_heights: np.ndarray
    source_unit_m: float | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.rotations.shape[0])

    @property
    def limb_names(self) -> tuple[str, ...]:
        """Names of the four limbs, in array order."""
        return LIMB_NAMES

    @property
    def limb_extension(self) -> np.ndarray:
        """(F, 4) normalised distal distance ``|limb_vectors|`` (in [0, 1])."""
        return np.linalg.norm(self.limb_vectors, axis=-1)

    @property
    def root_trajectory(self) -> np.ndarray:
        """(F, 3) normalised local translation of the root joint (root position / hip height)."""
        return self.translations[:, 0]

    def __repr__(self) -> str:
        return f"MorphologyIndependentMotion({len(self.joint_names)} joints, {self.n_frames} frames)"


def _limb_indices(sk: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    prox = np.array([sk.index(LIMBS[k][0]) for k in LIMB_NAMES])
    mid = np.array([sk.index(LIMBS[k][1]) for k in LIMB_NAMES])
    dist = np.array([sk.index(LIMBS[k][2]) for k in LIMB_NAMES])
    par = sk.parents[prox]
    if np.any(par < 0):
        raise MotionError("a limb's proximal joint is the root; limbs need a parent frame")
    return prox, mid, dist, par


def _swivel_frames(sk: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """``a0`` and ``r0`` per limb from the rest pose (see module docstring)."""
    p = sk.rest_positions()
    up = sk.trunk_axis
    a0s, r0s = [], []
    for limb in LIMB_NAMES:
        side, kind = limb.split("_")
        prox_role = "shoulder" if kind == "arm" else "hip"
        lat = p[sk.index(f"left_{prox_role}")] - p[sk.index(f"right_{prox_role}")]
        lat = lat - (lat @ up) * up
        n = np.linalg.norm(lat)
        if n <= 1e-9 * max(sk.height, 1e-300):
            raise MotionError(f"left and right {prox_role}s coincide in the rest pose; cannot tell left from right")
        lat /= n
        fwd = cross(lat, up)
        out = lat if side == "left" else -lat
        if kind == "arm":
            a0, r0 = (out + fwd) / np.sqrt(2.0), -up
        else:
            a0, r0 = (fwd - up) / np.sqrt(2.0), (fwd + up) / np.sqrt(2.0)
        a0s.append(a0)
        r0s.append(r0)
    return np.array(a0s), np.array(r0s)


def _fill_undefined(angle: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Carry the last valid angle forward (first valid backward) along axis 0; 0 if none."""
    F = angle.shape[0]
    if F == 0:
        return angle
    idx = np.where(valid, np.arange(F)[:, None], -1)
    idx = np.maximum.accumulate(idx, axis=0)
    first = np.argmax(valid, axis=0)  # first valid frame per column (0 if none)
    idx = np.where(idx < 0, first[None], idx)
    out = np.take_along_axis(angle, idx, axis=0)
    return np.where(valid.any(axis=0)[None], out, 0.0)


def _root_path(sk: Skeleton) -> np.ndarray:
    return np.array([0] + sk.path(sk.joint_names[0], "pelvis"), dtype=np.intp)


def encode(motion: Motion, roles=None) -> MorphologyIndependentMotion:
    """The morphology-independent representation of a motion (Kulpa et al. 2005; Section 3.4.1).

    Parameters
    ----------
    motion : Motion
        Any skeleton :func:`~repro.motion.body.roles.find_roles` understands.
    roles : mapping role -> joint, optional
        Complete role table (default: found from the names and the tree).

    Returns
    -------
    MorphologyIndependentMotion

    Raises
    ------
    repro.errors.MotionError
        Missing roles, zero-length limb bones, coincident left/right joints.
    """
    _check_motion(motion)
    sk = Skeleton.from_motion(motion, roles=check_role_table(roles))
    prox, mid, dist, par = _limb_indices(sk)
    bl = sk.bone_lengths
    l1, l2 = bl[mid], bl[dist]
    L = l1 + l2
    gq, gp = fk_arrays(depth_levels(sk.parents), motion.rotations, motion.local_translations())
    rp_inv = qinv(gq[:, par])  # (F, 4, 4)
    S = gp[:, prox]
    d = qrot(rp_inv, gp[:, dist] - S)  # (F, 4, 3) in the limb parent frame
    e = qrot(rp_inv, gp[:, mid] - S)
    n = d / L[None, :, None]
    a0, r0 = _swivel_frames(sk)
    a, dn = normalize(d)
    a = np.where((dn > 1e-12 * L[None])[..., None], a, a0[None])
    u = transport(a0[None], r0[None], a)
    v = cross(a, u)
    ep = e - np.sum(e * a, axis=-1, keepdims=True) * a
    radius = np.linalg.norm(ep, axis=-1)
    ang = np.arctan2(np.sum(ep * v, axis=-1), np.sum(ep * u, axis=-1))
    ang = _fill_undefined(ang, radius > 1e-9 * l1[None])
    end_rot = quat_multiply(rp_inv, gq[:, dist])

    H = sk.hip_height
    if not np.isfinite(H) or H <= 0:
        raise MotionError(f"source hip height must be > 0, got {H!r}")
    t = motion.local_translations()
    root_path = _root_path(sk)
    nonzero = bl > 1e-12 * sk.height
    div = np.where(nonzero, bl, H)
    div[root_path] = H
    trans = t / div[None, :, None]
    rest_dir = np.where(nonzero[:, None], sk.offsets / np.maximum(bl, 1e-300)[:, None], 0.0)
    contacts = foot_contacts(motion, global_positions=gp, skeleton=sk)
    ankle_h = gp[:, [sk.index("left_ankle"), sk.index("right_ankle")], UP_AXIS] / foot_scale(sk)
    return MorphologyIndependentMotion(
        joint_names=list(motion.joint_names),
        parents=np.array(motion.parents),
        channels=list(motion.channels),
        roles=dict(sk.roles),
        frame_time=motion.frame_time,
        rotations=np.array(motion.rotations),
        translations=trans,
        root_path=root_path,
        limb_vectors=n,
        limb_swivel=ang,
        limb_end_rotations=end_rot,
        swivel_axes=a0,
        swivel_refs=r0,
        rest_directions=rest_dir,
        source_hip_height=float(H),
        source_height=float(sk.height),
        contacts=contacts,
        ankle_heights=ankle_h,
        source_unit_m=motion.unit_m,
    )


def _check_motion(motion) -> None:
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a Motion, got {describe(motion)}")


def _check_target(target) -> None:
    if not isinstance(target, (Skeleton, Motion)):
        raise MotionError(f"target must be a Skeleton or a Motion, got {describe(target)}")


def _check_mi(mi: MorphologyIndependentMotion) -> None:
    if not isinstance(mi, MorphologyIndependentMotion):
        raise MotionError(f"expected a MorphologyIndependentMotion (encode), got {describe(mi)}")
    for name in ("rotations", "translations", "limb_vectors", "limb_swivel", "limb_end_rotations", "ankle_heights"):
        arr = np.asarray(getattr(mi, name))
        if not np.all(np.isfinite(arr)):
            raise MotionError(f"morphology-independent motion: {name} contains NaN or inf")
    F, J = mi.rotations.shape[:2]
    if (
        mi.translations.shape != (F, J, 3)
        or mi.limb_vectors.shape != (F, 4, 3)
        or mi.limb_swivel.shape != (F, 4)
        or mi.limb_end_rotations.shape != (F, 4, 4)
        or np.shape(mi.contacts) != (F, 2)
        or np.shape(mi.ankle_heights) != (F, 2)
    ):
        raise MotionError("morphology-independent motion: inconsistent array shapes")
    if np.any(np.linalg.norm(mi.limb_vectors, axis=-1) > 1.0 + 1e-6):
        raise MotionError("morphology-independent motion: a normalised limb vector is longer than 1")


def _target_skeleton(mi: MorphologyIndependentMotion, target, max_rest_angle_deg: float) -> Skeleton:
    if not (isinstance(target, Skeleton) or hasattr(target, "offsets")):
        raise MotionError(f"target must be a Skeleton or a Motion, got {type(target).__name__}")
    if list(target.joint_names) != list(mi.joint_names) or not np.array_equal(target.parents, mi.parents):
        raise MotionError(
            "target skeleton has a different topology (joint names / parents) from the encoded motion; "
            f"encoded {len(mi.joint_names)} joints {mi.joint_names[:4]}..., target "
            f"{len(target.joint_names)} joints {list(target.joint_names)[:4]}...; "
            "retargeting keeps the joint tree, so map the motion onto a skeleton with the same joints"
        )
    tgt = skeleton_of(target, roles=mi.roles)
    # bones must point the same way at rest for local rotations to mean the same pose
    bl = tgt.bone_lengths
    ok = (bl > 0) & (np.linalg.norm(mi.rest_directions, axis=1) > 0)
    cosang = np.sum(tgt.offsets[ok] / bl[ok, None] * mi.rest_directions[ok], axis=1)
    worst = np.degrees(np.arccos(np.clip(cosang, -1, 1))).max(initial=0.0)
    if worst > max_rest_angle_deg:
        j = np.flatnonzero(ok)[int(np.argmax(np.degrees(np.arccos(np.clip(cosang, -1, 1)))))]
        raise MotionError(
            f"target rest pose differs from the source's: bone to {tgt.joint_names[j]!r} is turned by "
            f"{worst:.1f} degrees (> {max_rest_angle_deg}); local rotations would not mean the same pose"
        )
    return tgt


@dataclass(frozen=True)
class DecodeReport:
    """Diagnostics of :func:`decode_with_report`.

    Attributes
    ----------
    clamped : dict[str, int]
        Per limb, the number of frames whose requested proximal-distal distance was out of
        the target limb's reach ``[|l_upper - l_lower|, l_upper + l_lower]`` and was clipped.
    max_distal_error : float
        Largest distance (file units) between a decoded distal joint and its requested
        position (0 up to rounding unless clipped).
    max_root_drop : float
        With ``fix_feet``, the largest amount (file units) the root was lowered so that a
        planted foot could be reached.
    """

    clamped: dict
    max_distal_error: float
    max_root_drop: float = 0.0


def _pin_planted_feet(mi, tgt, want, S, Rp, L, local_t, gp, prox, root_moves_up: bool, blend_time: float):
    """Leg goals of ``fix_feet``: planted ankles pinned, the root lowered where out of reach.

    ``local_t`` and ``gp`` are lowered in place; returns the new limb vectors ``want``,
    proximal positions ``S`` and the largest root drop.
    """
    lowered = 0.0
    legs = [LIMB_NAMES.index("left_leg"), LIMB_NAMES.index("right_leg")]
    A = S[:, legs] + qrot(Rp[:, legs], want[:, legs])
    n_blend = int(round(min(blend_time / mi.frame_time, 2.0**53)))  # longer than any clip: no overflow
    goal, w = foot_goals(A, mi.contacts, mi.ankle_heights * foot_scale(tgt), n_blend)
    goal = A + w[..., None] * (goal - A)
    if root_moves_up:
        # lower the root where a planted foot is out of the leg's reach
        r = goal - S[:, legs]
        ry = r[..., UP_AXIS]
        rh2 = np.sum(r * r, axis=-1) - ry**2
        drop = np.maximum(0.0, -ry - np.sqrt(np.maximum(L[legs][None] ** 2 - rh2, 0.0)))
        drop = drop.max(axis=1)
        lowered = float(drop.max(initial=0.0))
        local_t[:, 0, UP_AXIS] -= drop
        gp[..., UP_AXIS] -= drop[:, None]
        S = gp[:, prox]
    want = want.copy()
    want[:, legs] = qrot(qinv(Rp[:, legs]), goal - S[:, legs])
    return want, S, lowered


def decode_with_report(
    mi: MorphologyIndependentMotion,
    target,
    *,
    fix_feet: bool = False,
    blend_time: float = 0.1,
    max_rest_angle_deg: float = 5.0,
) -> tuple[Motion, DecodeReport]:
    """:func:`decode`, also returning a :class:`DecodeReport`."""
    _check_mi(mi)
    fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
    blend_time = as_real(blend_time, "blend_time (seconds)", error=MotionError, lo=0.0)
    max_rest_angle_deg = as_real(max_rest_angle_deg, "max_rest_angle_deg", error=MotionError, lo=0.0, hi=180.0)
    tgt = _target_skeleton(mi, target, max_rest_angle_deg)
    channels = tgt.channels if tgt.channels is not None else mi.channels
    mask = _position_mask(channels)
    bl = tgt.bone_lengths
    H = tgt.hip_height
    mul = np.where(np.linalg.norm(mi.rest_directions, axis=1) > 0, bl, H)
    mul[mi.root_path] = H
    trans = mi.translations * mul[None, :, None]
    local_t = np.where(mask[None], trans, tgt.offsets[None])
    rot = np.array(mi.rotations, dtype=float)
    gq, gp = fk_arrays(depth_levels(tgt.parents), rot, local_t)

    prox, mid, dist, par = _limb_indices(tgt)
    l1, l2 = bl[mid], bl[dist]
    L = l1 + l2
    Rp = gq[:, par]
    S = gp[:, prox]
    want = mi.limb_vectors * L[None, :, None]
    lowered = 0.0
    if fix_feet:
        want, S, lowered = _pin_planted_feet(mi, tgt, want, S, Rp, L, local_t, gp, prox, mask[0, UP_AXIS], blend_time)
    a, dn = normalize(want)
    a0, r0 = mi.swivel_axes, mi.swivel_refs
    a = np.where((dn > 1e-12 * L[None])[..., None], a, a0[None])
    lo, hi = np.abs(l1 - l2), L
    dc = np.clip(dn, lo[None], hi[None])
    clamped = (dn < lo[None] * (1 - 1e-9)) | (dn > hi[None] * (1 + 1e-9))
    cosb = np.clip((l1[None] ** 2 + dc**2 - l2[None] ** 2) / (2 * l1[None] * np.maximum(dc, 1e-300)), -1.0, 1.0)
    sinb = np.sqrt(1.0 - cosb**2)
    u = transport(a0[None], r0[None], a)
    v = cross(a, u)
    phi = mi.limb_swivel[..., None]
    e_loc = a * (l1[None] * cosb)[..., None] + (u * np.cos(phi) + v * np.sin(phi)) * (l1[None] * sinb)[..., None]
    w_loc = a * dc[..., None]
    E_star = S + qrot(Rp, e_loc)
    W_star = S + qrot(Rp, w_loc)
    E0, W0 = gp[:, mid], gp[:, dist]
    q1 = min_rotation(E0 - S, E_star - S)
    Gs = quat_multiply(q1, gq[:, prox])
    E1 = S + qrot(q1, E0 - S)
    W1 = S + qrot(q1, W0 - S)
    q2 = min_rotation(W1 - E1, W_star - E1)
    Ge = quat_multiply(q2, quat_multiply(q1, gq[:, mid]))
    Gw = quat_multiply(Rp, mi.limb_end_rotations)
    rot[:, prox] = quat_multiply(qinv(Rp), Gs)
    rot[:, mid] = quat_multiply(qinv(Gs), Ge)
    rot[:, dist] = quat_multiply(qinv(Ge), Gw)
    W_final = E1 + qrot(q2, W1 - E1)
    err = float(np.max(np.linalg.norm(W_final - S - qrot(Rp, want), axis=-1), initial=0.0))

    out = tgt.motion_with(rot, local_t, frame_time=mi.frame_time, channels=channels)
    report = DecodeReport(
        clamped={k: int(c) for k, c in zip(LIMB_NAMES, clamped.sum(axis=0))},
        max_distal_error=err,
        max_root_drop=lowered,
    )
    return out, report


def decode(
    mi: MorphologyIndependentMotion,
    target,
    *,
    fix_feet: bool = False,
    blend_time: float = 0.1,
    max_rest_angle_deg: float = 5.0,
) -> Motion:
    """Put a morphology-independent motion on a target skeleton (Section 3.4.1).

    "Retargetting mainly consists of multiplying adimensional data of the skeleton by
    the new dimensions of the character" (Section 3.4): the root trajectory is multiplied
    by the target's :attr:`~repro.motion.body.skeleton.Skeleton.hip_height`, each limb's
    normalised distal vector by the target limb length, and the middle joint is placed
    analytically (two-bone IK, law of cosines) on the circle about the proximal->distal
    axis at the stored swivel angle; every other joint keeps its local rotation.

    With ``fix_feet`` the feet artifacts are corrected as well ("retargetting mainly
    consists of multiplying adimensional data of the skeleton by the new dimensions of
    the character, and correcting the feet artifacts", Section 3.4): on the frames where
    the source's ankle was planted (:attr:`MorphologyIndependentMotion.contacts`) the
    target's ankle is pinned, per contact phase, to the mean horizontal position the
    plain decoding gives it during that phase, at the source's ankle height scaled by the
    ratio of foot lengths; the goal is blended in and out linearly over ``blend_time``
    seconds around each phase; where a goal is out of the leg's reach the root is
    lowered (when it has a vertical position channel), and the leg is solved by the same
    two-bone IK (the stored swivel is kept).  This changes the motion also on the source
    skeleton (it removes the actor's own foot sliding), so it is off by default.

    Parameters
    ----------
    mi : MorphologyIndependentMotion
        From :func:`encode`.
    target : Skeleton or Motion
        Same joint names and parents as the encoded motion (e.g. from
        :func:`~repro.motion.body.skeleton.scale_skeleton`); only its offsets, End Sites,
        channels and ``unit_m`` are used.
    fix_feet : bool, default False
        Pin planted feet (see above).
    blend_time : float, default 0.1
        Seconds over which a foot goal is blended in before and out after a contact.
    max_rest_angle_deg : float, default 5
        Largest allowed angle between a target bone's rest direction and the source's
        (a different rest pose would change what the copied local rotations mean).

    Returns
    -------
    Motion
        On the target skeleton (its offsets, channels, End Sites, ``unit_m``); position
        channels hold the decoded translations, rotations are such that forward
        kinematics gives the decoded positions, so :func:`~repro.motion.write_bvh` works.

    Raises
    ------
    repro.errors.MotionError
        Different topology, different rest directions, missing roles or zero-length limb
        bones in the target, NaN in ``mi``.
    """
    return decode_with_report(
        mi, target, fix_feet=fix_feet, blend_time=blend_time, max_rest_angle_deg=max_rest_angle_deg
    )[0]


def retarget(motion: Motion, target, *, roles=None, fix_feet: bool = False) -> Motion:
    """``decode(encode(motion), target)``: the paper's retargeting (Section 3.4.1).

    Note that when the target only changes lengths *uniformly within each limb* (as
    :func:`~repro.motion.body.skeleton.scale_skeleton` does with ``arm_scale`` /
    ``leg_scale``), the normalised limb vectors and swivel angles of the source pose are
    exactly those the copied joint angles give on the target, so the result equals
    :func:`naive_retarget` with ``scale_root=True``; the representation differs from
    angle copying when the upper/lower ratio of a limb changes, when the adimensional
    data are edited (Section 3.4.2 adapts them to reach targets), and with
    ``fix_feet=True``.

    Parameters
    ----------
    motion : Motion
    target : Skeleton or Motion
        A character with the same joints (see :func:`decode`).
    roles : mapping, optional
        Role table of the source (default: found).
    fix_feet : bool, default False
        Correct the feet artifacts (see :func:`decode`; across joint trees,
        :func:`~repro.motion.retargeting.trees.retarget_across`'s ``fix_feet``).

    A target whose joint tree differs (other joint names with the same parents; or
    another tree, rest pose or up axis) is retargeted too: with the same parents and
    the roles on the same joints, the joints are renamed and decoded as above (exact);
    otherwise through the body-part roles, :func:`repro.motion.retargeting.trees.retarget_across`.
    """
    _check_motion(motion)
    _check_target(target)
    roles = check_role_table(roles, "roles")
    fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
    if list(target.joint_names) == list(motion.joint_names) and np.array_equal(target.parents, motion.parents):
        return decode(encode(motion, roles=roles), target, fix_feet=fix_feet)
    mi = encode(motion, roles=roles)
    tgt = skeleton_of(target)
    if np.array_equal(tgt.parents, motion.parents):
        src_index = {r: motion.joint_names.index(j) for r, j in mi.roles.items()}
        if all(tgt.roles.get(r) == tgt.joint_names[i] for r, i in src_index.items()):
            renamed = dataclasses.replace(tgt, joint_names=list(motion.joint_names), roles=mi.roles)
            try:
                out = decode(mi, renamed, fix_feet=fix_feet)
            except MotionError:
                out = None  # another rest pose: through the roles
            if out is not None:
                return dataclasses.replace(out, joint_names=list(tgt.joint_names))
    return retarget_across(motion, target, roles=roles, fix_feet=fix_feet)


class RetargetPlan:
    """:func:`retarget` between two fixed skeletons of the same joint tree, for few frames at a time.

    Everything of :func:`encode` and :func:`decode` that depends only on the source and
    target skeletons (roles, limb indices and lengths, hip heights, swivel references,
    the rest-direction check, the depth levels) is computed once here; :meth:`positions`
    then runs only the per-frame arithmetic of the two, in the same order on the same
    array shapes, so its numbers are those of ``retarget(motion, target).global_positions()``
    bit for bit (``fix_feet=False``; checked in ``tests/motion/retargeting/test_morphology_plan.py``).
    It skips what the positions do not need (the Motion objects, the foot contacts).
    Used by :meth:`repro.motion.search.retrieval.MotionRetriever.prepare` (one pose per query).

    Parameters
    ----------
    source : Skeleton or Motion
        The skeleton the poses are on (roles found as :func:`encode` does).
    target : Skeleton or Motion
        Same joint names and parents (else :func:`retarget` takes other paths: not planned).

    Raises
    ------
    repro.errors.MotionError
        What :func:`retarget` raises for these skeletons (missing roles, zero-length limb
        bones, another topology or rest pose).
    """

    def __init__(self, source, target):
        _check_target(target)
        sk = skeleton_of(source)
        if list(target.joint_names) != list(sk.joint_names) or not np.array_equal(target.parents, sk.parents):
            raise MotionError("RetargetPlan: the target must have the source's joint names and parents")
        self.n_joints = sk.n_joints
        self.levels = depth_levels(sk.parents)
        prox, mid, dist, par = _limb_indices(sk)
        self.prox, self.mid, self.dist, self.par = prox, mid, dist, par
        bl = sk.bone_lengths
        self.L_src = bl[mid] + bl[dist]
        self.l1_src = bl[mid]
        self.a0, self.r0 = _swivel_frames(sk)
        H = sk.hip_height
        if not np.isfinite(H) or H <= 0:
            raise MotionError(f"source hip height must be > 0, got {H!r}")
        root_path = _root_path(sk)
        nonzero = bl > 1e-12 * sk.height
        div = np.where(nonzero, bl, H)
        div[root_path] = H
        self.div = div
        rest_dir = np.where(nonzero[:, None], sk.offsets / np.maximum(bl, 1e-300)[:, None], 0.0)
        # the target side, as decode_with_report: checked once (rest directions, roles)
        probe = _RestProbe(joint_names=list(sk.joint_names), parents=np.array(sk.parents), roles=dict(sk.roles),
                           rest_directions=rest_dir)
        tgt = _target_skeleton(probe, target, 5.0)
        channels = tgt.channels if tgt.channels is not None else sk.channels
        if channels is None:
            raise MotionError("RetargetPlan: neither skeleton has channels")
        self.mask = _position_mask(channels)
        tbl = tgt.bone_lengths
        TH = tgt.hip_height
        mul = np.where(np.linalg.norm(rest_dir, axis=1) > 0, tbl, TH)
        mul[root_path] = TH
        self.mul = mul
        self.t_offsets = tgt.offsets
        tprox, tmid, tdist, tpar = _limb_indices(tgt)
        if not (np.array_equal(tprox, prox) and np.array_equal(tmid, mid) and np.array_equal(tdist, dist)):
            raise MotionError("RetargetPlan: the target's limb roles are on other joints than the source's")
        self.l1, self.l2 = tbl[mid], tbl[dist]
        self.L = self.l1 + self.l2
        self.pair_md = np.stack([dist, mid], axis=1)  # (4, 2): distal, middle
        self.pair_pm = np.stack([prox, mid], axis=1)
        self.pair_mw = np.stack([mid, dist], axis=1)
        self.thr = np.stack([1e-12 * self.L_src, 1e-12 * self.L], axis=1)  # (4, 2): encode, decode
        self.limb_joints = np.concatenate([prox, mid, dist])
        # the joints whose world transforms the new limb rotations change (the limbs' subtrees), by
        # depth below the subtree roots: the last forward kinematics runs over these levels only
        parents = np.asarray(sk.parents)
        inside = np.zeros(sk.n_joints, dtype=bool)
        inside[prox] = True
        rel = np.full(sk.n_joints, -1)
        for j in range(sk.n_joints):
            p = parents[j]
            if p >= 0 and inside[p]:
                inside[j] = True
            if inside[j]:
                rel[j] = rel[p] + 1 if p >= 0 and inside[p] else 0
        self.outside = np.flatnonzero(~inside)
        self.sub_levels = [(np.flatnonzero(rel == r), parents[rel == r]) for r in range(int(rel.max()) + 1)]
        self.sub_joints = np.concatenate([i for i, _ in self.sub_levels])
        has_child = np.zeros(sk.n_joints, dtype=bool)
        has_child[parents[1:]] = True
        self.sub_rot_levels = [(i[has_child[i]], p[has_child[i]]) for i, p in self.sub_levels if has_child[i].any()]
        self.triple = np.stack([prox, mid, dist], axis=1)

    def positions(self, rotations: np.ndarray, translations: np.ndarray, *, source=None) -> np.ndarray:
        """(F, J, 3) world positions of the retargeted frames, target units.

        ``rotations`` (F, J, 4) unit quaternions and ``translations`` (F, J, 3) the local
        translations (:meth:`~repro.motion.core.motion.Motion.local_translations`) of the source;
        ``source``: its world ``(rotations, positions)`` when already computed
        (:meth:`~repro.motion.core.motion.Motion.global_transforms`; default: computed here).
        The arithmetic is :func:`encode`'s and :func:`decode`'s, element for element; pairs
        of like operations (the two limb vectors, the two swivel frames, ...) run as one
        stacked call, which gives the same numbers.
        """
        prox, mid, par = self.prox, self.mid, self.par
        a0, r0 = self.a0[None, :, None], self.r0[None, :, None]
        # encode (the per-frame part)
        rotations, translations = check_pose_arrays(rotations, translations, self.n_joints)
        gq, gp = world_of(self.levels, rotations, translations, source)
        rp_inv = qinv(gq[:, par])
        S = gp[:, prox]
        de = qrot(rp_inv[:, :, None], gp[:, self.pair_md] - S[:, :, None])  # (F, 4, 2, 3): d, e
        d, e = de[:, :, 0], de[:, :, 1]
        n = d / self.L_src[None, :, None]
        # the limb axes of encode (d) and decode (want = n L), together
        aw = np.stack([d, n * self.L[None, :, None]], axis=2)
        a2, dn2 = normalize(aw)
        a2 = np.where((dn2 > self.thr[None])[..., None], a2, a0)
        u2 = transport(a0, r0, a2)
        v2 = cross(a2, u2)
        a, u, v = a2[:, :, 0], u2[:, :, 0], v2[:, :, 0]
        ep = e - np.sum(e * a, axis=-1, keepdims=True) * a
        radius = vector_norm(ep)  # np.linalg.norm's numbers
        ang = np.arctan2(np.sum(ep * v, axis=-1), np.sum(ep * u, axis=-1))
        valid = radius > 1e-9 * self.l1_src[None]
        if not valid.all():  # (when all are, _fill_undefined gives the angles as they are)
            ang = _fill_undefined(ang, valid)
        trans = translations / self.div[None, :, None]
        # decode (the per-frame part, fix_feet=False)
        local_t = np.where(self.mask[None], trans * self.mul[None, :, None], self.t_offsets[None])
        # the target's world rotations are the source's (same local rotations, same tree): positions only
        gp = chain_positions(self.levels, gq, local_t.copy())
        l1, l2, L = self.l1, self.l2, self.L
        Rp = gq[:, par]
        S = gp[:, prox]
        a, dn, u, v = a2[:, :, 1], dn2[:, :, 1], u2[:, :, 1], v2[:, :, 1]
        lo, hi = np.abs(l1 - l2), L
        dc = np.clip(dn, lo[None], hi[None])
        cosb = np.clip((l1[None] ** 2 + dc**2 - l2[None] ** 2) / (2 * l1[None] * np.maximum(dc, 1e-300)), -1.0, 1.0)
        sinb = np.sqrt(1.0 - cosb**2)
        phi = ang[..., None]
        e_loc = a * (l1[None] * cosb)[..., None] + (u * np.cos(phi) + v * np.sin(phi)) * (l1[None] * sinb)[..., None]
        EW_star = S[:, :, None] + qrot(Rp[:, :, None], np.stack([e_loc, a * dc[..., None]], axis=2))
        E_star, W_star = EW_star[:, :, 0], EW_star[:, :, 1]
        E0 = gp[:, mid]
        q1 = min_rotation(E0 - S, E_star - S)
        # q1 G_prox, q1 G_mid and encode's end rotation R_parent^-1 G_dist, in one call
        G1 = quat_multiply(np.stack([q1, q1, rp_inv], axis=2), gq[:, self.triple])
        end_rot = G1[:, :, 2]
        EW1 = S[:, :, None] + qrot(q1[:, :, None], gp[:, self.pair_mw] - S[:, :, None])
        E1, W1 = EW1[:, :, 0], EW1[:, :, 1]
        q2 = min_rotation(W1 - E1, W_star - E1)
        Gs = G1[:, :, 0]
        GeGw = quat_multiply(np.stack([q2, Rp], axis=2), np.stack([G1[:, :, 1], end_rot], axis=2))
        Ge, Gw = GeGw[:, :, 0], GeGw[:, :, 1]
        rot = np.array(rotations, dtype=float)
        rot[:, self.limb_joints] = quat_multiply(qinv(np.concatenate([Rp, Gs, Ge], axis=1)),
                                                 np.concatenate([Gs, Ge, Gw], axis=1))
        # the Motion decode returns renormalises its rotations; its global positions are this FK
        rot = rot / vector_norm(rot, keepdims=True)  # np.linalg.norm's numbers
        out = self.outside
        if not np.array_equal(rot[:, out], rotations[:, out]):  # renormalising moved a bit: all levels
            return fk_arrays(self.levels, rot, local_t, copy=False)[1]
        # above the limbs nothing changed: forward kinematics of the limbs' subtrees only
        gq = gq.copy()
        for idx, jp in self.sub_rot_levels:  # world rotations of the subtree joints that have children
            gq[:, idx] = quat_multiply(gq[:, jp], rot[:, idx])
        gp[:, self.sub_joints] = local_t[:, self.sub_joints]
        return chain_positions(self.sub_levels, gq, gp)



@dataclass(frozen=True)
class _RestProbe:
    """What :func:`_target_skeleton` reads of an encoded motion (:class:`RetargetPlan`)."""

    joint_names: list
    parents: np.ndarray
    roles: dict
    rest_directions: np.ndarray


def naive_retarget(motion: Motion, target, *, scale_root: bool = False) -> Motion:
    """Baseline: copy the joint angles and the root translation onto the target skeleton.

    "People usually apply joint angles from character#1 to character#2" (Section 3.4.1)
    -- without the geometric constraint solving that should follow.  Position channels of
    the root path (root .. pelvis) are copied unchanged (``scale_root=False``) or
    multiplied by the ratio of hip heights (``scale_root=True``); other position channels
    take the target's offsets.

    Parameters
    ----------
    motion : Motion
    target : Skeleton or Motion
        Same joint names and parents.
    scale_root : bool, default False
    """
    _check_motion(motion)
    _check_target(target)
    scale_root = as_bool(scale_root, "scale_root", error=MotionError)
    tgt = skeleton_of(target)
    if not tgt.is_compatible(motion):
        raise MotionError("target skeleton has a different topology (joint names / parents) from the motion")
    src = Skeleton.from_motion(motion)
    channels = tgt.channels if tgt.channels is not None else motion.channels
    mask = _position_mask(channels)
    t = np.broadcast_to(tgt.offsets, (motion.n_frames, tgt.n_joints, 3)).copy()
    rp = _root_path(src)
    k = tgt.hip_height / src.hip_height if scale_root else 1.0
    t[:, rp] = motion.local_translations()[:, rp] * k
    return tgt.motion_with(motion.rotations, np.where(mask[None], t, tgt.offsets[None]),
                           frame_time=motion.frame_time, channels=channels)

