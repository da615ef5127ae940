"""The interactive kung-fu fighter of Pronost et al., Sections 3.1-3.4 and 4, as one class.

"Interactive Animation of Virtual Characters: Application to Virtual Kung-fu Fighting".
The user walks and crouches in a 3 m x 3 m area while his head is tracked; "the virtual
fighter follows the displacement of the user to stay close to him" and "at any time, the
supervisor can ask the virtual character to kick or punch the user" (Abstract, Section
4).  On an order the fighter (Section 3.1, figure 2):

1. stores the head position as the target ("if the user moves, *target* is not
   refreshed so that he can avoid the fighter's attacks");
2. prepares the query (Section 3.3): the target in the character's root frame, Eq. 1
   (``c_r = c * size_a / size_c``) and ``q_r``, the current pose retargeted to the
   database's actor -- :meth:`MotionRetriever.prepare`;
3. searches the database -- :meth:`MotionRetriever.search` (cluster nearest to ``q_r``,
   bounding-box pruning, ``d = d_qr + d_cr``);
4. loads the selected clip and converts it: :meth:`MotionDatabase.motion` (from memory;
   the paper read a BVH file from disk), cut from the selected start frame, retargeted
   to the character with the morphology-independent representation
   (:func:`repro.motion.morphology.retarget`, Section 3.4.1);
5. adapts it (Section 3.4): places it where the retrieval's alignment says (rotation
   about the vertical and translation fitting the start pose onto the current pose,
   scaled from the actor to the character), blends it with the current pose over the
   first frames ("synchronizing and blending M_s with the current active motion"), then
   solves the hit constraint with ``d(t)``, limb IK and CCD and keeps planted feet in
   place (:func:`repro.motion.adaptation.adapt`).

:class:`KungFuFighter` does this in :meth:`KungFuFighter.order` and measures every stage
with :func:`time.perf_counter` (a :class:`Strike` holds the result and the timings);
:meth:`KungFuFighter.follow` is the behaviour between orders; :func:`simulated_user`
replaces the tracked head by a deterministic trajectory.

Choices the paper leaves open (all documented, all parameters)
--------------------------------------------------------------
* **Frames.** World: y up, metres, floor y = 0; the user's area is ``x, z`` in
  ``[-1.5, 1.5]`` (:data:`AREA`).  The fighter has a position on the floor and a
  *facing* (the direction of its opponent, heading ``h``: direction ``(sin h, 0, cos
  h)``).  For the synthetic database the facing is the clip world's +z, where every
  synthetic clip hits (the hips of a fighting stance are turned ~25 degrees from it);
  for another database it is the direction of the stance clip's hit in its root frame.
* **Current motion.** Between orders the fighter loops an idle fighting stance
  retargeted to the character: the synthetic ``"stance"`` clip
  (:func:`repro.motion.synthetic.synthetic_clip`, at the database rate) when the
  database actor has the synthetic joint names, otherwise the first frame of a
  database clip held still.  The current pose is the stance frame at the fighter's
  clock, placed at its position and facing.
* **Striking distance.** :attr:`KungFuFighter.striking_distance`: the median forward
  distance of the database's punch hits (high and middle targets) from the actor's
  feet, per metre of actor size, times the character's size (0.47 x size on the
  synthetic database: 0.83 m for a 1.75 m fighter).  Punches are the shorter strikes;
  kicks are retrieved and adapted from there too.
* **Following** (:meth:`KungFuFighter.follow`): per tick the fighter turns towards the
  head (at most :data:`MAX_TURN_RATE` rad/s) and steps along the line to the head so
  that its horizontal distance becomes the striking distance (at most
  :data:`MAX_SPEED` m/s).  This is a kinematic root translation / rotation of the
  stance loop (no stepping animation; the paper does not describe one).
* **Blend.** The placed clip is blended into the current pose over
  :data:`BLEND_S` seconds (at most up to the contact frame): joint rotations by slerp,
  the root position by an offset that decays to 0 (smoothstep).  Frame 0 of the strike
  *is* the current pose, so the motion is continuous.
* **Contact.** ``t0`` = frame 0 (now), ``tc`` = the clip's hit frame minus the selected
  start frame (:attr:`RetrievalResult.lead_frames`).
* **After a strike** the fighter moves by the strike's root displacement (a punch lunges)
  and resumes its stance loop there, still facing the same way (no blend back: the
  synthetic clips end in the stance they started from).
* **Latency.** ``order -> first adapted frame`` is the sum of the stages: the adaptation
  is solved for the whole clip at once (vectorised over frames), so the first frame is
  available when all of them are.  The paper ran the search in a thread of its own
  while the animation went on; here every stage runs in the caller's thread, one after
  the other.

One-time cost (constructor, not an order): building / loading the database
(:func:`repro.motion.sources.default_database`, cached per process: ~3 s for the
synthetic one, ~1 s for CMU, on a 2-core machine), the :class:`MotionRetriever` (k-means
of the poses and the per-cluster indices: ~0.2 s), the character and its stance (~10
ms).  :attr:`KungFuFighter.setup_timings` has the measured values.

Errors: unknown order kinds, NaN / non-3-vector targets and targets outside the area
raise :class:`repro.errors.RetrievalError`; bad characters raise
:class:`repro.errors.MotionError`.  A target out of the fighter's reach is not an error:
the strike is the best effort with ``reached=False`` and the residual distance.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from repro.errors import MotionError, RetrievalError
from repro.motion.adaptation import Adaptation, adapt
from repro.motion.clustering import root_frames, rotate_y, to_root_frame
from repro.motion.annotation import SEMANTICS
from repro.motion.database import MotionDatabase
from repro.motion.ops import cut
from repro.motion.roles import effector_role
from repro.motion.morphology import retarget
from repro.motion.motion import Motion, finite_vector3
from repro.motion.paper import REACTION_BUDGET_S
from repro.motion.quaternion import quat_multiply, slerp
from repro.motion.retrieval import MotionRetriever, RetrievalResult
from repro.motion.skeleton import (
    Skeleton,
    rescale_constraint,
    scale_skeleton,
    skeleton_of,
)

__all__ = [
    "AREA",
    "BLEND_S",
    "MAX_SPEED",
    "MAX_TURN_RATE",
    "ORDER_KINDS",
    "STAGES",
    "character_from",
    "check_target",
    "simulated_user",
    "KungFuFighter",
    "Strike",
    "FollowStep",
]

#: The user's area (Section 1: "a real user that displaces in the VR system area (3m x
#: 3m area)"): ``(min, max)`` of x, y (height) and z, metres.  Targets outside raise.
AREA: tuple[tuple[float, float], tuple[float, float], tuple[float, float]] = ((-1.5, 1.5), (0.0, 2.5), (-1.5, 1.5))
#: Seconds over which a selected clip is blended into the current pose.
BLEND_S: float = 0.2
#: Largest following speed (m/s) and turning rate (rad/s) of :meth:`KungFuFighter.follow`.
MAX_SPEED: float = 2.0
MAX_TURN_RATE: float = math.radians(270.0)
#: The supervisor's orders (the database's semantics).
ORDER_KINDS: tuple[str, ...] = tuple(SEMANTICS)
#: Measured stages of an order, in :attr:`Strike.timings` (seconds).
STAGES: tuple[str, ...] = ("prepare", "search", "load_convert", "adapt", "first_frame")

# ------------------------------------------------------------------ characters
def character_from(height: float = 1.75, arm_scale: float = 1.0, leg_scale: float = 1.0, *, base=None) -> Skeleton:
    """A fighter's skeleton: ``base`` scaled to ``height`` metres with other arm / leg proportions.

    Parameters
    ----------
    height : float, default 1.75
        Straightened stature (:attr:`Skeleton.size`, the ``size_c`` of Eq. 1), metres.
    arm_scale, leg_scale : float, default 1
        Proportions of the arms (upper arm and forearm) and legs (thigh and shin)
        relative to the rest of the body, e.g. 0.75 to 1.25 for "±25%"
        (:func:`repro.motion.skeleton.scale_skeleton`).
    base : Skeleton or Motion, optional
        The skeleton to scale (default: the synthetic actor,
        :func:`repro.motion.synthetic.synthetic_skeleton`); it must have the joint tree
        of the database's actor for the retrieval.

    Raises
    ------
    repro.errors.MotionError
        Non-positive or non-finite height or factors.
    """
    if base is None:
        from repro.motion.synthetic import synthetic_skeleton

        base = synthetic_skeleton()
    return scale_skeleton(skeleton_of(base), height=height, arm_scale=arm_scale, leg_scale=leg_scale)


# ------------------------------------------------------------------ the user
def _smooth(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


def simulated_user(seed: int = 0, duration: float = 10.0, fps: float = 30.0, *, heights=(1.5, 1.8),
                   crouch_every: float = 4.0, crouch_depth=(0.25, 0.45), margin: float = 0.2) -> np.ndarray:
    """A deterministic head trajectory of a user wandering in the 3 m x 3 m area.

    The head moves between random waypoints (one every 1.5-3 s, each 0.3-1.2 m from the
    previous one in a random direction, kept in the area shrunk by ``margin``), with a
    smooth (C2) ease between them, so it walks at most 1.5 m/s; its standing height is
    drawn per waypoint in ``heights`` and eased the same way; crouches (the head drops by
    ``crouch_depth`` metres over 0.6-1.0 s and comes back up, a smooth bump) happen at
    random times, on average every ``crouch_every`` seconds.  Everything comes from
    ``numpy.random.default_rng(seed)``: equal arguments give equal arrays.

    Parameters
    ----------
    seed : int
    duration : float
        Seconds (> 0).
    fps : float
        Samples per second (> 0); the tracking cameras of the paper ran at 60 Hz.

    Returns
    -------
    (n, 3) array
        Head positions (x, y, z), metres, sample ``i`` at time ``i / fps``;
        ``n = floor(duration * fps) + 1``.  Always inside :data:`AREA`, heights in
        ``[heights[0] - crouch_depth[1], heights[1]]``.

    Raises
    ------
    repro.errors.MotionError
        Non-positive duration or fps, bad ranges.
    """
    for name, v in (("duration", duration), ("fps", fps), ("crouch_every", crouch_every)):
        if not (isinstance(v, (int, float, np.integer, np.floating)) and np.isfinite(v) and v > 0):
            raise MotionError(f"{name} must be a finite number > 0, got {v!r}")
    lo, hi = (float(v) for v in heights)
    dlo, dhi = (float(v) for v in crouch_depth)
    if not (0 < lo <= hi <= AREA[1][1]) or not (0 <= dlo <= dhi < lo):
        raise MotionError(f"bad heights {heights!r} or crouch_depth {crouch_depth!r}")
    (x0, x1), _, (z0, z1) = AREA
    m = float(margin)
    if not 0 <= m < (x1 - x0) / 2:
        raise MotionError(f"margin must be in [0, {(x1 - x0) / 2}), got {margin!r}")
    rng = np.random.default_rng(seed)
    n = int(math.floor(duration * fps + 1e-9)) + 1
    t = np.arange(n) / float(fps)
    # waypoints: times, positions, standing heights
    times = [0.0]
    while times[-1] <= duration:
        times.append(times[-1] + rng.uniform(1.5, 3.0))
    times = np.array(times)
    k = times.size
    wx, wz = np.empty(k), np.empty(k)
    wx[0], wz[0] = rng.uniform(x0 + m, x1 - m), rng.uniform(z0 + m, z1 - m)
    for i in range(1, k):  # a step of 0.3-1.2 m in a random direction, kept in the area
        r, a = rng.uniform(0.3, 1.2), rng.uniform(0.0, 2.0 * np.pi)
        wx[i] = np.clip(wx[i - 1] + r * np.cos(a), x0 + m, x1 - m)
        wz[i] = np.clip(wz[i - 1] + r * np.sin(a), z0 + m, z1 - m)
    wy = rng.uniform(lo, hi, k)
    seg = np.clip(np.searchsorted(times, t, side="right") - 1, 0, k - 2)
    u = _smooth((t - times[seg]) / (times[seg + 1] - times[seg]))
    x = wx[seg] + u * (wx[seg + 1] - wx[seg])
    z = wz[seg] + u * (wz[seg + 1] - wz[seg])
    y = wy[seg] + u * (wy[seg + 1] - wy[seg])
    # crouches: Poisson arrivals, each a smooth bump
    tc = rng.exponential(crouch_every)
    while tc < duration:
        length = rng.uniform(0.6, 1.0)
        depth = rng.uniform(dlo, dhi)
        v = (t - tc) / length
        bump = np.where((v > 0) & (v < 1), np.sin(np.pi * np.clip(v, 0, 1)) ** 2, 0.0)
        y = y - depth * bump
        tc += length + rng.exponential(crouch_every)
    y = np.maximum(y, lo - dhi)
    out = np.column_stack([np.clip(x, x0, x1), y, np.clip(z, z0, z1)])
    out.flags.writeable = False
    return out


# ------------------------------------------------------------------ helpers
def _qy(theta: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of the rotation about +y by ``theta`` (same as :func:`rotate_y`)."""
    return np.array([0.0, math.sin(theta / 2.0), 0.0, math.cos(theta / 2.0)])


