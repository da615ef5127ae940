"""Retargeting on one joint tree through the morphology-independent representation (Section 3.4.1).

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.4.1, retarget database motions to fighters of other sizes
with the representation of Kulpa, Multon and Arnaldi, "Morphology-independent
representation of motions for interactive human-like animation" (Eurographics 2005), and
"retargetting mainly consists of multiplying adimensional data of the skeleton by the new
dimensions of the character" (Section 3.4).  The method is in three modules, by idea:

* :mod:`repro.motion.retargeting.representation`: what is stored (limb vectors, swivel
  angles, ...) and :func:`encode`;
* :mod:`repro.motion.retargeting.decoding`: the data put on a target skeleton,
  :func:`decode` (two-bone IK of the limbs);
* :mod:`repro.motion.retargeting.planted_feet`: ``fix_feet``, the feet artifacts corrected.

This module puts them together: :class:`RetargetPlan`, the two skeletons' constants and the
per-frame arithmetic of encoding then decoding; :func:`retarget`, which builds the plan and
applies it (or goes through :func:`~repro.motion.retargeting.trees.retarget_across` for a
character of another joint tree); and :func:`naive_retarget`, the baseline the paper
improves on ("people usually apply joint angles from character#1 to character#2").
"""

from __future__ import annotations

import dataclasses

import numpy as np

from repro.checks import as_bool, as_real, describe
from repro.errors import MotionError
from repro.motion.body.rest_pose import match_rest_pose
from repro.motion.body.skeleton import Skeleton, check_role_table, skeleton_of
from repro.motion.core.kinematics import chain_positions, check_pose_arrays, fk_arrays, world_of
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import quat_multiply, quat_rotate, vector_norm
from repro.motion.retargeting.decoding import (
    REST_ANGLE_DEG,
    DecodeReport,
    Decoder,
    decode,
    decode_with_report,
    rest_turn,
)
from repro.motion.retargeting.planted_feet import pin_planted_feet
from repro.motion.retargeting.representation import (
    LIMB_NAMES,
    Encoder,
    MorphologyIndependentMotion,
    check_motion,
    encode,
    limb_frames,
    position_mask,
    root_path,
)
from repro.motion.retargeting.trees import retarget_across

__all__ = [
    "LIMB_NAMES",
    "REST_ANGLE_DEG",
    "DecodeReport",
    "MorphologyIndependentMotion",
    "RetargetPlan",
    "decode",
    "decode_with_report",
    "encode",
    "naive_retarget",
    "retarget",
]


def _check_target(target) -> None:
    if not isinstance(target, (Skeleton, Motion)):
        raise MotionError(f"target must be a Skeleton or a Motion, got {describe(target)}")


def _on_target_rest(motion: Motion, sk: Skeleton, target, roles) -> tuple[Motion, Skeleton]:
    """``(motion, its skeleton)``, re-expressed on ``target``'s rest directions when a bone's differ by
    more than :data:`REST_ANGLE_DEG` (:func:`repro.motion.body.rest_pose.match_rest_pose`: the same world
    bone directions, so the same poses; CMU subjects 131, 7 and 9 against subject 135, A- / N-pose rigs)."""
    tgt = skeleton_of(target)
    if rest_turn(sk.offsets, tgt.offsets)[0] <= REST_ANGLE_DEG:
        return motion, sk
    matched = match_rest_pose(motion, tgt)
    return matched, Skeleton.from_motion(matched, roles=roles)


