"""One order carried out: the runtime sequence of Pronost et al., Sections 3.3-3.4 (Fig. 2, Fig. 6).

:func:`strike` is the one pipeline of the reproduction; :class:`~repro.motion.runtime.fighter.KungFuFighter`
and every Pronost figure call it.  For an order (a target ``X`` and a semantics) and the
character's current motion it

1. **prepares the query** (Section 3.3): ``q_r`` = the current pose retargeted to the
   database's actor(s) and ``c`` = the target in the current pose's root frame
   (:meth:`~repro.motion.search.retrieval.MotionRetriever.prepare`);
2. **searches** the database (cluster nearest to ``q_r``, bounding boxes, Eq. 1,
   ``d = d_qr + d_cr``: :meth:`~repro.motion.search.retrieval.MotionRetriever.search`);
3. **loads and converts** the clip: cut from the selected start frame, retargeted to the
   character (:func:`~repro.motion.retargeting.morphology.retarget`, Section 3.4.1); the foot
   contacts are detected *once*, here, on the retrieved clip (on its actor; kept per database,
   clip and start frame for the next order that retrieves them), and carried through every
   later stage;
4. **places** it (rotation about the vertical and translation fitting the start pose onto
   the current pose, scaled from the actor to the character) and **blends and
   synchronises** it with the current motion over ``blend_s`` seconds (Fig. 6 lists
   this first): frame 0 of the strike is the current pose;
5. **solves the constraints** frame by frame (Section 3.4.2,
   :func:`~repro.motion.adaptation.adapt`): ``d(t)`` from ``t0`` (= frame 0, now) to
   ``tc`` (the hit), the limb, CCD when the limb cannot reach, feet kept on the ground.
   Every frame is solved on its own, so the level is decided on ``tc`` and frame
   ``t0 + 1`` is final (``timings["first_frame"]``) before the rest of the clip is solved
   (``timings["rest"]``).  A kick that may need the root level is solved whole: its
   trials read the support foot, which depends on CCD's pelvis on every frame CCD solves;
   but up to the kicking foot's lift-off ``t_start`` ``d(t) = 0`` and the root shift is 0
   at every level, so when ``t0 + 1 <= t_start`` that frame (the feet alone) is solved and
   final first, and the level is decided after it (``timings["level"]``; the frames it
   changes are played ``t_start / fps`` seconds later).  The early frame is counted only
   when it is the played one (compared, number for number).

How is :class:`~repro.motion.runtime.options.StrikeOptions` (one frozen dataclass, the
fighter's defaults; :data:`repro.motion.runtime.paper.PAPER` the paper's choices).

Whole-body reach (``reach``, :data:`~repro.motion.runtime.options.REACH_LEVELS`): ``"limb"`` is the two-bone IK alone,
``"spine"`` adds the paper's CCD (elbow, shoulder, clavicle and the spine for a punch;
knee, hip and pelvis for a kick, within joint limits), ``"root"`` (default) adds a root
shift when CCD cannot reach either: the root follows ``d(t)`` by the remaining miss
(at most ``max_root_shift`` of the leg length, halved until the support leg, pinned on
its planted foot, still reaches the ground), and the limb / CCD are solved again from
there.  ``"step"`` (punches; opt-in) adds a step of the front foot towards the target, the
root following halfway and the other foot pinned (:func:`_step`); a kick's foot lifts
within frames of the order, so its support foot never steps.  ``Strike.level`` says which
level the contact frame needed; ``reached=False`` with the residual and the highest level
tried (``levels_tried``) when nothing reaches.

Feet: the planted phases after ``t0`` are pinned (``feet="plant"``), and the whole foot (the
ankle, the joints below it, their End Sites) is kept at or above the floor (``y = 0``) on every
frame after ``t0``, the kicking foot's too.

Bad input: a target inside the body (horizontally within :data:`BODY_RADIUS` x size of
the current pose's root, below the head) raises :class:`repro.errors.MotionError`; so does
a character without the effector the retrieved clip strikes with.  Targets out of reach
are a documented best effort (``reached=False``).
"""

from __future__ import annotations