def _transform(motion: Motion, theta: float, translation) -> Motion:
    """The motion rotated about the vertical axis through the world origin by ``theta``, then translated."""
    rot = np.array(motion.rotations)
    rot[:, 0] = quat_multiply(np.broadcast_to(_qy(theta), rot[:, 0].shape), rot[:, 0])
    pos = np.array(motion.positions)
    pos[:, 0] = rotate_y(pos[:, 0], theta) + np.asarray(translation, dtype=float)
    return dataclasses.replace(motion, rotations=rot, positions=pos)


def _frame(motion: Motion, f: int) -> Motion:
    return dataclasses.replace(motion, rotations=motion.rotations[f:f + 1], positions=motion.positions[f:f + 1])


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _effector(sk: Skeleton, hit_role: str, hit_joint: str) -> str:
    """The adaptation effector role whose joint is the clip's hit joint (``"right_ankle"`` for a heel kick)."""
    try:
        return effector_role(sk.roles, hit_role, hit_joint)
    except MotionError as exc:
        raise RetrievalError(str(exc)) from None


def check_target(target) -> np.ndarray:
    """A finite 3-vector inside :data:`AREA`, else :class:`RetrievalError`."""
    c = finite_vector3(target, "target (x, y, z) in metres", RetrievalError)
    for v, (a, b), name in zip(c, AREA, "xyz"):
        if not a - 1e-9 <= v <= b + 1e-9:
            raise RetrievalError(
                f"target {name} = {v:.4g} m is outside the user's area [{a:g}, {b:g}] m (3 m x 3 m, heights 0-{AREA[1][1]:g} m)")
    return c


