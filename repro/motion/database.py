"""The annotated motion database of Pronost et al., Section 3.2.

"Interactive Animation of Virtual Characters: Application to Virtual Kung-fu Fighting",
Section 3.2.1 (Motion annotation):

    "the user can extract the most interesting subsequences from long kung-fu fighting
    sequences (such as times during which the actor is punching or kicking). For each
    resulting subsequence, the user specifies the name of the hit segment (such as the
    right hand or the left foot) as well as the semantics (such as punching or kicking).
    The system automatically calculates the trajectory of the hit point. For each
    motion, the system also automatically calculates the bounding box of this
    trajectory [...] The motion database is so composed of elements including the
    motion clip, the definition of the skeleton, the semantic information and some
    necessary quantitative data (such as the hit time and the position of the segment
    at this time)."

Here the "user" is replaced by :func:`detect_hits` (overridable by a manifest):

* :class:`Clip` -- one annotated subsequence: the motion (metres, resampled to the
  database rate, 30 Hz by default), the hit segment (a role such as ``"right_fist"`` or
  ``"left_foot"`` of :func:`repro.motion.roles.find_roles`, the joint, and whether
  the hit point is the joint or its End Site), the semantics (``"punch"`` or
  ``"kick"``), the hit frame/time, the source take and where it was cut.
* :class:`MotionDatabase` -- the clips plus everything the retrieval
  (:mod:`repro.motion.retrieval`) precomputes from them: per clip the actor and its
  :attr:`~repro.motion.skeleton.Skeleton.size` ``size_a`` (Eq. 1), the hit-point
  trajectory and its axis-aligned bounding box; per pose (every frame of every clip)
  the pose cloud of :mod:`repro.motion.clustering`.  Saved to / loaded from ``.npz``
  without pickles (:meth:`MotionDatabase.save`, :meth:`MotionDatabase.load`).
* :func:`build_database` -- from a folder of BVH files with an optional
  ``manifest.csv`` (the synthetic database of :mod:`repro.motion.synthetic`);
  :func:`build_cmu_database` -- from the real CMU karate takes of subject 135, cut into
  hit subsequences around every detected strike.
* :func:`augment` -- "scaling the database" for the latency-versus-size measurements:
  deterministic *synthetic* variants (mirror, actor rescaling, time warp, noise).

Frames
------
World: Y up, floor y = 0, metres.  The **root reference frame** of a frame (the frame
in which the paper expresses the target ``c``, Section 3.3) has its origin on the floor
below the pelvis, y up and z along the body's heading (see
:func:`repro.motion.clustering.root_frames`).  A clip's **hit-point trajectory**, its
**bounding box** and :attr:`MotionDatabase.hit_position` are expressed in the root frame
of the clip's **first frame** (the paper compares ``c_r``, "expressed in the root
reference frame", with them), in metres of the actor.  Pose clouds are expressed in the
root frame of their own frame and divided by ``size_a`` (adimensional).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import operator
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from repro.errors import DataError, MotionError, ReproError, RetrievalError
from repro.io import MAX_READ_BYTES, atomic_path, read_npz
from repro.motion.clustering import (
    POSE_ROLES,
    heading_from_hips,
    pose_points,
    root_frames,
    to_root_frame,
)
from repro.motion.kinematics import slerp as _slerp
from repro.motion.motion import CMU_UNIT_M, Motion
from repro.motion.skeleton import Skeleton

__all__ = [
    "DATABASE_FPS",
    "SEMANTICS",
    "CMU_TAKES",
    "CMU_WINDOW",
    "Hit",
    "Clip",
    "MotionDatabase",
    "detect_hits",
    "hit_frame_for",
    "resample",
    "cut",
    "mirror_motion",
    "mirror_joint_map",
    "annotate",
    "build_database",
    "build_cmu_database",
    "load_or_build",
    "augment",
    "default_database",
    "effector_role",
]

#: Common frame rate of the database (the retrieval compares poses frame by frame).
DATABASE_FPS: float = 30.0
#: The semantics of the paper ("punching or kicking", Section 3.2.1).
SEMANTICS: tuple[str, ...] = ("punch", "kick")
#: Subject-135 takes of the staged CMU set used by :func:`build_cmu_database`, with the
#: kind of strike they hold (``mocap/cmu/PROVENANCE.md``, "The clips, and strikes found
#: in them").  135_03 (labelled Empi but a 5 m walk with no strike) and 135_08 (the
#: calibration pose) are left out.
CMU_TAKES: dict[str, str] = {
    "135_02": "kata_arm",  # Empi kata
    "135_04": "front_kick",
    "135_05": "kata_arm",  # Gedanbarai (down block)
    "135_06": "kata_arm",  # Heiansyodan kata
    "135_07": "roundhouse_kick",  # Mawashigeri
    "135_09": "lunge_punch",  # Oiduki
    "135_10": "kata_arm",  # Syutouuke (knife-hand block)
    "135_11": "side_kick",  # Yokogeri
}
#: Seconds kept before and after each detected hit when cutting the CMU takes.
CMU_WINDOW: tuple[float, float] = (0.6, 0.3)

_ROLE_OF = {("punch", "left"): "left_fist", ("punch", "right"): "right_fist",
            ("kick", "left"): "left_foot", ("kick", "right"): "right_foot"}
#: The hit segments a clip may name (roles of :func:`repro.motion.skeleton.find_roles`).
HIT_ROLES: tuple[str, ...] = tuple(_ROLE_OF.values())


# ======================================================================= motions
def resample(motion: Motion, fps: float | None = None, *, frames: Sequence[float] | np.ndarray | None = None,
             frame_time: float | None = None) -> Motion:
    """A motion sampled at other times: slerp of rotations, linear position channels.

    Parameters
    ----------
    motion : Motion
    fps : float, optional
        New rate; samples at ``0, 1/fps, ...`` up to the last frame's time.
    frames : (n,) array, optional
        Instead of ``fps``: the (fractional) source frame index of every new frame,
        within ``[0, F-1]``.
    frame_time : float, optional
        Frame time of the result with ``frames`` (default the source's).

    Returns
    -------
    Motion
        Same skeleton; sample times that fall on source frames reproduce them exactly.
    """
    F = motion.n_frames
    if frames is None:
        if fps is None or not np.isfinite(fps) or fps <= 0:
            raise MotionError(f"fps must be finite and > 0, got {fps!r}")
        n = int(math.floor((F - 1) * motion.frame_time * fps + 1e-9)) + 1
        u = np.arange(n) / fps / motion.frame_time
        frame_time = 1.0 / fps
    else:
        u = np.asarray(frames, dtype=float).reshape(-1)
        frame_time = motion.frame_time if frame_time is None else float(frame_time)
    if u.size == 0 or not np.all(np.isfinite(u)) or u.min() < -1e-9 or u.max() > F - 1 + 1e-9:
        raise MotionError(f"sample frames must be finite and inside [0, {F - 1}]")
    u = np.clip(u, 0, F - 1)
    i0 = np.clip(np.floor(u + 1e-9).astype(np.intp), 0, F - 1)
    a = u - i0
    a[np.abs(a) < 1e-9] = 0.0
    i1 = np.minimum(i0 + 1, F - 1)
    rot = _slerp(motion.rotations[i0], motion.rotations[i1], a[:, None, None])
    exact = a == 0.0
    rot[exact] = motion.rotations[i0[exact]]
    pos = motion.positions[i0] * (1 - a)[:, None, None] + motion.positions[i1] * a[:, None, None]
    return dataclasses.replace(motion, rotations=rot, positions=pos, frame_time=frame_time)


def cut(motion: Motion, start: int, stop: int) -> Motion:
    """Frames ``[start, stop)`` of a motion."""
    if not 0 <= start < stop <= motion.n_frames:
        raise MotionError(f"cannot cut frames [{start}, {stop}) of a {motion.n_frames}-frame motion")
    return dataclasses.replace(motion, rotations=motion.rotations[start:stop], positions=motion.positions[start:stop])


_SWAPS = (("Left", "Right"), ("left", "right"), ("LEFT", "RIGHT"))


def _mirror_candidates(name: str) -> list[str]:
    out = []
    for a, b in _SWAPS:
        if a in name:
            out.append(name.replace(a, b))
        if b in name:
            out.append(name.replace(b, a))
    for a, b in (("_L", "_R"), ("_l", "_r"), (".L", ".R"), (".l", ".r")):
        if name.endswith(a):
            out.append(name[: -len(a)] + b)
        if name.endswith(b):
            out.append(name[: -len(b)] + a)
        if a + "_" in name:
            out.append(name.replace(a + "_", b + "_"))
        if b + "_" in name:
            out.append(name.replace(b + "_", a + "_"))
    m = re.match(r"^([A-Za-z]*:)?([lLrR])([a-z].*)$", name)  # CMU lhumerus / rhumerus
    if m:
        ns, s, rest = m.group(1) or "", m.group(2), m.group(3)
        out.append(ns + {"l": "r", "r": "l", "L": "R", "R": "L"}[s] + rest)
    return out


def mirror_joint_map(joint_names: Sequence[str], parents: Sequence[int] | np.ndarray) -> np.ndarray:
    """Left/right partner of every joint (itself for central joints), from the names.

    Recognises ``Left``/``Right`` anywhere in the name (Mixamo), ``_L``/``_R`` suffixes
    (Bandai Namco) and a leading ``l``/``r`` (CMU ``lhumerus``).  The map must be an
    involution compatible with the tree (the partner of a joint's parent is the parent of
    its partner), else :class:`~repro.errors.MotionError`.
    """
    names = list(joint_names)
    index = {n: i for i, n in enumerate(names)}
    par = np.asarray(parents, dtype=np.intp)
    pi = np.arange(len(names))
    for i, n in enumerate(names):
        for c in _mirror_candidates(n):
            if c != n and c in index:
                pi[i] = index[c]
                break
    if not np.array_equal(pi[pi], np.arange(len(names))):
        raise MotionError("left/right joint names do not pair up; cannot mirror this skeleton")
    for j in range(1, len(names)):
        if par[pi[j]] != pi[par[j]]:
            raise MotionError(f"mirror partner of {names[j]!r} has another parent; cannot mirror this skeleton")
    return pi


def mirror_motion(motion: Motion) -> Motion:
    """The motion reflected through the plane x = 0, with left and right swapped.

    Joint ``j`` of the result carries the data of its partner ``pi(j)``
    (:func:`mirror_joint_map`) reflected by ``M = diag(-1, 1, 1)``: offsets and positions
    ``M t``, rotations ``M R M`` (quaternion ``(x, -y, -z, w)``); End Sites likewise.
    Forward kinematics of the result is ``M p_{pi(j)}`` exactly.  For a left/right
    symmetric skeleton (the synthetic actor) the skeleton is unchanged; for a captured one
    (CMU) the mirrored skeleton has the other side's bone lengths.
    """
    pi = mirror_joint_map(motion.joint_names, motion.parents)
    M = np.array([-1.0, 1.0, 1.0])
    rot = motion.rotations[:, pi] * np.array([1.0, -1.0, -1.0, 1.0])
    pos = motion.positions[:, pi] * M
    off = motion.offsets[pi] * M
    esp = motion.end_site_parents
    eso = motion.end_site_offsets.copy()
    for e, p in enumerate(esp):
        mine = np.flatnonzero(esp == p)
        theirs = np.flatnonzero(esp == pi[p])
        k = int(np.flatnonzero(mine == e)[0])
        if theirs.size != mine.size:
            raise MotionError("End Sites are not symmetric; cannot mirror this skeleton")
        eso[e] = motion.end_site_offsets[theirs[k]] * M
    # position channels: a component is only meaningful where the mask says so; the mask
    # of joint j and of its partner must agree for the mirror to be expressible
    if not np.array_equal(motion.position_mask, motion.position_mask[pi]):
        raise MotionError("position channels differ between left and right joints; cannot mirror")
    return dataclasses.replace(motion, rotations=rot, positions=pos, offsets=off, end_site_offsets=eso,
                               source=(motion.source or "") + " (mirrored)")


# ================================================================ hit detection
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
    kin = _Kinematics(motion, skeleton)
    sems = SEMANTICS if semantics is None else (_check_semantics(semantics),)
    sides = ("left", "right") if side is None else (side,)
    hits = []
    for sem in sems:
        for sd in sides:
            role = _ROLE_OF[(sem, sd)]
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
    m = re.fullmatch(r"(left|right)_(fist|foot)", role)
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


def _check_semantics(s) -> str:
    if s not in SEMANTICS:
        raise MotionError(f"semantics must be one of {list(SEMANTICS)}, got {s!r}")
    return s


# ===================================================================== clips
@dataclass(frozen=True, eq=False)
class Clip:
    """One annotated subsequence of the database (Section 3.2.1).

    Attributes
    ----------
    name : str
        Unique name, e.g. ``"135_09_h03_right_fist"``.
    motion : Motion
        In metres (``unit_m = 1``), at the database rate.
    semantics : {"punch", "kick"}
    hit_role : str
        ``left_fist``, ``right_fist``, ``left_foot`` or ``right_foot``.
    hit_joint : str
        Joint carrying the hit point.
    hit_where : {"joint", "end_site"}
        The hit point is the joint itself or its (first) End Site.
    hit_frame : int
    kind : str
        Finer label (``"lunge_punch"``, ``"front_kick"``, ``"kata_arm"``, synthetic
        ``"kick_round"`` ...).
    side : {"left", "right"}
    source : str
        File the clip was cut from.
    source_time : float
        Time of the clip's first frame in the source file (s).
    level : str
        Target level of the synthetic clips (``"high"``...), ``""`` otherwise.
    """

    name: str
    motion: Motion
    semantics: str
    hit_role: str
    hit_joint: str
    hit_where: str
    hit_frame: int
    kind: str = ""
    side: str = ""
    source: str = ""
    source_time: float = 0.0
    level: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise MotionError(f"a clip name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.motion, Motion):
            raise MotionError(f"{self.name}: motion must be a repro.motion.Motion, got {type(self.motion).__name__}")
        _check_semantics(self.semantics)
        if self.hit_role not in HIT_ROLES:
            raise MotionError(f"{self.name}: hit segment (hit_role) must be one of {list(HIT_ROLES)}, "
                              f"got {self.hit_role!r}")
        if self.side not in ("", "left", "right"):
            raise MotionError(f"{self.name}: side must be 'left' or 'right', got {self.side!r}")
        if not isinstance(self.hit_joint, str):
            raise MotionError(f"{self.name}: hit_joint must be a joint name, got {self.hit_joint!r}")
        if isinstance(self.hit_frame, (bool, np.bool_)):
            raise MotionError(f"{self.name}: hit frame must be an integer, got {self.hit_frame!r}")
        try:
            operator.index(self.hit_frame)
        except TypeError:
            raise MotionError(f"{self.name}: hit frame must be an integer, got {self.hit_frame!r}") from None
        if self.hit_where not in ("joint", "end_site"):
            raise MotionError(f"hit_where must be 'joint' or 'end_site', got {self.hit_where!r}")
        if not 0 <= int(self.hit_frame) < self.motion.n_frames:
            raise MotionError(f"{self.name}: hit frame {self.hit_frame} outside the clip's {self.motion.n_frames} frames")
        if self.hit_joint not in self.motion.joint_names:
            raise MotionError(f"{self.name}: hit joint {self.hit_joint!r} is not a joint of the motion")
        if self.hit_where == "end_site" and not np.any(self.motion.end_site_parents == self.motion.joint_index(self.hit_joint)):
            raise MotionError(f"{self.name}: joint {self.hit_joint!r} has no End Site")
        if self.motion.unit_m != 1.0:
            raise MotionError(f"{self.name}: clip motions must be in metres (unit_m = 1), got {self.motion.unit_m}")
        object.__setattr__(self, "hit_frame", int(self.hit_frame))
        if not self.side:
            object.__setattr__(self, "side", self.hit_role.split("_")[0])

    @property
    def hit_time(self) -> float:
        """Hit time from the clip's start (s)."""
        return self.hit_frame * self.motion.frame_time


def annotate(motion: Motion, hit_frame: int, hit_role: str, semantics: str, *, name: str,
             hit_joint: str | None = None, hit_where: str = "joint", **kw) -> Clip:
    """A :class:`Clip` from a motion in metres; ``hit_joint`` defaults to the role's joint."""
    if hit_joint is None:
        hit_joint = Skeleton.from_motion(motion).roles[hit_role]
    return Clip(name=name, motion=motion, semantics=semantics, hit_role=hit_role, hit_joint=hit_joint,
                hit_where=hit_where, hit_frame=hit_frame, **kw)


def _cut_around(motion: Motion, hit_time: float, window: tuple[float, float] | None, fps: float):
    """Resample to ``fps`` on a grid through the hit time, keeping ``window`` around it.

    Returns the new motion, the hit frame in it and the start time in the source.
    """
    T = (motion.n_frames - 1) * motion.frame_time
    before, after = (hit_time, T - hit_time) if window is None else window
    k0 = int(math.floor(min(before, hit_time) * fps + 1e-9))
    k1 = int(math.floor(min(after, T - hit_time) * fps + 1e-9))
    times = hit_time + np.arange(-k0, k1 + 1) / fps
    out = resample(motion, frames=times / motion.frame_time, frame_time=1.0 / fps)
    return out, k0, float(times[0])


# =================================================================== database
def _json_list(a) -> str:
    return json.dumps([str(x) for x in a])


def _same_topology(a, b) -> bool:
    return list(a.joint_names) == list(b.joint_names) and np.array_equal(a.parents, b.parents)


def _proportional(base: Skeleton, sk: Skeleton) -> float | None:
    """``s`` if ``sk`` is ``base`` scaled uniformly by ``s`` (same topology), else None."""
    if not _same_topology(base, sk) or base.end_site_offsets.shape != sk.end_site_offsets.shape:
        return None
    if not np.array_equal(base.end_site_parents, sk.end_site_parents):
        return None
    s = sk.size / base.size
    tol = 1e-6 * sk.size
    if np.abs(sk.offsets - s * base.offsets).max() > tol:
        return None
    if sk.end_site_offsets.size and np.abs(sk.end_site_offsets - s * base.end_site_offsets).max() > tol:
        return None
    return float(s)


_CLIP_STR = ("names", "sources", "semantics", "kinds", "sides", "levels", "hit_roles", "hit_joints", "hit_wheres")
_CLIP_NUM = ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_clip", "source_time", "mirror", "warp",
             "noise", "box_min", "box_max", "hit_position", "traj_start", "pose_start")