import dataclasses
import math
import time
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from repro.checks import as_bool, as_choice, as_int, as_real, as_real_array, describe
from repro.errors import MotionError, RetrievalError
from repro.motion.adaptation import EFFECTOR_STEMS, Adaptation, AdaptOptions, adapt
from repro.motion.adaptation.adapt_clip import FrameSolve, adapt_frames
from repro.motion.database.annotation import SEMANTICS
from repro.motion.adaptation.cost import adaptation_cost
from repro.motion.adaptation.offset import offset_curve
from repro.motion.body.pose_frames import from_root_frame, rotate_y, to_root_frame
from repro.motion.database.clips import MotionDatabase
from repro.motion.core.ops import cut, ease
from repro.motion.body.roles import effector_role
from repro.motion.body.feet import foot_contacts, max_foot_slide
from repro.motion.core.quaternion import slerp
from repro.motion.core.motion import Motion, finite_vector3
from repro.motion.runtime.options import REACH_LEVELS, StrikeOptions
from repro.motion.runtime.paper import REACTION_BUDGET_S
from repro.motion.core.quaternion import quat_multiply
from repro.motion.retargeting.dispatch import character_skeleton, retarget_to
from repro.motion.search.retrieval import MotionRetriever, Query, RetrievalResult
from repro.motion.body.skeleton import Skeleton, rescale_constraint

__all__ = [
    "BODY_RADIUS",
    "STAGES",
    "Strike",
    "blend_into",
    "clip_effector",
    "one_frame",
    "reach_by_distance",
    "strike",
    "turn_and_move",
]

#: Longest step of the ``"step"`` level, per metre of leg length; its duration (s) and foot lift (per metre of leg).
MAX_STEP: float = 0.6
STEP_S: float = 0.3
STEP_LIFT: float = 0.06
#: Fractions of the miss left by CCD that the root shift tries, in order (the first the support leg follows wins).
ROOT_SHIFT_TRIALS: tuple[float, ...] = (1.15, 0.5)
#: CCD sweeps per frame after a root shift (the shift does most of the work).
ROOT_MAX_ITER: int = 20
#: A target horizontally closer than this fraction of the character's size to the current
#: pose's root (and below the head) is inside the body.
BODY_RADIUS: float = 0.08
#: Most equal-count bins :func:`reach_by_distance` makes (a table of reach, not a histogram of millions).
MAX_BINS: int = 10_000
#: Most (clip, start frame) foot contacts kept per database (:func:`_contacts_of`; about 100 bytes each).
MAX_CACHED_CONTACTS: int = 4096
#: database -> {(clip, start frame): contacts of the clip cut there}, as long as the database lives
_CONTACTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: Measured stages of an order, in :attr:`Strike.timings` (seconds).
STAGES: tuple[str, ...] = ("prepare", "search", "load_convert", "adapt", "first_frame")


# ------------------------------------------------------------------ helpers (one home each)
def _check_motion(m, name: str) -> None:
    if not isinstance(m, Motion):
        raise MotionError(f"{name} must be a Motion, got {describe(m)}")


def one_frame(motion: Motion, f: int) -> Motion:
    """The one-frame motion holding frame ``f`` of ``motion`` (a current pose)."""
    _check_motion(motion, "motion")
    F = motion.n_frames
    f = as_int(f, "f (a frame)", error=MotionError)
    if not -F <= f < F:
        raise MotionError(f"frame {f} outside the motion's {F} frames")
    f %= F
    return dataclasses.replace(motion, rotations=motion.rotations[f:f + 1], positions=motion.positions[f:f + 1])


def _qy(theta: float) -> np.ndarray:
    return np.array([0.0, math.sin(theta / 2.0), 0.0, math.cos(theta / 2.0)])


def turn_and_move(motion: Motion, theta: float, translation) -> Motion:
    """The motion rotated by ``theta`` about the vertical axis through the world origin, then translated."""
    _check_motion(motion, "motion")
    theta = as_real(theta, "theta (radians)", error=MotionError)
    translation = finite_vector3(translation, "translation (x, y, z)", MotionError)
    rot = np.array(motion.rotations)
    rot[:, 0] = quat_multiply(np.broadcast_to(_qy(theta), rot[:, 0].shape), rot[:, 0])
    pos = np.array(motion.positions)
    pos[:, 0] = rotate_y(pos[:, 0], theta) + translation
    return dataclasses.replace(motion, rotations=rot, positions=pos)


def blend_into(pose: Motion, placed: Motion, n_blend: int) -> Motion:
    """Blend ``placed`` into the pose (frame 0 of the result = ``pose``'s last frame) over ``n_blend`` frames.

    Joint rotations by slerp, the root position by an offset that decays to 0 (smootherstep).
    """
    _check_motion(pose, "pose")
    _check_motion(placed, "placed")
    if pose.rotations.shape[1:] != placed.rotations.shape[1:]:
        raise MotionError(f"pose and placed must have the same joints, got {pose.n_joints} and {placed.n_joints}")
    F = placed.n_frames
    nb = max(1, as_int(n_blend, "n_blend (frames)", 0, error=MotionError))
    w = ease(np.arange(F) / nb)
    r0 = np.broadcast_to(pose.rotations[-1], placed.rotations.shape)
    rot = slerp(r0, placed.rotations, w[:, None, None])
    pos = np.array(placed.positions)
    pos[:, 0] += (1.0 - w)[:, None] * (pose.positions[-1, 0] - placed.positions[0, 0])[None, :]
    return dataclasses.replace(placed, rotations=rot, positions=pos)


