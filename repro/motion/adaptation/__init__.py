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

This package implements that pipeline, one module per step (each module's docstring
tells its part of the method):

* :mod:`.offset`, :func:`offset_curve` -- ``d(t)``: 0 up to ``t_0``, ``d(t_c)`` at ``t_c``, an
  easing in between, then held or released (the paper does not say what happens after
  the contact; :func:`adapt` releases it by default);
* :mod:`.limb`, :func:`reach_limb` -- the limb step: analytic two-bone IK of the arm or leg,
  the hand / foot keeping its world orientation and the elbow / knee its swivel;
* :mod:`.ccd_solver`, :func:`ccd` -- CCD over a longer chain (spine, pelvis) within joint
  limits, for frames the limb alone cannot reach;
* :mod:`.adapt_clip`, :func:`adapt` -- the whole edit of a clip: ``d(t)``, per frame the limb
  step and CCD where needed, the feet kept planted; returns an :class:`Adaptation`;
* :mod:`.foot_pins` -- the other feet during the edit: pinned where planted, above the
  floor, their slide measured;
* :mod:`.cost` -- what an adaptation costs against the clip (rotation change, added
  acceleration, bone lengths, joint limits).

:mod:`.options` holds :func:`adapt`'s options (:class:`AdaptOptions`, the library's defaults);
:mod:`.rig` what the solvers share (the per-motion :class:`~.rig.Rig` and its effector
:class:`~.rig.Chain`, argument checks).  The solvers' wall-clock measure is
:func:`repro.bench.adaptation.time_adaptation`.  (The modules are not named ``ccd`` / ``adapt``: a submodule
named like the function it exports would be shadowed by it on the package.)

Targets beyond reach (even with CCD at its joint limits) are not an error: the result is
the best effort with ``reached=False`` and the residual distance.  Bad inputs (NaN
targets, unknown effectors, ``t_0 > t_c``, frames out of range, chains that are not on
the effector's path) raise :class:`repro.errors.MotionError`.

Effectors are roles of :func:`repro.motion.body.roles.find_roles`: ``{side}_fist``,
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
the original at 120 fps).  :func:`adapt` moves the root only by the ``root_offsets`` it
is given (the root level of :func:`repro.motion.runtime.strike.strike`).  Balance is not
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
from repro.motion.adaptation.options import AdaptOptions
from repro.motion.adaptation.rig import EFFECTOR_STEMS

__all__ = [
    "EFFECTOR_STEMS",
    "DEFAULT_LIMITS_DEG",
    "DEFAULT_HINGE_RANGE_DEG",
    "offset_curve",
    "reach_limb",
    "ccd",
    "adapt",
    "AdaptOptions",
    "default_chain",
    "LimbSolution",
    "CCDSolution",
    "Adaptation",
]
