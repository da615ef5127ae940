"""The annotated motion database of Pronost et al., Section 3.2: clips, the database, its file.

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

* :class:`Clip` -- one annotated subsequence: the motion (metres, resampled to the
  database rate, 30 Hz by default), the hit segment (a role such as ``"right_fist"`` or
  ``"left_foot"`` of :func:`repro.motion.body.roles.find_roles`, the joint, and whether
  the hit point is the joint or its End Site), the semantics (``"punch"`` or
  ``"kick"``), the hit frame/time, the source take and where it was cut.
* :class:`MotionDatabase` -- the clips plus everything the retrieval
  (:mod:`repro.motion.search.retrieval`) precomputes from them: per clip the actor and its
  :attr:`~repro.motion.body.skeleton.Skeleton.size` ``size_a`` (Eq. 1), the hit-point
  trajectory and its axis-aligned bounding box; per pose (every frame of every clip)
  the pose cloud of :mod:`repro.motion.body.pose_frames`.  Saved to / loaded from ``.npz``
  without pickles (:meth:`MotionDatabase.save`, :meth:`MotionDatabase.load`; a
  damaged file is refused with a :class:`~repro.errors.DataError` naming it).

Around it: the annotation (:mod:`repro.motion.database.annotation`: :func:`detect_hits`, the
hit-point trajectory), the builders from files and the catalogue of real takes
(:mod:`repro.motion.database.sources`: :func:`build_database`, :func:`build_cmu_database` ...),
and the "scaling the database" variants (:mod:`repro.motion.database.augment`).

Frames
------
World: Y up, floor y = 0, metres.  The **root reference frame** of a frame (the frame
in which the paper expresses the target ``c``, Section 3.3) has its origin on the floor
below the pelvis, y up and z along the body's heading (see
:func:`repro.motion.body.pose_frames.root_frames`).  A clip's **hit-point trajectory**, its
**bounding box** and :attr:`MotionDatabase.hit_position` are expressed in the root frame
of the clip's **first frame** (the paper compares ``c_r``, "expressed in the root
reference frame", with them), in metres of the actor.  Pose clouds are expressed in the
root frame of their own frame and divided by ``size_a`` (adimensional).
"""

from __future__ import annotations

import json
import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from repro.checks import as_choice, as_int, as_names, as_real, as_real_array, as_str, describe
from repro.errors import MotionError
from repro.io import MAX_READ_BYTES
from repro.motion.database.annotation import (
    HIT_ROLES,
    SEMANTICS,
    check_semantics,
    hit_point_trajectory,
)
from repro.motion.database.archive import CLIP_NUM, CLIP_STR, POSE_NUM, load_database, save_database
from repro.motion.body.pose_frames import MAX_WINDOW, POSE_ROLES, pose_points, root_frames, to_root_frame
from repro.motion.core.motion import Motion
from repro.motion.core.ops import variant_motion
from repro.motion.body.skeleton import Skeleton

__all__ = ["DATABASE_FPS", "Clip", "MotionDatabase", "annotate", "clip_record"]

#: Common frame rate of the database (the retrieval compares poses frame by frame).
DATABASE_FPS: float = 30.0


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
        check_semantics(self.semantics)
        as_choice(self.hit_role, f"{self.name}: hit segment (hit_role)", HIT_ROLES, error=MotionError)
        as_choice(self.side, f"{self.name}: side", ("", "left", "right"), error=MotionError)
        as_choice(self.hit_where, f"{self.name}: hit_where", ("joint", "end_site"), error=MotionError)
        for k in ("kind", "source", "level"):
            as_str(getattr(self, k), f"{self.name}: {k}", error=MotionError)
        object.__setattr__(self, "source_time", as_real(self.source_time, f"{self.name}: source_time (s)",
                                                        error=MotionError))
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
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a repro.motion.Motion, got {describe(motion)}")
    as_choice(hit_role, "hit_role (hit segment)", HIT_ROLES, error=MotionError)
    if hit_joint is None:
        hit_joint = Skeleton.from_motion(motion).roles[hit_role]
    return Clip(name=name, motion=motion, semantics=semantics, hit_role=hit_role, hit_joint=hit_joint,
                hit_where=hit_where, hit_frame=hit_frame, **kw)


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