def clip_effector(db: MotionDatabase, clip: int, character: Skeleton) -> str:
    """The effector role (on ``character``) of the joint clip ``clip`` strikes with; MotionError if it has none."""
    if not isinstance(db, MotionDatabase):
        raise RetrievalError(f"db must be a MotionDatabase, got {describe(db)}")
    clip = as_int(clip, "clip", 0, db.n_clips - 1, error=RetrievalError)
    if not isinstance(getattr(character, "roles", None), Mapping):
        raise MotionError(f"character must be a Skeleton (with roles), got {describe(character)}")
    hit_role, hit_joint = str(db.hit_roles[clip]), str(db.hit_joints[clip])
    role = effector_role(db.actor_skeleton(clip).roles, hit_role, hit_joint)
    if role not in character.roles:
        raise MotionError(f"the character has no {role!r} (clip {db.names[clip]!r} strikes with it); its roles: "
                          f"{sorted(character.roles)}")
    return role


# ------------------------------------------------------------------ the result
@dataclass(frozen=True, eq=False)
class Strike:
    """One order carried out: what was retrieved, the played motion, how well it hits, its cost, how long it took.

    Attributes
    ----------
    kind : str
        The order's semantics (``"punch"`` or ``"kick"``).
    target : (3,) array
        The target stored at the order (world, metres); never refreshed.
    target_local : (3,) array
        ``c``: the target in the root frame of the current pose (Section 3.3).
    retrieval : RetrievalResult
    effector : str
        The hit point's role on the character.
    motion : Motion
        The played motion on the character, world frame; frame 0 is the current pose.
    original : Motion
        The same before the constraint solver (retargeted, placed and blended).
    adaptation : Adaptation
        The solver's report (of the level used).
    tc : int
        Contact frame of :attr:`motion`.
    hit_error : float
        Distance (m) between the hit point and the target at the contact.
    reached : bool
    unadapted_error : float
        The same distance without the solver.
    foot_slide : float
        Largest horizontal slide (m) of a planted ankle over the contacts of the retrieved clip.
    timings : dict
        Seconds: ``prepare``, ``search``, ``load_convert`` (of which ``retarget``), ``adapt``
        (placement, blend, solver at every level tried, whole clip; of which ``solver``),
        ``first_frame`` (order -> frame ``t0 + 1`` final: the level decided on ``tc``, or
        for a kick still planted at ``t0 + 1`` that frame alone, which no level changes),
        ``level`` (order -> level decided; ``>= first_frame``),
        ``rest`` (the rest of the clip solved after it; ``first_frame + rest = order``),
        ``order`` (the whole call), ``adapt_per_frame``, ``retarget_adapt_per_frame``
        (the paper's 88 µs).
    level : str
        The reach level the contact frame needed (:data:`REACH_LEVELS`); for an unreachable
        target the highest level tried.
    levels_tried : tuple of str
    contacts : (F, 2) bool
        Planted frames (left, right), detected once on the retrieved clip.
    closest_error : float
        Closest approach (m) of the unadapted hit-point trajectory to the target.
    cost : dict
        :func:`repro.motion.adaptation.cost.adaptation_cost` of :attr:`motion` against :attr:`original`.
    budget_s : float
    """

    kind: str
    target: np.ndarray
    target_local: np.ndarray
    retrieval: RetrievalResult
    effector: str
    motion: Motion
    original: Motion
    adaptation: Adaptation
    tc: int
    hit_error: float
    reached: bool
    unadapted_error: float
    foot_slide: float
    timings: dict
    level: str = "limb"
    levels_tried: tuple = ()
    contacts: np.ndarray | None = None
    closest_error: float = float("nan")
    cost: dict = field(default_factory=dict)
    budget_s: float = REACTION_BUDGET_S

    @property
    def clip_name(self) -> str:
        return self.retrieval.name

    @property
    def semantics(self) -> str:
        return self.retrieval.semantics

    @property
    def n_frames(self) -> int:
        return self.motion.n_frames

    @property
    def within_budget(self) -> bool:
        """Whether order -> first adapted frame took less than 1/30 s."""
        return self.timings["first_frame"] <= self.budget_s

    def hit_positions(self) -> np.ndarray:
        """(F, 3) world trajectory of the hit point in :attr:`motion`."""
        return self.adaptation.hit_positions

    def original_hit_positions(self) -> np.ndarray:
        """(F, 3) world trajectory of the hit point in :attr:`original` (before the solver)."""
        return self.adaptation.original_hit

    def summary(self, timings: bool = True) -> dict:
        """Flat numbers for tables; ``timings=False`` keeps only the deterministic ones."""
        timings = as_bool(timings, "timings", error=MotionError)
        r = self.retrieval
        out = {
            "kind": self.kind, "clip": r.name, "start_frame": r.start_frame, "contact_frame": self.tc,
            "d": r.d, "d_qr": r.d_qr, "d_cr": r.d_cr, "fallback": r.fallback, "effector": self.effector,
            "unadapted_error_m": self.unadapted_error, "hit_error_m": self.hit_error, "reached": self.reached,
            "foot_slide_m": self.foot_slide, "frames": self.n_frames, "level": self.level,
        }
        out.update({k: v for k, v in self.cost.items()})
        if timings:
            out.update({f"{k}_ms": v * 1e3 for k, v in self.timings.items()})
            out["within_budget"] = self.within_budget
        return out


