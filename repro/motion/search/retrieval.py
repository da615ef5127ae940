"""Motion retrieval of Pronost et al., Section 3.3, with two baselines and a benchmark.

"Interactive Animation of Virtual Characters: Application to Virtual Kung-fu Fighting",
Section 3.3 (Motion retrieval).  The inputs are the target ``c`` (e.g. the opponent's
head), expressed in the root reference frame of the character, the character's current
pose ``q`` and skeleton, and the semantics ordered by the supervisor (``"punch"`` or
``"kick"``).  :meth:`MotionRetriever.search` follows the paper step by step:

1. **Eq. 1**: ``c_r = c * size_a / size_c`` for the actor of every clip
   (:func:`repro.motion.body.skeleton.rescale_constraint`; ``size`` is the straightened
   stature, :attr:`repro.motion.body.skeleton.Skeleton.size`).
2. **q_r**: the current pose retargeted to the actor
   (:func:`repro.motion.retargeting.morphology.retarget`, Section 3.4.1), as a pose cloud
   (:mod:`repro.motion.body.pose_frames`), "so that the distance calculated between q_r and a
   pose in each clip is based on the same skeleton".
3. **Cluster selection**: "the centroids are compared with the initial pose q_r"; the
   cluster whose centroid is nearest to ``q_r`` in the aligned distance of Kovar et al.
   is selected (clusters: k-means of all poses, Section 3.2.2, made once in
   :class:`MotionRetriever`).
4. **Pruning**: clips "associated with the bounding box that does not contain" ``c_r``
   are eliminated.  (The paper's text reads "does not contain q_r"; a pose cannot be
   inside a box of hit-point positions, and Figure 4's caption shows the constraint
   ``c_r`` (green) inside the box of the trajectory (red): ``q_r`` is a typo for
   ``c_r``.)  Poses of clips of another semantics are eliminated too.
5. **Scoring**: each remaining pose gets ``d = w_q d_qr + w_c d_cr`` with ``d_qr`` the
   aligned distance between the pose and ``q_r`` (weighted RMS over the pose points,
   metres of the actor) and ``d_cr`` the minimum distance between its clip's hit-point
   trajectory and ``c_r`` (metres); "the pose (and the corresponding motion) that is
   finally selected by the algorithm is the one that minimizes the weighted sum d".
6. **Alignment**: "the motion associated with the lowest distance d is then rotated and
   translated to fit the initial pose q_r": :class:`RetrievalResult` holds that rotation
   about the vertical axis and translation (Kovar et al.'s closed form).

Choices the paper leaves open (documented here, all parameters):

* Start frames: only poses *before* their clip's hit frame can start a motion (a pose
  after the hit would start a motion whose hit has already happened).
* Frames: ``c`` and the hit trajectories are in root frames as defined in
  :mod:`repro.motion.database.clips` (origin on the floor below the pelvis, z = heading);
  each trajectory in the root frame of its clip's first frame, as in the paper, which
  compares one bounding box per motion with ``c_r``.
* Fallbacks when pruning leaves nothing (the paper does not say): widen to the next
  clusters in order of centroid distance (``fallback="neighbour_clusters"``); if no
  clip of the semantics has a box containing ``c_r``, score every startable pose of the
  semantics without the box test (``fallback="no_box"``).  The result says which.
* Several actors: the database's clips may come from actors of other statures (the
  synthetic database has three).  ``c_r`` is computed per clip with its own ``size_a``;
  ``q_r`` is retargeted once per *base* actor (actors that are uniform scalings of one
  another share it, scaled), and pose clouds are compared in units of the actor's size.
  A character of other proportions on the actor's tree is retargeted with the actor's
  :class:`~repro.motion.retargeting.morphology.RetargetPlan` (what depends only on the two skeletons
  made once and cached; the same numbers as :func:`~repro.motion.retargeting.morphology.retarget`).
* Several joint trees (a mixed-skeleton database: CMU + Bandai, synthetic clips
  rewritten onto other rigs, any user BVH): pose clouds are role point clouds
  (:data:`~repro.motion.body.pose_frames.POSE_ROLES`) in units of stature, so they compare
  across trees.  The actors of the character's own tree take ``q_r`` as before (same
  numbers); where an actor's tree differs, ``q_r`` is retargeted across trees
  (:func:`retarget_to_tree`), so every clip can be served to any humanoid character
  without asking (``MotionRetriever(db, across_trees=False)`` keeps a character to the
  actors of its own tree) (:func:`repro.motion.runtime.strike.strike` then
  retargets the selected clip to the character across trees as well).

The exact search (``method="exact"``, the fighter's default: the exhaustive optimum through
bounds over the same clusters and boxes) lives in :mod:`repro.motion.search.exact`, a mixin of
:class:`MotionRetriever`.

Baselines (for the figures): :meth:`MotionRetriever.search_exhaustive` scores every
startable pose of the semantics with the same ``d`` (no clusters, no boxes: the exact
optimum of ``d``); :meth:`MotionRetriever.search_kdtree` queries a
:class:`scipy.spatial.cKDTree` over a feature vector (the pose cloud in its canonical
frame and the hit position at the hit frame, both in units of the actor's size,
weighted by ``w_q`` and ``w_c``) for its nearest neighbours and rescores them with
``d``.  :func:`repro.bench.retrieval.time_search` measures the latency of the three.

Arguments are checked, never silently cut or coerced (a
:class:`~repro.errors.RetrievalError` names the value and what is allowed):

* the target ``c`` is a finite 3-vector with every coordinate within
  :data:`MAX_TARGET_M` (1,000 km) of the character's root: nothing a fighter can
  reach, and far inside what float64 squared distances handle (beyond about 1e154 m
  they overflow, and the searches would return ``d = inf`` or, in the k-d tree,
  missing neighbours); a search whose distance still comes out non-finite (a
  character of a tiny size making ``c_r`` enormous) is refused;
* ``w_q`` and ``w_c`` are positive real numbers in ``(0, MAX_WEIGHT]`` (1e6) (only their
  ratio matters for the selection; a weight of 0 would drop a term of Eq. d and leave
  ties that no bound separates: ask for a small weight instead);
* ``k`` (clusters) is an int in ``[1, n_poses]``, ``seed`` an int >= 0,
  ``kd_neighbours`` an int >= 1 (more than a semantics' startable poses means all of
  them), ``frame`` an int inside the current pose, ``semantics`` one of
  :data:`~repro.motion.database.annotation.SEMANTICS`, ``prune`` / ``scale_target`` booleans.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import NoReturn
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from repro.checks import as_int, as_real, describe
from repro.errors import MotionError, RetrievalError
from repro.motion.database.annotation import SEMANTICS
from repro.motion.body.pose_frames import pose_points, root_frames, rotate_y
from repro.motion.search.distance import AlignedPoseIndex
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.index_build import block_order, build_pose_index
from repro.motion.retargeting.morphology import RetargetPlan
from repro.motion.core.cache import LRUCache
from repro.motion.core.motion import LEVEL_LOOP_MAX_DEPTH as _FK_LEVEL_LOOP_MAX
from repro.motion.core.motion import Motion, finite_vector3
from repro.motion.core.ops import resample
from repro.motion.retargeting.trees import TreePlan
from repro.motion.search.exact import ExactSearch
from repro.motion.retargeting.dispatch import rest_motion_y_up
from repro.motion.body.skeleton import Skeleton, rescale_constraint, skeleton_of

__all__ = [
    "FALLBACKS",
    "MAX_TARGET_M",
    "MAX_WEIGHT",
    "METHODS",
    "MotionRetriever",
    "Query",
    "RetrievalResult",
    "make_queries",
    "search",
]

#: Values of :attr:`RetrievalResult.fallback`.
FALLBACKS: tuple[str, ...] = ("none", "neighbour_clusters", "no_box", "disabled")
#: Largest |coordinate| (metres) of a target accepted by the searches (see the module docstring).
MAX_TARGET_M: float = 1e6
#: Largest accepted ``w_q`` / ``w_c`` (only their ratio matters).
MAX_WEIGHT: float = 1e6
#: The search methods (``method=`` of :meth:`MotionRetriever.search`).
METHODS: tuple[str, ...] = ("pruned", "exact", "exhaustive", "kdtree")
#: Ties: candidates whose ``d`` is within ``TIE_RTOL * d + TIE_ATOL`` of the best are tied, and the
#: lowest pose index wins (shared by the exact and exhaustive searches, so that both return the same
#: pose even when two evaluations of ``d`` differ in the last bits).
TIE_RTOL: float = 1e-12
TIE_ATOL: float = 1e-15
#: Candidates within ``NEAR_RTOL * d + NEAR_ATOL * w_q * size_a`` of the best are re-scored one by one
#: before the tie rule (the closed-form aligned distance loses about 1e-8 of the actor's size near 0, and
#: its last bits depend on the batch a pose is scored in); at most ``MAX_NEAR`` of them.
NEAR_RTOL: float = 1e-9
NEAR_ATOL: float = 1e-7
MAX_NEAR: int = 64


@dataclass(frozen=True, eq=False)
class Query:
    """The character-dependent inputs of a search, prepared by :meth:`MotionRetriever.prepare`.

    Attributes
    ----------
    q_n : dict base actor -> (P', 3) array
        ``q_r`` (the current pose retargeted to that actor) as a pose cloud in its root
        frame, divided by the actor's size.
    size_c : float
        The character's size (metres), Eq. 1.
    heading, origin : float, (3,) array
        Root frame of the current pose in the character's world.
    actors : tuple of int
        The base actors the character could be retargeted to (same joint tree).
    """

    q_n: dict
    size_c: float
    heading: float
    origin: np.ndarray
    actors: tuple


@dataclass(frozen=True, eq=False)
class RetrievalResult:
    """The selected motion, where to start it, how to place it, and why.

    Attributes
    ----------
    clip : int
        Clip index in the database; ``name``, ``semantics``, ``hit_role`` describe it.
    start_frame : int
        The selected pose's frame: the motion is played from there.
    hit_frame : int
        The clip's hit frame (the hit comes ``hit_frame - start_frame`` frames later).
    pose : int
        Index of the selected pose in the database.
    d, d_qr, d_cr : float
        ``d = w_q d_qr + w_c d_cr`` (metres); ``d_qr`` aligned pose distance to ``q_r``,
        ``d_cr`` distance from the clip's hit trajectory to ``c_r``.
    w_q, w_c : float
    c_r : (3,) array
        The target for this clip's actor (Eq. 1), in the actor's root frame (metres).
    size_a, size_c : float
        Actor and character sizes (metres).
    cluster : int
        Selected cluster (-1 for the baselines).
    n_candidates : int
        Number of poses scored.
    fallback : str
        One of :data:`FALLBACKS`: ``"none"`` (the paper's algorithm found candidates in
        the nearest cluster), ``"neighbour_clusters"`` (found in the ``cluster_rank``-th
        nearest cluster), ``"no_box"`` (no clip of the semantics contains ``c_r``: every
        startable pose of the semantics scored), ``"disabled"`` (pruning off, or a
        baseline).
    cluster_rank : int
    method : str
        ``"pruned"``, ``"exhaustive"`` or ``"kdtree"``.
    rotation_y : float
        Rotation (radians, about +y) of the alignment ``A`` taking the clip's world
        coordinates (metres of the actor) to the root frame of ``q_r``:
        ``A(p) = rotate_y(p, rotation_y) + translation``.
    translation : (3,) array
        Its translation (y = 0).
    heading, origin : float, (3,) array
        Root frame of the current pose in the character's world.
    """

    clip: int
    name: str
    semantics: str
    hit_role: str
    start_frame: int
    hit_frame: int
    pose: int
    d: float
    d_qr: float
    d_cr: float
    w_q: float
    w_c: float
    c_r: np.ndarray
    size_a: float
    size_c: float
    cluster: int
    n_candidates: int
    fallback: str
    cluster_rank: int
    method: str
    rotation_y: float
    translation: np.ndarray
    heading: float = 0.0
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def align(self, points) -> np.ndarray:
        """Clip-world points (actor metres) -> root frame of ``q_r`` (actor metres)."""
        return rotate_y(points, self.rotation_y) + self.translation  # (rotate_y checks the points)

    def place(self, points, scale: float | None = None) -> np.ndarray:
        """Clip-world points -> the character's world.

        ``R_y(heading) (scale * align(p)) + origin``: the aligned clip, scaled from the
        actor to the character (default ``scale = size_c / size_a``, a uniform
        approximation of retargeting; exact when the character is the actor, where the
        start pose lands on the current pose up to ``d_qr``) and put in the current
        pose's root frame.
        """
        k = self.size_c / self.size_a if scale is None else as_real(scale, "scale", lo=0.0, lo_open=True,
                                                                      error=RetrievalError)
        return rotate_y(k * self.align(points), self.heading) + self.origin

    @property
    def lead_frames(self) -> int:
        """Frames from the start pose to the hit."""
        return self.hit_frame - self.start_frame


@dataclass(eq=False)
class _Block:
    """Candidate poses with their precomputed, contiguous data."""

    rows: np.ndarray  # global pose indices
    index: AlignedPoseIndex  # their closed-form terms
    clips: np.ndarray  # clip of each pose
    size: np.ndarray  # size_a of each pose's actor
    actor: np.ndarray  # base actor of each pose
    uclips: np.ndarray  # distinct clips
    inv: np.ndarray  # clips == uclips[inv]
    single_actor: int | None
    # groups (the poses of one clip in the block, contiguous since rows are sorted), for the exact search
    gstart: np.ndarray | None = None  # (G+1,) offsets
    gradius: np.ndarray | None = None  # (G,) largest aligned distance centroid -> pose
    gcent: np.ndarray | None = None  # (G, P, 3) float32 centroids, until the exact search gathers them


def _check_target(target) -> np.ndarray:
    if isinstance(target, (str, bytes)):
        raise RetrievalError(f"target must be a 3-vector of numbers (metres), got {target!r}")
    try:
        a = np.asarray(target)
    except (TypeError, ValueError):
        a = None
    if a is None or a.dtype.kind not in "biuf" and a.dtype.kind != "O":
        raise RetrievalError(f"target must be a 3-vector of real numbers (metres), got {target!r}")
    c = finite_vector3(target, "target (x, y, z) in the character's root frame", RetrievalError)
    if np.abs(c).max() > MAX_TARGET_M:
        raise RetrievalError(f"target {c.tolist()} is more than {MAX_TARGET_M:g} m from the character; "
                             "expected metres in the character's root frame")
    return c


def _check_weight(name: str, w) -> float:
    """A weight of ``d = w_q d_qr + w_c d_cr``: a positive finite real number, at most :data:`MAX_WEIGHT`."""
    if isinstance(w, (bool, np.bool_)) or not isinstance(w, (int, float, np.integer, np.floating)):
        raise RetrievalError(f"{name} must be a positive real number in (0, {MAX_WEIGHT:g}], got {w!r}")
    w = float(w)
    if not (np.isfinite(w) and 0.0 < w <= MAX_WEIGHT):
        raise RetrievalError(f"{name} must be positive, finite and at most {MAX_WEIGHT:g}, got {w!r}")
    return w


def _check_flag(name: str, v) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise RetrievalError(f"{name} must be True or False, got {v!r}")
    return bool(v)


class MotionRetriever(ExactSearch):
    """The database organised for the search: clusters, indices, per-clip arrays.

    Everything that does not depend on the query is computed here once (Section 3.2.2:
    "we propose to organize the database into clusters in a precomputation process"):
    k-means clusters of all poses, the candidate poses of every (cluster, semantics), the
    closed-form terms of the aligned distance for every pose, padded hit trajectories.

    Parameters
    ----------
    db : MotionDatabase
    k : int, optional
        Number of clusters (default :func:`repro.motion.search.kmeans.default_k`).
    seed : int, default 0
        k-means seed.
    weights : (P',) array, optional
        Pose point weights (default uniform).
    w_q, w_c : float, default 1
        Weights of ``d = w_q d_qr + w_c d_cr`` (both distances in metres), in
        ``(0, MAX_WEIGHT]`` (positive: see the module docstring).
    kd_neighbours : int, default 32
        Neighbours fetched by :meth:`search_kdtree` before rescoring (>= 1; at most the
        startable poses of the semantics are fetched).
    across_trees : bool, default True
        Serve characters of *other joint trees* than the actors' (a mixed-skeleton
        database, any humanoid character): where the character's tree differs from an
        actor's, :meth:`prepare` retargets the current pose across trees
        (:func:`repro.motion.retargeting.trees.retarget_across`, through the body-part
        roles), so every clip is a candidate (poses are compared as role point clouds in
        units of the actor's stature); actors of the character's own tree are reached as
        without it (same numbers).  False: only the actors of the character's own joint
        tree are candidates (the behaviour before mixed-skeleton databases).

    Raises
    ------
    repro.errors.RetrievalError
        Empty database; ``k`` not an int in ``[1, n_poses]``; bad ``seed``, weights,
        ``w_q``, ``w_c`` or ``kd_neighbours``.
    """

    def __init__(self, db: MotionDatabase, *, k: int | None = None, seed: int = 0, weights=None,
                 w_q: float = 1.0, w_c: float = 1.0, kd_neighbours: int = 32, across_trees: bool = True):
        if not isinstance(db, MotionDatabase):
            raise RetrievalError(f"expected a MotionDatabase, got {type(db).__name__}")
        if db.n_clips == 0 or db.n_poses == 0:
            raise RetrievalError("the motion database is empty")
        w_q, w_c = _check_weight("w_q", w_q), _check_weight("w_c", w_c)
        if k is not None:
            k = as_int(k, "k (number of clusters)", 1, db.n_poses, error=RetrievalError)
        seed = as_int(seed, "seed", 0, None, error=RetrievalError)
        self.db = db
        self.w_q, self.w_c = w_q, w_c
        self.kd_neighbours = as_int(kd_neighbours, "kd_neighbours", 1, None, error=RetrievalError)
        self.across_trees = _check_flag("across_trees", across_trees)
        try:
            self.index, self.clusters = build_pose_index(db, k, weights=weights, seed=seed)
        except MotionError as e:
            raise RetrievalError(str(e)) from None
        self.weights = self.index.weights
        self.centroid_index = AlignedPoseIndex(self.clusters.centroids, self.weights)
        pc = db.pose_clip
        self.pose_size = db.size_a[pc]
        self._size_max = float(db.size_a.max())
        self.startable = db.pose_frame < db.hit_frame[pc]
        sem_of_pose = db.semantics[pc]
        self.actors_present = np.unique(db.actor)
        self.sem_rows = {s: np.flatnonzero(self.startable & (sem_of_pose == s)) for s in SEMANTICS}
        self.sem_block = {s: self._block(r) for s, r in self.sem_rows.items()}
        self._cluster_blocks(sem_of_pose)
        L = int((db.traj_start[1:] - db.traj_start[:-1]).max())
        idx = db.traj_start[:-1, None] + np.minimum(np.arange(L)[None, :], (db.n_frames - 1)[:, None])
        self.traj_padded = db.traj[idx]  # (C, L, 3), each padded with its last sample
        self._kd: dict = {}
        self._prep_cache: dict = {}
        self._actor_rest: dict = {}  # actor -> its rest pose, Y up (retargeting across trees)
        self._plans: dict = {}  # (actor, pose skeleton) -> RetargetPlan (same tree, other proportions)
        self._tree_plans: dict = {}  # (actor, pose skeleton, roles) -> TreePlan (another joint tree)
        self._qm_cache = None
        self._ratio_cache = None
        self._cterms = None  # the centroids' index terms (the compiled exact search reads them)
        self._bounds_setup()
        self._exact_setup()

    # ------------------------------------------------------------ query side
    @property
    def k(self) -> int:
        """Number of clusters."""
        return self.clusters.k

    def prepare(self, current_pose: Motion, character, *, frame: int | None = None) -> Query:
        """Retarget the current pose to the database's actors: ``q_r`` (Section 3.3).

        Parameters
        ----------
        current_pose : Motion
            The character's motion; its frame ``frame`` (default: the last) is the current
            pose ``q``.  For pose windows longer than 1 frame the preceding frames are used
            (resampled to the database rate when needed).
        character : Skeleton or Motion
            The character (its ``size`` is ``size_c`` of Eq. 1); must have the joint tree
            of the database actor(s) it is compared with (e.g. made by
            :func:`~repro.motion.body.skeleton.scale_skeleton`), unless the retriever
            serves across trees (``across_trees``, the default): then any humanoid skeleton, the pose retargeted
            across trees to the other actors through a cached :class:`~repro.motion.retargeting.trees.TreePlan`
            (:meth:`tree_plan`; whether an actor can be, per character, is
            cached).

        Raises
        ------
        repro.errors.RetrievalError
            No database actor shares the character's joint tree (``across_trees=False``),
            or none can be retargeted to (``across_trees=True``: the message names the
            roles missing); a pose that is not a Motion.
        """
        if not isinstance(current_pose, Motion):
            raise RetrievalError(f"current_pose must be a repro.motion.Motion, got {type(current_pose).__name__}")
        try:
            ch = skeleton_of(character)
            size_c = ch.size
        except MotionError as e:
            raise RetrievalError(f"bad character: {e}") from None
        if not ch.is_compatible(current_pose):
            raise RetrievalError("current_pose is not on the character's skeleton (joint names / parents differ)")
        m = self._pose_window(current_pose, ch, frame)
        gq_c, gc = m.global_transforms()
        q_n = {}
        refused: dict[int, str] = {}
        for a in self.actors_present.tolist():
            pts = self._actor_pose(m, ch, a, (gq_c, gc), refused)
            if pts is not None:
                q_n[a] = pts
        if not q_n:
            self._refuse(ch, refused)
        th, o = root_frames(gc[-1:], ch.index("pelvis"), ch.index("left_hip"), ch.index("right_hip"))
        return Query(q_n=q_n, size_c=float(size_c), heading=float(th[0]), origin=o[0], actors=tuple(q_n))

    def _pose_window(self, current_pose: Motion, ch: Skeleton, frame: int | None) -> Motion:
        """The frames of the pose window ending at ``frame`` (at the database's rate), in metres."""
        db = self.db
        F = current_pose.n_frames
        f = F - 1 if frame is None else as_int(frame, "frame", None, None, error=RetrievalError)
        if not 0 <= f < F:
            raise RetrievalError(f"frame {frame} outside the current pose's {F} frames (expected 0 to {F - 1})")
        need = (db.window - 1) * db.step + 1
        m = current_pose
        if need > 1 and abs(m.fps - db.fps) > 1e-6 * db.fps:
            t = f * m.frame_time - np.arange(need - 1, -1, -1) / db.fps
            m = resample(m, frames=np.clip(t / m.frame_time, 0, F - 1), frame_time=1.0 / db.fps)
        else:
            lo = max(0, f - need + 1)
            R = m.rotations
            # the window (a new Motion renormalises its rotations); when it is the whole pose and that
            # renormalising gives the same bits, the pose itself (its Motion checks cost about 0.1 ms)
            if not (lo == 0 and f + 1 == F and np.array_equal(R / np.linalg.norm(R, axis=-1, keepdims=True), R)):
                m = dataclasses.replace(m, rotations=R[lo:f + 1], positions=m.positions[lo:f + 1])
        unit = m.unit_m if m.unit_m is not None else ch.unit_m
        if unit is None:
            raise RetrievalError("the current pose's length unit is unknown; read it with unit_m=... (metres expected)")
        if unit != 1.0:
            m = m.to_metres(unit)
        return m

    def _actor_pose(self, m: Motion, ch: Skeleton, a: int, source: tuple, refused: dict) -> np.ndarray | None:
        """``q_r`` on actor ``a`` in units of its size (Section 3.3), or None when the pose does not reach it
        (a refused retargeting across trees is noted in ``refused``).  ``source``: ``m``'s global transforms."""
        gq_c, gc = source
        actor = self.db.actors[a]
        mode = self._compatible(ch, a)
        if mode is None:
            return None
        if mode == "across":
            try:  # q on the character -> the actor's tree, through the roles (character's own table):
                # retarget_to_tree(m, actor, ...).global_positions(), what depends only on the skeletons cached
                plan = self.tree_plan(m, a, ch.roles)
            except MotionError as e:
                refused[a] = str(e)
                self._prep_cache[(id(ch), a)] = (ch, None, str(e))  # not again for this character
                return None
            src = (gq_c, gc) if m.n_depth_levels <= _FK_LEVEL_LOOP_MAX else None
            g = plan.positions(m.rotations, m.local_translations(), source=src)
            return self._pose_cloud(g, actor, actor.size)
        k = self._scaling_of(m, a)
        if k is not None:  # a uniform scaling of the actor: q_r is the pose scaled, no retargeting needed
            return self._pose_cloud(gc, actor, k * actor.size)
        try:  # retarget(m, actor).global_positions(), with what depends only on the skeletons cached
            g = self.retarget_plan(m, a).positions(m.rotations, m.local_translations(), source=(gq_c, gc))
        except MotionError as e:
            raise RetrievalError(f"cannot retarget the current pose to actor {a}: {e}") from None
        return self._pose_cloud(g, actor, actor.size)

    def _pose_cloud(self, g: np.ndarray, actor: Skeleton, size: float) -> np.ndarray:
        """The last pose cloud of the global positions ``g`` on ``actor``, divided by ``size``."""
        db = self.db
        idx = [actor.index(r) for r in db.pose_roles]
        pts = pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                          window=db.window, step=db.step)[-1]
        return pts / size

    def _refuse(self, ch: Skeleton, refused: dict) -> NoReturn:
        """Why the pose reaches no actor: the refused retargetings, or no shared joint tree."""
        why = refused or self._refusals(ch)
        if why:
            raise RetrievalError("the current pose cannot be retargeted to any actor of the database: "
                                 + "; ".join(f"actor {a}: {e}" for a, e in sorted(why.items())))
        raise RetrievalError(
            "the character shares no joint tree with the database's actors; make it from an actor "
            "with repro.motion.scale_skeleton (joints: " + ", ".join(ch.joint_names[:5]) + ", ...)")

    def _compatible(self, ch: Skeleton, a: int) -> bool | str | None:
        """How the pose reaches actor ``a``; cached per (character, actor).

        True: the character shares the actor's joint tree; ``"across"``: another tree,
        retargeted through the roles (``across_trees=True``); None: not at all (another
        tree without ``across_trees``, or a retargeting across trees that failed before
        for this character).
        """
        key = (id(ch), a)
        hit = self._prep_cache.get(key)
        if hit is not None and hit[0] is ch:
            return hit[1]
        if self.db.actors[a].is_compatible(ch):
            out = True
        else:
            out = "across" if self.across_trees else None
        if len(self._prep_cache) > 64:
            self._prep_cache.clear()
        self._prep_cache[key] = (ch, out, "")
        return out

    def _plan_arguments(self, m, a) -> int:
        """A plan's motion (a :class:`Motion`) and actor index (in ``0..len(actors)-1``), checked."""
        if not isinstance(m, Motion):
            raise MotionError(f"m must be a repro.motion.Motion, got {describe(m)}")
        return as_int(a, "a (actor index)", 0, len(self.db.actors) - 1, error=RetrievalError)

    def retarget_plan(self, m: Motion, a: int) -> RetargetPlan:
        """The :class:`~repro.motion.retargeting.morphology.RetargetPlan` from the skeleton of ``m`` to actor ``a``.

        Cached by actor and what :meth:`Skeleton.from_motion` reads of ``m`` (joints, parents,
        offsets, channels, End Sites, unit), so a pose on another skeleton never reuses a plan.
        """
        a = self._plan_arguments(m, a)
        key = (a, tuple(m.joint_names), m.parents.tobytes(), m.offsets.tobytes(), tuple(m.channels),
               m.end_site_parents.tobytes(), m.end_site_offsets.tobytes(), m.unit_m)
        plan = self._plans.get(key)
        if plan is None:
            plan = RetargetPlan(m, self.db.actors[a])
            if len(self._plans) >= 64:
                self._plans.clear()
            self._plans[key] = plan
        return plan

    def tree_plan(self, m: Motion, a: int, roles) -> TreePlan:
        """The :class:`~repro.motion.retargeting.trees.TreePlan` from the skeleton of ``m`` (role table
        ``roles``) to actor ``a``'s rest pose in the database world: :func:`retarget_to_tree`'s
        positions with what depends only on the skeletons computed once.

        Cached by actor, what :meth:`Skeleton.from_motion` reads of ``m`` (joints, parents,
        offsets, channels, End Sites, unit), its ``up`` and the role table, so a pose on
        another skeleton (or with other roles) never reuses a plan; at most 64 are kept.
        """
        a = self._plan_arguments(m, a)
        if not isinstance(roles, Mapping):
            raise MotionError(f"roles must be a role table (a mapping role -> joint name), got {describe(roles)}")
        key = (a, tuple(m.joint_names), m.parents.tobytes(), m.offsets.tobytes(), tuple(m.channels),
               m.end_site_parents.tobytes(), m.end_site_offsets.tobytes(), m.unit_m, m.up,
               tuple(sorted(dict(roles).items())))
        plan = self._tree_plans.get(key)
        if plan is None:
            if a not in self._actor_rest:
                self._actor_rest[a] = rest_motion_y_up(self.db.actors[a])
            actor = self.db.actors[a]
            src = m if m.up is not None else dataclasses.replace(m, up="y")
            plan = TreePlan(src, self._actor_rest[a], roles=dict(roles), character_roles=dict(actor.roles))
            if len(self._tree_plans) >= 64:
                self._tree_plans.clear()
            self._tree_plans[key] = plan
        return plan

    def _refusals(self, ch: Skeleton) -> dict[int, str]:
        """Cached reasons why the pose of ``ch`` could not be retargeted across trees, per actor."""
        return {a: v[2] for (i, a), v in self._prep_cache.items() if i == id(ch) and v[0] is ch and v[2]}

    def _scaling_of(self, m: Motion, a: int) -> float | None:
        """The factor ``k`` if the pose's skeleton (metres) is actor ``a``'s scaled by ``k``, else None.

        Then retargeting the pose to the actor (same rotations, bones scaled) scales its
        pose cloud, and ``q_r`` in units of the actor's size is the pose's own cloud in
        units of its size: no retargeting is needed (``prepare``'s fast path).
        """
        oa = self.db.actors[a].offsets
        om = np.asarray(m.offsets, dtype=float)
        if om.shape != np.shape(oa):
            return None
        k = float(np.linalg.norm(om) / max(float(np.linalg.norm(oa)), 1e-300))
        ok = k > 0 and np.allclose(om, k * oa, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(om).max())))
        return k if ok else None

    def _semantics(self, semantics) -> str:
        if not isinstance(semantics, str) or semantics not in SEMANTICS:
            raise RetrievalError(f"unknown semantics {semantics!r}; expected one of {list(SEMANTICS)}")
        if self.sem_rows[semantics].size == 0:
            raise RetrievalError(f"the database has no {semantics!r} clip with a pose before its hit")
        return semantics

    def _query(self, current_pose, character, frame) -> Query:
        """A prepared :class:`Query` (checked), or :meth:`prepare` of the current pose."""
        if not isinstance(current_pose, Query):
            return self.prepare(current_pose, character, frame=frame)
        q = current_pose
        if not isinstance(q.q_n, dict) or not q.q_n:
            raise RetrievalError("the Query has no retargeted pose (q_n); make it with MotionRetriever.prepare")
        P = self.index._P
        for a, qn in q.q_n.items():
            if a not in set(self.actors_present.tolist()):
                raise RetrievalError(f"the Query names actor {a!r}, not an actor of this database "
                                     f"({self.actors_present.tolist()})")
            try:
                v = np.asarray(qn, dtype=float)
            except (TypeError, ValueError):
                v = None
            if v is None or v.shape != (P, 3) or not np.all(np.isfinite(v)):
                raise RetrievalError(f"the Query's pose for actor {a} must be a finite ({P}, 3) array")
        try:
            ok = np.isfinite(q.size_c) and q.size_c > 0
        except TypeError:
            ok = False
        if not ok:
            raise RetrievalError(f"the Query's size_c must be finite and > 0, got {q.size_c!r}")
        if tuple(q.actors) != tuple(q.q_n):
            raise RetrievalError("the Query's actors do not match its poses; make it with MotionRetriever.prepare")
        return q

    def _c_r(self, c: np.ndarray, size_c: float, scale_target: bool) -> np.ndarray:
        """(C, 3) target of every clip's actor: Eq. 1 (or c itself without scaling)."""
        if not scale_target:
            return np.broadcast_to(c, (self.db.n_clips, 3))
        # Eq. 1, c * size_a / size_c (rescale_constraint), for every clip's size_a at once
        rescale_constraint(c, 1.0, size_c)  # validates c and size_c
        hit = self._ratio_cache  # size_a / size_c per clip, kept while the character's size is the same
        if hit is None or hit[0] != size_c:
            ratio = self.db.size_a / size_c
            self._ratio_cache = hit = (size_c, ratio, float(ratio.max()))
        _, ratio, rmax = hit
        # |c_k ratio_i| is largest at the largest ratio (rounding is monotone): one check for every clip
        if not np.all(np.abs(c * rmax) <= MAX_TARGET_M * 1e3):
            raise RetrievalError(f"target {c.tolist()} rescaled from the character's size {size_c:g} m to the "
                                 f"actors' (Eq. 1) is beyond {MAX_TARGET_M * 1e3:g} m")
        # the same products as c[None, :] * ratio[:, None], formed along the clips (a (C, 3) broadcast
        # over a length-3 inner axis costs ~5x more, measured at 7,200 clips): a transposed view
        return (c[:, None] * ratio[None, :]).T

    def _block(self, rows: np.ndarray, clips=None, size=None, actor=None) -> _Block | None:
        """Contiguous precomputed data of a set of candidate poses (None if empty); ``clips``, ``size``,
        ``actor`` of ``rows`` when already gathered (views, not copied)."""
        if rows.size == 0:
            return None
        db = self.db
        clips = db.pose_clip[rows] if clips is None else clips
        uclips, inv = np.unique(clips, return_inverse=True)
        actor = db.actor[clips] if actor is None else actor
        size = self.pose_size[rows] if size is None else size
        return _Block(rows=rows, index=self.index.subset(rows), clips=clips, size=size, actor=actor,
                      uclips=uclips, inv=inv, single_actor=int(actor[0]) if np.all(actor == actor[0]) else None)

    def _cluster_blocks(self, sem_of_pose: np.ndarray) -> None:
        """``cluster_block[cluster][semantics]``: the startable poses of each (cluster, semantics), and
        ``_sem_span[semantics]``, the slice of all of its blocks, cluster by cluster.

        The candidates are gathered once in :func:`~repro.motion.search.index_build.block_order` (the
        index's stored order): each block's rows, clips, sizes and actors are views of those
        arrays, and so are the exact search's per-semantics arrays (:meth:`_exact_setup`).
        """
        db, k = self.db, self.clusters.k
        labels = self.clusters.labels
        order = self.index.order if self.index.order is not None else block_order(labels, self.startable, sem_of_pose)
        clips = db.pose_clip[order]
        self._cand = {"rows": order, "clip": clips, "size": self.pose_size[order], "actor": db.actor[clips]}
        code = np.full(order.size, len(SEMANTICS), dtype=np.intp)
        for i, s in enumerate(SEMANTICS):
            code[sem_of_pose[order] == s] = i
        at = np.searchsorted(code * k + labels[order], np.arange(len(SEMANTICS) * k + 1))
        c = self._cand
        self.cluster_block = [{s: self._block(*(c[n][at[i * k + cl]:at[i * k + cl + 1]] for n in ("rows", "clip", "size", "actor")))
                               for i, s in enumerate(SEMANTICS)} for cl in range(k)]
        self._sem_span = {s: slice(int(at[i * k]), int(at[(i + 1) * k])) for i, s in enumerate(SEMANTICS)}

    def _allowed(self, rows: np.ndarray, q: Query) -> np.ndarray:
        if len(q.actors) == len(self.actors_present):
            return rows
        return rows[np.isin(self.db.actor[self.db.pose_clip[rows]], q.actors)]

    def _d_qr(self, rows: np.ndarray, q: Query) -> np.ndarray:
        """Aligned distances (metres of each pose's actor) from q_r to poses ``rows`` (gathered)."""
        out = np.empty(rows.size)
        act = self.db.actor[self.db.pose_clip[rows]]
        for a, qn in q.q_n.items():
            sel = act == a
            if np.any(sel):
                out[sel] = self.index.distances(qn, rows[sel])
        return self.pose_size[rows] * out

    def _d_cr(self, clips: np.ndarray, c_r: np.ndarray) -> np.ndarray:
        """Min distance from each clip's hit trajectory to its c_r."""
        diff = self.traj_padded[clips] - c_r[clips][:, None, :]
        return np.sqrt(np.min(np.einsum("ctk,ctk->ct", diff, diff), axis=1))

    def _score(self, rows: np.ndarray, q: Query, c_r: np.ndarray):
        """Best of an arbitrary set of poses (gathering path, for the k-d tree's neighbours)."""
        clips_of_rows = self.db.pose_clip[rows]
        uc, inv = np.unique(clips_of_rows, return_inverse=True)
        dcr = self._d_cr(uc, c_r)[inv]
        dqr = self._d_qr(rows, q)
        d = self.w_q * dqr + self.w_c * dcr
        j = int(np.argmin(d))
        return int(rows[j]), float(d[j]), float(dqr[j]), float(dcr[j]), rows.size

    def _score_block(self, b: _Block | None, q: Query, c_r: np.ndarray, inside: np.ndarray | None = None, *,
                     tie: bool = False):
        """Best pose of a block: ``(row, d, d_qr, d_cr, n_scored)``, or None if none qualifies.

        ``inside`` (C,) bool: the box test; poses of other clips are not candidates.
        """
        if b is None:
            return None
        valid_u = np.ones(b.uclips.size, dtype=bool) if inside is None else inside[b.uclips]
        if len(q.q_n) != len(self.actors_present):
            valid_u &= np.isin(self.db.actor[b.uclips], q.actors)
        if not valid_u.any():
            return None
        dcr_u = np.zeros(b.uclips.size)
        dcr_u[valid_u] = self._d_cr(b.uclips[valid_u], c_r)
        if b.single_actor is not None:
            dq = b.index.distances(q.q_n[b.single_actor])
        else:
            dq = np.zeros(b.rows.size)
            for a, qn in q.q_n.items():
                sel = np.flatnonzero(b.actor == a)
                if sel.size:
                    dq[sel] = b.index.distances(qn, sel)
        dq *= b.size
        valid = valid_u[b.inv]
        d = self.w_q * dq + self.w_c * dcr_u[b.inv]
        n = int(valid.sum())
        if n < valid.size:
            d[~valid] = np.inf
        if tie:
            return self._select(q, b.rows, d, c_r, n)
        j = int(np.argmin(d))
        return int(b.rows[j]), float(d[j]), float(dq[j]), float(dcr_u[b.inv[j]]), n

    def _result(self, q: Query, best, c_r, *, cluster, fallback, rank, method) -> RetrievalResult:
        """The result of ``best = (row, d, d_qr, d_cr, n[, (theta, x0, z0)])`` (the transform onto
        ``q_r`` when already known, as :meth:`_select` gives it)."""
        row, d, dqr, dcr, n = best[:5]
        if not np.isfinite(d):
            raise RetrievalError(f"the weighted distance d is not finite (d = {d}) for clip "
                                 f"{int(self.db.pose_clip[row])}: target or weights too large")
        db = self.db
        i = int(db.pose_clip[row])
        a = int(db.actor[i])
        if len(best) > 5:
            alpha, x0, z0 = best[5]
        else:
            _, alpha, x0, z0 = (float(v[0]) for v in self.index.distances(
                q.q_n[a], np.array([row]), return_transform=True, prepared=self._prepared(q, a)))
        s = float(db.size_a[i])
        th_i, o_i = float(db.pose_heading[row]), db.pose_origin[row]
        rot = alpha - th_i
        t = -rotate_y(o_i, rot) + s * np.array([x0, 0.0, z0])
        return RetrievalResult(
            clip=i, name=str(db.names[i]), semantics=str(db.semantics[i]), hit_role=str(db.hit_roles[i]),
            start_frame=int(db.pose_frame[row]), hit_frame=int(db.hit_frame[i]), pose=int(row), d=d, d_qr=dqr,
            d_cr=dcr, w_q=self.w_q, w_c=self.w_c, c_r=np.array(c_r[i]), size_a=s, size_c=q.size_c,
            cluster=cluster, n_candidates=int(n), fallback=fallback, cluster_rank=rank, method=method,
            rotation_y=rot, translation=t, heading=q.heading, origin=np.array(q.origin))

    # ------------------------------------------------------------- searches
    def search(self, target, current_pose, character=None, semantics: str = "punch", *, prune: bool = True,
               scale_target: bool = True, frame: int | None = None, method: str = "pruned") -> RetrievalResult:
        """The paper's retrieval (Section 3.3): cluster, box pruning, weighted distance.

        Clips whose hit-trajectory box does not contain ``c_r`` are pruned (the paper's
        "does not contain q_r" is a typo for ``c_r``: see Figure 4 and the module
        docstring).

        Parameters
        ----------
        target : (3,) array
            ``c``: the target in the character's root frame (metres; origin on the floor
            below the pelvis, y up, z the character's heading).
        current_pose : Motion or Query
            The character's current pose (see :meth:`prepare`), or an already prepared
            :class:`Query`.
        character : Skeleton or Motion
            The character (ignored with a :class:`Query`).
        semantics : {"punch", "kick"}
        prune : bool, default True
            False disables both the cluster selection and the box test (every startable
            pose of the semantics is scored): then the result is the exhaustive optimum.
        scale_target : bool, default True
            Apply Eq. 1; False uses ``c_r = c`` (an ablation, to show what Eq. 1 does).
        frame : int, optional
            Frame of ``current_pose`` to use (default the last).
        method : {"pruned", "exact", "exhaustive", "kdtree"}, default "pruned"
            ``"pruned"``: the paper's search (above), unchanged.  ``"exact"``: branch and
            bound over the same clusters and boxes (:meth:`search_exact`), the exhaustive
            optimum at a fraction of its cost.  ``"exhaustive"`` / ``"kdtree"``: the
            baselines (:meth:`search_exhaustive`, :meth:`search_kdtree`).

        Returns
        -------
        RetrievalResult

        Raises
        ------
        repro.errors.RetrievalError
            Unknown semantics or method, a database without clips of it, a
            target that is not a finite 3-vector, a character that cannot be retargeted to.
        """
        c, q, sem, method, scale_target, prune = self.arguments(
            target, current_pose, character, semantics, method=method, scale_target=scale_target, frame=frame,
            prune=prune)
        if method == "exact":
            return self._search_exact(c, q, sem, scale_target)
        if method == "exhaustive":
            return self._search_exhaustive(c, q, sem, scale_target)
        if method == "kdtree":
            return self.search_kdtree(c, q, None, sem)
        return self._search_pruned(c, q, sem, prune=prune, scale_target=scale_target)

    def arguments(self, target, current_pose, character, semantics, *, method: str, scale_target: bool = True,
                  frame: int | None = None, prune: bool = True):
        """The checked arguments of every search: ``(c, q, semantics, method, scale_target, prune)``.

        One preamble for :meth:`search`, :meth:`search_exact`, :meth:`search_exhaustive`
        and :meth:`search_kdtree`: the target (:data:`MAX_TARGET_M`), the semantics, the
        flags, the method (:meth:`check_method`), then the prepared query
        (:meth:`prepare`, or a :class:`Query` checked), in that order (the cheap checks
        before the retargeting).

        Raises
        ------
        repro.errors.RetrievalError
            Naming the first bad value.
        """
        c = _check_target(target)
        sem = self._semantics(semantics)
        prune, scale_target = _check_flag("prune", prune), _check_flag("scale_target", scale_target)
        method = self.check_method(method)
        q = self._query(current_pose, character, frame)
        return c, q, sem, method, scale_target, prune

    @staticmethod
    def check_method(method) -> str:
        """``method`` checked: one of :data:`METHODS`."""
        if not isinstance(method, str) or method not in METHODS:
            raise RetrievalError(f"unknown method {method!r}; expected one of {list(METHODS)}")
        return method

    def search_exact(self, target, current_pose, character=None, semantics: str = "punch", *,
                     scale_target: bool = True, frame: int | None = None, stats: dict | None = None) -> RetrievalResult:
        """Exact search: the exhaustive optimum of ``d``, by bounds over clusters, clip runs and clips.

        Kovar et al.'s aligned distance ``D`` minimises over an isometry group (rotations
        about the vertical, horizontal translations) applied to a whole cloud, under a
        weighted Euclidean seminorm (non-negative weights): it is a pseudometric, so for
        a cluster of centroid ``m`` and radius ``r`` (largest ``D(m, p)`` of its poses of
        the semantics) every pose has ``D(q_r, p) >= D(q_r, m) - r``; ``d_cr >= dist(c_r, box)``
        and then the exact ``d_cr`` of every clip within reach.  The cascade (cheap bounds first,
        a first best ``d`` from the most promising clip runs, exact ``d`` only for the poses whose
        bound can beat it) is compiled: :mod:`repro.motion.search.kernel`.
        Candidates within rounding of the best are re-scored one by one and ties (within
        :data:`TIE_RTOL`) go to the lowest pose index, as in :meth:`search_exhaustive`:
        both return the same pose with the same numbers.  ``stats`` (a dict), when given,
        receives ``clusters_visited``, ``groups_scored`` and ``poses_scored`` (the clusters of
        the clip runs scored, those runs, their poses).
        """
        c, q, sem, _, scale_target, _ = self.arguments(
            target, current_pose, character, semantics, method="exact", scale_target=scale_target, frame=frame)
        if stats is not None and not isinstance(stats, dict):  # filled in after the search: checked before it
            raise RetrievalError(f"stats must be a dict to fill or None, got {describe(stats)}")
        return self._search_exact(c, q, sem, scale_target, stats=stats)

    def _search_pruned(self, c, q: Query, sem: str, *, prune: bool = True, scale_target: bool = True):
        c_r = self._c_r(c, q.size_c, scale_target)
        if not prune:
            best = self._score_block(self.sem_block[sem], q, c_r, tie=True)
            if best is None:
                raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
            return self._result(q, best, c_r, cluster=-1, fallback="disabled", rank=-1, method="pruned")
        # 3. the cluster nearest to q_r (aligned distance to the centroids)
        if len(q.q_n) == 1:
            (qn,) = q.q_n.values()
            dc = self.centroid_index.distances(qn)
        else:
            dc = np.min([self.centroid_index.distances(v) for v in q.q_n.values()], axis=0)
        order = np.argsort(dc, kind="stable")
        # 4. box pruning (clip level, all clips at once), 5. scoring of what remains
        db = self.db
        inside = np.all((db.box_min <= c_r) & (c_r <= db.box_max), axis=1)
        any_inside = bool(np.any(inside[self.sem_block[sem].uclips]))
        for rank, cl in enumerate(order.tolist() if any_inside else ()):
            best = self._score_block(self.cluster_block[cl][sem], q, c_r, inside)
            if best is not None:
                return self._result(q, best, c_r, cluster=int(cl),
                                    fallback="none" if rank == 0 else "neighbour_clusters", rank=rank,
                                    method="pruned")
        # no clip of this semantics has a box containing c_r: score them all
        best = self._score_block(self.sem_block[sem], q, c_r)
        if best is None:
            raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
        return self._result(q, best, c_r, cluster=int(order[0]), fallback="no_box", rank=-1, method="pruned")

    def search_exhaustive(self, target, current_pose, character=None, semantics: str = "punch", *,
                          scale_target: bool = True, frame: int | None = None) -> RetrievalResult:
        """Baseline: score every startable pose of the semantics with the same ``d``.

        Ties (``d`` within :data:`TIE_RTOL` of the minimum) go to the lowest pose index.
        """
        c, q, sem, _, scale_target, _ = self.arguments(
            target, current_pose, character, semantics, method="exhaustive", scale_target=scale_target, frame=frame)
        return self._search_exhaustive(c, q, sem, scale_target)

    @staticmethod
    def _tie_threshold(best: float) -> float:
        return best + TIE_RTOL * abs(best) + TIE_ATOL

    def _near_threshold(self, best: float) -> float:
        """Candidates whose ``d`` is below this are re-scored one by one (:meth:`_select`)."""
        rtol, atol = self._near_terms()
        return best + rtol * abs(best) + atol

    def _near_terms(self) -> tuple[float, float]:
        """``(rtol, atol)`` of :meth:`_near_threshold`: ``best + rtol |best| + atol``."""
        return NEAR_RTOL, NEAR_ATOL * self.w_q * self._size_max

    def _canonical(self, q: Query, row: int, c_r: np.ndarray) -> tuple:
        """``(d, d_qr, d_cr, (theta, x0, z0))`` of one pose, always by the same one-row evaluation (so that
        every search reports the same numbers for the same pose, whatever batch it was first scored in),
        and its transform onto ``q_r``."""
        db = self.db
        i = int(db.pose_clip[row])
        qn = q.q_n[int(db.actor[i])]
        # the pose distance summed directly: the closed form cancels to ~1e-8 near a match
        D, alpha, x0, z0 = self.index.direct_distance(qn, row)
        dcr = float(self._d_cr(np.array([i]), c_r)[0])
        dqr = D * float(self.pose_size[row])
        return self.w_q * dqr + self.w_c * dcr, dqr, dcr, (alpha, x0, z0)

    def _select(self, q: Query, rows: np.ndarray, d: np.ndarray, c_r: np.ndarray, n: int) -> tuple:
        """The selection among scored poses: ``(row, d, d_qr, d_cr, n)``.

        The poses within :meth:`_near_threshold` of the lowest ``d`` (above the rounding of
        the closed form, which differs in the last bits between batches) are re-scored by
        :meth:`_canonical`; the lowest of those wins, ties (:data:`TIE_RTOL`) to the lowest
        pose index.  The exact and exhaustive searches share it.
        """
        m = float(np.min(d))
        near = np.flatnonzero(d <= self._near_threshold(m))
        near = near[np.argsort(rows[near], kind="stable")]
        if near.size > MAX_NEAR:  # degenerate databases (many copies of one pose): the lowest indices
            near = np.concatenate([near[:MAX_NEAR], [int(np.argmin(d))]])
        scored = [(self._canonical(q, int(rows[j]), c_r), int(rows[j])) for j in near]
        m2 = min(v[0][0] for v in scored)
        (dd, dqr, dcr, tf), row = min((v for v in scored if v[0][0] <= self._tie_threshold(m2)), key=lambda v: v[1])
        return row, float(dd), float(dqr), float(dcr), int(n), tf

    def _finish(self, q: Query, parts: list, c_r: np.ndarray, *, method: str, n: int):
        if not parts:
            raise RetrievalError("no clip of an actor compatible with the character for this semantics")
        rows = np.concatenate([p[0] for p in parts])
        d = np.concatenate([p[1] for p in parts])
        best = self._select(q, rows, d, c_r, n)
        return self._result(q, best, c_r, cluster=-1, fallback="disabled", rank=-1, method=method)

    def _search_exhaustive(self, c, q: Query, sem: str, scale_target: bool = True, *,
                           method: str = "exhaustive") -> RetrievalResult:
        c_r = self._c_r(c, q.size_c, scale_target)
        best = self._score_block(self.sem_block[sem], q, c_r, tie=True)
        if best is None:
            raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
        return self._result(q, best, c_r, cluster=-1, fallback="disabled", rank=-1, method=method)

    def _kdtree(self, sem: str):
        if sem not in self._kd:
            rows = self.sem_rows[sem]
            db = self.db
            sw = np.sqrt(self.weights)[None, :, None]
            pose = (db.pose_points[rows] * sw).reshape(rows.size, -1) * self.w_q
            clips = db.pose_clip[rows]
            hit = db.hit_position[clips] / db.size_a[clips, None] * self.w_c
            self._kd[sem] = (cKDTree(np.concatenate([pose, hit], axis=1)), rows)
        return self._kd[sem]

    def search_kdtree(self, target, current_pose, character=None, semantics: str = "punch", *,
                      frame: int | None = None) -> RetrievalResult:
        """Baseline: k-d tree nearest neighbours of a feature vector, rescored with ``d``.

        Feature of a pose: ``w_q sqrt(w) * cloud`` (its canonical-frame cloud, in units of
        the actor's size, flattened) and ``w_c * hit_position / size_a``; the query uses
        ``q_r``'s cloud and ``c / size_c`` (= ``c_r / size_a`` by Eq. 1).  Euclidean
        distance between these vectors ignores the alignment (an upper bound of
        ``d_qr``) and replaces ``d_cr`` by the distance to the hit position; the
        ``kd_neighbours`` nearest are rescored with the exact ``d``.  No box pruning.
        Built lazily per semantics (the first call includes the build).
        """
        c, q, sem, *_ = self.arguments(target, current_pose, character, semantics, method="kdtree", frame=frame)
        tree, rows_all = self._kdtree(sem)
        c_r = self._c_r(c, q.size_c, True)
        sw = np.sqrt(self.weights)[:, None]
        best = None
        for a, qn in q.q_n.items():
            v = np.concatenate([(qn * sw).reshape(-1) * self.w_q, c / q.size_c * self.w_c])
            kk = min(self.kd_neighbours, rows_all.size)
            dist, nb = tree.query(v, k=kk)
            nb = np.atleast_1d(nb)[np.isfinite(np.atleast_1d(dist))]  # cKDTree marks missing ones with n
            rows = self._allowed(rows_all[nb], q)
            if rows.size == 0:
                continue
            cand = self._score(rows, q, c_r)
            if best is None or cand[1] < best[1]:
                best = cand
        if best is None:
            raise RetrievalError(f"no {sem!r} clip of an actor compatible with the character")
        return self._result(q, best, c_r, cluster=-1, fallback="disabled", rank=-1, method="kdtree")


