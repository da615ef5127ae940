"""Rest-pose matching: a motion re-expressed on a skeleton with another skeleton's rest directions.

CMU subjects share the joint tree but not the rest directions (ASF bone axes); the
retargeting of Pronost et al. Section 3.4.1 (:func:`repro.motion.retargeting.morphology.decode`)
copies local rotations, which only mean the same pose on skeletons whose bones point the
same way at rest.  :func:`match_rest_pose` bridges that (see its docstring for the
construction and the measured sizes).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from repro.errors import MotionError
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import quat_multiply, quat_rotate
from repro.motion.body.skeleton import skeleton_of

__all__ = ["match_rest_pose"]


def _best_rotation(ref_dirs: np.ndarray, src_vecs: np.ndarray) -> np.ndarray:
    """Quaternion ``C`` minimising ``sum_c |C (l_c r_c) - s_c|^2`` (``l_c = |s_c|``).

    ``ref_dirs`` (n, 3) unit directions, ``src_vecs`` (n, 3) vectors; one pair (or only
    parallel pairs): the smallest rotation taking the longest ``r`` to its ``s``;
    several: Kabsch (SVD), proper rotation.
    """
    if ref_dirs.shape[0] == 0:
        return np.array([0.0, 0.0, 0.0, 1.0])
    a = ref_dirs * np.linalg.norm(src_vecs, axis=1, keepdims=True)
    H = a.T @ src_vecs  # sum a_c s_c^T
    sv = np.linalg.svd(H, compute_uv=False)
    if ref_dirs.shape[0] == 1 or sv[1] <= 1e-9 * sv[0]:
        # one direction (or several parallel ones, e.g. CMU children sharing the end of
        # their parent's bone): the smallest rotation, no arbitrary twist
        k = int(np.argmax(np.linalg.norm(src_vecs, axis=1)))
        u = ref_dirs[k] / np.linalg.norm(ref_dirs[k])
        v = src_vecs[k] / np.linalg.norm(src_vecs[k])
        ax = np.cross(u, v)
        q = np.concatenate([ax, [1.0 + float(u @ v)]])
        n = np.linalg.norm(q)
        if n < 1e-9:  # opposite: half turn about any perpendicular axis
            e = np.eye(3)[int(np.argmin(np.abs(u)))]
            ax = np.cross(u, e)
            return np.concatenate([ax / np.linalg.norm(ax), [0.0]])
        return q / n
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return Rotation.from_matrix(R).as_quat()


def match_rest_pose(motion: Motion, reference, *, return_error: bool = False):
    """The motion's poses on a skeleton with ``reference``'s rest directions and its own bone lengths.

    The retargeting of Section 3.4.1 (:func:`repro.motion.retargeting.morphology.decode`) copies
    the local rotations of the non-limb segments, which only mean the same pose on
    skeletons whose bones point the same way at rest; it refuses targets whose rest
    directions differ by more than 5 degrees.  CMU subjects share the joint tree but not
    the rest directions (ASF bone axes): subjects 131, 7 and 9 differ from subject 135 by
    11.7, 12.0 and 14.1 degrees (femurs, clavicles, neck, humerus), so their takes cannot
    be retargeted to the CMU 135 actor as they are.  This function re-expresses such a
    motion on a skeleton ``S'`` with the *same joint tree and bone lengths* as the motion
    and the *rest directions* of ``reference``, keeping every bone's world direction.

    For every joint ``j`` a constant rotation ``C_j`` takes the reference's rest
    directions of ``j``'s children (joints and End Sites) to the motion's rest offsets
    (the exact smallest rotation for one child, the least-squares rotation weighted by
    the bone lengths for several, :func:`_best_rotation`); then world rotations become
    ``G'_j = G_j C_j`` and local ones ``L'_j = C_p^-1 L_j C_j``.  Offsets of ``S'``:
    ``|offset_c| r_c``; root-path translations (position channels below the root, e.g.
    Bandai's Hips) are kept exactly (``C_p^-1 t``).  A joint with one child keeps every
    child position exactly; where the angles between several children differ between the
    two rest poses (CMU root: hips and lower back; thorax: neck and clavicles) the
    children move by the residual of the fit, and the subtree below moves rigidly with
    them.  With ``return_error=True`` the largest joint displacement (file units) is
    returned as well.  On the CMU files it is 0 up to rounding: there every child of a
    joint starts at the end of that joint's bone (one offset shared by the children,
    zero offsets below the root), so one rotation fits them all exactly.

    Bone lengths are kept; the :attr:`~repro.motion.body.skeleton.Skeleton.size` changes a
    little (it measures the hip drop and head top along rest directions): subject 131
    1.530 -> 1.511 m, 7 1.568 -> 1.551 m, 9 1.627 -> 1.605 m against subject 135.

    Parameters
    ----------
    motion : Motion
    reference : Skeleton or Motion
        Same joint names and parents.

    Returns
    -------
    Motion, or (Motion, float)
        Same frames, channels, frame time, unit and source (``" (rest of <ref>)"``
        appended).  A joint without rotation channels may get a non-identity rotation
        (then :func:`~repro.motion.write_bvh` refuses it; the CMU and Bandai files have
        rotation channels on every joint).

    Raises
    ------
    repro.errors.MotionError
        Different joint trees.
    """
    ref = skeleton_of(reference)
    if not ref.is_compatible(motion):
        raise MotionError("reference skeleton has another joint tree (joint names / parents) than the motion")
    par = np.asarray(motion.parents)
    off = np.asarray(motion.offsets, dtype=float)
    varying = _translated_joints(motion, off)
    roff = np.asarray(ref.offsets, dtype=float)
    esp, eso = motion.end_site_parents, np.asarray(motion.end_site_offsets, dtype=float)
    reso = np.asarray(ref.end_site_offsets, dtype=float) if np.array_equal(esp, ref.end_site_parents) else None
    C = _rest_corrections(par, varying, off, roff, esp, eso, reso)
    Cinv = C * np.array([-1.0, -1.0, -1.0, 1.0])
    new_off = _new_offsets(par, varying, off, roff, Cinv)
    new_eso = _new_end_site_offsets(esp, eso, reso, Cinv)
    rotations, positions = _new_channels(motion, par, varying, new_off, C, Cinv)
    out = dataclasses.replace(motion, offsets=new_off, rotations=rotations, positions=positions,
                              end_site_offsets=new_eso, source=(motion.source or "") + " (rest pose matched)")
    if not return_error:
        return out
    err = float(np.linalg.norm(out.global_positions() - motion.global_positions(), axis=-1).max())
    return out, err


def _unit(v: np.ndarray) -> np.ndarray | None:
    """``v / |v|``, or None for a (near) zero vector."""
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else None


def _translated_joints(motion: Motion, off: np.ndarray) -> np.ndarray:
    """(J,) bool: joints below the root whose position channels carry a translation other than the OFFSET.

    Bandai's Hips (the root trajectory); constant ones (Bandai's other joints, equal to
    their OFFSET up to 1e-7 relative) are offsets and follow the new rest directions.
    """
    mask = motion.position_mask
    scale = max(float(np.abs(off).max()), 1e-300)
    varying = np.zeros(motion.n_joints, dtype=bool)
    varying[1:] = np.any(mask[1:] & (np.abs(np.asarray(motion.positions)[:, 1:] - off[None, 1:]).max(axis=0)
                                     > 1e-5 * scale), axis=1)
    return varying


def _rest_corrections(par, varying, off, roff, esp, eso, reso) -> np.ndarray:
    """(J, 4) quaternions ``C_j`` taking the reference's rest directions of each joint's children
    to the motion's rest offsets (:func:`_best_rotation`; identity for a joint without children).

    The children are the joints not on a translated path and, when ``reso`` is given (the
    two skeletons have the same End Sites), the End Sites."""
    C = np.tile([0.0, 0.0, 0.0, 1.0], (len(par), 1))
    for j in range(len(par)):
        pairs = [(roff[c], off[c]) for c in np.flatnonzero(par == j) if not varying[c]]
        if reso is not None:
            pairs += [(reso[e], eso[e]) for e in np.flatnonzero(esp == j)]
        r_list, s_list = [], []
        for ref_vec, sv in pairs:
            r = _unit(ref_vec)
            if r is not None and np.linalg.norm(sv) > 1e-12:
                r_list.append(r)
                s_list.append(sv)
        if r_list:
            C[j] = _best_rotation(np.array(r_list), np.array(s_list))
    return C


def _new_offsets(par, varying, off, roff, Cinv) -> np.ndarray:
    """Offsets of ``S'``: ``|offset_c| r_c``; a translated joint's (or one with no reference direction)
    turned by its parent's ``C_p^-1``."""
    new_off = off.copy()
    for c in range(1, len(par)):
        r = _unit(roff[c])
        if varying[c] or r is None:
            new_off[c] = quat_rotate(Cinv[par[c]], off[c])
        else:
            new_off[c] = np.linalg.norm(off[c]) * r
    return new_off


