"""The morphology-independent representation of motion, and :func:`encode` (Section 3.4.1).

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
adimensional data (this module); :func:`~repro.motion.retargeting.decoding.decode`
multiplies it by a target skeleton's dimensions; :func:`~repro.motion.retargeting.morphology.retarget`
is both, through a :class:`~repro.motion.retargeting.morphology.RetargetPlan`.  The per-frame
arithmetic of encoding is :class:`Encoder`'s, which the plan runs too.  Everything is
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
and does not jump; ``decode`` clips the law of cosines to [-1, 1], so a fully
extended (or unreachable) limb is solved without NaN.  A limb whose target proportions
(upper/lower ratio) differ can be asked to fold closer than it can (``n * L <
|l_upper - l_lower|``): the distance is clipped to the reachable range, the middle joint
placed accordingly; :func:`~repro.motion.retargeting.decoding.decode_with_report` counts
those frames per limb.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.checks import describe
from repro.errors import MotionError
from repro.motion.body.feet import UP_AXIS, foot_contacts, foot_scale
from repro.motion.body.roles import LIMBS
from repro.motion.body.skeleton import Skeleton, check_role_table
from repro.motion.core.channels import POSITION_CHANNELS
from repro.motion.core.kinematics import depth_levels, fk_arrays, normalize, transport
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import cross, quat_multiply, vector_norm
from repro.motion.core.quaternion import quat_conjugate as qinv
from repro.motion.core.quaternion import quat_rotate as qrot

__all__ = ["LIMB_NAMES", "Encoder", "MorphologyIndependentMotion", "encode", "limb_frames", "limb_segments"]

LIMB_NAMES: tuple[str, ...] = tuple(LIMBS)  # left_arm, right_arm, left_leg, right_leg


def position_mask(channels) -> np.ndarray:
    """(J, 3) bool: which of X, Y, Z position channels each joint has."""
    return np.array([[c in ch for c in POSITION_CHANNELS] for ch in channels], dtype=bool).reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class MorphologyIndependentMotion:
    """A motion in the morphology-independent representation (Kulpa et al. 2005; Section 3.4.1).

    Built by :func:`encode`; :func:`~repro.motion.retargeting.decoding.decode` puts it on a skeleton.  All arrays are per
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