# ------------------------------------------------------------------ the pipeline
def _retriever_of(source, seed: int) -> MotionRetriever:
    if isinstance(source, MotionRetriever):
        return source
    if isinstance(source, MotionDatabase):
        return MotionRetriever(source, seed=seed)
    raise RetrievalError(f"strike needs a MotionDatabase or a MotionRetriever, got {type(source).__name__}")


def _check_inside_body(X: np.ndarray, c: np.ndarray, ch: Skeleton) -> None:
    """MotionError for a target inside the character's body (near the root axis, below the head)."""
    r = float(np.hypot(c[0], c[2]))
    if r < BODY_RADIUS * ch.size and X[1] < ch.size:
        raise MotionError(
            f"target {np.round(X, 3).tolist()} is inside the character's body: {r:.3f} m from its root axis "
            f"(less than {BODY_RADIUS:g} x size = {BODY_RADIUS * ch.size:.3f} m) below its head; "
            "a strike needs a target in front of the character")


def _root_shift(ad: Adaptation | FrameSolve, frac: float, limit: float, kind: str, release) -> np.ndarray:
    """Root offsets (F, 3) following ``d(t)``'s timing by the miss left at the contact (capped)."""
    tc = ad.tc
    miss = ad.target - ad.contact_hit
    n = float(np.linalg.norm(miss))
    if n > limit:
        miss = miss * (limit / n)
    F = ad.offsets.shape[0]
    return offset_curve(ad.t_start, tc, frac * miss, F, kind=kind, release=release)


def _step(blended, effector, X, tc, ad, contacts, ch, opts, kind, release, max_root_shift):
    """The ``"step"`` level of a punch: the front foot steps towards the target, the root follows halfway.

    The foot nearer the target (horizontally, at frame 0) leaves the floor at frame 1 and
    lands ``STEP_S`` seconds later (before ``tc``), moved by twice the horizontal miss left
    by the lower levels (at most ``MAX_STEP`` x leg length), lifted ``STEP_LIFT`` x leg in
    between; the root moves by half the step over the same frames; the other foot stays
    pinned; then the root shift of :func:`strike` on top.  Its contacts are the clip's with
    the stepping foot's swing unplanted, so it lands on a new contact phase.  Returns
    ``(adaptation, side, contacts)`` of the best trial whose other foot still follows and
    that gets closer, else None.
    """
    F, fps = blended.n_frames, 1.0 / blended.frame_time
    leg = ch.leg_length
    t_land = min(max(2, round(STEP_S * fps)), tc - 1)
    if t_land < 2:
        return None
    g0 = blended.global_positions()[0]
    ank = [ch.index("left_ankle"), ch.index("right_ankle")]
    side = int(np.argmin([np.hypot(*(X - g0[a])[[0, 2]]) for a in ank]))
    miss = X - ad.hit_positions[tc]
    miss[1] = 0.0
    foot_tol = max(1e-3 * leg, ad.foot_error)
    n_rel = None if release is None else int(round(float(release) / blended.frame_time))
    best = None
    w = offset_curve(0, t_land, np.ones(3), F, kind=kind, release=None)[:, 0]  # 0 -> 1 over the step
    for scale in (1.0, 0.5):
        step = 2.0 * scale * miss
        n = float(np.linalg.norm(step))
        if n > MAX_STEP * leg:
            step *= MAX_STEP * leg / n
        feet_off = np.zeros((F, 2, 3))
        feet_off[:, side] = w[:, None] * step
        feet_off[1:t_land, side, 1] += STEP_LIFT * leg * np.sin(np.pi * w[1:t_land])
        root = 0.5 * w[:, None] * step
        c2 = np.array(contacts)
        c2[1:t_land, side] = False
        o = dict(options=opts, contacts=c2)
        trial = adapt(blended, effector, X, 0, tc, root_offsets=root, foot_offsets=feet_off, **o)
        trials = [trial]
        if not trial.reached:
            for frac in ROOT_SHIFT_TRIALS:
                extra = _root_shift(trial, frac, max_root_shift * leg, kind, n_rel)
                trials.append(adapt(blended, effector, X, 0, tc, root_offsets=root + extra, foot_offsets=feet_off,
                                    **o))
        for t in trials:
            if t.foot_error <= foot_tol and t.residual < (ad.residual if best is None else best[0].residual):
                best = (t, ("left", "right")[side], c2)
        if best is not None:
            break
    return best