_POSE_NUM = ("traj", "pose_points", "pose_clip", "pose_frame", "pose_heading", "pose_origin")


class MotionDatabase:
    """Annotated clips and the query-independent data of the retrieval (Sections 3.2-3.3).

    Build with :meth:`from_clips`, :func:`build_database`, :func:`build_cmu_database` or
    :func:`augment`; save and load with :meth:`save` / :meth:`load`.

    Attributes (C clips, N poses, T trajectory samples, P pose points)
    -------------------------------------------------------------------
    fps : float
        Frame rate of every clip.
    pose_roles : tuple of str
        Roles of the pose points (:data:`~repro.motion.clustering.POSE_ROLES`).
    window, step : int
        Frames per pose cloud and their spacing (:func:`~repro.motion.clustering.pose_points`).
    actors : list of Skeleton
        The distinct *base* actor skeletons (metres); every clip's actor is a base actor
        scaled uniformly by :attr:`scale` (several synthetic actors of other heights
        share one base).
    names, sources, semantics, kinds, sides, levels, hit_roles, hit_joints, hit_wheres : (C,) str arrays
        Annotations (see :class:`Clip`).
    hit_frame, n_frames : (C,) int arrays
    actor : (C,) int array
        Index into :attr:`actors`.
    scale : (C,) float array
        Clip actor = base actor x scale.
    size_a : (C,) float array
        The actor's :attr:`~repro.motion.skeleton.Skeleton.size` (metres), Eq. 1.
    source_clip : (C,) int array
        The clip a variant was made from (:func:`augment`); itself for original clips.
    source_time : (C,) float array
        Start of the clip in its source file (s).
    mirror : (C,) bool array; warp, noise : (C,) float arrays
        Augmentation parameters (False, 1, 0 for original clips).
    box_min, box_max : (C, 3) arrays
        Bounding box of the hit-point trajectory, clip's first-frame root frame, metres.
    hit_position : (C, 3) array
        The hit point at the hit frame, same frame.
    traj : (T, 3) array; traj_start : (C+1,) int array
        Hit-point trajectories, clip ``i`` at ``traj[traj_start[i]:traj_start[i+1]]``.
    pose_points : (N, window*P, 3) array
        Pose clouds in their own root frame, divided by ``size_a`` (adimensional).
    pose_clip, pose_frame : (N,) int arrays
        Clip and frame of every pose; ``pose_start`` (C+1,) as ``traj_start``.
    pose_heading : (N,) array; pose_origin : (N, 3) array
        Root frame of every pose in the clip's world (radians, metres).
    """

    def __init__(self, *, fps: float, pose_roles, window: int, step: int, actors: list[Skeleton],
                 motions: Mapping[int, Motion], arrays: Mapping[str, np.ndarray], meta: Mapping | None = None):
        self.fps = float(fps)
        self.pose_roles = tuple(pose_roles)
        self.window = int(window)
        self.step = int(step)
        self.actors = list(actors)
        self._motions = dict(motions)
        self.meta = dict(meta or {})
        for k in _CLIP_STR:
            setattr(self, k, np.asarray(arrays[k], dtype=str))
        for k in _CLIP_NUM + _POSE_NUM:
            setattr(self, k, np.asarray(arrays[k]))
        self.mirror = self.mirror.astype(bool)
        for k in ("hit_frame", "n_frames", "actor", "source_clip", "traj_start", "pose_start", "pose_clip", "pose_frame"):
            setattr(self, k, getattr(self, k).astype(np.intp))
        C = self.names.size
        if len(set(self.names.tolist())) != C:
            raise MotionError("clip names must be unique")
        if self.traj_start.shape != (C + 1,) or self.pose_start.shape != (C + 1,):
            raise MotionError("inconsistent database arrays")

    # ------------------------------------------------------------------ sizes
    @property
    def n_clips(self) -> int:
        """Number of clips C."""
        return int(self.names.size)

    @property
    def n_poses(self) -> int:
        """Number of poses N (all frames of all clips)."""
        return int(self.pose_clip.size)

    def __len__(self) -> int:
        return self.n_clips

    @property
    def hit_time(self) -> np.ndarray:
        """(C,) hit time of every clip from its first frame (s)."""
        return self.hit_frame / self.fps

    def __repr__(self) -> str:
        counts = {s: int(np.sum(self.semantics == s)) for s in SEMANTICS}
        return (f"MotionDatabase({self.n_clips} clips {counts}, {self.n_poses} poses at {self.fps:g} fps, "
                f"{len(self.actors)} base actor(s))")

    def summary(self) -> dict:
        """Counts for reports: clips per semantics, per kind, poses, actors, frames."""
        return {
            "clips": self.n_clips,
            "poses": self.n_poses,
            "fps": self.fps,
            "per_semantics": {s: int(np.sum(self.semantics == s)) for s in SEMANTICS},
            "per_kind": {k: int(np.sum(self.kinds == k)) for k in sorted(set(self.kinds.tolist()))},
            "base_actors": len(self.actors),
            "actor_sizes_m": sorted({round(float(s), 4) for s in self.size_a}),
            "augmented": int(np.sum(self.source_clip != np.arange(self.n_clips))),
        }

    # ------------------------------------------------------------------ access
    def trajectory(self, i: int) -> np.ndarray:
        """(n_frames, 3) hit-point trajectory of clip ``i`` (first-frame root frame, metres)."""
        return self.traj[self.traj_start[i]:self.traj_start[i + 1]]

    def poses_of(self, i: int) -> np.ndarray:
        """Pose indices of clip ``i``."""
        return np.arange(self.pose_start[i], self.pose_start[i + 1])

    def actor_skeleton(self, i: int) -> Skeleton:
        """Skeleton of the actor of clip ``i`` (base actor scaled by ``scale[i]``)."""
        base = self.actors[int(self.actor[i])]
        s = float(self.scale[i])
        return base if s == 1.0 else base.with_offsets(base.offsets * s, base.end_site_offsets * s)

    def motion(self, i: int) -> Motion:
        """The motion of clip ``i`` (metres, database rate).

        For a variant made by :func:`augment` the motion is rebuilt from its source clip
        (time warp, rescaling, mirror); the feature noise is not applied to it.
        """
        i = int(i)
        if i in self._motions:
            return self._motions[i]
        src = int(self.source_clip[i])
        if src not in self._motions:
            raise MotionError(f"clip {i}: its source clip {src} has no stored motion")
        return _variant_motion(self._motions[src], int(self.n_frames[i]), float(self.scale[i] / self.scale[src]),
                               bool(self.mirror[i]))

    def clip(self, i: int) -> Clip:
        """Clip ``i`` as a :class:`Clip`."""
        return Clip(name=str(self.names[i]), motion=self.motion(i), semantics=str(self.semantics[i]),
                    hit_role=str(self.hit_roles[i]), hit_joint=str(self.hit_joints[i]),
                    hit_where=str(self.hit_wheres[i]), hit_frame=int(self.hit_frame[i]), kind=str(self.kinds[i]),
                    side=str(self.sides[i]), source=str(self.sources[i]), source_time=float(self.source_time[i]),
                    level=str(self.levels[i]))

    def clips(self) -> list[Clip]:
        """Every clip (materialising augmented motions; slow for large databases)."""
        return [self.clip(i) for i in range(self.n_clips)]

    def select(self, mask) -> MotionDatabase:
        """A database of the clips where ``mask`` (bool (C,) or indices) is true."""
        idx = np.flatnonzero(np.asarray(mask)) if np.asarray(mask).dtype == bool else np.asarray(mask, dtype=np.intp)
        return _subset(self, idx)

    # ----------------------------------------------------------- construction
    @classmethod
    def from_clips(cls, clips: Sequence[Clip], *, pose_roles: Sequence[str] = POSE_ROLES, window: int = 1,
                   step: int = 1, meta: Mapping | None = None) -> MotionDatabase:
        """Compute the per-clip and per-pose data of annotated clips.

        Parameters
        ----------
        clips : sequence of Clip
            All at the same frame rate, motions in metres.
        pose_roles : sequence of str
            Roles of the pose clouds.
        window, step : int
            Pose cloud window (:func:`~repro.motion.clustering.pose_points`).
        meta : mapping, optional
            JSON-serialisable provenance stored with the database.
        """
        if len(clips) == 0:
            raise MotionError("a motion database needs at least one clip")
        fps = clips[0].motion.fps
        for c in clips:
            if abs(c.motion.fps - fps) > 1e-6 * fps:
                raise MotionError(f"clip {c.name!r} is at {c.motion.fps:g} fps, not {fps:g}; resample first")
        actors: list[Skeleton] = []
        recs = []
        for c in clips:
            sk = Skeleton.from_motion(c.motion)
            a, s = None, None
            for ai, base in enumerate(actors):
                s = _proportional(base, sk)
                if s is not None:
                    a = ai
                    break
            if a is None:
                actors.append(sk)
                a, s = len(actors) - 1, 1.0
            recs.append(_clip_features(c, sk, a, s, pose_roles, window, step))
        motions = {i: c.motion for i, c in enumerate(clips)}
        arrays = _stack(recs)
        arrays["source_clip"] = np.arange(len(clips))
        return cls(fps=fps, pose_roles=pose_roles, window=window, step=step, actors=actors, motions=motions,
                   arrays=arrays, meta=meta)

    # ---------------------------------------------------------------- I/O
    def save(self, path) -> Path:
        """Write the database to ``path`` (``.npz``, no pickles), atomically.

        Arrays are stored as they are; strings and structure (joint names, channels,
        roles, metadata) as JSON strings.  :meth:`load` gives back an equal database
        (:meth:`equals`).  The file is written to a temporary file beside ``path`` and
        moved into place only once complete (:func:`repro.io.atomic_path`), so saving
        over the file a database was loaded from is safe, and a failed save leaves the
        previous file as it was.

        Raises
        ------
        repro.errors.MotionError
            :attr:`meta` is not JSON-serialisable.
        repro.errors.DataError
            ``path`` cannot be written (a folder, no permission, disk full ...).
        """
        try:
            path = Path(path)
        except TypeError:
            raise DataError(f"expected a path to save the database to, got {type(path).__name__}") from None
        out: dict[str, np.ndarray] = {}
        for k in _CLIP_STR:
            out[k] = np.array(json.dumps(getattr(self, k).tolist()))
        for k in _CLIP_NUM + _POSE_NUM:
            out[k] = np.asarray(getattr(self, k))
        for a, sk in enumerate(self.actors):
            out[f"actor{a}_parents"] = np.asarray(sk.parents)
            out[f"actor{a}_offsets"] = np.asarray(sk.offsets)
            out[f"actor{a}_end_site_parents"] = np.asarray(sk.end_site_parents)
            out[f"actor{a}_end_site_offsets"] = np.asarray(sk.end_site_offsets)
        motion_ids = sorted(self._motions)
        for i in motion_ids:
            m = self._motions[i]
            for f in ("parents", "offsets", "rotations", "positions", "end_site_parents", "end_site_offsets"):
                out[f"motion{i}_{f}"] = np.asarray(getattr(m, f))
        header = {
            "format": "repro.motion.database/1",
            "fps": self.fps,
            "pose_roles": list(self.pose_roles),
            "window": self.window,
            "step": self.step,
            "meta": self.meta,
            "actors": [{"joint_names": sk.joint_names, "channels": [list(c) for c in sk.channels or []],
                        "unit_m": sk.unit_m, "roles": dict(sk.roles)} for sk in self.actors],
            "motions": [{"clip": i, "joint_names": self._motions[i].joint_names,
                         "channels": [list(c) for c in self._motions[i].channels],
                         "frame_time": self._motions[i].frame_time, "unit_m": self._motions[i].unit_m,
                         "source": self._motions[i].source} for i in motion_ids],
        }
        try:
            out["header"] = np.array(json.dumps(header))
        except (TypeError, ValueError) as exc:
            raise MotionError(f"the database's meta (or an actor's roles) cannot be saved as JSON: {exc}") from None
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        if path.is_dir():
            raise DataError(f"{path}: is a folder; cannot save the database there")
        try:
            with atomic_path(path) as tmp:
                with open(tmp, "wb") as fh:
                    np.savez_compressed(fh, **out)
        except OSError as exc:
            raise DataError(f"{path}: cannot write the database: {exc}") from exc
        return path

    @classmethod
    def load(cls, path, *, max_bytes: int = MAX_READ_BYTES) -> MotionDatabase:
        """Read a database written by :meth:`save` (``allow_pickle=False``).

        Everything is checked before use: the archive, every array's declared size
        against its bytes (before allocating), dtypes (no object arrays), shapes,
        finiteness, the JSON header and the consistency of the arrays (clip and pose
        offsets, frame indices, actors, stored motions), so that a damaged file fails
        here rather than later with an ``IndexError``.

        Parameters
        ----------
        path : path-like or binary stream
        max_bytes : int, default :data:`repro.io.MAX_READ_BYTES` (2 GiB)
            Cap on the file's bytes and on the decompressed arrays.

        Raises
        ------
        repro.errors.DataError
            A missing, unreadable, truncated, corrupt or foreign file, or one whose
            content is inconsistent; the message names the file and what is wrong.
        """
        where = str(path) if not hasattr(path, "read") else str(getattr(path, "name", "<stream>"))
        # the archive, each array's declared size (before allocating) and dtypes: repro.io.read_npz;
        # finiteness and the schema: _Check below, with messages about the database
        arrays = read_npz(path, error=DataError, finite=False, max_bytes=max_bytes)
        if not arrays:
            raise DataError(f"{where}: not a motion database (the archive holds no .npy arrays)")
        return _database_from_arrays(cls, arrays, where)

    def equals(self, other: MotionDatabase) -> bool:
        """Exact equality of every array, annotation, actor, stored motion and metadata."""
        if not isinstance(other, MotionDatabase):
            return False
        if (self.fps, self.pose_roles, self.window, self.step) != (other.fps, other.pose_roles, other.window, other.step):
            return False
        if json.dumps(self.meta, sort_keys=True) != json.dumps(other.meta, sort_keys=True):
            return False
        for k in _CLIP_STR + _CLIP_NUM + _POSE_NUM:
            a, b = getattr(self, k), getattr(other, k)
            if a.shape != b.shape or not np.array_equal(a, b):
                return False
        if len(self.actors) != len(other.actors):
            return False
        for x, y in zip(self.actors, other.actors):
            if not (_same_topology(x, y) and np.array_equal(x.offsets, y.offsets) and x.roles == y.roles
                    and np.array_equal(x.end_site_offsets, y.end_site_offsets) and x.unit_m == y.unit_m):
                return False
        if sorted(self._motions) != sorted(other._motions):
            return False
        for i, m in self._motions.items():
            n = other._motions[i]
            if not (_same_topology(m, n) and m.channels == n.channels and m.frame_time == n.frame_time
                    and all(np.array_equal(getattr(m, f), getattr(n, f)) for f in
                            ("offsets", "rotations", "positions", "end_site_parents", "end_site_offsets"))):
                return False
        return True