def retarget(motion: Motion, target, *, roles=None, fix_feet: bool = False) -> Motion:
    """``decode(encode(motion), target)``: the paper's retargeting (Section 3.4.1).

    ``RetargetPlan(motion, target, roles=roles).apply(motion, fix_feet=fix_feet)``: the plan of
    the two skeletons, applied (the numbers of :func:`encode` then :func:`decode`).

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

    A target of the same joint tree whose rest pose differs (a bone turned by more than
    :data:`REST_ANGLE_DEG`: another CMU subject's ASF axes, an A- or N-pose rig) gets the motion
    re-expressed on its rest directions first (the same poses).  A target whose joint tree
    differs (other joint names with the same parents; or another tree, rest pose or up axis) is
    retargeted too: with the same parents and
    the roles on the same joints, the joints are renamed and decoded as above (exact);
    otherwise through the body-part roles, :func:`repro.motion.retargeting.trees.retarget_across`.
    """
    check_motion(motion)
    _check_target(target)
    roles = check_role_table(roles, "roles")
    fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
    sk = Skeleton.from_motion(motion, roles=roles)
    if list(target.joint_names) == list(motion.joint_names) and np.array_equal(target.parents, motion.parents):
        motion, sk = _on_target_rest(motion, sk, target, roles)
        return RetargetPlan(sk, target).apply(motion, fix_feet=fix_feet)
    Encoder(sk)  # what encoding refuses is refused whatever the target
    tgt = skeleton_of(target)
    if np.array_equal(tgt.parents, motion.parents):
        src_index = {r: motion.joint_names.index(j) for r, j in sk.roles.items()}
        if all(tgt.roles.get(r) == tgt.joint_names[i] for r, i in src_index.items()):
            renamed = dataclasses.replace(tgt, joint_names=list(motion.joint_names), roles=sk.roles)
            try:
                out = RetargetPlan(sk, renamed).apply(motion, fix_feet=fix_feet)
            except MotionError:
                out = None  # another rest pose: through the roles
            if out is not None:
                return dataclasses.replace(out, joint_names=list(tgt.joint_names))
    return retarget_across(motion, target, roles=roles, fix_feet=fix_feet)


