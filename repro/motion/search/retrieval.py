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
   :class:`~repro.motion.search.index.RetrievalIndex`).
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

The parts: :class:`~repro.motion.search.index.RetrievalIndex` (everything that does not depend on
the query, built once), :mod:`~repro.motion.search.query` (step 2, ``q_r``),
:mod:`~repro.motion.search.scoring` (Eq. 1 and ``d``), :mod:`~repro.motion.search.pruned` (the
paper's steps 3-5), :mod:`~repro.motion.search.results` (step 6 and the selection rule), the exact
search (``method="exact"``, the fighter's default: the exhaustive optimum through bounds over the
same clusters and boxes, :mod:`~repro.motion.search.exact`) and the baselines
(:mod:`~repro.motion.search.exhaustive`, :mod:`~repro.motion.search.kdtree`).
:class:`MotionRetriever` puts them together.

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

import numpy as np

from repro.checks import as_int, as_real, describe
from repro.errors import RetrievalError
from repro.motion.body.skeleton import Skeleton
from repro.motion.core.cache import LRUCache
from repro.motion.core.motion import Motion
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.clips import MotionDatabase
from repro.motion.search.arguments import MAX_TARGET_M, MAX_WEIGHT, METHODS, check_flag, check_method, check_target
from repro.motion.search.exact import ExactSearch
from repro.motion.search.exhaustive import search_exhaustive
from repro.motion.search.index import RetrievalIndex
from repro.motion.search.kdtree import KdTrees, search_kdtree
from repro.motion.search.pruned import search_pruned
from repro.motion.search.query import Query, QueryPreparer
from repro.motion.search.results import FALLBACKS, QueryMatrices, RetrievalResult
from repro.motion.search.scoring import ClipTargets

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


class MotionRetriever(QueryPreparer):
    """The database organised for the search: clusters, indices, per-clip arrays.

    Everything that does not depend on the query is computed once (Section 3.2.2:
    "we propose to organize the database into clusters in a precomputation process"), in its
    :class:`~repro.motion.search.index.RetrievalIndex` (``retrieval_index``): k-means clusters of all
    poses, the candidate poses of every (cluster, semantics), the closed-form terms of the
    aligned distance for every pose, padded hit trajectories, the exact search's bounds.  The
    searches are the functions of :mod:`~repro.motion.search.pruned`,
    :mod:`~repro.motion.search.exact`, :mod:`~repro.motion.search.exhaustive` and
    :mod:`~repro.motion.search.kdtree` over it; the query side (:meth:`prepare`) is
    :class:`~repro.motion.search.query.QueryPreparer`'s.

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
        # the facade's own arguments first: refused before the index's k-means runs
        self.kd_neighbours = as_int(kd_neighbours, "kd_neighbours", 1, None, error=RetrievalError)
        across_trees = check_flag("across_trees", across_trees)
        index = RetrievalIndex(db, k=k, seed=seed, weights=weights, w_q=w_q, w_c=w_c)
        super().__init__(index, across_trees=across_trees)
        self.retrieval_index = index
        # what the index holds, read by the notebooks, experiments and tests (the same objects)
        self.index, self.clusters, self.centroid_index, self.weights = (
            index.index, index.clusters, index.centroid_index, index.weights)
        self.w_q, self.w_c, self.pose_size, self.startable = index.w_q, index.w_c, index.pose_size, index.startable
        self.sem_rows, self.sem_block, self.cluster_block = index.sem_rows, index.sem_block, index.cluster_block
        self.exact = ExactSearch(index)
        self.kd_trees = KdTrees(index)
        self.targets = ClipTargets(index)
        self.matrices = QueryMatrices(index)

    @property
    def k(self) -> int:
        """Number of clusters."""
        return self.retrieval_index.k

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
        if method == "kdtree":  # Eq. 1 always (its feature is c / size_c)
            return self._kdtree(c, q, sem)
        c_r = self.targets.c_r(c, q.size_c, scale_target)
        if method == "exact":
            return self._exact(c, q, sem, c_r, scale_target)
        if method == "exhaustive":
            return search_exhaustive(self.retrieval_index, q, sem, c_r)
        return search_pruned(self.retrieval_index, q, sem, c_r, self.matrices, prune=prune)

    def arguments(self, target, current_pose, character, semantics, *, method: str, scale_target: bool = True,
                  frame: int | None = None, prune: bool = True):
        """The checked arguments of every search: ``(c, q, semantics, method, scale_target, prune)``.

        One preamble for :meth:`search`, :meth:`search_exact`, :meth:`search_exhaustive`
        and :meth:`search_kdtree`: the target (:data:`MAX_TARGET_M`), the semantics, the
        flags, the method (:func:`~repro.motion.search.arguments.check_method`), then the prepared query
        (:meth:`prepare`, or a :class:`Query` checked), in that order (the cheap checks
        before the retargeting).

        Raises
        ------
        repro.errors.RetrievalError
            Naming the first bad value.
        """
        c = check_target(target)
        sem = self._semantics(semantics)
        prune, scale_target = check_flag("prune", prune), check_flag("scale_target", scale_target)
        method = check_method(method)
        q = self.query(current_pose, character, frame)
        return c, q, sem, method, scale_target, prune

    def _semantics(self, semantics) -> str:
        if not isinstance(semantics, str) or semantics not in SEMANTICS:
            raise RetrievalError(f"unknown semantics {semantics!r}; expected one of {list(SEMANTICS)}")
        if self.sem_rows[semantics].size == 0:
            raise RetrievalError(f"the database has no {semantics!r} clip with a pose before its hit")
        return semantics

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
        :data:`~repro.motion.search.results.TIE_RTOL`) go to the lowest pose index, as in :meth:`search_exhaustive`:
        both return the same pose with the same numbers.  ``stats`` (a dict), when given,
        receives ``clusters_visited``, ``groups_scored`` and ``poses_scored`` (the clusters of
        the clip runs scored, those runs, their poses).
        """
        c, q, sem, _, scale_target, _ = self.arguments(
            target, current_pose, character, semantics, method="exact", scale_target=scale_target, frame=frame)
        if stats is not None and not isinstance(stats, dict):  # filled in after the search: checked before it
            raise RetrievalError(f"stats must be a dict to fill or None, got {describe(stats)}")
        return self._exact(c, q, sem, self.targets.c_r(c, q.size_c, scale_target), scale_target, stats=stats)

    def _exact(self, c, q: Query, sem: str, c_r: np.ndarray, scale_target: bool, *, stats: dict | None = None,
               batch: int = 32) -> RetrievalResult:
        if not scale_target:  # the normalised target differs per actor size: score everything (exact)
            return search_exhaustive(self.retrieval_index, q, sem, c_r, method="exact")
        return self.exact.search(q, sem, c_r, c / q.size_c, stats=stats, batch=batch)

    def search_exhaustive(self, target, current_pose, character=None, semantics: str = "punch", *,
                          scale_target: bool = True, frame: int | None = None) -> RetrievalResult:
        """Baseline: score every startable pose of the semantics with the same ``d``.

        Ties (``d`` within :data:`~repro.motion.search.results.TIE_RTOL` of the minimum) go to the lowest pose index.
        """
        c, q, sem, _, scale_target, _ = self.arguments(
            target, current_pose, character, semantics, method="exhaustive", scale_target=scale_target, frame=frame)
        return search_exhaustive(self.retrieval_index, q, sem, self.targets.c_r(c, q.size_c, scale_target))

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
        return self._kdtree(c, q, sem)

    def _kdtree(self, c, q: Query, sem: str) -> RetrievalResult:
        c_r = self.targets.c_r(c, q.size_c, True)
        return search_kdtree(self.retrieval_index, self.kd_trees, c, q, sem, c_r, self.matrices,
                             kd_neighbours=self.kd_neighbours)


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