# ================================================================ loading
_DB_FORMAT = "repro.motion.database/1"


class _Check:
    """Schema checks of a loaded database, raising DataError naming the file."""

    def __init__(self, arrays: dict, where: str):
        self.arrays, self.where = arrays, where

    def fail(self, msg: str):
        raise DataError(f"{self.where}: {msg}")

    def array(self, key: str) -> np.ndarray:
        if key not in self.arrays:
            shown = ", ".join(sorted(self.arrays)[:8]) + (", ..." if len(self.arrays) > 8 else "")
            self.fail(f"no array {key!r}: not a complete motion database written by MotionDatabase.save "
                      f"(holds: {shown})")
        return self.arrays[key]

    def json(self, key: str):
        a = self.array(key)
        if a.shape != () or a.dtype.kind != "U":
            self.fail(f"{key!r} must be a JSON string, got a {a.dtype} array of shape {a.shape}")
        try:
            return json.loads(str(a))
        except (ValueError, RecursionError) as exc:
            self.fail(f"{key!r} is not valid JSON ({exc})")

    def strings(self, key: str, n: int | None) -> np.ndarray:
        v = self.json(key)
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(f"{key!r} must be a JSON list of strings")
        if n is not None and len(v) != n:
            self.fail(f"{key!r} has {len(v)} entries, expected {n} (one per clip)")
        return np.array(v, dtype=str) if v else np.zeros(0, dtype=str)

    def numbers(self, key: str, shape: tuple, kind: str) -> np.ndarray:
        """``kind``: "int", "float" or "bool"; ``shape`` entries None match any length."""
        a = self.array(key)
        ok = {"int": "iu", "float": "iuf", "bool": "biu"}[kind]
        if a.dtype.kind not in ok:
            self.fail(f"array {key!r} has dtype {a.dtype}, expected {kind}")
        if a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape)):
            want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            self.fail(f"array {key!r} has shape {a.shape}, expected {want}")
        if kind == "float":
            a = a.astype(float, copy=False)
            if not np.all(np.isfinite(a)):
                self.fail(f"array {key!r} contains NaN or inf")
        elif kind == "bool":
            if a.dtype.kind != "b" and not np.all((a == 0) | (a == 1)):
                self.fail(f"array {key!r} must hold booleans")
            a = a.astype(bool)
        else:
            a = a.astype(np.int64)
        return a

    def ensure(self, cond, msg: str) -> None:
        if not cond:
            self.fail(msg)


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_skeleton_header(ck: _Check, h, what: str) -> None:
    ck.ensure(isinstance(h, dict), f"{what} must be a JSON object")
    names = h.get("joint_names")
    ck.ensure(isinstance(names, list) and names and all(isinstance(n, str) for n in names),
              f"{what}: joint_names must be a non-empty list of strings")
    ch = h.get("channels")
    ck.ensure(isinstance(ch, list) and all(isinstance(c, list) and all(isinstance(x, str) for x in c) for c in ch),
              f"{what}: channels must be a list of lists of channel names")
    u = h.get("unit_m")
    ck.ensure(u is None or (_is_num(u) and u > 0), f"{what}: unit_m must be a finite number > 0 or null, got {u!r}")


