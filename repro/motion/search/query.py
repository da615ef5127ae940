"""The query of a retrieval: the current pose retargeted to the database's actors (Pronost et al., Section 3.3).

Step 2 of the search, ``q_r``: "the current pose retargeted to the actor, so that the distance
calculated between q_r and a pose in each clip is based on the same skeleton"
(:func:`repro.motion.retargeting.morphology.retarget`, Section 3.4.1), as a pose cloud
(:mod:`repro.motion.body.pose_frames`) in units of the actor's size.  :class:`QueryPreparer`
makes the :class:`Query` of a pose, caching what depends only on the skeletons (retargeting
plans, which actors a character reaches); how several actors and joint trees are served is in
:mod:`repro.motion.search.retrieval`'s docstring.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from repro.checks import as_int, describe
from repro.errors import MotionError, RetrievalError
from repro.motion.body.pose_frames import pose_points, root_frames
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.core.motion import LEVEL_LOOP_MAX_DEPTH, Motion
from repro.motion.core.ops import resample
from repro.motion.retargeting.dispatch import rest_motion_y_up
from repro.motion.retargeting.morphology import RetargetPlan
from repro.motion.retargeting.trees import TreePlan
from repro.motion.search.arguments import check_flag
from repro.motion.search.index import RetrievalIndex

__all__ = ["Query", "QueryPreparer"]


@dataclass(frozen=True, eq=False)
class Query:
    """The character-dependent inputs of a search, prepared by :meth:`QueryPreparer.prepare`.

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


class QueryPreparer:
    """Makes the :class:`Query` of a current pose on a :class:`~repro.motion.search.index.RetrievalIndex`.

    Parameters
    ----------
    index : RetrievalIndex
    across_trees : bool, default True
        Serve characters of other joint trees than the actors' (see
        :class:`repro.motion.search.retrieval.MotionRetriever`).
    """

    def __init__(self, index: RetrievalIndex, *, across_trees: bool = True):
        self.across_trees = check_flag("across_trees", across_trees)
        self.db = index.db
        self._actors = index.actors_present
        self._n_points = index.index.n_points
        self._prep_cache: dict = {}
        self._actor_rest: dict = {}  # actor -> its rest pose, Y up (retargeting across trees)
        self._plans: dict = {}  # (actor, pose skeleton) -> RetargetPlan (same tree, other proportions)
        self._tree_plans: dict = {}  # (actor, pose skeleton, roles) -> TreePlan (another joint tree)

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
        for a in self._actors.tolist():
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
            src = (gq_c, gc) if m.n_depth_levels <= LEVEL_LOOP_MAX_DEPTH else None
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

    def query(self, current_pose, character=None, frame: int | None = None) -> Query:
        """A prepared :class:`Query` (checked), or :meth:`prepare` of the current pose."""
        if not isinstance(current_pose, Query):
            return self.prepare(current_pose, character, frame=frame)
        q = current_pose
        if not isinstance(q.q_n, dict) or not q.q_n:
            raise RetrievalError("the Query has no retargeted pose (q_n); make it with MotionRetriever.prepare")
        P = self._n_points
        for a, qn in q.q_n.items():
            if a not in set(self._actors.tolist()):
                raise RetrievalError(f"the Query names actor {a!r}, not an actor of this database "
                                     f"({self._actors.tolist()})")
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