def strike(source, character, current_motion: Motion, target, semantics: str, *, frame: str = "world", query=None,
           options: StrikeOptions | None = None, seed: int = 0, t_order: float | None = None) -> Strike:
    """Carry out an order: retrieve, convert, place and blend, solve (Sections 3.3-3.4; module docstring).

    Parameters
    ----------
    source : MotionRetriever or MotionDatabase
        A database is wrapped in a new retriever (k-means with ``seed``, a one-time cost).
    character : Skeleton or Motion
        The character (any humanoid joint tree: :func:`~repro.motion.retargeting.dispatch.retarget_to`).
    current_motion : Motion
        World frame, metres; its last frame is the current pose (pass the database's pose
        window so that ``q_r`` has it).
    target : (3,) array
        ``X``, metres: world (``frame="world"``) or the current pose's root frame (``"root"``: ``c``).
    semantics : {"punch", "kick"}
    query : Query, optional
        :meth:`MotionRetriever.prepare` of ``current_motion`` already made.
    options : StrikeOptions, optional
        How (the search, the blend, the reach, the edit); default ``StrikeOptions()``, the
        fighter's.  :data:`repro.motion.runtime.paper.PAPER` is the paper's.
    seed : int
    t_order : float, optional
        ``time.perf_counter()`` at the order (default: now).

    Raises
    ------
    repro.errors.RetrievalError
        Bad source, semantics, target or pose (from the retrieval).
    repro.errors.MotionError
        A target inside the body; a character without the clip's effector; bad options.
    """
    now = time.perf_counter()
    # every argument checked here, at the entry: a later level (the root shift, the step) never sees a bad one
    marks = {"order": now if t_order is None else as_real(t_order, "t_order (a time.perf_counter() value)",
                                                          error=MotionError, hi=now)}
    options, frame, semantics, seed = _checked_arguments(options, frame, semantics, seed, current_motion, query)
    retriever = _retriever_of(source, seed)
    db = retriever.db
    # a character of any tree: what the strike needs, named (an arm for a punch, a leg for a kick)
    ch = character_skeleton(character, {"punch": ("a punch",), "kick": ("a kick",)}.get(semantics, ()))
    # 1. the query: q_r, c in the root frame, Eq. 1 validated
    X, c, q = _order_in_root_frame(retriever, current_motion, ch, target, frame, query)
    marks["search"] = time.perf_counter()
    # 2. the search
    res = retriever.search(c, q, semantics=semantics, method=options.method)
    marks["load"] = time.perf_counter()
    # 3. load + convert; the contacts, once, on the retrieved clip
    effector = clip_effector(db, res.clip, ch)
    m = cut(db.motion(res.clip), res.start_frame, int(db.n_frames[res.clip]))
    contacts = _contacts_of(db, res.clip, res.start_frame, m)
    marks["retarget"] = time.perf_counter()
    mc = retarget_to(m, ch, fix_feet=options.fix_feet)
    marks["adapt"] = time.perf_counter()
    # 4. place on the current pose, blend with the current motion
    blended, tc = _place_and_blend(current_motion, mc, res, options.blend_s, db.fps)
    marks["solver"] = time.perf_counter()
    # 5. the constraints: the level decided on the contact frame, the next frame, the rest streamed
    edit = _Edit(blended, effector, X, tc, dataclasses.replace(options.adapt, hit_point=str(db.hit_wheres[res.clip])),
                 contacts)
    ad, level, tried = _solve(edit, options, ch, marks)
    p0 = ad.original_hit
    return Strike(
        kind=semantics, target=X, target_local=c, retrieval=res, effector=effector, motion=ad.motion,
        original=blended, adaptation=ad, tc=tc, hit_error=float(ad.residual), reached=bool(ad.reached),
        unadapted_error=float(np.linalg.norm(p0[tc] - X)),
        foot_slide=max_foot_slide(ad.motion, edit.contacts, skeleton=ch),
        timings=_timings(marks, ad.motion.n_frames), level=level, levels_tried=tried, contacts=edit.contacts,
        closest_error=float(np.linalg.norm(p0 - X, axis=1).min()),
        cost=adaptation_cost(blended, ad.motion, ch, frames=slice(1, None)),
    )