def _database_from_arrays(cls, z: dict, where: str) -> MotionDatabase:
    ck = _Check(z, where)
    header = ck.json("header")
    ck.ensure(isinstance(header, dict), "not a motion database (header is not a JSON object)")
    fmt = header.get("format")
    ck.ensure(fmt == _DB_FORMAT, f"not a motion database file (format {fmt!r}, expected {_DB_FORMAT!r})")
    fps = header.get("fps")
    ck.ensure(_is_num(fps) and fps > 0, f"fps must be a finite number > 0, got {fps!r}")
    roles = header.get("pose_roles")
    ck.ensure(isinstance(roles, list) and roles and all(isinstance(r, str) for r in roles),
              "pose_roles must be a non-empty list of role names")
    window, step = header.get("window"), header.get("step")
    ck.ensure(_is_int(window) and window >= 1 and _is_int(step) and step >= 1,
              f"window and step must be integers >= 1, got {window!r}, {step!r}")
    meta = header.get("meta")
    ck.ensure(isinstance(meta, dict), "meta must be a JSON object")
    ah, mh = header.get("actors"), header.get("motions")
    ck.ensure(isinstance(ah, list) and ah, "the header lists no actor")
    ck.ensure(isinstance(mh, list), "the header's motions must be a list")

    # ------------------------------------------------- per-clip annotations
    names = ck.strings("names", None)
    C = names.size
    ck.ensure(C >= 1, "the database has no clip")
    ck.ensure(len(set(names.tolist())) == C, "clip names are not unique")
    arrays: dict[str, np.ndarray] = {"names": names}
    for k in _CLIP_STR[1:]:
        arrays[k] = ck.strings(k, C)
    bad = sorted(set(arrays["semantics"].tolist()) - set(SEMANTICS))
    ck.ensure(not bad, f"unknown semantics {bad}; expected {list(SEMANTICS)}")
    bad = sorted(set(arrays["hit_roles"].tolist()) - set(HIT_ROLES))
    ck.ensure(not bad, f"unknown hit segments {bad}; expected {list(HIT_ROLES)}")
    bad = sorted(set(arrays["hit_wheres"].tolist()) - {"joint", "end_site"})
    ck.ensure(not bad, f"hit_wheres must be 'joint' or 'end_site', got {bad}")
    for k in ("hit_frame", "n_frames", "actor", "source_clip"):
        arrays[k] = ck.numbers(k, (C,), "int")
    for k in ("scale", "size_a", "source_time", "warp", "noise"):
        arrays[k] = ck.numbers(k, (C,), "float")
    arrays["mirror"] = ck.numbers("mirror", (C,), "bool")
    for k in ("box_min", "box_max", "hit_position"):
        arrays[k] = ck.numbers(k, (C, 3), "float")
    nf = arrays["n_frames"]
    ck.ensure(np.all(nf >= 1), "n_frames must be >= 1 for every clip")
    ck.ensure(np.all((arrays["hit_frame"] >= 0) & (arrays["hit_frame"] < nf)),
              "a hit frame lies outside its clip (hit_frame not in [0, n_frames))")
    ck.ensure(np.all((arrays["actor"] >= 0) & (arrays["actor"] < len(ah))),
              f"a clip's actor index is outside the {len(ah)} stored actors")
    ck.ensure(np.all((arrays["source_clip"] >= 0) & (arrays["source_clip"] < C)),
              f"a source_clip index is outside [0, {C})")
    ck.ensure(np.all(arrays["scale"] > 0) and np.all(arrays["size_a"] > 0) and np.all(arrays["warp"] > 0),
              "scale, size_a and warp must be > 0")
    ck.ensure(np.all(arrays["noise"] >= 0), "noise must be >= 0")
    ck.ensure(np.all(arrays["box_min"] <= arrays["box_max"]), "a bounding box has box_min > box_max")

    # --------------------------------------------------- trajectories, poses
    for k in ("traj_start", "pose_start"):
        arrays[k] = ck.numbers(k, (C + 1,), "int")
    offsets = np.concatenate([[0], np.cumsum(nf)])
    for k in ("traj_start", "pose_start"):
        ck.ensure(np.array_equal(arrays[k], offsets),
                  f"{k} does not match the clips' frame counts (offsets must be 0 and the running sum of n_frames)")
    T = N = int(offsets[-1])
    arrays["traj"] = ck.numbers("traj", (T, 3), "float")
    arrays["pose_points"] = ck.numbers("pose_points", (N, window * len(roles), 3), "float")
    arrays["pose_clip"] = ck.numbers("pose_clip", (N,), "int")
    arrays["pose_frame"] = ck.numbers("pose_frame", (N,), "int")
    arrays["pose_heading"] = ck.numbers("pose_heading", (N,), "float")
    arrays["pose_origin"] = ck.numbers("pose_origin", (N, 3), "float")
    pc = np.repeat(np.arange(C), nf)
    ck.ensure(np.array_equal(arrays["pose_clip"], pc), "pose_clip does not match the clips' frame counts")
    ck.ensure(np.array_equal(arrays["pose_frame"], np.arange(N) - offsets[pc]),
              "pose_frame does not number the frames of each clip from 0")

    # ----------------------------------------------------------- actors
    actors = []
    for a, h in enumerate(ah):
        _check_skeleton_header(ck, h, f"actor {a}")
        ck.ensure(isinstance(h.get("roles"), dict) and all(isinstance(k, str) and isinstance(v, str)
                                                           for k, v in h["roles"].items()),
                  f"actor {a}: roles must map role names to joint names")
        J = len(h["joint_names"])
        try:
            sk = Skeleton(joint_names=h["joint_names"],
                          parents=ck.numbers(f"actor{a}_parents", (J,), "int"),
                          offsets=ck.numbers(f"actor{a}_offsets", (J, 3), "float"),
                          channels=[tuple(c) for c in h["channels"]] or None,
                          end_site_parents=ck.numbers(f"actor{a}_end_site_parents", (None,), "int"),
                          end_site_offsets=ck.numbers(f"actor{a}_end_site_offsets", (None, 3), "float"),
                          unit_m=h["unit_m"], roles=h["roles"])
        except DataError:
            raise
        except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
            ck.fail(f"actor {a} is unusable: {exc}")
        missing = [r for r in roles if r not in sk.roles]
        ck.ensure(not missing, f"actor {a} lacks the pose roles {missing}")
        actors.append(sk)
    for i in range(C):
        sk = actors[int(arrays["actor"][i])]
        if str(arrays["hit_joints"][i]) not in sk.joint_names:
            ck.fail(f"clip {i} ({names[i]}): hit joint {arrays['hit_joints'][i]!r} is not a joint of its actor")

    # ---------------------------------------------------------- motions
    motions = {}
    for h in mh:
        _check_skeleton_header(ck, h, "a stored motion")
        i = h.get("clip")
        ck.ensure(_is_int(i) and 0 <= i < C, f"a stored motion names clip {i!r}, not in [0, {C})")
        ck.ensure(i not in motions, f"clip {i} has two stored motions")
        ft = h.get("frame_time")
        ck.ensure(_is_num(ft) and ft > 0 and abs(1.0 / ft - fps) <= 1e-6 * fps,
                  f"motion of clip {i}: frame_time {ft!r} does not match the database's {fps:g} fps")
        src = h.get("source")
        ck.ensure(src is None or isinstance(src, str), f"motion of clip {i}: source must be a string or null")
        J, F = len(h["joint_names"]), int(nf[i])
        rot = ck.numbers(f"motion{i}_rotations", (F, J, 4), "float")
        try:
            m = Motion(joint_names=h["joint_names"], parents=ck.numbers(f"motion{i}_parents", (J,), "int"),
                       offsets=ck.numbers(f"motion{i}_offsets", (J, 3), "float"),
                       channels=[tuple(c) for c in h["channels"]], frame_time=ft, rotations=rot,
                       positions=ck.numbers(f"motion{i}_positions", (F, J, 3), "float"),
                       end_site_parents=ck.numbers(f"motion{i}_end_site_parents", (None,), "int"),
                       end_site_offsets=ck.numbers(f"motion{i}_end_site_offsets", (None, 3), "float"),
                       unit_m=h["unit_m"], source=src)
        except DataError:
            raise
        except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
            ck.fail(f"the motion of clip {i} is unusable: {exc}")
        # Motion() re-normalises quaternions, which may change their last bit; the
        # stored ones are unit already, keep them bit for bit
        ck.ensure(np.all(np.abs(np.linalg.norm(rot, axis=-1) - 1.0) < 1e-6),
                  f"motion of clip {i}: rotations are not unit quaternions")
        rot = np.array(rot, dtype=float)
        rot.flags.writeable = False
        object.__setattr__(m, "rotations", rot)
        motions[i] = m
    src = arrays["source_clip"]
    lacking = [i for i in range(C) if i not in motions and int(src[i]) not in motions]
    ck.ensure(not lacking, f"clips {lacking[:5]} have no stored motion, nor has their source clip")
    try:
        return cls(fps=fps, pose_roles=roles, window=window, step=step, actors=actors, motions=motions,
                   arrays=arrays, meta=meta)
    except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
        ck.fail(f"inconsistent database: {exc}")


