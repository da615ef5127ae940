"""Motion adaptation to a target: the constraints solver of Section 3.4.2.

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.4.2 ("Constraints solver"): a motion selected from the small
database rarely hits the target exactly, so it is edited, fast ("when the supervisor
provides an order, the system should react in less than 1/30s"), by a *frame-by-frame
solver driven by continuous constraints*:

    "In the selected motion M, the duration between the current frame t_0 and the one
    corresponding to the contact with the target t_c is known. At t_c, the constraint
    corresponds to the vector d(t_c) between M(t_c) and the actual target X. At t_0, this
    distance is d(t_0) = 0. In between, d(t) is an interpolation between d(t_0) and
    d(t_c). At any time t, we thus adapt the joint angles of the character in order to
    make the wrist or the foot reach the new position p(t) + d(t), where p(t) is the
    initial position without adaptation. However, in many cases, the constraint is not
    reachable by only using the corresponding limb. In that case, we use an iterative
    algorithm derived from the Cyclic Coordinate Descent method [21]. [...] If only the
    limb is involved, this method only requires 88 us."

This package implements that pipeline, one module per step:

* :mod:`.offset`, :func:`offset_curve` -- ``d(t)``: 0 up to ``t_0``, ``d(t_c)`` at ``t_c``, an easing
  curve (linear, smoothstep or smootherstep) in between, and after ``t_c`` either held or
  released back to 0 over a given number of frames (the paper does not say what happens
  after the contact; holding the offset forever would displace the whole rest of a long
  clip, so :func:`adapt` releases it by default).
* :mod:`.limb`, :func:`reach_limb` -- the limb step: analytic two-bone IK of the arm
  (shoulder-elbow-wrist) or leg (hip-knee-ankle), vectorised over frames.  The hand /
  foot keeps its world orientation, so the hit point (the fist = CMU ``rhand`` joint, the
  ball of the foot = ``rtoes``, or an End Site) keeps its offset from the wrist / ankle
  and the wrist goal is ``goal - (hit - wrist)``; the elbow / knee stays in the plane it
  had in the original pose (its *swivel* is parallel-transported from the original
  shoulder->wrist axis to the new one, the same construction as the swivel reference of
  :mod:`repro.motion.morphology`), and the shoulder and elbow rotations are changed by
  the smallest rotations that place the elbow and wrist (as
  :func:`repro.motion.morphology.decode` does), so the upper-arm twist is kept.  One
  frame is solved with a scalar (pure Python float) implementation, several at once with
  numpy; the two agree to rounding (tested).
* :mod:`.ccd_solver`, :func:`ccd` -- Cyclic Coordinate Descent (Welman 1993, the paper's [21]) over a longer
  chain, for frames where the limb alone cannot reach: by default elbow, shoulder,
  clavicle and the spine joints up to (not including) the pelvis for a punch, and knee,
  hip and pelvis for a kick (:func:`default_chain`).  Each sweep visits the chain from
  distal to proximal and turns each joint by the smallest rotation that points it at its
  goal.  "Derived from" CCD as in the paper: since the limb has an exact analytic solver,
  the joints *above* the limb do not aim the hit point at the target but the limb's root
  (shoulder / hip) at the nearest point from which the limb reaches the target (the
  objective is the distance of the target beyond the limb's reach), and the limb step
  then places the hit point exactly; this converges in a few sweeps where plain CCD
  creeps (measured on CMU 135_09, frame 303, fist moved 5 / 10 cm beyond the extended
  arm: 4 / 8 sweeps to 1e-11 m, against 48 / 65 sweeps of plain CCD to 5e-5 m).  ``finish_with_limb=False`` gives plain CCD on the hit point over the
  whole chain.  Joint limits: the elbow / knee is a hinge (rotation about its clip-wide
  bending axis only, flexion kept within ``hinge_range_deg``, 0 = straight: it bends one
  way and never hyperextends); every other joint stays within a cone of ``limits``
  degrees around its original local rotation (:data:`DEFAULT_LIMITS_DEG`).  A sweep that
  makes a frame worse is undone; a frame stops when its goal is reached, when it stalls
  (joint limits) or after ``max_iter`` sweeps, so CCD always terminates.  Vectorised over
  frames (the frames of a clip are solved together, each independently).
* :mod:`.adapt_clip`, :func:`adapt` -- the whole Section 3.4.2 edit of a clip: ``d(t)``, per frame the limb
  step and CCD where needed, then the feet: the actor's planted feet (contacts detected
  on the original motion by :func:`repro.motion.feet.foot_contacts`) are kept on
  the ground without sliding by a leg IK (the same two-bone solver) that pins each
  planted ankle, for every contact phase overlapping the edited frames, at its position
  at the start of the phase (or at ``t_0`` if the phase started earlier, so the frame
  ``t_0`` is unchanged), with the foot's original world orientation.  Returns an
  :class:`Adaptation` with the adapted motion (same skeleton; only local rotations
  change, so bone lengths are unchanged by construction -- and checked), per-frame hit
  errors and solver used, and summary numbers.

:mod:`.rig` holds what the solvers share (the per-motion :class:`~.rig.Rig` and its
effector :class:`~.rig.Chain`, argument checks); :mod:`.timing` the wall-clock measure
(:func:`time_adaptation`).  (The modules are not named ``ccd`` / ``adapt``: a submodule
named like the function it exports would be shadowed by it on the package.)

Targets beyond reach (even with CCD at its joint limits) are not an error: the result is
the best effort with ``reached=False`` and the residual distance.  Bad inputs (NaN
targets, unknown effectors, ``t_0 > t_c``, frames out of range, chains that are not on
the effector's path) raise :class:`repro.errors.MotionError`.

Effectors are roles of :func:`repro.motion.roles.find_roles`: ``{side}_fist``,
``{side}_hand``, ``{side}_wrist`` (arm) and ``{side}_foot``, ``{side}_toe``,
``{side}_ankle`` (leg), for ``side`` in ``left``/``right``.  All lengths are in the
motion's units (use :meth:`repro.motion.Motion.to_metres` for metres).

Two-bone IK is singular at full extension (the elbow angle changes infinitely fast with
the shoulder-wrist distance), which makes a limb pushed to its reach snap straight and
lock; :func:`adapt` therefore lets the limb step extend the limb only to
``max_extension`` (0.98) of its length (or the motion's own extension if larger) and
leaves the rest to CCD.

Limitations: CCD solutions are computed per frame independently (no temporal
filtering); they are continuous in the goal, but joint velocities can still increase
(measured on 135_09 with the fist moved 10 cm forward: at most ~9 degrees/frame more than
the original at 120 fps).  The root *position* is never moved, only rotations change:
a kick cannot gain reach by pushing the hips forward, so kick targets more than a few
centimetres beyond the extended leg are not reached (best effort).  Balance is not
considered; the swing foot is not checked against the floor; the contact frames of the
feet come from a threshold detector on the original motion.
"""

from repro.motion.adaptation.adapt_clip import Adaptation, adapt
from repro.motion.adaptation.ccd_solver import (
    DEFAULT_HINGE_RANGE_DEG,
    DEFAULT_LIMITS_DEG,
    CCDSolution,
    ccd,
    default_chain,
)
from repro.motion.adaptation.limb import LimbSolution, reach_limb
from repro.motion.adaptation.offset import offset_curve
from repro.motion.adaptation.rig import EFFECTOR_STEMS
from repro.motion.adaptation.timing import time_adaptation

__all__ = [
    "EFFECTOR_STEMS",
    "DEFAULT_LIMITS_DEG",
    "DEFAULT_HINGE_RANGE_DEG",
    "offset_curve",
    "reach_limb",
    "ccd",
    "adapt",
    "default_chain",
    "LimbSolution",
    "CCDSolution",
    "Adaptation",
    "time_adaptation",
]