class RestStep:
    """:func:`~repro.motion.body.rest_pose.match_rest_pose` of ``source`` onto ``target``'s rest directions,
    as a plan step: its per-joint constant rotations ``C_j`` computed once, applied to poses by :meth:`pose`.

    ``C_j`` are the world rotations of the source's rest pose matched (``G'_j = G_j C_j`` with
    ``G = I``); a pose's local rotations become ``L'_j = C_p^-1 L_j C_j``, its local translations
    the matched offsets, except the root's (kept) and those of the joints below the root whose
    position channels vary in ``source`` (turned by ``C_p^-1``): the numbers of ``match_rest_pose``
    up to rounding.

    Parameters
    ----------
    source : Motion
        The poses' skeleton and channels (a Skeleton's :meth:`~repro.motion.body.skeleton.Skeleton.rest_motion`).
    target : Skeleton or Motion
        Same joint names and parents.
    """

    def __init__(self, source: Motion, target):
        rest = np.zeros_like(source.rotations)
        rest[..., 3] = 1.0
        #: the source's skeleton with the target's rest directions (its first frame: rest pose)
        self.skeleton = match_rest_pose(dataclasses.replace(source, rotations=rest), target)
        self.C = self.skeleton.global_transforms()[0][0]
        self.Cinv = self.C * np.array([-1.0, -1.0, -1.0, 1.0])
        self.parents = np.asarray(source.parents)
        self.offsets = np.asarray(self.skeleton.offsets)
        moved = np.abs(self.skeleton.local_translations() - self.offsets[None]).max(axis=0).max(axis=1) > 0
        moved[0] = False
        self.varying = np.flatnonzero(moved)

    def pose(self, rotations: np.ndarray, translations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(local rotations, local translations)`` (F, J, 4), (F, J, 3) on the matched skeleton."""
        par = self.parents
        r = quat_multiply(rotations, self.C[None])
        r[:, 1:] = quat_multiply(self.Cinv[None, par[1:]], r[:, 1:])
        t = np.broadcast_to(self.offsets, translations.shape).copy()
        t[:, 0] = translations[:, 0]
        for c in self.varying:
            t[:, c] = quat_rotate(np.broadcast_to(self.Cinv[par[c]], (len(t), 4)), translations[:, c])
        return r, t


class RetargetPlan:
    """:func:`retarget` between two fixed skeletons of the same joint tree.

    Everything of :func:`encode` and :func:`decode` that depends only on the source and
    target skeletons (roles, limb indices and lengths, hip heights, swivel references,
    the rest-direction check, the depth levels) is computed once here
    (:class:`~repro.motion.retargeting.representation.Encoder`,
    :class:`~repro.motion.retargeting.decoding.Decoder`); the per-frame arithmetic is
    theirs, run by :meth:`apply` (the retargeted Motion: :func:`retarget` is this plan
    applied) and :meth:`positions` (its world positions only, for few frames at a time,
    without the Motion objects nor the foot contacts:
    :meth:`repro.motion.search.retrieval.MotionRetriever.prepare`, one pose per query).
    Encoding's and decoding's limb frames run as one stacked call when the feet are not
    fixed, which gives the numbers of two.  A target whose rest directions differ by more than
    :data:`REST_ANGLE_DEG` gets the poses re-expressed on them first, as :func:`retarget` does,
    by a :class:`RestStep` (per-joint constant rotations computed here, applied to all frames at
    once; :func:`retarget`'s numbers up to rounding); otherwise the plan has no such step.

    Parameters
    ----------
    source : Skeleton or Motion
        The skeleton the poses are on (roles found as :func:`encode` does, or ``roles``).
    target : Skeleton or Motion
        Same joint names and parents (else :func:`retarget` takes other paths: not planned).
    roles : mapping role -> joint, optional
        The source's role table, when ``source`` is a Motion (default: found).

    Raises
    ------
    repro.errors.MotionError
        What :func:`retarget` raises for these skeletons (missing roles, zero-length limb
        bones, another topology).
    """

    def __init__(self, source, target, *, roles=None):
        _check_target(target)
        roles = check_role_table(roles, "roles")
        sk = skeleton_of(source, roles=roles)
        if list(target.joint_names) != list(sk.joint_names) or not np.array_equal(target.parents, sk.parents):
            raise MotionError("RetargetPlan: the target must have the source's joint names and parents")
        self.n_joints = sk.n_joints
        self.rest = None
        if rest_turn(sk.offsets, skeleton_of(target).offsets)[0] > REST_ANGLE_DEG:
            self.rest = RestStep(source if isinstance(source, Motion) else sk.rest_motion(), target)
            sk = Skeleton.from_motion(self.rest.skeleton, roles=roles)
        self.encoder = enc = Encoder(sk)
        self.decoder = dec = Decoder(enc, target, REST_ANGLE_DEG)
        self.thr = np.stack([1e-12 * enc.L, 1e-12 * dec.L], axis=1)  # (4, 2): encode, decode
        self._subtrees(np.asarray(sk.parents), enc.prox)

    def _subtrees(self, parents: np.ndarray, prox: np.ndarray) -> None:
        """The joints whose world transforms the new limb rotations change (the limbs' subtrees), by
        depth below the subtree roots: :meth:`positions`' last forward kinematics runs over these only."""
        J = self.n_joints
        inside = np.zeros(J, dtype=bool)
        inside[prox] = True
        rel = np.full(J, -1)
        for j in range(J):
            p = parents[j]
            if p >= 0 and inside[p]:
                inside[j] = True
            if inside[j]:
                rel[j] = rel[p] + 1 if p >= 0 and inside[p] else 0
        self.outside = np.flatnonzero(~inside)
        self.sub_levels = [(np.flatnonzero(rel == r), parents[rel == r]) for r in range(int(rel.max()) + 1)]
        self.sub_joints = np.concatenate([i for i, _ in self.sub_levels])
        has_child = np.zeros(J, dtype=bool)
        has_child[parents[1:]] = True
        self.sub_rot_levels = [(i[has_child[i]], p[has_child[i]]) for i, p in self.sub_levels if has_child[i].any()]

    def apply(self, motion: Motion, *, fix_feet: bool = False, blend_time: float = 0.1) -> Motion:
        """``motion`` (on the plan's source skeleton) on the target: ``decode(encode(motion), target, ...)``.

        ``fix_feet``, ``blend_time``: see :func:`decode`."""
        check_motion(motion)
        if list(motion.joint_names) != self.encoder.joint_names:
            raise MotionError("RetargetPlan.apply: the motion must be on the plan's source skeleton")
        fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
        blend_time = as_real(blend_time, "blend_time (seconds)", error=MotionError, lo=0.0)
        r, t = motion.rotations, motion.local_translations()
        if self.rest is not None:
            r, t = self.rest.pose(r, t)
        gq, gp = fk_arrays(self.encoder.levels, r, t)
        feet = None
        if fix_feet:
            feet = self.encoder.feet(motion, gp) + (motion.frame_time, blend_time)
        rot, local_t, _ = self._solve(r, t, gq, gp, feet)
        return self.decoder.motion(rot, local_t, motion.frame_time)

    def positions(self, rotations: np.ndarray, translations: np.ndarray, *, source=None) -> np.ndarray:
        """(F, J, 3) world positions of the retargeted frames, target units: ``apply(...).global_positions()``.

        ``rotations`` (F, J, 4) unit quaternions and ``translations`` (F, J, 3) the local
        translations (:meth:`~repro.motion.core.motion.Motion.local_translations`) of the source;
        ``source``: its world ``(rotations, positions)`` when already computed
        (:meth:`~repro.motion.core.motion.Motion.global_transforms`; default: computed here).
        """
        rotations, translations = check_pose_arrays(rotations, translations, self.n_joints)
        if self.rest is not None:
            rotations, translations = self.rest.pose(rotations, translations)
            source = None if source is None else (quat_multiply(source[0], self.rest.C[None]), source[1])
        gq, gp = world_of(self.encoder.levels, rotations, translations, source)
        rot, local_t, gp = self._solve(rotations, translations, gq, gp)
        # the Motion apply returns renormalises its rotations; its global positions are this FK
        rot = rot / vector_norm(rot, keepdims=True)  # np.linalg.norm's numbers
        out = self.outside
        if not np.array_equal(rot[:, out], rotations[:, out]):  # renormalising moved a bit: all levels
            return fk_arrays(self.encoder.levels, rot, local_t, copy=False)[1]
        # above the limbs nothing changed: forward kinematics of the limbs' subtrees only
        gq = gq.copy()
        for idx, jp in self.sub_rot_levels:  # world rotations of the subtree joints that have children
            gq[:, idx] = quat_multiply(gq[:, jp], rot[:, idx])
        gp[:, self.sub_joints] = local_t[:, self.sub_joints]
        return chain_positions(self.sub_levels, gq, gp)

    def _solve(self, rotations, translations, gq, gp, feet=None):
        """``(rotations, local translations, world positions before the limbs)`` on the target, of the
        source's local ``rotations`` and ``translations`` and world transforms ``gq``, ``gp``;
        ``feet``: ``(contacts, ankle heights, frame time, blend time)`` to pin planted feet."""
        enc, dec = self.encoder, self.decoder
        rp_inv, d, e = enc.limb_vectors(gq, gp)
        want = d / enc.L[None, :, None] * dec.L[None, :, None]
        local_t = dec.local_translations(enc.translations(translations))
        # the target's world rotations are the source's (same local rotations, same tree): positions only
        gp_t = chain_positions(dec.levels, gq, local_t.copy())
        a0, r0 = enc.swivel_axes[None], enc.swivel_refs[None]
        if feet is None:  # the limb frames of encode (d) and decode (want), in one call
            a, dn, u, v = limb_frames(np.stack([d, want], axis=2), self.thr[None], a0[:, :, None], r0[:, :, None])
            axes, frames = (a[:, :, 0], u[:, :, 0], v[:, :, 0]), (a[:, :, 1], dn[:, :, 1], u[:, :, 1], v[:, :, 1])
        else:
            a, _, u, v = limb_frames(d, self.thr[None, :, 0], a0, r0)
            axes = (a, u, v)
            want, _ = pin_planted_feet(dec, want, gq, gp_t, local_t, *feet)
            frames = limb_frames(want, self.thr[None, :, 1], a0, r0)
        swivel = enc.swivel(e, *axes)
        rot, _ = dec.place_limbs(rotations, gq, gp_t, *frames, swivel, rp_inv=rp_inv)
        return rot, local_t, gp_t


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
    check_motion(motion)
    _check_target(target)
    scale_root = as_bool(scale_root, "scale_root", error=MotionError)
    tgt = skeleton_of(target)
    if not tgt.is_compatible(motion):
        raise MotionError("target skeleton has a different topology (joint names / parents) from the motion")
    src = Skeleton.from_motion(motion)
    channels = tgt.channels if tgt.channels is not None else motion.channels
    mask = position_mask(channels)
    t = np.broadcast_to(tgt.offsets, (motion.n_frames, tgt.n_joints, 3)).copy()
    rp = root_path(src)
    k = tgt.hip_height / src.hip_height if scale_root else 1.0
    t[:, rp] = motion.local_translations()[:, rp] * k
    return tgt.motion_with(motion.rotations, np.where(mask[None], t, tgt.offsets[None]),
                           frame_time=motion.frame_time, channels=channels)