def _hit_trajectory(motion: Motion, g: np.ndarray, joint: str, where: str) -> np.ndarray:
    j = motion.joint_index(joint)
    if where == "joint":
        return g[:, j]
    sites = np.flatnonzero(motion.end_site_parents == j)
    return motion.end_site_positions()[:, sites[0]]


def _clip_features(c: Clip, sk: Skeleton, actor: int, scale: float, pose_roles, window, step,
                   *, noise: float = 0.0, rng=None) -> dict:
    m = c.motion
    g = m.global_positions()
    idx = [sk.index(r) for r in pose_roles]
    pel, lh, rh = sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip")
    theta, origin = root_frames(g, pel, lh, rh)
    traj_w = _hit_trajectory(m, g, c.hit_joint, c.hit_where)
    size = sk.size
    pts = pose_points(g, idx, pel, lh, rh, window=window, step=step)
    if noise > 0:
        traj_w = traj_w + rng.normal(0.0, noise, traj_w.shape)
        pts = pts + rng.normal(0.0, noise, pts.shape)
    traj = to_root_frame(traj_w, theta[0], origin[0])
    return {
        "names": c.name, "sources": c.source, "semantics": c.semantics, "kinds": c.kind, "sides": c.side,
        "levels": c.level, "hit_roles": c.hit_role, "hit_joints": c.hit_joint, "hit_wheres": c.hit_where,
        "hit_frame": c.hit_frame, "n_frames": m.n_frames, "actor": actor, "scale": scale, "size_a": size,
        "source_time": c.source_time, "mirror": False, "warp": 1.0, "noise": float(noise),
        "box_min": traj.min(axis=0), "box_max": traj.max(axis=0), "hit_position": traj[c.hit_frame],
        "traj": traj, "pose_points": pts / size, "pose_frame": np.arange(m.n_frames),
        "pose_heading": theta, "pose_origin": origin,
    }


def _stack(recs: list[dict]) -> dict:
    out = {k: np.array([r[k] for r in recs]) for k in _CLIP_STR}
    for k in ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_time", "mirror", "warp", "noise"):
        out[k] = np.array([r[k] for r in recs])
    for k in ("box_min", "box_max", "hit_position"):
        out[k] = np.stack([r[k] for r in recs]).reshape(len(recs), 3)
    lens = np.array([r["traj"].shape[0] for r in recs])
    out["traj_start"] = np.concatenate([[0], np.cumsum(lens)])
    out["pose_start"] = out["traj_start"].copy()
    out["traj"] = np.concatenate([r["traj"] for r in recs])
    out["pose_points"] = np.concatenate([r["pose_points"] for r in recs])
    out["pose_clip"] = np.repeat(np.arange(len(recs)), lens)
    out["pose_frame"] = np.concatenate([r["pose_frame"] for r in recs])
    out["pose_heading"] = np.concatenate([r["pose_heading"] for r in recs])
    out["pose_origin"] = np.concatenate([r["pose_origin"] for r in recs])
    return out


def _subset(db: MotionDatabase, idx: np.ndarray) -> MotionDatabase:
    idx = np.asarray(idx, dtype=np.intp)
    if idx.size == 0:
        raise MotionError("selection is empty")
    arrays = {k: getattr(db, k)[idx] for k in _CLIP_STR}
    for k in ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_time", "mirror", "warp", "noise",
              "box_min", "box_max", "hit_position"):
        arrays[k] = getattr(db, k)[idx]
    lens = db.traj_start[idx + 1] - db.traj_start[idx]
    rows = np.concatenate([np.arange(db.traj_start[i], db.traj_start[i + 1]) for i in idx])
    arrays["traj_start"] = np.concatenate([[0], np.cumsum(lens)])
    arrays["pose_start"] = arrays["traj_start"].copy()
    arrays["traj"] = db.traj[rows]
    for k in ("pose_points", "pose_frame", "pose_heading", "pose_origin"):
        arrays[k] = getattr(db, k)[rows]
    arrays["pose_clip"] = np.repeat(np.arange(idx.size), lens)
    new_of_old = {int(o): n for n, o in enumerate(idx)}
    motions, src = {}, np.arange(idx.size)
    for n, o in enumerate(idx.tolist()):
        if o in db._motions:
            motions[n] = db._motions[o]
        elif int(db.source_clip[o]) in new_of_old:
            src[n] = new_of_old[int(db.source_clip[o])]
        else:  # the source is not selected: keep a materialised copy
            motions[n] = db.motion(o)
    arrays["source_clip"] = src
    return MotionDatabase(fps=db.fps, pose_roles=db.pose_roles, window=db.window, step=db.step, actors=db.actors,
                          motions=motions, arrays=arrays, meta={**db.meta, "selected_from": db.n_clips})


# ============================================================= building
def _infer_unit(motion: Motion) -> float:
    """Metres per unit guessed from the stature in file units (metres, cm, CMU units)."""
    h = Skeleton.from_motion(motion).height
    if 0.5 <= h <= 3.0:
        return 1.0
    if 50.0 <= h <= 300.0:
        return 0.01
    if 20.0 <= h <= 45.0:
        return CMU_UNIT_M
    raise MotionError(f"cannot guess the length unit of {motion.source!r} (stature {h:.4g} units); pass unit_m")


def _read(path: Path, unit_m: float | None) -> Motion:
    from repro.motion.bvh import read_bvh

    m = read_bvh(path)
    u = _infer_unit(m) if unit_m is None else float(unit_m)
    return dataclasses.replace(m, unit_m=u).to_metres()


def _clips_from_take(motion: Motion, name: str, *, fps: float, window, hits: Iterable[Hit], kind: str = "",
                     level: str = "", hit_joint: str | None = None, hit_where: str = "joint", tag=True) -> list[Clip]:
    sk = Skeleton.from_motion(motion)
    out = []
    for n, h in enumerate(hits):
        m, k0, t0 = _cut_around(motion, h.frame * motion.frame_time, window, fps)
        cname = f"{name}_h{n:02d}_{h.role}" if tag else name
        out.append(Clip(name=cname, motion=m, semantics=h.semantics, hit_role=h.role,
                        hit_joint=hit_joint or sk.roles[h.role], hit_where=hit_where, hit_frame=k0, kind=kind,
                        side=h.side, source=str(motion.source or name), source_time=t0, level=level))
    return out