def _contacts_of(db: MotionDatabase, clip: int, start: int, m: Motion) -> np.ndarray:
    """:func:`~repro.motion.body.feet.foot_contacts` of ``m``, clip ``clip`` of ``db`` cut from ``start``
    (a copy): detected once per database, clip and start frame (a database does not change)."""
    per = _CONTACTS.get(db)
    if per is None:
        per = _CONTACTS[db] = {}
    c = per.get((clip, start))
    if c is None:
        if len(per) >= MAX_CACHED_CONTACTS:  # the oldest goes
            per.pop(next(iter(per)))
        c = per[(clip, start)] = foot_contacts(m)
    return c.copy()


def _checked_arguments(options, frame, semantics, seed, current_motion, query):
    """:func:`strike`'s arguments checked: ``(options, frame, semantics, seed)``."""
    if options is None:
        options = StrikeOptions()
    elif not isinstance(options, StrikeOptions):
        raise MotionError(f"options must be None or a StrikeOptions, got {describe(options)}")
    frame = as_choice(frame, "frame", ("world", "root"), error=MotionError)
    semantics = as_choice(semantics, "semantics", SEMANTICS, error=RetrievalError)
    seed = as_int(seed, "seed", 0, 2**63 - 1, error=MotionError)
    if not isinstance(current_motion, Motion):
        raise RetrievalError(f"current_motion must be a Motion (the character's current motion), got "
                             f"{describe(current_motion)}")
    if query is not None and not isinstance(query, Query):
        raise RetrievalError(f"query must be None or a Query (MotionRetriever.prepare), got {describe(query)}")
    return options, frame, semantics, seed


def _order_in_root_frame(retriever, current_motion, ch, target, frame, query):
    """Step 1: ``(X, c, q)``, the target in the world and in the current pose's root frame, and the query."""
    v = finite_vector3(target, "target (x, y, z) in metres", RetrievalError)
    q = retriever.prepare(current_motion, ch) if query is None else query
    if frame == "world":
        X, c = v, to_root_frame(v, q.heading, q.origin)
    else:
        c, X = v, from_root_frame(v, q.heading, q.origin)
    rescale_constraint(c, 1.0, q.size_c)
    _check_inside_body(X, c, ch)
    return X, c, q


def _place_and_blend(current_motion, mc, res, blend_s, fps):
    """Step 4: the converted clip placed on the current pose and blended with it; ``(blended, tc)``."""
    k = res.size_c / res.size_a
    placed = turn_and_move(mc, res.heading + res.rotation_y, rotate_y(k * res.translation, res.heading) + res.origin)
    tc = res.lead_frames
    nb = int(round(min(blend_s * fps, tc, placed.n_frames - 1)))  # a long blend_s stops at the contact
    return (blend_into(current_motion, placed, nb) if nb >= 1 else placed), tc


@dataclass(eq=False)
class _Edit:
    """Step 5's clip: what every reach level's :func:`adapt` call shares (the contacts change with a step)."""

    blended: Motion
    effector: str
    X: np.ndarray
    tc: int
    base: AdaptOptions
    contacts: np.ndarray

    def run(self, max_iter: int, *, root_offsets=None, frames=None, **changes) -> Adaptation | FrameSolve | None:
        """The whole clip solved (an :class:`Adaptation`), or with ``frames`` those frames only (a
        :class:`FrameSolve`: their poses and the contact, what is needed before the first frame)."""
        options = dataclasses.replace(self.base, max_iter=max_iter, **changes)
        if frames is not None:
            return adapt_frames(self.blended, self.effector, self.X, 0, self.tc, frames=frames, options=options,
                                contacts=self.contacts, root_offsets=root_offsets)
        return adapt(self.blended, self.effector, self.X, 0, self.tc, options=options, contacts=self.contacts,
                     root_offsets=root_offsets)


