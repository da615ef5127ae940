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
   (:func:`repro.motion.retargeting.morphology.retarget`, Section 3.4.1);
5. adapts it (Section 3.4): places it where the retrieval's alignment says (rotation
   about the vertical and translation fitting the start pose onto the current pose,
   scaled from the actor to the character), blends it with the current pose over the
   first frames ("synchronizing and blending M_s with the current active motion"), then
   solves the hit constraint with ``d(t)``, limb IK and CCD and keeps planted feet in
   place (:func:`repro.motion.adaptation.adapt`).

:class:`KungFuFighter` does this in :meth:`KungFuFighter.order` through the one pipeline,
:func:`repro.motion.runtime.strike.strike` (which also brings in the spine and a root shift when the
limb cannot reach, and measures every stage with :func:`time.perf_counter`; a
:class:`~repro.motion.runtime.strike.Strike` holds the result, the timings and the cost);
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
  (:func:`repro.motion.database.synthetic.synthetic_clip`, at the database rate) when the
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
  :data:`~repro.motion.runtime.options.BLEND_S` seconds (at most up to the contact frame): joint rotations by slerp,
  the root position by an offset that decays to 0 (smoothstep).  Frame 0 of the strike
  *is* the current pose, so the motion is continuous.
* **Contact.** ``t0`` = frame 0 (now), ``tc`` = the clip's hit frame minus the selected
  start frame (:attr:`RetrievalResult.lead_frames`).
* **After a strike** the fighter moves by the strike's root displacement (a punch lunges)
  and resumes its stance loop there, still facing the same way (no blend back: the
  synthetic clips end in the stance they started from).
* **Latency.** ``order -> first adapted frame`` is the stages up to frame ``t0 + 1``
  final: the reach level is decided on the contact frame and that frame solved, the rest
  of the clip after it (:func:`repro.motion.runtime.strike.strike`).  The paper ran the search in a thread of its own
  while the animation went on; here every stage runs in the caller's thread, one after
  the other.