def _read_manifest_rows(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as fh:
        return [dict(r) for r in csv.DictReader(fh)]


def build_database(source, *, fps: float = DATABASE_FPS, window: tuple[float, float] | None = None,
                   unit_m: float | None = None, manifest: str | None = "manifest.csv",
                   pose_roles: Sequence[str] = POSE_ROLES, pose_window: int = 1, detect_kw: Mapping | None = None
                   ) -> MotionDatabase:
    """Build the database from a folder of BVH files (and its manifest when there is one).

    With a manifest (the columns of :data:`repro.motion.synthetic.MANIFEST_COLUMNS`:
    ``file``, ``semantics``, ``side``, ``hit_joint``, ``hit_point`` (``joint`` or
    ``end_site``), ``hit_frame``, ``kind``, ``level``; an optional ``unit_m``) each row
    is one clip, annotated as the manifest says -- rows whose semantics is not a strike
    (``"other"``, the stance clips) are skipped; an empty or negative ``hit_frame`` is
    found with :func:`hit_frame_for`, an empty ``hit_joint`` is the role's joint.  Without
    a manifest every BVH file is searched with :func:`detect_hits` and cut around each
    strike.  Clips are resampled to ``fps`` on a grid that passes through the hit time
    (so the hit stays on a frame).

    Parameters
    ----------
    source : str or os.PathLike
        Folder (or a single manifest file).
    fps : float, default 30
    window : (before, after) seconds, optional
        Cut each clip to this window around its hit; default: the whole clip for manifest
        rows (the manifest's clips *are* the annotated subsequences), (0.6, 0.3) for
        detected strikes.
    unit_m : float, optional
        Metres per file unit; default from the manifest's ``unit_m`` column, else guessed
        from the stature (metres, centimetres or CMU units).
    manifest : str or None, default "manifest.csv"
        Name of the manifest in the folder; None to ignore it.
    pose_roles, pose_window
        Pose representation (:meth:`MotionDatabase.from_clips`).
    detect_kw : mapping, optional
        Thresholds passed to :func:`detect_hits`.

    Raises
    ------
    repro.errors.MotionError
        No clip found, a manifest naming a missing file or bad annotation.
    """
    src = Path(source)
    folder = src.parent if src.is_file() else src
    mpath = src if src.is_file() else (folder / manifest if manifest else None)
    detect_kw = dict(detect_kw or {})
    clips: list[Clip] = []
    if mpath is not None and mpath.is_file():
        for r in _read_manifest_rows(mpath):
            sem = (r.get("semantics") or "").strip()
            if sem not in SEMANTICS:
                continue
            f = folder / r["file"]
            if not f.is_file():
                raise MotionError(f"{mpath}: {r['file']} is missing")
            u = unit_m if unit_m is not None else (float(r["unit_m"]) if r.get("unit_m") else None)
            m = _read(f, u)
            side = (r.get("side") or "").strip()
            role = _ROLE_OF.get((sem, side))
            if role is None:
                raise MotionError(f"{mpath}: {r['file']}: side must be left or right, got {side!r}")
            hf = (r.get("hit_frame") or "").strip()
            hf = int(hf) if hf not in ("",) else -1
            if hf < 0:
                hf = hit_frame_for(m, role, **detect_kw)
            where = (r.get("hit_point") or "joint").strip() or "joint"
            hj = (r.get("hit_joint") or "").strip() or None
            hit = Hit(frame=hf, time=hf * m.frame_time, role=role, semantics=sem, side=side, extension=float("nan"),
                      height=float("nan"), start=hf, stop=hf + 1)
            clips += _clips_from_take(m, Path(r["file"]).stem, fps=fps, window=window, hits=[hit],
                                      kind=(r.get("kind") or "").strip(), level=(r.get("level") or "").strip(),
                                      hit_joint=hj, hit_where=where, tag=False)
        how = f"manifest {mpath.name}"
    else:
        for f in sorted(folder.glob("*.bvh")):
            m = _read(f, unit_m)
            hits = detect_hits(m, **detect_kw)
            clips += _clips_from_take(m, f.stem, fps=fps, window=CMU_WINDOW if window is None else window, hits=hits)
        how = "detect_hits"
    if not clips:
        raise MotionError(f"no punch or kick clip found in {src}")
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": str(src), "annotations": how, "fps": fps,
                                           "window": None if window is None else list(window)})


def build_cmu_database(takes: Mapping[str, str] | Sequence[str] | None = None, *, fps: float = DATABASE_FPS,
                       window: tuple[float, float] = CMU_WINDOW, pose_roles: Sequence[str] = POSE_ROLES,
                       pose_window: int = 1, detect_kw: Mapping | None = None) -> MotionDatabase:
    """The database of the real CMU karate takes (subject 135), cut around detected strikes.

    Each take of :data:`CMU_TAKES` is read in metres (:data:`~repro.motion.CMU_UNIT_M`),
    searched with :func:`detect_hits` (kick drills for kicks, the other takes for arm
    strikes), and every hit becomes a clip from ``window[0]`` s before to ``window[1]`` s
    after it, resampled to ``fps``.  Semantics: ``"kick"`` for kicks, ``"punch"`` for
    every arm strike (the lunge punches of 135_09 and the arm strikes and blocks of the
    katas, kind ``"kata_arm"``).  With the default thresholds this gives 14 kicks, 9
    lunge punches and about 50 kata arm strikes (see ``mocap/cmu/PROVENANCE.md``), about
    the 75 motions of the paper.

    Parameters
    ----------
    takes : mapping take -> kind, or sequence of takes, optional
        Default :data:`CMU_TAKES`.
    fps, window, pose_roles, pose_window, detect_kw
        As :func:`build_database`.

    Raises
    ------
    repro.errors.DataError
        If the staged CMU files are missing (:func:`repro.data.fetch`).
    """
    clips, takes = _cmu135_clips(takes, fps=fps, window=window, detect_kw=detect_kw)
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": "mocap/cmu", "takes": dict(takes), "annotations": "detect_hits",
                                           "fps": fps, "window": list(window)})


def load_or_build(path, build=build_cmu_database, **kw) -> MotionDatabase:
    """Load the database saved at ``path``, or ``build(**kw)`` it and save it there.

    For notebooks: the first run builds (about a second for the CMU takes) and saves
    atomically; later runs load.  Delete the file to rebuild (nothing checks that the
    saved database was built with the same ``kw``).
    """
    path = Path(path)
    if path.exists():
        return MotionDatabase.load(path)
    db = build(**kw)
    db.save(path)
    return db


# ============================================================= augmentation
def _variant_motion(m: Motion, n_frames: int, scale: float, mirror: bool) -> Motion:
    if n_frames != m.n_frames:
        m = resample(m, frames=np.linspace(0.0, m.n_frames - 1, n_frames))
    if scale != 1.0:
        m = m.scaled(scale, unit_m=1.0)
    if mirror:
        m = mirror_motion(m)
    return m


def augment(db: MotionDatabase, factor: int, seed: int = 0, *, scale_range=(0.85, 1.15), warp_range=(0.85, 1.15),
            noise: float = 0.005, mirror_probability: float = 0.5) -> MotionDatabase:
    """A ``factor`` times larger database of *synthetic* variants, for latency-vs-size.

    "Scaling the database": the paper's database holds about 75 motions; to measure how
    the search time grows with the size of the database, every clip gets ``factor - 1``
    variants (the originals are kept, first), each with parameters drawn from
    ``numpy.random.default_rng(seed)`` in a fixed order (so the result is deterministic):

    * mirrored left/right with probability ``mirror_probability``
      (:func:`mirror_motion`; a punch with the right fist becomes one with the left);
    * the actor rescaled uniformly by a factor in ``scale_range`` (a new, taller or
      smaller actor: every length and ``size_a`` multiplied);
    * time-warped: the number of frames multiplied by a factor in ``warp_range``
      (resampled uniformly, the hit frame moved accordingly);
    * Gaussian noise of ``noise`` metres (std) added to the pose clouds and the hit
      trajectory (as capture noise; the stored motion is not noisy).

    These are not new captures: the variants are strongly correlated with their source,
    which makes the retrieval's job *easier* than on as many real motions would be.  A
    mirrored variant keeps its source's base actor (exact for the left/right symmetric
    synthetic actor; for a captured skeleton such as CMU's the mirrored one has the other
    side's bone lengths, a difference of millimetres that the retrieval ignores).

    Returns
    -------
    MotionDatabase
        ``factor * n_clips`` clips; the variants store no motion of their own
        (:meth:`MotionDatabase.motion` rebuilds it from the source clip).
    """
    factor = int(factor)
    if factor < 1:
        raise MotionError(f"factor must be >= 1, got {factor}")
    rng = np.random.default_rng(seed)
    C = db.n_clips
    recs = []
    src_ids = []
    for v in range(1, factor):
        for i in range(C):
            mir = bool(rng.random() < mirror_probability)
            s = float(rng.uniform(*scale_range))
            w = float(rng.uniform(*warp_range))
            n = max(2, int(round((db.n_frames[i] - 1) * w)) + 1)
            base = db.motion(i)
            m = _variant_motion(base, n, s, mir)
            hf = int(round(db.hit_frame[i] * (n - 1) / (db.n_frames[i] - 1)))
            role = str(db.hit_roles[i])
            side = str(db.sides[i])
            joint = str(db.hit_joints[i])
            if mir:
                role = role.replace("left", "@").replace("right", "left").replace("@", "right")
                side = {"left": "right", "right": "left"}.get(side, side)
                pi = mirror_joint_map(base.joint_names, base.parents)
                joint = base.joint_names[pi[base.joint_index(joint)]]
            c = Clip(name=f"{db.names[i]}~v{v:03d}", motion=m, semantics=str(db.semantics[i]), hit_role=role,
                     hit_joint=joint, hit_where=str(db.hit_wheres[i]), hit_frame=min(hf, n - 1),
                     kind=str(db.kinds[i]), side=side, source=str(db.sources[i]),
                     source_time=float(db.source_time[i]), level=str(db.levels[i]))
            sk = db.actor_skeleton(i)
            sk = sk.with_offsets(sk.offsets * s, sk.end_site_offsets * s)
            r = _clip_features(c, sk, int(db.actor[i]), float(db.scale[i]) * s, db.pose_roles, db.window, db.step,
                               noise=noise, rng=rng)
            r.update(mirror=mir ^ bool(db.mirror[i]), warp=w * float(db.warp[i]))
            recs.append(r)
            src_ids.append(int(db.source_clip[i]) if int(db.source_clip[i]) != i else i)
    if not recs:
        return db
    new = _stack(recs)
    arrays = {}
    for k in _CLIP_STR + ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_time", "mirror", "warp",
                          "noise", "box_min", "box_max", "hit_position"):
        arrays[k] = np.concatenate([getattr(db, k), new[k]])
    arrays["source_clip"] = np.concatenate([db.source_clip, np.asarray(src_ids, dtype=np.intp)])
    T0, N0 = db.traj.shape[0], db.n_poses
    arrays["traj_start"] = np.concatenate([db.traj_start, new["traj_start"][1:] + T0])
    arrays["pose_start"] = np.concatenate([db.pose_start, new["pose_start"][1:] + N0])
    arrays["traj"] = np.concatenate([db.traj, new["traj"]])
    arrays["pose_clip"] = np.concatenate([db.pose_clip, new["pose_clip"] + C])
    for k in ("pose_points", "pose_frame", "pose_heading", "pose_origin"):
        arrays[k] = np.concatenate([getattr(db, k), new[k]])
    meta = {**db.meta, "augmented": {"factor": factor, "seed": seed, "scale_range": list(scale_range),
                                     "warp_range": list(warp_range), "noise_m": noise,
                                     "mirror_probability": mirror_probability,
                                     "note": "synthetic variants of the original clips, for latency-vs-size only"}}
    return MotionDatabase(fps=db.fps, pose_roles=db.pose_roles, window=db.window, step=db.step, actors=db.actors,
                          motions=dict(db._motions), arrays=arrays, meta=meta)


# ============================================================= the two default databases
def default_database(name: str = "synthetic", seed: int = 0) -> MotionDatabase:
    """A ready database by name, built once per process.

    ``"synthetic"``: the embedded set of :func:`repro.motion.synthetic.synthetic_database`
    (75 clips written to a temporary folder, built from its manifest), always available.
    ``"cmu"``: :func:`build_cmu_database` from the staged CMU takes (needs dataset
    ``cmu-bvh``; raises :class:`~repro.errors.DataError` saying how to get it).
    """
    import copy

    if name == "synthetic":
        key = ("synthetic", int(seed))
    elif name == "cmu":
        from repro import data

        reason = data.missing_reason("cmu-bvh")
        if reason:
            raise DataError(reason)
        key = ("cmu", str(data.data_dir()))
    else:
        raise RetrievalError(f"unknown database {name!r}; known: 'synthetic', 'cmu'")
    if key not in _DEFAULT_DATABASES:
        if name == "synthetic":
            import tempfile

            from repro.motion.synthetic import synthetic_database

            with tempfile.TemporaryDirectory(prefix="repro-synthetic-") as tmp:
                synthetic_database(tmp, seed=seed)
                _DEFAULT_DATABASES[key] = build_database(tmp)
        else:
            _DEFAULT_DATABASES[key] = build_cmu_database()
    # a copy each call (~20 ms): a caller changing its database cannot change the next caller's
    return copy.deepcopy(_DEFAULT_DATABASES[key])