def _solve(edit: _Edit, options: StrikeOptions, ch: Skeleton, marks: dict) -> tuple[Adaptation, str, tuple]:
    """Step 5: the lowest reach level that hits, decided on ``tc``; ``(adaptation, level, levels tried)``.

    Every frame is solved on its own (the same pose alone or with the clip): the level is
    decided on ``tc``, the first frame after now is final, and the rest follows it.
    """
    reach, tc = options.reach, edit.tc
    first = sorted({min(1, edit.blended.n_frames - 1), tc})
    max_iter = 0 if reach == "limb" else 50
    # a root trial reads the support foot over the whole clip: exact on two frames when the feet
    # do not depend on the hit solve (a punch); a kick's trials are solved in full (CCD's pelvis)
    whole_body = reach in ("root", "step")
    limb = EFFECTOR_STEMS[edit.effector.split("_", 1)[1]]  # "arm" (punch) or "leg" (kick)
    part = options.stream and not (whole_body and limb == "leg")
    early = _early_frame(edit, first[0]) if options.stream and not part and first[0] > 0 else None
    ad = edit.run(max_iter, frames=first if part else None)
    tried = ["limb"] if reach == "limb" else ["limb", "spine"]
    off, final = None, (None if part else ad)
    if not ad.reached and whole_body:
        tried.append("root")
        ad, off, max_iter, final = _root_level(edit, ad, final, part, first, max_iter, options, ch.leg_length)
    stepped = None
    if not ad.reached and reach == "step" and limb == "arm":
        tried.append("step")
        ad, final, stepped = _step_level(edit, ad, final, off, max_iter, options, ch)
    marks["level"] = marks["first_frame"] = time.perf_counter()
    if final is None:  # the rest of the clip, at the level decided
        final = edit.run(max_iter, root_offsets=off)
    marks["end"] = time.perf_counter()
    # the early frame counts only as the played one (checked: the same numbers)
    f1 = first[0]
    if early is not None and np.array_equal(early[0], final.motion.rotations[f1]) and \
            np.array_equal(early[1], final.motion.positions[f1]):
        marks["first_frame"] = early[2]
    return final, _level_of(final, tried, stepped, reach), tuple(tried)


def _early_frame(edit: _Edit, f1: int):
    """A kick solved whole: up to the kicking foot's lift-off ``t_start``, ``d(t) = 0`` and the root
    shift is 0 at every level, so frame ``t0 + 1`` (feet only) is final before the level is decided."""
    a1 = edit.run(0, frames=[f1])
    if f1 <= a1.t_start:
        return a1.rotations[0], a1.positions[0], time.perf_counter()
    return None


def _root_level(edit: _Edit, ad: Adaptation, final, part: bool, first, max_iter: int, options: StrikeOptions,
                leg: float):
    """The ``"root"`` level: ``(adaptation, root offsets, max_iter, final)`` of the first root-shift trial
    that the support leg follows and that gets closer, else the level below unchanged."""
    if part and not ad.feet_independent:
        part = False
        ad = final = edit.run(max_iter)
    release = edit.base.release
    n_rel = None if release is None else int(round(float(release) / edit.blended.frame_time))
    foot_tol = 1e-3 * leg
    for frac in ROOT_SHIFT_TRIALS:  # the support leg must still reach its pinned foot
        shift = _root_shift(ad, frac, options.max_root_shift * leg, edit.base.kind, n_rel)
        foot_max = max(foot_tol, ad.foot_error)
        # max_foot_error: a trial whose support foot fails stops before its hit solve when it can (None)
        ad2 = edit.run(ROOT_MAX_ITER, root_offsets=shift, frames=first if part else None,
                       max_foot_error=foot_max if options.early_stop else None)
        if ad2 is not None and ad2.foot_error <= foot_max and ad2.residual < ad.residual:
            return ad2, shift, ROOT_MAX_ITER, (None if part else ad2)
    return ad, None, max_iter, final


def _step_level(edit: _Edit, ad: Adaptation, final, off, max_iter: int, options: StrikeOptions, ch: Skeleton):
    """The ``"step"`` level of a punch (:func:`_step`), from the whole clip at the level reached so far:
    ``(adaptation, final, stepping side or None)``; a step changes the contacts."""
    if final is None:
        ad = final = edit.run(max_iter, root_offsets=off)
    base = edit.base
    best = _step(edit.blended, edit.effector, edit.X, edit.tc, ad, edit.contacts, ch,
                 dataclasses.replace(base, max_iter=ROOT_MAX_ITER), base.kind, base.release, options.max_root_shift)
    if best is None:
        return ad, final, None
    edit.contacts = best[2]
    return best[0], best[0], best[1]