One-time cost (constructor, not an order): building / loading the database
(:func:`repro.motion.database.sources.default_database`, cached per process: ~3 s for the
synthetic one, ~1 s for CMU, on a 2-core machine), the :class:`MotionRetriever` (k-means
of the poses and the per-cluster indices: ~0.2 s; with it the compiled kernels of the exact
search and of CCD, loaded from numba's cache, ~1 s, compiled on a fresh install, ~30 s), the
character and its stance (~10 ms).  :attr:`KungFuFighter.setup_timings` has the measured values.

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

from repro.checks import as_bool, as_int, as_real, as_real_array, check_alloc, describe
from repro.errors import MotionError, RetrievalError
from repro.motion.body.pose_frames import root_frames
from repro.motion.database.annotation import SEMANTICS
from repro.motion.database.clips import MotionDatabase
from repro.motion.retargeting.morphology import retarget
from repro.motion.core.motion import Motion, finite_vector3
from repro.motion.core.ops import ease
from repro.motion.retargeting.dispatch import character_skeleton, retarget_to
from repro.motion.search.retrieval import MotionRetriever
from repro.motion.body.units import y_up_metres
from repro.motion.body.skeleton import (
    Skeleton,
    scale_skeleton,
    skeleton_of,
)
from repro.motion.runtime.options import StrikeOptions
from repro.motion.runtime.strike import (
    STAGES,
    Strike,
    one_frame,
    strike,
    turn_and_move,
)

__all__ = [
    "AREA",
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
#: Largest following speed (m/s) and turning rate (rad/s) of :meth:`KungFuFighter.follow`.
MAX_SPEED: float = 2.0
MAX_TURN_RATE: float = math.radians(270.0)
#: The supervisor's orders (the database's semantics).
ORDER_KINDS: tuple[str, ...] = tuple(SEMANTICS)
#: Most frames :meth:`KungFuFighter.current_pose` returns (an order asks for the pose window, a few
#: dozen frames): an hour of the stance loop at 30 Hz, far beyond any window.
MAX_POSE_FRAMES: int = 108_000
#: Longest single clock step of :meth:`KungFuFighter.advance` / :meth:`~KungFuFighter.follow` (s): a day.
MAX_DT: float = 86_400.0
#: Longest :func:`simulated_user` trajectory (s) and highest rate (Hz).
MAX_DURATION: float = 86_400.0
MAX_FPS: float = 1_000.0

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
        (:func:`repro.motion.body.skeleton.scale_skeleton`).
    base : Skeleton or Motion, optional
        The skeleton to scale (default: the synthetic actor,
        :func:`repro.motion.database.synthetic.synthetic_skeleton`); it must have the joint tree
        of the database's actor for the retrieval.

    Raises
    ------
    repro.errors.MotionError
        Non-positive or non-finite height or factors.
    """
    if base is None:
        from repro.motion.database.synthetic import synthetic_skeleton

        base = synthetic_skeleton()
    if not isinstance(base, (Skeleton, Motion)):
        raise MotionError(f"base must be a Skeleton or a Motion, got {describe(base)}")
    return scale_skeleton(skeleton_of(base), height=height, arm_scale=arm_scale, leg_scale=leg_scale)


# ------------------------------------------------------------------ the user
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
    seed = as_int(seed, "seed", 0, 2**63 - 1, error=MotionError)
    duration = as_real(duration, "duration (seconds)", error=MotionError, lo=0.0, lo_open=True, hi=MAX_DURATION)
    fps = as_real(fps, "fps", error=MotionError, lo=0.0, lo_open=True, hi=MAX_FPS)
    crouch_every = as_real(crouch_every, "crouch_every (seconds)", error=MotionError, lo=0.0, lo_open=True)
    lo, hi = as_real_array(heights, "heights (lo, hi) in metres", error=MotionError, shape=(2,)).tolist()
    dlo, dhi = as_real_array(crouch_depth, "crouch_depth (lo, hi) in metres", error=MotionError, shape=(2,)).tolist()
    if not (0 < lo <= hi <= AREA[1][1]) or not (0 <= dlo <= dhi < lo):
        raise MotionError(f"bad heights {heights!r} or crouch_depth {crouch_depth!r}")
    (x0, x1), _, (z0, z1) = AREA
    m = as_real(margin, "margin (metres)", error=MotionError, lo=0.0, hi=(x1 - x0) / 2, hi_open=True)
    # about ten float arrays of n samples (t, segments, easing, x, y, z, bumps, the output)
    check_alloc(16 * 8 * (int(duration * fps) + 1), f"simulated_user(duration={duration:g}, fps={fps:g})",
                error=MotionError)
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
    u = ease((t - times[seg]) / (times[seg + 1] - times[seg]))
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
def _check_dt(dt) -> float:
    """A clock step: finite seconds in ``[0, MAX_DT]`` (a larger one would run the clock past float precision)."""
    return as_real(dt, "dt (seconds)", error=MotionError, lo=0.0, hi=MAX_DT)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def check_target(target) -> np.ndarray:
    """A finite 3-vector inside :data:`AREA`, else :class:`RetrievalError`."""
    c = finite_vector3(target, "target (x, y, z) in metres", RetrievalError)
    for v, (a, b), name in zip(c, AREA, "xyz"):
        if not a - 1e-9 <= v <= b + 1e-9:
            raise RetrievalError(
                f"target {name} = {v:.4g} m is outside the user's area [{a:g}, {b:g}] m (3 m x 3 m, heights 0-{AREA[1][1]:g} m)")
    return c


# ------------------------------------------------------------------ results
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
        :func:`repro.motion.database.sources.default_database`, built once per process).
    character : Skeleton or Motion, optional
        The fighter: the database actor's joint tree scaled (:func:`character_from`),
        or any humanoid skeleton of another joint tree (e.g. a BVH read with
        :func:`~repro.motion.read_bvh`: Mixamo, Bandai ...), which makes the retriever
        is played through the body-part roles; default :func:`character_from` of
        ``height``, ``arm_scale``, ``leg_scale`` on the database's actor.
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
        cost); built here otherwise.  Its ``across_trees`` decides which characters
        :meth:`set_character` accepts.
    options : StrikeOptions, optional
        How every order is carried out (:func:`~repro.motion.runtime.strike.strike`); default
        ``StrikeOptions()``: the exact optimum of Eq. 1's ``d``, the library's defaults
        (:data:`repro.motion.runtime.paper.PAPER`: the paper's pruned search).
    across_trees : bool, optional
        Build the retriever with ``across_trees`` (:class:`MotionRetriever`): characters of
        any joint tree, every clip a candidate for them.  Default: the retriever's (True);
        False keeps the fighter to characters of the database actors' trees.

    Attributes
    ----------
    options : StrikeOptions
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
        Seconds: ``database``, ``retriever`` (with compiling the exact search, once per process),
        ``character`` (one-time costs).
    time : float
        The fighter's clock (s); advances with :meth:`follow` and :meth:`advance`.
    strikes : list of Strike
        Every order carried out.
    """

    def __init__(self, database="synthetic", character: Skeleton | None = None, *, height: float = 1.75,
                 arm_scale: float = 1.0, leg_scale: float = 1.0, seed: int = 0, position=(0.0, -0.8),
                 heading: float = 0.0, retriever: MotionRetriever | None = None,
                 options: StrikeOptions | None = None, across_trees: bool | None = None):
        from repro.motion.database.sources import default_database

        t0 = time.perf_counter()
        # every argument checked before the (slow) database and retriever are built
        seed = as_int(seed, "seed", 0, 2**63 - 1, error=MotionError)
        if options is not None and not isinstance(options, StrikeOptions):
            raise MotionError(f"options must be None or a StrikeOptions, got {describe(options)}")
        #: how every order is carried out (the library's defaults: the exact optimum of Eq. 1's d)
        self.options = StrikeOptions() if options is None else options
        if across_trees is not None:
            across_trees = as_bool(across_trees, "across_trees", error=MotionError)
        if character is None:
            for name, v in (("height", height), ("arm_scale", arm_scale), ("leg_scale", leg_scale)):
                as_real(v, name, error=MotionError, lo=0.0, lo_open=True)
        position, heading = self._checked_place(position, heading)
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
            kw = {} if across_trees is None else {"across_trees": across_trees}
            self.retriever = MotionRetriever(db, seed=seed, **kw)
        t2 = time.perf_counter()
        self.db = db
        self.seed = seed
        tc = time.perf_counter()
        if self.options.method == "exact":
            from repro.motion.search.kernel import compile_search  # numba: imported when used

            compile_search()  # ready before the first order (compiling takes seconds on a fresh install)
        if self.options.adapt.compiled:
            from repro.motion.adaptation.ccd_kernel import compile_ccd  # numba: imported when used

            compile_ccd()  # CCD's sweeps, the same
        tc = time.perf_counter() - tc
        self._base = db.actors[0]
        self._make_stance()
        self.set_character(character if character is not None else
                           character_from(height, arm_scale, leg_scale, base=self._base))
        t3 = time.perf_counter()
        self.setup_timings = {"database": t1 - t0, "retriever": t2 - t1 + tc, "character": t3 - t2 - tc}
        self.position = np.zeros(2)
        self.heading = 0.0
        self.place(position, heading)
        self.time = 0.0
        self.strikes: list[Strike] = []
        self.playing: Strike | None = None
        self._play_end = 0.0

    # ------------------------------------------------------------- character
    def _make_stance(self) -> None:
        """The idle loop on the database actor, in a local frame: origin below the pelvis, +z = facing."""
        from repro.motion.database.synthetic import JOINT_NAMES, synthetic_clip

        db, base = self.db, self._base
        if list(base.joint_names) == list(JOINT_NAMES):
            m, _ = synthetic_clip("stance", "right", actor_height=1.75, seed=self.seed, fps=db.fps)
            m = retarget(m, base)
            g = m.global_positions()[:1]
            _, o = root_frames(g, base.index("pelvis"), base.index("left_hip"), base.index("right_hip"))
            # synthetic clips face their opponent along the clip world's +z
            self._stance_actor = turn_and_move(m, 0.0, -o[0])
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
            one = one_frame(m, 0)
            still = dataclasses.replace(one, rotations=np.repeat(one.rotations, int(db.fps), axis=0),
                                        positions=np.repeat(one.positions, int(db.fps), axis=0))
            self._stance_actor = turn_and_move(turn_and_move(still, 0.0, -o[0]), -facing, np.zeros(3))
            self.stance_source = f"first frame of clip {db.names[i]}, held"

    def set_character(self, character) -> None:
        """Change the fighter's morphology (takes effect at once, as the paper's supervisor does).

        ``character``: a Skeleton or a Motion; of the database actor's joint tree, or --
        with a retriever serving ``across_trees`` (the default) -- of any humanoid tree (its
        roles found from its structure, :func:`repro.motion.body.roles.find_roles`), in any unit
        and Y- or Z-up: converted to the fighter's Y-up metres first
        (:func:`repro.motion.body.units.y_up_metres`, a UnitWarning naming what was inferred).

        Raises
        ------
        repro.errors.MotionError
            Another joint tree on a single-tree retriever; a character without what a
            punch (an arm) or a kick (a leg) needs, named (:func:`repro.motion.body.roles.check_roles`).
        """
        ch = character_skeleton(character, ("a punch", "a kick"))
        if not ch.is_compatible(self._base) and not getattr(self.retriever, "across_trees", False):
            raise MotionError("the character must have the joint tree of the database's actor (make it with "
                              "character_from), or the fighter must be made with across_trees=True")
        conv = y_up_metres(character)  # any unit, Z-up: the fighter's world is Y-up, metres
        if conv is not character:
            ch = skeleton_of(conv, roles=dict(ch.roles))
        self.character = ch
        # another tree: its feet kept on the floor (another foot geometry may put the toes below it)
        self.stance = retarget_to(self._stance_actor, ch, fix_feet=not ch.is_compatible(self._stance_actor))
        hp = self.db.hit_position
        punch = (self.db.semantics == "punch") & np.isin(self.db.levels, ["high", "middle"])
        sel = punch if punch.any() else (self.db.semantics == "punch")
        sel = sel if sel.any() else np.ones(self.db.n_clips, dtype=bool)
        frac = float(np.median(np.hypot(hp[sel, 0], hp[sel, 2]) / self.db.size_a[sel]))
        self.striking_distance = frac * ch.size

    # ------------------------------------------------------------- state
    def place(self, position, heading: float | None = None) -> None:
        """Put the fighter at ``position`` = (x, z) on the floor, facing ``heading`` (radians)."""
        p, h = self._checked_place(position, heading)
        self.position = p
        if h is not None:
            self.heading = _wrap(h)

    @staticmethod
    def _checked_place(position, heading):
        try:
            p = as_real_array(position, "position (x, z) in metres", error=MotionError, shape=(2,))
        except MotionError as e:
            raise MotionError(f"position must be a finite (x, z) pair: {e}") from None
        if heading is not None:
            heading = as_real(heading, "heading (radians)", error=MotionError)
        return p.copy(), heading

    @property
    def stance_frame(self) -> int:
        """Frame of the stance loop at the fighter's clock."""
        return int(math.floor(self.time * self.db.fps + 1e-9)) % self.stance.n_frames

    def current_pose(self, frames: int = 1) -> Motion:
        """The current pose (world frame, on the character): the last ``frames`` frames of the stance loop.

        One frame by default; :meth:`order` passes the database's pose window
        (``(window - 1) * step + 1`` frames) so that ``q_r`` has the same window as the
        database's poses.  At most :data:`MAX_POSE_FRAMES` frames (and what they take within
        :data:`repro.checks.MEMORY_BUDGET`).
        """
        frames = as_int(frames, "frames", 1, MAX_POSE_FRAMES, error=MotionError)
        J = self.stance.n_joints
        # rotations (4) and positions (3) per joint and frame: the selection and turn_and_move's two copies
        check_alloc(3 * frames * J * 7 * 8, f"current_pose(frames={frames})", error=MotionError)
        F = self.stance.n_frames
        idx = (self.stance_frame - np.arange(frames - 1, -1, -1)) % F
        m = dataclasses.replace(self.stance, rotations=self.stance.rotations[idx], positions=self.stance.positions[idx])
        return turn_and_move(m, self.heading, np.array([self.position[0], 0.0, self.position[1]]))

    def advance(self, dt: float) -> None:
        """Advance the clock by ``dt`` seconds (the stance loop plays), ``0 <= dt <=`` :data:`MAX_DT`."""
        dt = _check_dt(dt)
        self.time += dt
        if self.playing is not None and self.time >= self._play_end - 1e-9:
            s, self.playing = self.playing, None
            self._finish(s)

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
        dt = _check_dt(dt)
        snap = as_bool(snap, "snap", error=MotionError)
        v = np.array([head[0], head[2]]) - self.position
        dist = float(np.hypot(*v))
        if dist > 1e-9 and self.playing is None:  # no following while a strike plays
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
    def order(self, kind: str, target, *, commit: bool | str = True) -> Strike:
        """Carry out a supervisor's order with :func:`repro.motion.runtime.strike.strike`; every stage timed.

        Parameters
        ----------
        kind : {"punch", "kick"}
        target : (3,) array
            The user's head (world, metres), stored now and not refreshed.
        commit : bool or "play", default True
            True: append the strike to :attr:`strikes`, move the fighter by the strike's
            root displacement and advance the clock by the strike's duration (played at
            once).  ``"play"``: the strike starts now and plays as the clock advances
            (:meth:`advance`, :meth:`follow`, which does not move the fighter meanwhile);
            it is recorded and the fighter moved when it ends.  False: nothing changes.

        A second order while a strike plays (``commit="play"``) is refused with
        :class:`repro.errors.MotionError`: the playing strike keeps its stored target
        (the paper does not refresh it) and is not interrupted.

        Returns
        -------
        Strike

        Raises
        ------
        repro.errors.RetrievalError
            Unknown kind; a target that is not a finite 3-vector inside :data:`AREA`.
        repro.errors.MotionError
            An order while a strike plays; a target inside the fighter's body.
        """
        if not (isinstance(commit, (bool, np.bool_)) or (isinstance(commit, str) and commit == "play")):
            raise MotionError(f"commit must be True, False or 'play', got {describe(commit)}")
        commit = commit if isinstance(commit, str) else bool(commit)
        t_order = time.perf_counter()
        if not isinstance(kind, str) or kind not in ORDER_KINDS:
            raise RetrievalError(f"unknown order {describe(kind)}; the supervisor orders one of {list(ORDER_KINDS)}")
        if self.playing is not None:
            p = self.playing
            raise MotionError(
                f"a {p.kind} is playing until t = {self._play_end:.3f} s (now {self.time:.3f} s): the order is refused; "
                "the playing strike keeps its stored target (the paper does not refresh it)")
        X = check_target(target)
        pose = self.current_pose((self.db.window - 1) * self.db.step + 1)
        s = strike(self.retriever, self.character, pose, X, kind, t_order=t_order, options=self.options)
        if commit == "play":
            self.playing = s
            self._play_end = self.time + (s.n_frames - 1) / self.db.fps
        elif commit:
            self._commit(s)
        return s

    def _commit(self, s: Strike) -> None:
        self.time += (s.n_frames - 1) / self.db.fps
        self._finish(s)

    def _finish(self, s: Strike) -> None:
        """The strike is over: move by its root displacement, record it."""
        sk = self.character
        g = s.motion.global_positions()[[0, -1]]
        _, o = root_frames(g, sk.index("pelvis"), sk.index("left_hip"), sk.index("right_hip"))
        self.position = self.position + (o[1] - o[0])[[0, 2]]
        self.strikes.append(s)

    def kick(self, target, *, commit: bool | str = True) -> Strike:
        """``order("kick", target, commit=commit)``."""
        return self.order("kick", target, commit=commit)

    def punch(self, target, *, commit: bool | str = True) -> Strike:
        """``order("punch", target, commit=commit)``."""
        return self.order("punch", target, commit=commit)

    def __repr__(self) -> str:
        return (f"KungFuFighter({self.character.size:.2f} m, database of {self.db.n_clips} clips, "
                f"at ({self.position[0]:.2f}, {self.position[1]:.2f}), heading {math.degrees(self.heading):.0f} deg)")