#: :func:`default_database`'s builds, by (name, seed or data folder): built once per process
_DEFAULT_DATABASES: dict = {}


# ============================================================= the other real sources
# The issue asks for a database built "from the real clips in ../shared/data/mocap/": CMU
# subject 135 (above, build_cmu_database), the Bandai Namco clips (another skeleton) and
# walks/runs of other CMU subjects for non-fighting poses.  What follows adds them
# without changing anything above.

#: Bandai Namco strike takes and their semantics, from the ``semantics`` column of
#: ``mocap/bandai/manifest.csv`` (walk and bow are ``other``: see
#: :data:`NON_FIGHTING_TAKES`).  The kick take also holds arm swings that the punch
#: detector would report ("arm swings 2/3" in ``mocap/bandai/PROVENANCE.md``): as for the
#: CMU drills, only strikes of the take's semantics are searched for.
BANDAI_TAKES: dict[str, str] = {
    "dataset-1_kick_normal_001": "kick",
    "dataset-1_punch_normal_001": "punch",
    "dataset-1_punch_normal_002": "punch",
}

#: Non-fighting takes (``semantics = other`` in the manifests), for "current poses" of
#: retrieval queries: path -> (subject, kind, description).  :class:`MotionDatabase`
#: only holds strikes (:data:`SEMANTICS`; a :class:`Clip` must have a hit), so these
#: are not database clips; :func:`non_fighting_poses` loads them.  Subjects 131, 7 and
#: 9 share the CMU joint tree with subject 135 but neither its bone lengths nor its rest
#: directions (the retrieval can retarget them to the 135 actor only after
#: :func:`match_rest_pose`, ``non_fighting_poses(rest_like=db)``); the Bandai walk and bow are on the
#: Bandai joint tree (the bow's file has a 10 cm Head End Site and a slightly different
#: Hips offset, so its skeleton is *not* the one of the other Bandai takes: its size is
#: 1.40 m instead of 1.30 m).  135_03 is labelled "Empi" in the CMU index but is a
#: ~5 m walk without any strike (``mocap/cmu/PROVENANCE.md``): subject 135's only walk.
NON_FIGHTING_TAKES: dict[str, tuple[str, str, str]] = {
    "mocap/cmu/131_01.bvh": ("cmu131", "walk", "Start Walk Stop"),
    "mocap/cmu/131_02.bvh": ("cmu131", "walk", "Start Walk Stop"),
    "mocap/cmu/131_09.bvh": ("cmu131", "walk", "Start Walk Left"),
    "mocap/cmu/131_10.bvh": ("cmu131", "walk", "Start Walk Left"),
    "mocap/cmu/131_12.bvh": ("cmu131", "walk", "Start Walk Right"),
    "mocap/cmu/131_13.bvh": ("cmu131", "walk", "Start Walk Right"),
    "mocap/cmu/07_05.bvh": ("cmu07", "walk", "slow walk"),
    "mocap/cmu/09_06.bvh": ("cmu09", "run", "run"),
    "mocap/cmu/135_03.bvh": ("cmu135", "walk", "Empi (index label); a ~5 m walk, no strike"),
    "mocap/bandai/dataset-1_walk_normal_001.bvh": ("bandai", "walk", "walk (style: normal)"),
    "mocap/bandai/dataset-1_bow_normal_001.bvh": ("bandai", "bow", "bow (style: normal)"),
}

#: Sources :func:`build_real_database` can combine.
REAL_SOURCES: tuple[str, ...] = ("cmu135", "bandai")


def _dataset_of(path: str) -> str:
    return "bandai" if path.startswith("mocap/bandai/") else "cmu-bvh"


def _cmu135_clips(takes, *, fps: float, window, detect_kw) -> tuple[list[Clip], dict]:
    """The clips of :func:`build_cmu_database` (same reading, detection and cutting)."""
    from repro import data

    if takes is None:
        takes = CMU_TAKES
    if not isinstance(takes, Mapping):
        takes = {t: CMU_TAKES.get(t, "") for t in takes}
    clips: list[Clip] = []
    for take, kind in takes.items():
        m = _read(data.fetch(f"mocap/cmu/{take}.bvh"), CMU_UNIT_M)
        m = dataclasses.replace(m, source=f"mocap/cmu/{take}.bvh")
        sem = "kick" if kind.endswith("kick") else "punch"
        hits = detect_hits(m, semantics=sem, **dict(detect_kw or {}))
        clips += _clips_from_take(m, take, fps=fps, window=window, hits=hits, kind=kind)
    return clips, dict(takes)


def _bandai_clips(takes, *, fps: float, window, detect_kw) -> tuple[list[Clip], dict]:
    from repro import data
    from repro.motion.motion import BANDAI_UNIT_M

    if takes is None:
        takes = BANDAI_TAKES
    if not isinstance(takes, Mapping):
        unknown = [t for t in takes if t not in BANDAI_TAKES]
        if unknown:
            raise MotionError(f"unknown Bandai strike take(s) {unknown}; known: {sorted(BANDAI_TAKES)}")
        takes = {t: BANDAI_TAKES[t] for t in takes}
    clips: list[Clip] = []
    for take, sem in takes.items():
        _check_semantics(sem)
        rel = f"mocap/bandai/{take}.bvh"
        m = _read(data.fetch(rel), BANDAI_UNIT_M)
        m = dataclasses.replace(m, source=rel)
        hits = detect_hits(m, semantics=sem, **dict(detect_kw or {}))
        clips += _clips_from_take(m, take, fps=fps, window=window, hits=hits, kind=f"{sem}_normal")
    return clips, dict(takes)


def build_bandai_database(takes: Mapping[str, str] | Sequence[str] | None = None, *, fps: float = DATABASE_FPS,
                          window: tuple[float, float] = CMU_WINDOW, pose_roles: Sequence[str] = POSE_ROLES,
                          pose_window: int = 1, detect_kw: Mapping | None = None) -> MotionDatabase:
    """The database of the Bandai Namco strike takes, cut around detected strikes.

    Each take of :data:`BANDAI_TAKES` is read in metres
    (:data:`~repro.motion.BANDAI_UNIT_M`; the 6-channel joints' position channels
    replace their OFFSET, :func:`~repro.motion.read_bvh`), searched with
    :func:`detect_hits` for strikes of the manifest's semantics only, and every hit
    becomes a clip from ``window[0]`` s before to ``window[1]`` s after it, resampled to
    ``fps`` (the files are at 30 fps already).  Kind ``"kick_normal"`` /
    ``"punch_normal"`` (the dataset's "normal" style).  With the default thresholds:
    3 right kicks (``dataset-1_kick_normal_001``), 2 left punches (``punch_normal_001``)
    and 5 right punches (``punch_normal_002``): 10 clips, as counted in
    ``mocap/bandai/PROVENANCE.md``.

    The actor is the Bandai skeleton itself (one base actor): leg 0.80 m, arm 0.47 m,
    ``size_a`` 1.30 m -- the straightened stature stops at the ``Head`` joint (the file
    has no head-top point) and counts no ankle height, so it is *not* comparable with the
    CMU actor's 1.64 m (see :attr:`repro.motion.skeleton.Skeleton.height`).  Hit points:
    ``Hand_L``/``Hand_R`` (the wrist; no fist point) and ``Toes_L``/``Toes_R``.

    Raises
    ------
    repro.errors.DataError
        If the staged Bandai files are missing (:func:`repro.data.fetch`).
    """
    clips, takes = _bandai_clips(takes, fps=fps, window=window, detect_kw=detect_kw)
    if not clips:
        raise MotionError("no strike found in the Bandai takes")
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": "mocap/bandai", "takes": takes, "annotations": "detect_hits",
                                           "fps": fps, "window": list(window), "sources": {"bandai": len(clips)}})


def build_real_database(include: Sequence[str] = REAL_SOURCES, *, cmu_takes=None, bandai_takes=None,
                        fps: float = DATABASE_FPS, window: tuple[float, float] = CMU_WINDOW,
                        pose_roles: Sequence[str] = POSE_ROLES, pose_window: int = 1,
                        detect_kw: Mapping | None = None) -> MotionDatabase:
    """One database of the real strike clips: CMU subject 135 and/or Bandai Namco.

    ``include`` names the sources (:data:`REAL_SOURCES`): ``"cmu135"`` gives exactly the
    clips of :func:`build_cmu_database`, ``"bandai"`` those of
    :func:`build_bandai_database`, in that order.  The two skeletons have different
    joint trees (31 CMU joints, 22 Bandai joints), so the database holds two base actors
    (:attr:`MotionDatabase.actors`, ``actor`` per clip); pose clouds are role-based
    (:data:`~repro.motion.clustering.POSE_ROLES`) and share one array and one
    clustering (in practice every k-means cluster holds poses of one family only: the
    clouds are divided by sizes that the two rigs measure differently).

    What the retrieval (:class:`repro.motion.retrieval.MotionRetriever`) does with it:
    the current pose is retargeted (Section 3.4.1) to every actor *with the character's
    joint tree*, and only the clips of those actors are candidates (clusters without
    such poses are skipped: the result then says ``fallback="neighbour_clusters"``).  A
    CMU character (subject 135 and its :func:`~repro.motion.scale_skeleton`
    derivatives; subjects 131, 7 and 9 only after :func:`match_rest_pose`) therefore
    retrieves only CMU clips and a Bandai character only Bandai clips; nothing is retargeted across joint trees
    (:func:`repro.motion.morphology.decode` requires the same topology), and Eq. 1 is
    never applied between a CMU character and a Bandai actor, whose sizes are not
    measured alike.  Mixing the sources in one file is for bookkeeping (one database,
    one save, one retriever); it gives no character more clips.

    ``"cmu-walks"`` (non-fighting takes) cannot be included: a database clip needs a hit;
    use :func:`non_fighting_poses`.

    Raises
    ------
    repro.errors.MotionError
        Unknown or empty ``include``.
    repro.errors.DataError
        A needed staged file is missing and cannot be downloaded
        (:func:`repro.data.fetch`).
    """
    include = tuple(include)
    bad = [s for s in include if s not in REAL_SOURCES]
    if bad:
        hint = (" (non-fighting takes are not database clips: use non_fighting_poses())"
                if any("walk" in s or "other" in s for s in bad) else "")
        raise MotionError(f"unknown source(s) {bad}; known: {list(REAL_SOURCES)}{hint}")
    if not include:
        raise MotionError("include names no source")
    clips: list[Clip] = []
    counts: dict[str, int] = {}
    takes: dict[str, dict] = {}
    for s in dict.fromkeys(include):
        if s == "cmu135":
            c, t = _cmu135_clips(cmu_takes, fps=fps, window=window, detect_kw=detect_kw)
        else:
            c, t = _bandai_clips(bandai_takes, fps=fps, window=window, detect_kw=detect_kw)
        clips += c
        counts[s] = len(c)
        takes[s] = t
    if not clips:
        raise MotionError(f"no strike found in {list(include)}")
    return MotionDatabase.from_clips(clips, pose_roles=pose_roles, window=pose_window,
                                     meta={"built_from": ["mocap/cmu" if s == "cmu135" else "mocap/bandai"
                                                          for s in counts],
                                           "takes": takes, "annotations": "detect_hits", "fps": fps,
                                           "window": list(window), "sources": counts})


