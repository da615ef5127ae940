"""Motion annotation, Pronost et al. Section 3.2.1: hit segment, semantics, hit frame, hit point.

"For each resulting subsequence, the user specifies the name of the hit segment (such
as the right hand or the left foot) as well as the semantics (such as punching or
kicking).  The system automatically calculates the trajectory of the hit point."  Here
the user is replaced by :func:`detect_hits` (a manifest can override it,
:func:`repro.motion.database.sources.build_database`); :func:`hit_frame_for` finds the hit frame
of a clip whose hit segment is known, and :func:`hit_point_trajectory` is the hit
point's world trajectory (a joint or its End Site).

Hit segments are roles of :func:`repro.motion.body.roles.find_roles` (:data:`HIT_ROLES`);
lengths are metres (the motion's ``unit_m`` must be known), y up.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from repro.checks import as_choice, as_real, as_real_array, as_str, describe
from repro.errors import MotionError
from repro.motion.body.hit_points import hit_offset
from repro.motion.body.pose_frames import heading_from_hips
from repro.motion.core.quaternion import quat_rotate
from repro.motion.core.motion import Motion
from repro.motion.body.skeleton import Skeleton

__all__ = [
    "SEMANTICS",
    "HIT_ROLES",
    "HIT_ROLE_OF",
    "Hit",
    "detect_hits",
    "hit_frame_for",
    "hit_point_trajectory",
    "check_semantics",
]

#: The semantics of the paper ("punching or kicking", Section 3.2.1).
SEMANTICS: tuple[str, ...] = ("punch", "kick")
#: The hit segment (role) of each (semantics, side).
HIT_ROLE_OF: dict[tuple[str, str], str] = {
    ("punch", "left"): "left_fist", ("punch", "right"): "right_fist",
    ("kick", "left"): "left_foot", ("kick", "right"): "right_foot"}
#: The hit segments a clip may name (roles of :func:`repro.motion.body.roles.find_roles`).
HIT_ROLES: tuple[str, ...] = tuple(HIT_ROLE_OF.values())


@dataclass(frozen=True)
class Hit:
    """A strike found by :func:`detect_hits`.

    Attributes
    ----------
    frame : int
        Hit frame (full reach).
    time : float
        ``frame * frame_time`` (s).
    role : str
        Hit segment: ``left_fist``, ``right_fist``, ``left_foot`` or ``right_foot``.
    semantics : {"punch", "kick"}
    side : {"left", "right"}
    extension : float
        Distal joint distance from the proximal one (shoulder->wrist, hip->ankle) over the
        limb length, at the hit (1 = straight).
    height : float
        Hit point height above the floor over the stature.
    start, stop : int
        The run of frames satisfying the detector's criteria.
    """

    frame: int
    time: float
    role: str
    semantics: str
    side: str
    extension: float
    height: float
    start: int
    stop: int


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


class _Kinematics:
    """Per-motion quantities used by the detector (metres, y up)."""

    def __init__(self, motion: Motion, skeleton: Skeleton | None):
        self.motion = motion
        self.sk = skeleton or Skeleton.from_motion(motion)
        if self.sk.unit_m is None:
            raise MotionError("hit detection needs lengths in a known unit; read the BVH with unit_m=...")
        self.k = self.sk.unit_m  # metres per unit
        self.g = motion.global_positions() * self.k
        sk, g = self.sk, self.g
        self.floor = float(np.percentile(np.minimum(g[:, sk.index("left_foot"), 1],
                                                    g[:, sk.index("right_foot"), 1]), 1.0))
        lat = (g[:, sk.index("left_hip")] - g[:, sk.index("right_hip")]) + (
            g[:, sk.index("left_shoulder")] - g[:, sk.index("right_shoulder")])
        th = heading_from_hips(lat, np.zeros_like(lat))
        self.forward = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], axis=1)
        self.fps = motion.fps
        self.stature = sk.size

    def limb(self, semantics: str, side: str):
        sk, g = self.sk, self.g
        if semantics == "punch":
            prox, dist = g[:, sk.index(f"{side}_shoulder")], g[:, sk.index(f"{side}_wrist")]
            L = sk.limb_lengths[f"{side}_arm"] * self.k
        else:
            prox, dist = g[:, sk.index(f"{side}_hip")], g[:, sk.index(f"{side}_ankle")]
            L = sk.limb_lengths[f"{side}_leg"] * self.k
        ext = np.linalg.norm(dist - prox, axis=1) / L
        return ext, dist, L

    def hit_point(self, role: str) -> np.ndarray:
        return self.g[:, self.sk.index(role)]


def _refine_frame(kin: _Kinematics, role: str, ext: np.ndarray, a: int, b: int, tol: float) -> int:
    """Full reach inside run [a, b): the first local maximum of the extension within
    ``tol`` of the run's peak -- the arrival of the fist or foot, where its radial speed
    away from the shoulder / hip vanishes (a lunge punch then holds the arm out; the hit
    is the arrival, not a later drift of the held pose)."""
    seg = ext[a:b]
    f = int(np.flatnonzero(seg >= seg.max() - tol)[0])
    while f + 1 < seg.size and seg[f + 1] > seg[f]:
        f += 1
    return a + f


def detect_hits(motion: Motion, skeleton: Skeleton | None = None, *, semantics: str | None = None,
                side: str | None = None, arm_extension: float = 0.9, arm_front: float = 0.6,
                kick_height: float = 0.55, leg_extension: float = 0.85, merge_gap: float = 0.25,
                min_duration: float = 0.015, peak_tolerance: float = 0.02) -> list[Hit]:
    """Find the strikes of a motion: hit segment, semantics and hit frame (Section 3.2.1).

    The paper's user marks the subsequences, the hit segment and the semantics by hand;
    this detector does it from the kinematics, for each candidate end effector:

    * **punch** (hit segment ``{side}_fist``): the arm is extended (shoulder->wrist
      distance >= ``arm_extension`` x arm length) *and* the wrist is in front of the chest
      (>= ``arm_front`` x arm length along the body's heading, from hips and shoulders);
    * **kick** (``{side}_foot``): the ankle is high (>= ``kick_height`` x leg length
      above the floor, the floor being the 1st percentile of the lower foot's height) *and*
      the leg is extended (hip->ankle >= ``leg_extension`` x leg length; this rejects the
      knee raises of the katas).

    Runs of frames meeting a criterion that are less than ``merge_gap`` seconds apart are
    merged, runs shorter than ``min_duration`` dropped; each run is one hit, whose frame is
    the arrival at full reach: the first frame within ``peak_tolerance`` of the run's peak
    extension, moved forward to the local maximum of the extension it belongs to (where
    the limb's extension speed is zero; on the synthetic clips this is the annotated hit
    frame exactly).  These
    are the thresholds used to count the strikes of ``mocap/cmu/PROVENANCE.md``.

    Parameters
    ----------
    motion : Motion
        With a known ``unit_m``.
    skeleton : Skeleton, optional
        Default :meth:`Skeleton.from_motion`.
    semantics : {"punch", "kick"}, optional
        Only look for these.
    side : {"left", "right"}, optional
        Only this limb.

    Returns
    -------
    list of Hit
        Sorted by frame.
    """
    _check_motion(motion, skeleton)
    sems = SEMANTICS if semantics is None else (check_semantics(semantics),)
    sides = ("left", "right") if side is None else (as_choice(side, "side", ("left", "right"), error=MotionError),)
    arm_extension, arm_front, kick_height, leg_extension = (
        as_real(v, n, error=MotionError) for v, n in ((arm_extension, "arm_extension"), (arm_front, "arm_front"),
                                                      (kick_height, "kick_height"), (leg_extension, "leg_extension")))
    merge_gap, min_duration, peak_tolerance = (
        as_real(v, f"{n} (s)" if n != "peak_tolerance" else n, lo=0.0, error=MotionError)
        for v, n in ((merge_gap, "merge_gap"), (min_duration, "min_duration"), (peak_tolerance, "peak_tolerance")))
    kin = _Kinematics(motion, skeleton)
    hits = []
    for sem in sems:
        for sd in sides:
            role = HIT_ROLE_OF[(sem, sd)]
            ext, dist, L = kin.limb(sem, sd)
            if sem == "punch":
                chest = kin.g[:, kin.sk.index("chest")]
                front = np.sum((dist - chest) * kin.forward, axis=1) / L
                mask = (ext >= arm_extension) & (front >= arm_front)
            else:
                leg = kin.sk.leg_length * kin.k
                mask = ((dist[:, 1] - kin.floor) >= kick_height * leg) & (ext >= leg_extension)
            runs = []
            for a, b in _runs(mask):
                if runs and a - runs[-1][1] < merge_gap * kin.fps:
                    runs[-1] = (runs[-1][0], b)
                else:
                    runs.append((a, b))
            for a, b in runs:
                if (b - a) / kin.fps < min_duration:
                    continue
                f = _refine_frame(kin, role, ext, a, b, peak_tolerance)
                hp = kin.hit_point(role)[f]
                hits.append(Hit(frame=f, time=f * motion.frame_time, role=role, semantics=sem, side=sd,
                                extension=float(ext[f]), height=float((hp[1] - kin.floor) / kin.stature),
                                start=a, stop=b))
    return sorted(hits, key=lambda h: (h.frame, h.role))


def hit_frame_for(motion: Motion, role: str, skeleton: Skeleton | None = None, **kw) -> int:
    """Hit frame of a clip whose hit segment is known (e.g. from a manifest).

    The strongest :func:`detect_hits` detection of that role (largest extension); when
    the criteria are never met (a low kick, a short hook), the frame of peak extension of
    the limb over the clip, refined like the detector.
    """
    _check_motion(motion, skeleton)
    m = re.fullmatch(r"(left|right)_(fist|foot)", as_str(role, "role (hit segment)", error=MotionError))
    if not m:
        raise MotionError(f"hit role must be left_fist, right_fist, left_foot or right_foot, got {role!r}")
    side, seg = m.groups()
    sem = "punch" if seg == "fist" else "kick"
    hits = detect_hits(motion, skeleton, semantics=sem, side=side, **kw)
    if hits:
        return max(hits, key=lambda h: h.extension).frame
    kin = _Kinematics(motion, skeleton)
    ext, _, _ = kin.limb(sem, side)
    return _refine_frame(kin, role, ext, 0, motion.n_frames, kw.get("peak_tolerance", 0.02))


def check_semantics(s) -> str:
    """``s`` if it is one of :data:`SEMANTICS`, else :class:`~repro.errors.MotionError`."""
    return as_choice(s, "semantics", SEMANTICS, error=MotionError)


def _check_motion(motion, skeleton=None) -> None:
    """A :class:`Motion` (and a :class:`Skeleton` or ``None``), else :class:`MotionError`."""
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a repro.motion.Motion, got {describe(motion)}")
    if skeleton is not None and not isinstance(skeleton, Skeleton):
        raise MotionError(f"skeleton must be a repro.motion.Skeleton or None, got {describe(skeleton)}")


def hit_point_trajectory(motion: Motion, joint: str, where: str = "joint", *,
                         positions: np.ndarray | None = None) -> np.ndarray:
    """(F, 3) world trajectory of a hit point: a joint, or its tip (:func:`repro.motion.body.hit_points.hit_offset`).

    Parameters
    ----------
    motion : Motion
        Any motion (file units).
    joint : str
        Joint name (a clip's ``hit_joint``).
    where : {"joint", "end_site"}
        The joint's own position, or its tip: its (first) End Site, else the knuckles of the
        fingers below it (a hand with fingers), else the joint.
    positions : (F, J, 3) array, optional
        The motion's :meth:`~repro.motion.core.motion.Motion.global_positions` when already
        computed (used for ``where="joint"``).
    """
    _check_motion(motion)
    j = motion.joint_index(as_str(joint, "joint", error=MotionError))
    as_choice(where, "where", ("joint", "end_site"), error=MotionError)
    if positions is not None:
        positions = as_real_array(positions, "positions", error=MotionError,
                                  shape=(motion.n_frames, len(motion.joint_names), 3))
    if where == "joint":
        return (motion.global_positions() if positions is None else positions)[:, j]
    if where == "end_site":
        off = hit_offset(motion, j)[0]
        gq, gp = motion.global_transforms()
        return gp[:, j] + quat_rotate(gq[:, j], off[None])
    raise MotionError(f"where must be 'joint' or 'end_site', got {where!r}")