#: The retriever :func:`search` built last, by its database's ``id()``: one (an index weighs about
#: as much as its database's arrays).  The retriever holds its database, so that id is not reused
#: while the entry is kept.
_RETRIEVERS: LRUCache[MotionRetriever] = LRUCache(1)


def search(db: MotionDatabase, target, current_pose, character, semantics: str, **kw) -> RetrievalResult:
    """``MotionRetriever(db).search(target, current_pose, character, semantics)``.

    The retriever (clusters, indices) is built on the first call for ``db`` and kept
    (:data:`_RETRIEVERS`); keyword arguments go to :meth:`MotionRetriever.search`.
    """
    if not isinstance(db, MotionDatabase):
        raise RetrievalError(f"expected a MotionDatabase, got {type(db).__name__}")
    r = _RETRIEVERS.get(id(db), lambda: MotionRetriever(db))
    return r.search(target, current_pose, character, semantics, **kw)


# ------------------------------------------------------------------ random queries
def _pose_motion(m: Motion, f: int) -> Motion:
    return dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])


def _check_noise(noise) -> float:
    return as_real(noise, "noise (metres)", lo=0.0, hi=MAX_TARGET_M, error=RetrievalError)


#: Most queries :func:`make_queries` makes: each holds a pose and a skeleton, and
#: ``n = 10**12`` ran until killed (issue 23); the figures use 200, the benchmark up to a few thousand.
MAX_QUERIES: int = 100_000