def clip_source_dataset(db: MotionDatabase) -> np.ndarray:
    """(C,) ``"cmu135"`` / ``"bandai"`` / ``""`` for every clip, from its source file."""
    out = np.full(db.n_clips, "", dtype=object)
    for i, s in enumerate(db.sources.tolist()):
        if "mocap/bandai/" in s:
            out[i] = "bandai"
        elif re.search(r"mocap/cmu/135_\d+\.bvh", s):
            out[i] = "cmu135"
    return out.astype(str)


def _best_rotation(ref_dirs: np.ndarray, src_vecs: np.ndarray) -> np.ndarray:
    """Quaternion ``C`` minimising ``sum_c |C (l_c r_c) - s_c|^2`` (``l_c = |s_c|``).

    ``ref_dirs`` (n, 3) unit directions, ``src_vecs`` (n, 3) vectors; one pair (or only
    parallel pairs): the smallest rotation taking the longest ``r`` to its ``s``;
    several: Kabsch (SVD), proper rotation.
    """
    from scipy.spatial.transform import Rotation

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

    The retargeting of Section 3.4.1 (:func:`repro.motion.morphology.decode`) copies
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

    Bone lengths are kept; the :attr:`~repro.motion.skeleton.Skeleton.size` changes a
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
    from repro.motion.quaternion import quat_multiply
    from repro.motion.skeleton import skeleton_of

    ref = skeleton_of(reference)
    if not ref.is_compatible(motion):
        raise MotionError("reference skeleton has another joint tree (joint names / parents) than the motion")
    J = motion.n_joints
    par = np.asarray(motion.parents)
    mask = motion.position_mask
    off = np.asarray(motion.offsets, dtype=float)
    # joints below the root whose position channels carry a translation other than the
    # OFFSET (Bandai's Hips: the root trajectory); constant ones (Bandai's other joints,
    # equal to their OFFSET up to 1e-7 relative) are offsets and follow the new rest
    # directions
    scale = max(float(np.abs(off).max()), 1e-300)
    varying = np.zeros(J, dtype=bool)
    varying[1:] = np.any(mask[1:] & (np.abs(np.asarray(motion.positions)[:, 1:] - off[None, 1:]).max(axis=0)
                                     > 1e-5 * scale), axis=1)
    roff = np.asarray(ref.offsets, dtype=float)
    esp, eso = motion.end_site_parents, np.asarray(motion.end_site_offsets, dtype=float)
    resp, reso = ref.end_site_parents, np.asarray(ref.end_site_offsets, dtype=float)
    same_sites = np.array_equal(esp, resp)

    def unit(v):
        n = np.linalg.norm(v)
        return v / n if n > 1e-12 else None

    # children (joints that are not on a translated path, and End Sites) of every joint
    C = np.tile([0.0, 0.0, 0.0, 1.0], (J, 1))
    for j in range(J):
        r_list, s_list = [], []
        for c in np.flatnonzero(par == j):
            if varying[c]:
                continue
            r, sv = unit(roff[c]), off[c]
            if r is not None and np.linalg.norm(sv) > 1e-12:
                r_list.append(r)
                s_list.append(sv)
        if same_sites:
            for e in np.flatnonzero(esp == j):
                r, sv = unit(reso[e]), eso[e]
                if r is not None and np.linalg.norm(sv) > 1e-12:
                    r_list.append(r)
                    s_list.append(sv)
        if r_list:
            C[j] = _best_rotation(np.array(r_list), np.array(s_list))
    Cinv = C * np.array([-1.0, -1.0, -1.0, 1.0])

    new_off = off.copy()
    for c in range(1, J):
        p = par[c]
        r = unit(roff[c])
        if varying[c] or r is None:
            new_off[c] = _qrot_np(Cinv[p], off[c])
        else:
            new_off[c] = np.linalg.norm(off[c]) * r
    new_eso = eso.copy()
    for e, p in enumerate(esp):
        r = unit(reso[e]) if same_sites else None
        new_eso[e] = np.linalg.norm(eso[e]) * r if r is not None else _qrot_np(Cinv[p], eso[e])
    rot = np.asarray(motion.rotations)
    new_rot = quat_multiply(rot, C[None])
    new_rot[:, 1:] = quat_multiply(Cinv[None, par[1:]], new_rot[:, 1:])
    pos = np.array(motion.positions, dtype=float)
    for c in np.flatnonzero(varying):
        pos[:, c] = _qrot_np(np.broadcast_to(Cinv[par[c]], (motion.n_frames, 4)), pos[:, c])
    pos[:, 0] = np.asarray(motion.positions)[:, 0]
    pos = np.where((mask & (varying | (np.arange(J) == 0))[:, None])[None], pos, new_off[None])
    out = dataclasses.replace(motion, offsets=new_off, rotations=new_rot, positions=pos, end_site_offsets=new_eso,
                              source=(motion.source or "") + " (rest pose matched)")
    if not return_error:
        return out
    err = float(np.linalg.norm(out.global_positions() - motion.global_positions(), axis=-1).max())
    return out, err


def _qrot_np(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    from repro.motion.quaternion import quat_rotate

    return quat_rotate(np.asarray(q, dtype=float), np.asarray(v, dtype=float))


def non_fighting_poses(takes: Sequence[str] | None = None, *, fps: float | None = DATABASE_FPS,
                       kinds: Sequence[str] | None = None, rest_like=None) -> dict[str, Motion]:
    """The non-fighting takes as motions in metres, for the current poses of queries.

    Parameters
    ----------
    takes : sequence of str, optional
        Paths relative to the data folder (keys of :data:`NON_FIGHTING_TAKES`); default
        all of them (CMU 131 walks, CMU 7 slow walk, CMU 9 run, CMU 135_03 walk, Bandai
        walk and bow).  Any staged BVH path is accepted (centimetres under
        ``mocap/bandai/``, CMU units elsewhere).
    fps : float or None, default 30
        Resample to this rate (the database's); None keeps the file's (120 Hz for CMU).
    kinds : sequence of str, optional
        Keep only these kinds of :data:`NON_FIGHTING_TAKES` (``"walk"``, ``"run"``,
        ``"bow"``), e.g. ``("walk", "run")``.
    rest_like : MotionDatabase, Skeleton, Motion or sequence of them, optional
        Put every motion that shares the joint tree of one of these skeletons (for a
        database: of one of its :attr:`~MotionDatabase.actors`) on that skeleton's rest
        directions with :func:`match_rest_pose` (bone lengths and joint positions
        kept).  Needed for the CMU subjects 131, 7 and 9 to be used against the CMU 135
        actor: the retrieval retargets the current pose to the actor
        (:meth:`repro.motion.retrieval.MotionRetriever.prepare`), and the retargeting
        refuses rest directions more than 5 degrees apart (they differ by 12-14
        degrees).  Motions with no matching joint tree are returned unchanged.

    Returns
    -------
    dict
        Take name (file stem) -> :class:`~repro.motion.Motion` in metres
        (``unit_m = 1``), ``source`` the relative path.  Any frame of it is a
        ``current_pose`` for the retrieval with the motion's own skeleton
        (``Skeleton.from_motion``) as the character: as they are, the Bandai walk and bow
        (against the Bandai actor) and CMU 135_03 (against the CMU 135 actor); the other
        CMU subjects after ``rest_like=db``.

    Raises
    ------
    repro.errors.DataError
        A needed staged file is missing.
    """
    from repro import data
    from repro.motion.motion import BANDAI_UNIT_M

    if takes is None:
        takes = list(NON_FIGHTING_TAKES)
    takes = list(takes)
    if kinds is not None:
        kinds = set(kinds)
        takes = [t for t in takes if NON_FIGHTING_TAKES.get(t, ("", "", ""))[1] in kinds]
    refs: list[Skeleton] = []
    if rest_like is not None:
        items = rest_like if isinstance(rest_like, (list, tuple)) else [rest_like]
        for it in items:
            if isinstance(it, MotionDatabase):
                refs += list(it.actors)
            else:
                from repro.motion.skeleton import skeleton_of

                refs.append(skeleton_of(it))
    out: dict[str, Motion] = {}
    for rel in takes:
        unit = BANDAI_UNIT_M if _dataset_of(rel) == "bandai" else CMU_UNIT_M
        m = _read(data.fetch(rel), unit)
        if fps is not None and abs(m.fps - fps) > 1e-9 * fps:
            m = resample(m, fps)
        m = dataclasses.replace(m, source=rel)
        for sk in refs:
            if sk.is_compatible(m):
                m = dataclasses.replace(match_rest_pose(m, sk), source=rel)
                break
        out[Path(rel).stem] = m
    return out


__all__ += [
    "BANDAI_TAKES",
    "NON_FIGHTING_TAKES",
    "REAL_SOURCES",
    "build_bandai_database",
    "build_real_database",
    "clip_source_dataset",
    "non_fighting_poses",
    "match_rest_pose",
]


def effector_role(roles: Mapping[str, str], hit_role: str, hit_joint: str) -> str:
    """The role (of a skeleton's ``roles``) whose joint is a clip's hit joint: the effector to adapt.

    A clip's ``hit_role`` names its striking limb's default hit point (``left_foot`` is
    the toe joint), but its ``hit_joint`` can be another joint of that limb: the
    synthetic side and round kicks strike with the heel (``LeftFoot``, the ankle).
    Driving the role's own joint onto the target would put the toe there instead.
    """
    side, _, stem = hit_role.partition("_")
    stems = ("fist", "hand", "wrist") if stem in ("fist", "hand", "wrist") else ("foot", "toe", "ankle")
    for role in (hit_role,) + tuple(f"{side}_{s}" for s in stems):
        if roles.get(role) == hit_joint:
            return role
    raise MotionError(f"no {side} effector role maps to the hit joint {hit_joint!r} (hit role {hit_role!r})")
