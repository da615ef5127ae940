"""Decoding: the morphology-independent representation put on a target skeleton (Section 3.4.1).

"Retargetting mainly consists of multiplying adimensional data of the skeleton by the new
dimensions of the character" (Pronost et al., Section 3.4): :func:`decode` multiplies the
data :func:`~repro.motion.retargeting.representation.encode` stored (Kulpa et al. 2005) by a
target skeleton's dimensions.  The per-frame arithmetic is :class:`Decoder`'s, which
:class:`~repro.motion.retargeting.morphology.RetargetPlan` runs too.

Decoding keeps every source local rotation, then replaces, for each limb, the rotations
of the proximal and middle joints by the smallest corrections that bring the middle and
distal joints onto the analytic two-bone solution (so the twist of the upper arm / thigh
is kept), and sets the distal joint's local rotation so its orientation in the limb's
parent frame is the source's.  On the source skeleton every correction is the identity:
the round trip reproduces the motion to rounding error.  Twist joints inside a limb's bones
(MakeHuman ``upperarm02.L``: joints of no role between the proximal, middle and distal ones)
keep their local rotations and turn with the joint above them; the bones are measured
between the limb's joints (:func:`~repro.motion.retargeting.representation.limb_segments`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.checks import as_bool, as_real, describe
from repro.errors import MotionError
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.core.kinematics import depth_levels, fk_arrays
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import min_rotation, quat_multiply
from repro.motion.core.quaternion import quat_conjugate as qinv
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.retargeting.planted_feet import pin_planted_feet
from repro.motion.retargeting.representation import (
    LIMB_NAMES,
    Encoder,
    MorphologyIndependentMotion,
    limb_frames,
    limb_indices,
    limb_segments,
    position_mask,
)

__all__ = ["REST_ANGLE_DEG", "DecodeReport", "Decoder", "decode", "decode_with_report", "rest_turn"]


def check_mi(mi: MorphologyIndependentMotion) -> None:
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


#: Largest angle (degrees) between a bone's rest direction on the source and on the target for the
#: copied local rotations to mean the same pose: the decoder refuses more (``max_rest_angle_deg``), and
#: :func:`repro.motion.retargeting.morphology.retarget` first re-expresses the motion on the target's rest.
REST_ANGLE_DEG: float = 5.0


def rest_turn(source, target_offsets: np.ndarray) -> tuple[float, int]:
    """``(degrees, joint)``: the largest angle between a bone's rest direction on the source (``source``:
    its rest offsets or unit directions, a zero row for no bone) and on the target (its rest offsets), and
    the joint whose bone it is (``(0.0, -1)`` when no bone has a length on both)."""
    ls, lt = np.linalg.norm(source, axis=1), np.linalg.norm(target_offsets, axis=1)
    ok = (ls > 0) & (lt > 0)
    if not ok.any():
        return 0.0, -1
    cos = np.sum(target_offsets[ok] / lt[ok, None] * (source[ok] / ls[ok, None]), axis=1)
    ang = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    k = int(np.argmax(ang))
    return float(ang[k]), int(np.flatnonzero(ok)[k])


def target_skeleton(mi, target, max_rest_angle_deg: float) -> Skeleton:
    """``target`` as a Skeleton with the roles of ``mi`` (an encoded motion or an :class:`~repro.motion.retargeting.representation.Encoder`),
    checked: the same joint names and parents, bones pointing the same way at rest."""
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
    worst, j = rest_turn(mi.rest_directions, tgt.offsets)
    if worst > max_rest_angle_deg:
        raise MotionError(
            f"target rest pose differs from the source's: bone to {tgt.joint_names[j]!r} is turned by "
            f"{worst:.1f} degrees (> {max_rest_angle_deg}); local rotations would not mean the same pose"
        )
    return tgt


class Decoder:
    """What decoding reads of the target skeleton (and of the source's layout), computed once, and
    the per-frame arithmetic: :func:`decode_with_report` and
    :class:`~repro.motion.retargeting.morphology.RetargetPlan` run its methods.

    Parameters
    ----------
    source
        A :class:`~repro.motion.retargeting.representation.MorphologyIndependentMotion` or the
        source's :class:`~repro.motion.retargeting.representation.Encoder` (their joint names,
        parents, roles, channels, rest directions, root path and swivel references).
    target : Skeleton or Motion
        Same joint names and parents.
    max_rest_angle_deg : float
        See :func:`decode`.

    Raises
    ------
    repro.errors.MotionError
        Another topology or rest pose, a limb whose proximal joint is the root, no channels.
    """

    def __init__(self, source, target, max_rest_angle_deg: float):
        tgt = target_skeleton(source, target, max_rest_angle_deg)
        self.skeleton = tgt
        self.channels = tgt.channels if tgt.channels is not None else source.channels
        if self.channels is None:
            raise MotionError("neither skeleton has channels: the decoded motion needs them")
        self.mask = position_mask(self.channels)
        bl = tgt.bone_lengths
        H = tgt.hip_height
        mul = np.where(np.linalg.norm(source.rest_directions, axis=1) > 0, bl, H)
        mul[source.root_path] = H
        self.mul = mul
        self.offsets = tgt.offsets
        # the same tree: an encoder's levels are the target's
        self.levels = source.levels if isinstance(source, Encoder) else depth_levels(tgt.parents)
        self.prox, self.mid, self.dist, self.par = limb_indices(tgt)
        self.l1, self.l2 = limb_segments(tgt, self.prox, self.mid, self.dist)
        self.L = self.l1 + self.l2
        # the frames the middle and distal joints' rotations are local to: the proximal and middle
        # joints', or those of the twist joints between (carried along with their bone)
        self.par_mid, self.par_dist = tgt.parents[self.mid], tgt.parents[self.dist]
        self.twisted = bool(np.any(self.par_mid != self.prox) or np.any(self.par_dist != self.mid))
        self.pair_pm = np.stack([self.prox, self.mid], axis=1)  # (4, 2): proximal, middle
        self.pair_mw = np.stack([self.mid, self.dist], axis=1)  # (4, 2): middle, distal
        self.limb_joints = np.concatenate([self.prox, self.mid, self.dist])
        self.triple = np.stack([self.prox, self.mid, self.dist], axis=1)

    def local_translations(self, translations: np.ndarray) -> np.ndarray:
        """(F, J, 3) the target's local translations of normalised ones: the position channels
        scaled by its hip height / bone lengths, its offsets elsewhere."""
        return np.where(self.mask[None], translations * self.mul[None, :, None], self.offsets[None])

    def place_limbs(self, rotations, gq, gp, a, dn, u, v, swivel, end_rot=None, rp_inv=None):
        """``(rotations, (E1, W1, q2))``: ``rotations`` (F, J, 4) with the limbs' joints replaced.

        ``gq``, ``gp``: the target's world transforms with the source's local rotations;
        ``a, dn, u, v``: :func:`~repro.motion.retargeting.representation.limb_frames` of the
        wanted proximal -> distal vectors (F, 4, 3) in the limbs' parent frames; ``swivel``
        (F, 4) and ``end_rot`` (F, 4, 4) the stored angles and distal orientations; without
        ``end_rot`` (source and target of one plan: the same world rotations),
        :meth:`~repro.motion.retargeting.representation.Encoder.end_rotations` of ``rp_inv``
        and ``gq``, in the call that turns the proximal and middle joints.  The
        middle joint goes on the circle about the axis at the swivel angle (two-bone IK, law
        of cosines, distances clipped to the reach), the proximal and middle joints turn by
        the smallest rotations that bring the middle and distal joints there; ``E1``,
        ``W1`` and ``q2`` let :func:`decode_with_report` measure the distal error.  Like
        operations of the limbs (the two goals, the two world products) run as one stacked
        call each, which gives the numbers of separate calls.
        """
        l1, l2, L = self.l1, self.l2, self.L
        Rp = gq[:, self.par]
        S = gp[:, self.prox]
        lo, hi = np.abs(l1 - l2), L
        dc = np.clip(dn, lo[None], hi[None])
        cosb = np.clip((l1[None] ** 2 + dc**2 - l2[None] ** 2) / (2 * l1[None] * np.maximum(dc, 1e-300)), -1.0, 1.0)
        sinb = np.sqrt(1.0 - cosb**2)
        phi = swivel[..., None]
        e_loc = a * (l1[None] * cosb)[..., None] + (u * np.cos(phi) + v * np.sin(phi)) * (l1[None] * sinb)[..., None]
        EW_star = S[:, :, None] + qrot(Rp[:, :, None], np.stack([e_loc, a * dc[..., None]], axis=2))
        E_star, W_star = EW_star[:, :, 0], EW_star[:, :, 1]
        q1 = min_rotation(gp[:, self.mid] - S, E_star - S)
        if end_rot is None:  # q1 G_prox, q1 G_mid and R_parent^-1 G_dist
            G1 = quat_multiply(np.stack([q1, q1, rp_inv], axis=2), gq[:, self.triple])
            end_rot = G1[:, :, 2]
        else:  # q1 G_prox, q1 G_mid
            G1 = quat_multiply(np.stack([q1, q1], axis=2), gq[:, self.pair_pm])
        EW1 = S[:, :, None] + qrot(q1[:, :, None], gp[:, self.pair_mw] - S[:, :, None])
        E1, W1 = EW1[:, :, 0], EW1[:, :, 1]
        q2 = min_rotation(W1 - E1, W_star - E1)
        Gs = G1[:, :, 0]
        GeGw = quat_multiply(np.stack([q2, Rp], axis=2), np.stack([G1[:, :, 1], end_rot], axis=2))
        Ge, Gw = GeGw[:, :, 0], GeGw[:, :, 1]
        rot = np.array(rotations, dtype=float)
        Pm, Pd = Gs, Ge  # the middle and distal joints' parents' new world rotations
        if self.twisted:  # a twist joint turns with the joint above it
            Pm = np.where((self.par_mid == self.prox)[None, :, None], Gs, quat_multiply(q1, gq[:, self.par_mid]))
            Pd = np.where((self.par_dist == self.mid)[None, :, None], Ge,
                          quat_multiply(q2, quat_multiply(q1, gq[:, self.par_dist])))
        rot[:, self.limb_joints] = quat_multiply(qinv(np.concatenate([Rp, Pm, Pd], axis=1)),
                                                 np.concatenate([Gs, Ge, Gw], axis=1))
        return rot, (E1, W1, q2)

    def motion(self, rotations: np.ndarray, local_t: np.ndarray, frame_time: float) -> Motion:
        """The decoded Motion on the target skeleton (its channels, else the source's)."""
        return self.skeleton.motion_with(rotations, local_t, frame_time=frame_time, channels=self.channels)


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


def decode_with_report(
    mi: MorphologyIndependentMotion,
    target,
    *,
    fix_feet: bool = False,
    blend_time: float = 0.1,
    max_rest_angle_deg: float = REST_ANGLE_DEG,
) -> tuple[Motion, DecodeReport]:
    """:func:`decode`, also returning a :class:`DecodeReport`."""
    check_mi(mi)
    fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
    blend_time = as_real(blend_time, "blend_time (seconds)", error=MotionError, lo=0.0)
    max_rest_angle_deg = as_real(max_rest_angle_deg, "max_rest_angle_deg", error=MotionError, lo=0.0, hi=180.0)
    dec = Decoder(mi, target, max_rest_angle_deg)
    local_t = dec.local_translations(mi.translations)
    rot = np.array(mi.rotations, dtype=float)
    gq, gp = fk_arrays(dec.levels, rot, local_t)
    want = mi.limb_vectors * dec.L[None, :, None]
    lowered = 0.0
    if fix_feet:
        want, lowered = pin_planted_feet(dec, want, gq, gp, local_t, mi.contacts, mi.ankle_heights, mi.frame_time,
                                         blend_time)
    a, dn, u, v = limb_frames(want, 1e-12 * dec.L[None], mi.swivel_axes[None], mi.swivel_refs[None])
    rot, (E1, W1, q2) = dec.place_limbs(rot, gq, gp, a, dn, u, v, mi.limb_swivel, mi.limb_end_rotations)
    lo, hi = np.abs(dec.l1 - dec.l2), dec.L
    clamped = (dn < lo[None] * (1 - 1e-9)) | (dn > hi[None] * (1 + 1e-9))
    S, Rp = gp[:, dec.prox], gq[:, dec.par]
    W_final = E1 + qrot(q2, W1 - E1)
    err = float(np.max(np.linalg.norm(W_final - S - qrot(Rp, want), axis=-1), initial=0.0))
    report = DecodeReport(
        clamped={k: int(c) for k, c in zip(LIMB_NAMES, clamped.sum(axis=0))},
        max_distal_error=err,
        max_root_drop=lowered,
    )
    return dec.motion(rot, local_t, mi.frame_time), report


def decode(
    mi: MorphologyIndependentMotion,
    target,
    *,
    fix_feet: bool = False,
    blend_time: float = 0.1,
    max_rest_angle_deg: float = REST_ANGLE_DEG,
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