def _new_end_site_offsets(esp, eso, reso, Cinv) -> np.ndarray:
    """End Site offsets of ``S'``: the reference's direction (``reso``, None when the End Sites
    differ) at the motion's length, else turned by the parent's ``C_p^-1``."""
    new_eso = eso.copy()
    for e, p in enumerate(esp):
        r = _unit(reso[e]) if reso is not None else None
        new_eso[e] = np.linalg.norm(eso[e]) * r if r is not None else quat_rotate(Cinv[p], eso[e])
    return new_eso


def _new_channels(motion: Motion, par, varying, new_off, C, Cinv) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``L'_j = C_p^-1 L_j C_j`` and positions: root and translated joints' kept
    (``C_p^-1 t`` below the root), the other position channels the new offsets."""
    new_rot = quat_multiply(np.asarray(motion.rotations), C[None])
    new_rot[:, 1:] = quat_multiply(Cinv[None, par[1:]], new_rot[:, 1:])
    pos = np.array(motion.positions, dtype=float)
    for c in np.flatnonzero(varying):
        pos[:, c] = quat_rotate(np.broadcast_to(Cinv[par[c]], (motion.n_frames, 4)), pos[:, c])
    pos[:, 0] = np.asarray(motion.positions)[:, 0]
    keep = motion.position_mask & (varying | (np.arange(motion.n_joints) == 0))[:, None]
    return new_rot, np.where(keep[None], pos, new_off[None])