class MotionDatabase:
    """Annotated clips and the query-independent data of the retrieval (Sections 3.2-3.3).

    Build with :meth:`from_clips`, :func:`repro.motion.database.sources.build_database`,
    :func:`repro.motion.database.sources.build_cmu_database` or :func:`repro.motion.database.augment.augment`;
    save and load with :meth:`save` / :meth:`load`.

    Attributes (C clips, N poses, T trajectory samples, P pose points)
    -------------------------------------------------------------------
    fps : float
        Frame rate of every clip.
    pose_roles : tuple of str
        Roles of the pose points (:data:`~repro.motion.body.pose_frames.POSE_ROLES`).
    window, step : int
        Frames per pose cloud and their spacing (:func:`~repro.motion.body.pose_frames.pose_points`).
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
        The actor's :attr:`~repro.motion.body.skeleton.Skeleton.size` (metres), Eq. 1.
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
        for k in CLIP_STR:
            setattr(self, k, np.asarray(arrays[k], dtype=str))
        for k in CLIP_NUM + POSE_NUM:
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
    def clip_index(self, i, name: str = "i") -> int:
        """``i`` as a clip index in ``0..C-1``, else a :class:`MotionError` naming ``name``.

        Python's negative indices are refused: ``motion(-1)`` silently answered the last
        clip (issue 23, section 5).
        """
        return as_int(i, f"{name} (a clip index of a {self.n_clips}-clip database)", 0, self.n_clips - 1,
                      error=MotionError)

    def trajectory(self, i: int) -> np.ndarray:
        """(n_frames, 3) hit-point trajectory of clip ``i`` (first-frame root frame, metres)."""
        i = self.clip_index(i)
        return self.traj[self.traj_start[i]:self.traj_start[i + 1]]

    def poses_of(self, i: int) -> np.ndarray:
        """Pose indices of clip ``i``."""
        i = self.clip_index(i)
        return np.arange(self.pose_start[i], self.pose_start[i + 1])

    def stored_motions(self) -> dict[int, Motion]:
        """Clip index -> motion of the clips that store one (the others are variants rebuilt from them)."""
        return dict(self._motions)

    def actor_skeleton(self, i: int) -> Skeleton:
        """Skeleton of the actor of clip ``i`` (base actor scaled by ``scale[i]``)."""
        i = self.clip_index(i)
        base = self.actors[int(self.actor[i])]
        s = float(self.scale[i])
        return base if s == 1.0 else base.with_offsets(base.offsets * s, base.end_site_offsets * s)

    def motion(self, i: int) -> Motion:
        """The motion of clip ``i`` (metres, database rate).

        For a variant made by :func:`augment` the motion is rebuilt from its source clip
        (time warp, rescaling, mirror); the feature noise is not applied to it.
        """
        i = self.clip_index(i)
        if i in self._motions:
            return self._motions[i]
        src = int(self.source_clip[i])
        if src not in self._motions:
            raise MotionError(f"clip {i}: its source clip {src} has no stored motion")
        return variant_motion(self._motions[src], int(self.n_frames[i]), float(self.scale[i] / self.scale[src]),
                               bool(self.mirror[i]))

    def clip(self, i: int) -> Clip:
        """Clip ``i`` as a :class:`Clip`."""
        i = self.clip_index(i)
        return Clip(name=str(self.names[i]), motion=self.motion(i), semantics=str(self.semantics[i]),
                    hit_role=str(self.hit_roles[i]), hit_joint=str(self.hit_joints[i]),
                    hit_where=str(self.hit_wheres[i]), hit_frame=int(self.hit_frame[i]), kind=str(self.kinds[i]),
                    side=str(self.sides[i]), source=str(self.sources[i]), source_time=float(self.source_time[i]),
                    level=str(self.levels[i]))

    def clips(self) -> list[Clip]:
        """Every clip (materialising augmented motions; slow for large databases)."""
        return [self.clip(i) for i in range(self.n_clips)]

    def select(self, mask) -> MotionDatabase:
        """A database of the clips where ``mask`` is true: a boolean mask of length C, or clip indices.

        Indices are integers in ``0..C-1`` without repeats (kept in the order given);
        anything else -- floats (``[0.5]`` used to select clip 0), negative or too-large
        indices, a mask of another length, strings, NaN, an empty selection -- is a
        :class:`MotionError` (issue 23, sections 5-6).
        """
        C = self.n_clips
        what = f"mask (a boolean mask of length {C} or clip indices in 0..{C - 1})"
        try:
            # a selection has at most C entries: longer ones (range(10**12)) are refused before numpy copies them
            if hasattr(mask, "__len__") and len(mask) > C:
                raise MotionError(f"{what} has {len(mask)} entries, more than the {C} clips")
        except (TypeError, OverflowError):
            raise MotionError(f"{what} has more entries than the {C} clips") from None
        try:
            a = None if isinstance(mask, (str, bytes)) or mask is None else np.asarray(mask)
        except (ValueError, TypeError):  # ragged nesting
            a = None
        if a is None or a.ndim != 1:
            raise MotionError(f"{what} must be a 1-D sequence, got {describe(mask)}")
        if a.dtype.kind == "b":
            if a.shape != (C,):
                raise MotionError(f"{what}: a boolean mask of length {a.size}, not {C}")
            idx = np.flatnonzero(a)
        else:
            idx = as_real_array(a, what, error=MotionError, integer=True, ndim=1)
            bad = idx[(idx < 0) | (idx >= C)]
            if bad.size:
                raise MotionError(f"{what} holds {bad.size} index(es) out of range, e.g. {int(bad[0])}")
            if np.unique(idx).size != idx.size:
                raise MotionError(f"{what} repeats a clip index (clip names must stay unique)")
        if idx.size == 0:
            raise MotionError(f"{what} selects no clip")
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
            Pose cloud window (:func:`~repro.motion.body.pose_frames.pose_points`).
        meta : mapping, optional
            JSON-serialisable provenance stored with the database.
        """
        if isinstance(clips, (str, bytes, Clip)) or not isinstance(clips, Sequence):
            raise MotionError(f"clips must be a sequence of Clip, got {describe(clips)}")
        if len(clips) == 0:
            raise MotionError("a motion database needs at least one clip")
        bad = [i for i, c in enumerate(clips) if not isinstance(c, Clip)]
        if bad:
            raise MotionError(f"clips must be a sequence of Clip; item {bad[0]} is {describe(clips[bad[0]])}")
        pose_roles = as_names(pose_roles, "pose_roles", error=MotionError, item="a role name")
        window = as_int(window, "window (frames per pose cloud)", 1, MAX_WINDOW, error=MotionError)
        step = as_int(step, "step (frames between the cloud's frames)", 1, MAX_WINDOW, error=MotionError)
        if meta is not None and not isinstance(meta, Mapping):
            raise MotionError(f"meta must be a mapping (JSON object) or None, got {describe(meta)}")
        try:  # what save() will write: a JSON object with string keys and finite numbers
            json.loads(json.dumps(dict(meta or {}), allow_nan=False, sort_keys=True))
        except (TypeError, ValueError) as exc:
            raise MotionError(f"meta must be JSON (string keys, finite numbers): {exc}") from None
        if any(not isinstance(k, str) for k in (meta or {})):
            raise MotionError("meta must be JSON: its keys must be strings")
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
            recs.append(clip_record(c, sk, a, s, pose_roles, window, step))
        motions = {i: c.motion for i, c in enumerate(clips)}
        arrays = _stack(recs)
        arrays["source_clip"] = np.arange(len(clips))
        return cls(fps=fps, pose_roles=pose_roles, window=window, step=step, actors=actors, motions=motions,
                   arrays=arrays, meta=meta)

    # ---------------------------------------------------------------- I/O
    def save(self, path, *, identity: Mapping | None = None) -> Path:
        """Write the database to ``path`` (``.npz``, no pickles), atomically
        (:func:`~repro.motion.database.archive.save_database`).

        :meth:`load` gives back an equal database (:meth:`equals`); ``identity`` (a JSON
        object saying what the file is) makes ``load(path, identity=...)`` refuse another file.
        """
        return save_database(self, path, identity=identity)

    @classmethod
    def load(cls, path, *, max_bytes: int = MAX_READ_BYTES, identity: Mapping | None = None) -> MotionDatabase:
        """Read a database written by :meth:`save`, every part checked first:
        :func:`~repro.motion.database.archive.load_database` (a damaged, foreign or other file is a
        :class:`~repro.errors.DataError` naming it)."""
        return load_database(cls, path, max_bytes=max_bytes, identity=identity)

    def equals(self, other: MotionDatabase) -> bool:
        """Exact equality of every array, annotation, actor, stored motion and metadata."""
        if not isinstance(other, MotionDatabase):
            return False
        if (self.fps, self.pose_roles, self.window, self.step) != (other.fps, other.pose_roles, other.window, other.step):
            return False
        if json.dumps(self.meta, sort_keys=True) != json.dumps(other.meta, sort_keys=True):
            return False
        for k in CLIP_STR + CLIP_NUM + POSE_NUM:
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


def clip_record(c: Clip, sk: Skeleton, actor: int, scale: float, pose_roles, window, step,
                *, noise: float = 0.0, rng=None) -> dict:
    """The database row of clip ``c``: its annotations and per-clip and per-pose arrays.

    ``sk`` is the clip's actor (base actor ``actor`` scaled by ``scale``); the hit-point
    trajectory, its bounding box and the hit position are in the root frame of the
    clip's first frame (metres), the pose clouds divided by ``sk.size``.  With
    ``noise > 0``, Gaussian noise of that std (metres, drawn from ``rng``) is added to the
    trajectory and the pose clouds.
    """
    m = c.motion
    g = m.global_positions()
    idx = [sk.index(r) for r in pose_roles]
    pel, lh, rh = sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip")
    theta, origin = root_frames(g, pel, lh, rh)
    traj_w = hit_point_trajectory(m, c.hit_joint, c.hit_where, positions=g)
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
    out = {k: np.array([r[k] for r in recs]) for k in CLIP_STR}
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
    arrays = {k: getattr(db, k)[idx] for k in CLIP_STR}
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