def limb_indices(sk: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Proximal, middle, distal joints and the limb's parent (the proximal joint's) of each limb."""
    prox = np.array([sk.index(LIMBS[k][0]) for k in LIMB_NAMES])
    mid = np.array([sk.index(LIMBS[k][1]) for k in LIMB_NAMES])
    dist = np.array([sk.index(LIMBS[k][2]) for k in LIMB_NAMES])
    par = sk.parents[prox]
    if np.any(par < 0):
        raise MotionError("a limb's proximal joint is the root; limbs need a parent frame")
    return prox, mid, dist, par


def limb_segments(sk: Skeleton, prox, mid, dist) -> tuple[np.ndarray, np.ndarray]:
    """Upper and lower bone lengths of limbs: proximal -> middle and middle -> distal
    (:meth:`~repro.motion.body.skeleton.Skeleton.segment_lengths`: across twist joints, MakeHuman
    ``upperarm02.L``, the rest distance between the limb's joints)."""
    prox, mid, dist = (np.atleast_1d(np.asarray(x, dtype=np.intp)) for x in (prox, mid, dist))
    return sk.segment_lengths(prox, mid), sk.segment_lengths(mid, dist)


def root_path(sk: Skeleton) -> np.ndarray:
    """The joints from the root down to the pelvis (the root trajectory's)."""
    return np.array([0] + sk.path(sk.joint_names[0], "pelvis"), dtype=np.intp)


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


def limb_frames(vectors: np.ndarray, thr, a0, r0):
    """``(a, |vectors|, u, v)``: the limb axes ``a`` (``a0`` where a vector is not longer than ``thr``),
    the parallel-transported swivel references ``u = R(a0 -> a) r0`` and ``v = a x u`` (module
    docstring); ``thr``, ``a0``, ``r0`` broadcast against ``vectors``' leading axes.  Encoding
    measures the swivel in these frames, decoding places the middle joint in them."""
    a, dn = normalize(vectors)
    a = np.where((dn > thr)[..., None], a, a0)
    u = transport(a0, r0, a)
    return a, dn, u, cross(a, u)


class Encoder:
    """What :func:`encode` reads of the source skeleton, computed once, and the per-frame arithmetic.

    The limbs' joints and lengths, the swivel references ``a0`` and ``r0``, the hip height
    and the divisors of the translations, the rest directions.  :func:`encode` and
    :class:`~repro.motion.retargeting.morphology.RetargetPlan` run its methods.

    Raises
    ------
    repro.errors.MotionError
        A limb whose proximal joint is the root, coincident left/right joints, a hip
        height that is not > 0.
    """

    def __init__(self, sk: Skeleton):
        self.skeleton = sk
        self.joint_names, self.parents, self.roles = list(sk.joint_names), np.array(sk.parents), dict(sk.roles)
        self.channels = sk.channels
        self.levels = depth_levels(sk.parents)
        self.prox, self.mid, self.dist, self.par = limb_indices(sk)
        bl = sk.bone_lengths
        l1, l2 = limb_segments(sk, self.prox, self.mid, self.dist)
        self.l1 = l1
        self.L = l1 + l2
        self.swivel_axes, self.swivel_refs = _swivel_frames(sk)
        H = sk.hip_height
        if not np.isfinite(H) or H <= 0:
            raise MotionError(f"source hip height must be > 0, got {H!r}")
        self.hip_height = H
        self.root_path = root_path(sk)
        nonzero = bl > 1e-12 * sk.height
        div = np.where(nonzero, bl, H)
        div[self.root_path] = H
        self.div = div
        self.rest_directions = np.where(nonzero[:, None], sk.offsets / np.maximum(bl, 1e-300)[:, None], 0.0)
        self.pair_md = np.stack([self.dist, self.mid], axis=1)  # (4, 2): distal, middle

    def limb_vectors(self, gq: np.ndarray, gp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(R_parent^-1, d, e)`` of world transforms: the limbs' parent frames inverted (F, 4, 4), and
        the proximal -> distal and proximal -> middle vectors in them (F, 4, 3)."""
        rp_inv = qinv(gq[:, self.par])
        S = gp[:, self.prox]
        de = qrot(rp_inv[:, :, None], gp[:, self.pair_md] - S[:, :, None])  # (F, 4, 2, 3): d, e
        return rp_inv, de[:, :, 0], de[:, :, 1]

    def swivel(self, e: np.ndarray, a: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(F, 4) swivel angles of the middle joints ``e`` about the axes ``a`` from ``u`` towards ``v``,
        undefined ones (the middle joint on the axis) carried from the defined ones."""
        ep = e - np.sum(e * a, axis=-1, keepdims=True) * a
        radius = vector_norm(ep)
        ang = np.arctan2(np.sum(ep * v, axis=-1), np.sum(ep * u, axis=-1))
        valid = radius > 1e-9 * self.l1[None]
        if not valid.all():  # (when all are, _fill_undefined gives the angles as they are)
            ang = _fill_undefined(ang, valid)
        return ang

    def end_rotations(self, rp_inv: np.ndarray, gq: np.ndarray) -> np.ndarray:
        """(F, 4, 4) world rotations of the distal joints in the limbs' parent frames."""
        return quat_multiply(rp_inv, gq[:, self.dist])

    def translations(self, t: np.ndarray) -> np.ndarray:
        """(F, J, 3) normalised local translations (root path / hip height, others / bone length)."""
        return t / self.div[None, :, None]

    def feet(self, motion: Motion, gp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(contacts (F, 2), ankle heights (F, 2) in foot lengths)`` of the source's ankles."""
        sk = self.skeleton
        contacts = foot_contacts(motion, global_positions=gp, skeleton=sk)
        return contacts, gp[:, [sk.index("left_ankle"), sk.index("right_ankle")], UP_AXIS] / foot_scale(sk)


def check_motion(motion) -> None:
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a Motion, got {describe(motion)}")


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
    check_motion(motion)
    enc = Encoder(Skeleton.from_motion(motion, roles=check_role_table(roles)))
    t = motion.local_translations()
    gq, gp = fk_arrays(enc.levels, motion.rotations, t)
    rp_inv, d, e = enc.limb_vectors(gq, gp)
    a, _, u, v = limb_frames(d, 1e-12 * enc.L[None], enc.swivel_axes[None], enc.swivel_refs[None])
    contacts, ankle_heights = enc.feet(motion, gp)
    return MorphologyIndependentMotion(
        joint_names=list(motion.joint_names),
        parents=np.array(motion.parents),
        channels=list(motion.channels),
        roles=dict(enc.roles),
        frame_time=motion.frame_time,
        rotations=np.array(motion.rotations),
        translations=enc.translations(t),
        root_path=enc.root_path,
        limb_vectors=d / enc.L[None, :, None],
        limb_swivel=enc.swivel(e, a, u, v),
        limb_end_rotations=enc.end_rotations(rp_inv, gq),
        swivel_axes=enc.swivel_axes,
        swivel_refs=enc.swivel_refs,
        rest_directions=enc.rest_directions,
        source_hip_height=float(enc.hip_height),
        source_height=float(enc.skeleton.height),
        contacts=contacts,
        ankle_heights=ankle_heights,
        source_unit_m=motion.unit_m,
    )