def _level_of(ad: Adaptation, tried: list, stepped, reach: str) -> str:
    """The reach level the contact frame needed (for an unreachable target, the highest tried)."""
    if not ad.reached or reach == "limb":
        return tried[-1]
    if stepped is not None:
        return "step"
    if ad.root_offsets is not None and np.any(ad.root_offsets[ad.tc] != 0):
        return "root"
    return "spine" if ad.solver[ad.tc] == "ccd" else "limb"


def _timings(marks: dict, n_frames: int) -> dict:
    """:attr:`Strike.timings` from the marks of :func:`strike` (``time.perf_counter()`` values)."""
    t = {
        "prepare": marks["search"] - marks["order"],
        "search": marks["load"] - marks["search"],
        "load_convert": marks["adapt"] - marks["load"],
        "retarget": marks["adapt"] - marks["retarget"],
        "adapt": marks["end"] - marks["adapt"],
        "solver": marks["end"] - marks["solver"],
        "first_frame": marks["first_frame"] - marks["order"],
        "level": marks["level"] - marks["order"],
        "rest": marks["end"] - marks["first_frame"],
        "order": marks["end"] - marks["order"],
    }
    t["adapt_per_frame"] = t["adapt"] / n_frames
    t["retarget_adapt_per_frame"] = (t["retarget"] + t["adapt"]) / n_frames
    return t


def reach_by_distance(distances, reached, levels, bins=5) -> list[dict]:
    """Whole-body reach per target distance: reached fraction and the level each target needed.

    ``distances`` (n,) metres, ``reached`` (n,) bool, ``levels`` (n,) str of :data:`REACH_LEVELS`
    (:attr:`Strike.level`, one per strike); ``bins`` an int (equal-count bins) or the bin
    edges.  One dict per non-empty bin: ``distance_min_m``, ``distance_max_m``, ``n``,
    ``reached_fraction``, and ``limb_fraction`` / ``spine_fraction`` / ``root_fraction`` /
    ``step_fraction``: the fraction of the bin's targets reached at that level (they add up to
    ``reached_fraction``), ``unreached_fraction``.
    """
    d = as_real_array(distances, "distances (metres)", error=MotionError).reshape(-1)
    try:
        ok, lv = np.asarray(reached), np.asarray(levels)
    except (TypeError, ValueError) as e:
        raise MotionError(f"reached and levels must be 1-D arrays (bool, str): {e}") from None
    if ok.dtype.kind != "b" and ok.size:
        raise MotionError(f"reached must hold booleans, got dtype {ok.dtype}")
    if lv.dtype.kind not in "UO" and lv.size:
        raise MotionError(f"levels must hold level names ({list(REACH_LEVELS)}), got dtype {lv.dtype}")
    ok = ok.astype(bool).reshape(-1)
    lv = lv.astype(str).reshape(-1)
    if not (d.shape == ok.shape == lv.shape):
        raise MotionError("distances, reached and levels must be equal-length 1-D arrays of finite distances")
    bad = set(lv.tolist()) - set(REACH_LEVELS)
    if bad:
        raise MotionError(f"unknown levels {sorted(bad)}; expected {list(REACH_LEVELS)}")
    if d.size == 0:
        return []
    if isinstance(bins, (int, np.integer)) and not isinstance(bins, (bool, np.bool_)):
        bins = as_int(bins, "bins", 1, MAX_BINS, error=MotionError)
        edges = np.quantile(d, np.linspace(0.0, 1.0, bins + 1))
    else:
        edges = as_real_array(bins, "bins (an int or increasing bin edges)", error=MotionError, ndim=1)
        if edges.size < 2 or np.any(np.diff(edges) < 0):
            raise MotionError(f"bin edges must be at least 2 non-decreasing values, got {edges.size} values")
    which = np.clip(np.searchsorted(edges, d, side="right") - 1, 0, edges.size - 2)
    out = []
    for b in range(edges.size - 1):
        sel = which == b
        if not sel.any():
            continue
        row = {"distance_min_m": float(d[sel].min()), "distance_max_m": float(d[sel].max()), "n": int(sel.sum()),
               "reached_fraction": float(ok[sel].mean())}
        for name in REACH_LEVELS:
            row[f"{name}_fraction"] = float(np.mean(ok[sel] & (lv[sel] == name)))
        row["unreached_fraction"] = float(np.mean(~ok[sel]))
        out.append(row)
    return out