# ------------------------------------------------------------------ results
@dataclass(frozen=True, eq=False)
class Strike:
    """One order carried out: what was retrieved, the adapted motion, how well it hits, how long it took.

    Attributes
    ----------
    kind : str
        ``"punch"`` or ``"kick"`` (the order).
    target : (3,) array
        The head position stored at the order (world, metres).
    target_local : (3,) array
        ``c``: the target in the root frame of the current pose (Section 3.3).
    retrieval : RetrievalResult
        The search's answer (clip, start frame, ``d``, ``d_qr``, ``d_cr``, ``c_r``,
        alignment, fallback).
    effector : str
        The hit point's role on the character (``"right_fist"``, ``"left_ankle"`` ...).
    motion : Motion
        The adapted motion on the character, world frame, at the database rate; frame 0
        is the current pose at the order.
    original : Motion
        The same before the constraint solver (placed, retargeted and blended).
    adaptation : Adaptation
        The solver's report (:func:`repro.motion.adaptation.adapt`).
    tc : int
        Contact frame of :attr:`motion`.
    hit_error : float
        Distance (m) between the hit point and the target at the contact.
    reached : bool
        ``hit_error`` within the solver's tolerance (1e-4 of the limb length).
    unadapted_error : float
        The same distance without the solver (how far the retrieved clip alone misses).
    foot_slide : float
        Largest horizontal slide (m) of a pinned (planted) foot during the strike.
    timings : dict
        Seconds (``time.perf_counter``): ``prepare`` (order -> search start: checks, the
        current pose, the target in its root frame, ``q_r`` = the pose retargeted to the
        actor(s); Eq. 1 itself, one multiplication per clip, runs inside the search
        call), ``search``, ``load_convert`` (clip from the
        database, cut, retargeted; of which ``retarget``), ``adapt`` (placement, blend,
        constraint solver), ``first_frame`` (order -> first adapted frame, the sum),
        ``adapt_per_frame`` and ``retarget_adapt_per_frame`` (per frame of
        :attr:`motion`, the paper's 88 µs), ``solver`` (:func:`adapt` alone).
    budget_s : float
        :data:`repro.motion.paper.REACTION_BUDGET_S`.
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
    budget_s: float = REACTION_BUDGET_S

    @property
    def clip_name(self) -> str:
        """Name of the retrieved clip."""
        return self.retrieval.name

    @property
    def semantics(self) -> str:
        """Semantics of the retrieved clip (the order's kind)."""
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

    def summary(self, timings: bool = True) -> dict:
        """Flat numbers for tables; ``timings=False`` keeps only the deterministic ones."""
        r = self.retrieval
        out = {
            "kind": self.kind, "clip": r.name, "start_frame": r.start_frame, "contact_frame": self.tc,
            "d": r.d, "d_qr": r.d_qr, "d_cr": r.d_cr, "fallback": r.fallback, "effector": self.effector,
            "unadapted_error_m": self.unadapted_error, "hit_error_m": self.hit_error, "reached": self.reached,
            "foot_slide_m": self.foot_slide, "frames": self.n_frames,
        }
        if timings:
            out.update({f"{k}_ms": v * 1e3 for k, v in self.timings.items()})
            out["within_budget"] = self.within_budget
        return out


@dataclass(frozen=True)
class FollowStep:
    """The fighter's state after :meth:`KungFuFighter.follow`: position (x, z), facing, distance to the head."""

    position: np.ndarray
    heading: float
    distance: float
    bearing_error: float  # radians between the facing and the direction of the head


# ------------------------------------------------------------------ the fighter
class KungFuFighter:
    """A virtual kung-fu fighter that follows a user's head and kicks or punches it on order.

    Parameters
    ----------
    database : "synthetic", "cmu" or MotionDatabase, default "synthetic"
        The motion database (names go through
        :func:`repro.motion.sources.default_database`, built once per process).
    character : Skeleton, optional
        The fighter (must share the database actor's joint tree); default
        :func:`character_from` of ``height``, ``arm_scale``, ``leg_scale`` on the
        database's actor.
    height, arm_scale, leg_scale : float
        Used when ``character`` is None.
    seed : int, default 0
        Seed of the stance clip and of the retriever's k-means.
    position : (x, z), default (0, -0.8)
        Start position on the floor (metres).
    heading : float, default 0
        Start facing (radians; 0 faces +z).
    retriever : MotionRetriever, optional
        A prepared retriever of ``database`` to share (its construction is the one-time
        cost); built here otherwise.

    Attributes
    ----------
    db : MotionDatabase
    retriever : MotionRetriever
    character : Skeleton
    stance : Motion
        The idle loop on the character, in the fighter's local frame.
    stance_source : str
        Where the stance comes from.
    striking_distance : float
        Horizontal distance (m) from the head that :meth:`follow` keeps.
    setup_timings : dict
        Seconds: ``database``, ``retriever``, ``character`` (one-time costs).
    time : float
        The fighter's clock (s); advances with :meth:`follow` and :meth:`advance`.
    strikes : list of Strike
        Every order carried out.
    """

    def __init__(self, database="synthetic", character: Skeleton | None = None, *, height: float = 1.75,
                 arm_scale: float = 1.0, leg_scale: float = 1.0, seed: int = 0, position=(0.0, -0.8),
                 heading: float = 0.0, retriever: MotionRetriever | None = None):
        from repro.motion.sources import default_database

        t0 = time.perf_counter()
        if isinstance(database, str):
            db = default_database(database)
        elif isinstance(database, MotionDatabase):
            db = database
        else:
            raise RetrievalError(f"database must be 'synthetic', 'cmu' or a MotionDatabase, got {type(database).__name__}")
        t1 = time.perf_counter()
        if retriever is not None:
            if not isinstance(retriever, MotionRetriever) or retriever.db is not db:
                raise RetrievalError("retriever must be a MotionRetriever of the same database")
            self.retriever = retriever
        else:
            self.retriever = MotionRetriever(db, seed=seed)
        t2 = time.perf_counter()
        self.db = db
        self.seed = int(seed)
        self._base = db.actors[0]
        self._make_stance()
        self.set_character(character if character is not None else
                           character_from(height, arm_scale, leg_scale, base=self._base))
        t3 = time.perf_counter()
        self.setup_timings = {"database": t1 - t0, "retriever": t2 - t1, "character": t3 - t2}
        self.position = np.zeros(2)
        self.heading = 0.0
        self.place(position, heading)
        self.time = 0.0
        self.strikes: list[Strike] = []

    # ------------------------------------------------------------- character
    def _make_stance(self) -> None:
        """The idle loop on the database actor, in a local frame: origin below the pelvis, +z = facing."""
        from repro.motion.synthetic import JOINT_NAMES, synthetic_clip

        db, base = self.db, self._base
        if list(base.joint_names) == list(JOINT_NAMES):
            m, _ = synthetic_clip("stance", "right", actor_height=1.75, seed=self.seed, fps=db.fps)
            m = retarget(m, base)
            g = m.global_positions()[:1]
            _, o = root_frames(g, base.index("pelvis"), base.index("left_hip"), base.index("right_hip"))
            # synthetic clips face their opponent along the clip world's +z
            self._stance_actor = _transform(m, 0.0, -o[0])
            self.stance_source = "synthetic stance clip"
        else:
            kinds = np.asarray(db.kinds)
            cand = np.flatnonzero((db.source_clip == np.arange(db.n_clips)) & (kinds == "lunge_punch"))
            i = int(cand[0]) if cand.size else 0
            m = db.motion(i)
            g = m.global_positions()[:1]
            th, o = root_frames(g, base.index("pelvis"), base.index("left_hip"), base.index("right_hip"))
            hx, _, hz = db.hit_position[i]
            facing = th[0] + math.atan2(hx, hz)  # the clip's hit direction, as the opponent's
            one = _frame(m, 0)
            still = dataclasses.replace(one, rotations=np.repeat(one.rotations, int(db.fps), axis=0),
                                        positions=np.repeat(one.positions, int(db.fps), axis=0))
            self._stance_actor = _transform(_transform(still, 0.0, -o[0]), -facing, np.zeros(3))
            self.stance_source = f"first frame of clip {db.names[i]}, held"

    def set_character(self, character: Skeleton) -> None:
        """Change the fighter's morphology (takes effect at once, as the paper's supervisor does)."""
        ch = skeleton_of(character)
        if not ch.is_compatible(self._base):
            raise MotionError("the character must have the joint tree of the database's actor (make it with character_from)")
        self.character = ch
        self.stance = retarget(self._stance_actor, ch)
        hp = self.db.hit_position
        punch = (self.db.semantics == "punch") & np.isin(self.db.levels, ["high", "middle"])
        sel = punch if punch.any() else (self.db.semantics == "punch")
        sel = sel if sel.any() else np.ones(self.db.n_clips, dtype=bool)
        frac = float(np.median(np.hypot(hp[sel, 0], hp[sel, 2]) / self.db.size_a[sel]))
        self.striking_distance = frac * ch.size

    # ------------------------------------------------------------- state
    def place(self, position, heading: float | None = None) -> None:
        """Put the fighter at ``position`` = (x, z) on the floor, facing ``heading`` (radians)."""
        p = np.asarray(position, dtype=float).reshape(-1)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise MotionError(f"position must be a finite (x, z) pair, got {position!r}")
        self.position = p.copy()
        if heading is not None:
            if not np.isfinite(heading):
                raise MotionError(f"heading must be finite, got {heading!r}")
            self.heading = _wrap(float(heading))

    @property
    def stance_frame(self) -> int:
        """Frame of the stance loop at the fighter's clock."""
        return int(math.floor(self.time * self.db.fps + 1e-9)) % self.stance.n_frames

    def current_pose(self, frames: int = 1) -> Motion:
        """The current pose (world frame, on the character): the last ``frames`` frames of the stance loop.

        One frame by default; :meth:`order` passes the database's pose window
        (``(window - 1) * step + 1`` frames) so that ``q_r`` has the same window as the
        database's poses.
        """
        F = self.stance.n_frames
        idx = (self.stance_frame - np.arange(int(frames) - 1, -1, -1)) % F
        m = dataclasses.replace(self.stance, rotations=self.stance.rotations[idx], positions=self.stance.positions[idx])
        return _transform(m, self.heading, np.array([self.position[0], 0.0, self.position[1]]))

    def advance(self, dt: float) -> None:
        """Advance the clock by ``dt`` seconds (the stance loop plays)."""
        if not (np.isfinite(dt) and dt >= 0):
            raise MotionError(f"dt must be a finite number >= 0, got {dt!r}")
        self.time += float(dt)

    def follow(self, head_position, dt: float = 1.0 / 30.0, *, snap: bool = False) -> FollowStep:
        """One tick of the behaviour between orders: stay at striking distance of the head, facing it.

        The fighter turns towards the head by at most ``MAX_TURN_RATE * dt`` and moves
        along the line to the head by at most ``MAX_SPEED * dt`` towards the point at
        :attr:`striking_distance` (``snap=True``: all the way at once).  Then the clock
        advances by ``dt``.

        Raises
        ------
        repro.errors.RetrievalError
            A head position that is not a finite 3-vector in the area.
        """
        head = check_target(head_position)
        if not (np.isfinite(dt) and dt >= 0):
            raise MotionError(f"dt must be a finite number >= 0, got {dt!r}")
        v = np.array([head[0], head[2]]) - self.position
        dist = float(np.hypot(*v))
        if dist > 1e-9:
            want = math.atan2(v[0], v[1])
            turn = _wrap(want - self.heading)
            if not snap:
                turn = float(np.clip(turn, -MAX_TURN_RATE * dt, MAX_TURN_RATE * dt))
            self.heading = _wrap(self.heading + turn)
            step = dist - self.striking_distance
            if not snap:
                step = float(np.clip(step, -MAX_SPEED * dt, MAX_SPEED * dt))
            self.position = self.position + step * v / dist
        self.advance(dt)
        v = np.array([head[0], head[2]]) - self.position
        d = float(np.hypot(*v))
        bearing = _wrap(math.atan2(v[0], v[1]) - self.heading) if d > 1e-9 else 0.0
        return FollowStep(position=self.position.copy(), heading=self.heading, distance=d, bearing_error=bearing)

    # ------------------------------------------------------------- orders
    def order(self, kind: str, target, *, commit: bool = True) -> Strike:
        """Carry out a supervisor's order: retrieve, convert, adapt; every stage timed.

        Parameters
        ----------
        kind : {"punch", "kick"}
        target : (3,) array
            The user's head (world, metres), stored now and not refreshed.
        commit : bool, default True
            Append the strike to :attr:`strikes`, move the fighter by the strike's root
            displacement and advance the clock by the strike's duration.

        Returns
        -------
        Strike

        Raises
        ------
        repro.errors.RetrievalError
            Unknown kind; a target that is not a finite 3-vector inside :data:`AREA`.
        """
        t_order = time.perf_counter()
        # ---- 1. order -> search start: the query (c in the root frame, Eq. 1, q_r)
        if kind not in ORDER_KINDS:
            raise RetrievalError(f"unknown order {kind!r}; the supervisor orders one of {list(ORDER_KINDS)}")
        X = check_target(target)
        pose = self.current_pose((self.db.window - 1) * self.db.step + 1)
        q = self.retriever.prepare(pose, self.character)
        pose = _frame(pose, pose.n_frames - 1)
        c = to_root_frame(X, q.heading, q.origin)
        rescale_constraint(c, 1.0, q.size_c)  # Eq. 1 per clip happens in the search; this validates c
        t_search = time.perf_counter()
        # ---- 2. search
        res = self.retriever.search(c, q, semantics=kind)
        t_load = time.perf_counter()
        # ---- 3. clip load + convert (retarget to the character)
        db = self.db
        m = cut(db.motion(res.clip), res.start_frame, int(db.n_frames[res.clip]))
        t_rt = time.perf_counter()
        mc = retarget(m, self.character)
        t_adapt = time.perf_counter()
        # ---- 4. adaptation: place, blend, solve
        k = res.size_c / res.size_a
        placed = _transform(mc, res.heading + res.rotation_y, rotate_y(k * res.translation, res.heading) + res.origin)
        tc = res.lead_frames
        blended = self._blend(pose, placed, tc)
        effector = _effector(self.character, res.hit_role, str(db.hit_joints[res.clip]))
        t_solver = time.perf_counter()
        ad = adapt(blended, effector, X, 0, tc, hit_point=str(db.hit_wheres[res.clip]))
        t_end = time.perf_counter()
        F = ad.motion.n_frames
        timings = {
            "prepare": t_search - t_order,
            "search": t_load - t_search,
            "load_convert": t_adapt - t_load,
            "retarget": t_adapt - t_rt,
            "adapt": t_end - t_adapt,
            "solver": t_end - t_solver,
            "first_frame": t_end - t_order,
        }
        timings["adapt_per_frame"] = timings["adapt"] / F
        timings["retarget_adapt_per_frame"] = (timings["retarget"] + timings["adapt"]) / F
        strike = Strike(
            kind=kind, target=X, target_local=c, retrieval=res, effector=effector, motion=ad.motion,
            original=blended, adaptation=ad, tc=tc, hit_error=float(ad.residual), reached=bool(ad.reached),
            unadapted_error=float(np.linalg.norm(ad.original_hit[tc] - X)),
            foot_slide=float(max(ad.foot_slide.values())), timings=timings)
        if commit:
            self._commit(strike)
        return strike

    def _blend(self, pose: Motion, placed: Motion, tc: int) -> Motion:
        """Blend the placed clip into the current pose over the first frames (frame 0 = the pose)."""
        F = placed.n_frames
        nb = max(1, min(int(round(BLEND_S * self.db.fps)), tc, F - 1))
        w = _smooth(np.arange(F) / nb)  # 0 at frame 0, 1 from frame nb
        r0 = np.broadcast_to(pose.rotations[0], placed.rotations.shape)
        rot = slerp(r0, placed.rotations, w[:, None, None])
        pos = np.array(placed.positions)
        pos[:, 0] += (1.0 - w)[:, None] * (pose.positions[0, 0] - placed.positions[0, 0])[None, :]
        return dataclasses.replace(placed, rotations=rot, positions=pos)

    def _commit(self, strike: Strike) -> None:
        sk = self.character
        g = strike.motion.global_positions()[[0, -1]]
        _, o = root_frames(g, sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip"))
        self.position = self.position + (o[1] - o[0])[[0, 2]]
        self.time += (strike.n_frames - 1) / self.db.fps
        self.strikes.append(strike)

    def kick(self, target, **kw) -> Strike:
        """``order("kick", target)``."""
        return self.order("kick", target, **kw)

    def punch(self, target, **kw) -> Strike:
        """``order("punch", target)``."""
        return self.order("punch", target, **kw)

    def __repr__(self) -> str:
        return (f"KungFuFighter({self.character.size:.2f} m, database of {self.db.n_clips} clips, "
                f"at ({self.position[0]:.2f}, {self.position[1]:.2f}), heading {math.degrees(self.heading):.0f} deg)")