def make_queries(db: MotionDatabase, n: int, seed: int = 0, *, noise: float = 0.05):
    """Random queries for :func:`repro.bench.retrieval.time_search`: (target, current pose, character, semantics).

    The current pose is a random frame of a random original clip (on its actor, which is
    the character); the target is a random point of a random clip's hit trajectory near
    its hit (within 3 frames), moved by Gaussian noise of ``noise`` metres, rescaled to
    the character (Eq. 1 inverted) -- so that most queries have clips whose box contains
    ``c_r``, as in the paper's use.

    Raises
    ------
    repro.errors.RetrievalError
        Not a database, ``n`` not an int in 0..:data:`MAX_QUERIES`, ``seed`` not an int >= 0,
        ``noise`` not finite >= 0.
    """
    if not isinstance(db, MotionDatabase):
        raise RetrievalError(f"expected a MotionDatabase, got {type(db).__name__}")
    n = as_int(n, "n (number of queries)", 0, MAX_QUERIES, error=RetrievalError)
    seed = as_int(seed, "seed", 0, None, error=RetrievalError)
    noise = _check_noise(noise)
    rng = np.random.default_rng(seed)
    originals = np.flatnonzero(db.source_clip == np.arange(db.n_clips))
    out = []
    for _ in range(n):
        i = int(rng.choice(originals))
        m = db.motion(i)
        f = int(rng.integers(0, m.n_frames))
        pose = _pose_motion(m, f)
        character = Skeleton.from_motion(m)
        j = int(rng.integers(0, db.n_clips))
        h = int(db.hit_frame[j])
        tf = int(np.clip(h + rng.integers(-3, 4), 0, db.n_frames[j] - 1))
        c = db.trajectory(j)[tf] * (character.size / db.size_a[j]) + rng.normal(0, noise, 3)
        out.append((c, pose, character, str(db.semantics[j])))
    return out
