"""The whole Section 3.4.2 edit of a clip: :func:`adapt` and its result :class:`Adaptation`.

``d(t)`` (:func:`~repro.motion.adaptation.offset.offset_curve`, eased by ``kind``) grows
from ``t_start`` to ``X - p(tc)`` at ``tc`` and is released over ``release`` seconds (None:
held).  ``t_start`` is ``t0``, or for a foot effector planted after ``t0`` its lift-off,
so a planted kicking foot does not slide; that foot is pinned up to its lift-off where
the phase began, and ``d(t)`` starts from that pin and eases it out by ``tc``, so the
foot does not jump when the pin lets go.  Every frame with ``d(t) != 0`` is solved for
the goal ``p(t) + d(t)`` by the limb step (:mod:`.limb`, at most ``max_extension`` of the
limb length: two-bone IK is singular at full extension), then, where the limb cannot
reach, by CCD (:mod:`.ccd_solver`) and the limb step again.

Feet: ``"pin"`` pins each other ankle planted in the original motion, for every contact
phase overlapping the edited frames, at its position at ``max(phase start, t0)`` (so
frame ``t0`` is unchanged), with the foot's original world orientation, released over
``foot_blend`` seconds; ``"plant"`` pins every contact phase after ``t0`` (also those
after the edited frames, and the kicking foot up to its lift-off); ``"track"`` keeps the
other ankles on their original trajectories; None leaves the legs alone.  ``floor``
keeps the whole foot (the ankle, the joints below it, their End Sites) at or above that
height on every frame after ``t0``: the other feet's goals are lifted (pinned or not), and
so is the kicking foot's hit goal where ``d(t)`` would drive it through the floor (a
target lower than the clip's kick); a current pose already below it is lifted out over
``foot_blend`` (:mod:`.foot_pins`).  The contacts come from the caller (detected once on
the retrieved clip) or from :func:`repro.motion.body.feet.foot_contacts` on ``motion``.

Whole-body reach: ``root_offsets`` adds a root translation before solving (the root
level of :func:`repro.motion.runtime.strike.strike`); ``p(t)`` and the foot anchors stay the
input's, so the support foot does not move with the root.  ``max_foot_error`` bounds
such a trial: when the feet do not depend on the hit solve (an arm whose chain leaves
both legs alone) they are solved first and a foot error above the bound returns None
before the hit solve; for a leg effector the feet are first solved on the frames CCD will
not touch and a foot error above the bound there returns None; the result is otherwise
the same.

Streaming: every frame is solved on its own (CCD leaves the frames it has finished
untouched), so ``frames=`` gives, on those frames, the poses of the whole-clip solve
(tested); the feet on the other frames are solved too when they do not depend on the
hit solve.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from repro.checks import as_int, as_real_array
from repro.errors import MotionError
from repro.motion.adaptation.ccd_solver import ccd_spec, ccd_sweeps
from repro.motion.adaptation.foot_pins import (
    feet_independent, floor_heights, floor_offset, foot_slides, liftoff_offset, solve_feet, start_frame)
from repro.motion.adaptation.limb import limb_dmax, solve_limb
from repro.motion.adaptation.offset import offset_curve
from repro.motion.adaptation.options import AdaptOptions
from repro.motion.adaptation.rig import Chain, Rig, check_frames, default_tol, rig_of, vec3
from repro.motion.core.kinematics import fk_arrays
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.core.motion import Motion

__all__ = ["Adaptation", "FrameSolve", "adapt", "adapt_frames"]


@dataclass(frozen=True, eq=False)
class Adaptation:
    """Result of :func:`adapt` (Section 3.4.2).

    Attributes
    ----------
    motion : Motion
        The adapted motion: same skeleton and channels; only local rotations differ from
        the input (and the root trajectory by ``root_offsets`` when given).
    effector, hit_joint : str
        Effector role and the joint name of its hit point.
    target : (3,) array
        The target X.
    t0, tc : int
        Current frame and contact frame.
    t_start : int
        Frame where ``d(t)`` starts growing: ``t0``, or for a foot effector planted after
        ``t0`` its last planted frame before ``tc`` (lift-off), so a planted kicking foot
        does not slide.
    stop : int
        First frame after the stretch where ``d(t) != 0`` (``tc + release + 1``, or F).
    offsets : (F, 3)
        ``d(t)`` (:func:`offset_curve`).
    original_hit, goals, hit_positions : (F, 3)
        ``p(t)``, ``p(t) + d(t)``, and the adapted hit point.
    hit_error : (F,)
        ``|hit_positions - goals|`` (0 on frames that were not edited).
    solver : (F,) str
        ``""`` (frame not edited for the hit), ``"limb"`` or ``"ccd"``.
    ccd_iterations : (F,) int
    reached : bool
        Whether the hit point is within ``tol`` of the target at ``tc``.
    residual : float
        ``hit_error[tc]``: distance to the target at the contact.
    foot_pinned : (F, 2) bool
        Frames where the left / right ankle was pinned (planted in the original motion,
        in a contact phase overlapping the edited frames).
    foot_slide, foot_slide_original : dict
        ``{"left": s, "right": s}``: per side, the largest horizontal distance of the
        ankle from its anchor (position at the start of the pinned part of the phase),
        over the pinned frames, in the adapted and in the original motion; 0 when the
        side was never pinned.
    foot_error : float
        Largest distance between a pinned ankle and its goal (0 unless out of reach).
    bone_length_error : float
        Largest change of a joint-to-parent distance over all frames (0 to rounding:
        only rotations change).
    changed : (F,) bool
        Frames whose pose differs from the input.
    timings : dict
        Wall-clock seconds of the steps (``limb``, ``ccd``, ``feet``, ``total``) and the
        frame counts ``frames_limb``, ``frames_ccd``, ``frames_feet``.
    tol : float
        The reach tolerance used.
    root_offsets : (F, 3) array or None
        The root translation added to the input (None: the root did not move).
    contacts : (F, 2) bool array or None
        The planted frames used.
    feet_independent : bool
        Whether the foot pass and the hit solve turn disjoint joints (an arm effector
        whose CCD chain leaves the legs alone): the feet are then exact on every frame
        even when the hit was solved on some ``frames`` only.
    """

    motion: Motion
    effector: str
    hit_joint: str
    target: np.ndarray
    t0: int
    tc: int
    t_start: int
    stop: int
    offsets: np.ndarray
    original_hit: np.ndarray
    goals: np.ndarray
    hit_positions: np.ndarray
    hit_error: np.ndarray
    solver: np.ndarray
    ccd_iterations: np.ndarray
    reached: bool
    residual: float
    foot_pinned: np.ndarray
    foot_slide: dict
    foot_slide_original: dict
    foot_error: float
    bone_length_error: float
    changed: np.ndarray
    timings: dict
    tol: float
    root_offsets: np.ndarray | None = None
    contacts: np.ndarray | None = None
    feet_independent: bool = False

    @property
    def error_at_tc(self) -> float:
        """Hit-point error at the contact frame (same as :attr:`residual`)."""
        return self.residual

    @property
    def contact_hit(self) -> np.ndarray:
        """(3,) the adapted hit point at the contact frame ``tc``."""
        return self.hit_positions[self.tc]

    def summary(self) -> dict:
        """Summary numbers (motion units, seconds) for reports."""
        w = slice(self.t_start + 1, self.stop)
        return {
            "reached": self.reached,
            "error_at_tc": self.residual,
            "max_hit_error": float(self.hit_error[w].max(initial=0.0)),
            "frames_limb": int(np.sum(self.solver == "limb")),
            "frames_ccd": int(np.sum(self.solver == "ccd")),
            "max_foot_slide": max(self.foot_slide.values()),
            "max_foot_slide_original": max(self.foot_slide_original.values()),
            "foot_error": self.foot_error,
            "bone_length_error": self.bone_length_error,
            "d_tc": float(np.linalg.norm(self.offsets[self.tc])),
            **{f"time_{k}": v for k, v in self.timings.items()},
        }


@dataclass(frozen=True, eq=False)
class FrameSolve:
    """Result of :func:`adapt_frames`: a streamed solve's frames, without the whole clip's result.

    What a runtime needs before it releases a frame (Section 3.4.2: every frame is solved on
    its own): the poses of the solved frames -- bit for bit those of :func:`adapt` with the same
    ``frames``, hence those of the whole-clip solve -- and what decides the reach level at the
    contact; no Motion is made and forward kinematics runs on the solved frames only.

    Attributes
    ----------
    frames : (n,) int
        The frames solved, increasing.
    rotations, positions : (n, J, 4), (n, J, 3)
        Their local rotations and position-channel values in the adapted motion.
    hit_positions : (n, 3)
        The adapted hit point on those frames.
    target : (3,) array
    tc, t_start : int
        As :class:`Adaptation`'s.
    offsets : (F, 3)
        ``d(t)`` over the whole clip.
    contact_hit : (3,)
        The adapted hit point at ``tc`` (the input's when ``tc`` is not among the frames).
    residual : float
        Distance of the hit point to the target at ``tc`` (NaN when ``tc`` was not solved).
    reached : bool
    foot_error : float
    feet_independent : bool
    tol : float
    """

    frames: np.ndarray
    rotations: np.ndarray
    positions: np.ndarray
    hit_positions: np.ndarray
    target: np.ndarray
    tc: int
    t_start: int
    offsets: np.ndarray
    contact_hit: np.ndarray
    residual: float
    reached: bool
    foot_error: float
    feet_independent: bool
    tol: float


def _bone_lengths(gp: np.ndarray, parents: np.ndarray) -> np.ndarray:
    return np.linalg.norm(gp[:, 1:] - gp[:, parents[1:]], axis=-1)


def adapt(
    motion: Motion,
    effector: str,
    target,
    t0: int,
    tc: int,
    *,
    options: AdaptOptions | None = None,
    roles=None,
    contacts=None,
    root_offsets=None,
    frames=None,
    foot_offsets=None,
) -> Adaptation | None:
    """Edit ``motion`` so that its hit point reaches ``target`` at frame ``tc`` (Section 3.4.2; module docstring).

    Contract: frames ``<= t0`` never change (but ``tc`` when ``t0 == tc``); only local
    rotations change (and the root by ``root_offsets``), so bone lengths are kept; every
    frame is solved on its own.  ``effector`` is a role (``right_fist``, ``left_foot``, ...);
    ``target`` and ``root_offsets`` (F, 3) are in the motion's units; ``options`` an
    :class:`~repro.motion.adaptation.options.AdaptOptions` (default: the library's);
    ``contacts`` (F, 2) bool planted frames (default: detected on ``motion``); ``frames``
    solve the hit on those frames only (a streamed solve); ``foot_offsets`` (F, 2, 3) moves
    the left / right ankle goals (a step; motion units).  Returns an :class:`Adaptation`
    (unreachable: best effort, ``reached=False``), or None when ``options.max_foot_error``
    is set and the support foot is known to miss it.  Raises
    :class:`repro.errors.MotionError` for a NaN / non-3-vector target, an unknown effector,
    ``t0 > tc``, frames out of range or bad options.
    """
    t_total = time.perf_counter()
    e = _edit_of(motion, effector, target, t0, tc, options, roles, contacts, foot_offsets)
    _shift_root(e, root_offsets)
    _offset_goals(e, frames)
    if not _solve(e):
        return None
    return _result(e, t_total)


def adapt_frames(motion: Motion, effector: str, target, t0: int, tc: int, *, frames, options: AdaptOptions | None = None,
                 roles=None, contacts=None, root_offsets=None, foot_offsets=None) -> FrameSolve | None:
    """:func:`adapt` solving the hit on ``frames`` only, returning those frames' poses (a :class:`FrameSolve`).

    The same solve as ``adapt(..., frames=frames)`` (same arguments, checks and errors; the
    feet too), without the result of the whole clip (the adapted Motion, forward kinematics of
    every changed frame, bone lengths, foot slides): what a streaming runtime needs before the
    first frame is released (:func:`repro.motion.runtime.strike.strike`).  None as :func:`adapt`.
    """
    if frames is None:
        raise MotionError("adapt_frames needs the frames to solve (adapt solves the whole clip)")
    e = _edit_of(motion, effector, target, t0, tc, options, roles, contacts, foot_offsets)
    _shift_root(e, root_offsets)
    _offset_goals(e, frames)
    if not _solve(e):
        return None
    return _frames_result(e)


def _frames_result(e: _Edit) -> FrameSolve:
    """:func:`adapt_frames`' result: :func:`_result`'s numbers on the solved frames (frame by frame the same arithmetic)."""
    f = np.flatnonzero(e.only)
    orig = np.asarray(e.motion.rotations)[f]
    rot = e.rot[f]
    changed = np.any(rot != orig, axis=(1, 2)) | e.shifted[f]
    unit = rot / np.linalg.norm(rot, axis=-1, keepdims=True)
    hit = e.p[f].copy()
    if changed.any():
        c = f[changed]
        gq, gp = fk_arrays(e.rig.levels, e.rot[c], e.rig.trans[c])
        hit[changed] = gp[:, e.ch.hit] + qrot(gq[:, e.ch.hit], e.ch.hit_offset)
    at = np.flatnonzero(f == e.tc)
    contact = hit[at[0]] if at.size else e.p[e.tc]
    # the row norm of _result's error (not the vector norm's dot product: the same rounding)
    residual = float(np.linalg.norm((contact - e.goals[e.tc])[None], axis=-1)[0]) if at.size else float("nan")
    return FrameSolve(
        frames=f, rotations=np.where(changed[:, None, None], unit, orig), positions=np.array(e.motion.positions[f]),
        hit_positions=hit, target=e.X, tc=e.tc, t_start=e.t_start, offsets=e.d, contact_hit=contact,
        residual=residual, reached=bool(residual <= e.tol), foot_error=e.foot_err, feet_independent=e.independent,
        tol=e.tol)


@dataclass(eq=False)
class _Edit:
    """One :func:`adapt` call: its checked inputs, then ``d(t)`` and the goals, then the solve's state."""

    o: AdaptOptions
    motion: Motion  # the motion solved: the input, its root moved by root_offsets
    rig: Rig
    ch: Chain
    effector: str
    X: np.ndarray
    t0: int
    tc: int
    contacts: np.ndarray
    foot_offsets: np.ndarray | None
    n_release: int | None
    tol: float
    spec: list
    p: np.ndarray  # the input's hit trajectory p(t)
    ref_gp: np.ndarray  # the input's joint positions: the feet's anchors
    shifted: np.ndarray | None = None
    off: np.ndarray | None = None
    t_start: int = 0
    d: np.ndarray | None = None
    goals: np.ndarray | None = None
    edit: np.ndarray | None = None
    stop: int = 0
    only: np.ndarray | None = None
    rot: np.ndarray | None = None
    solver: np.ndarray | None = None
    iters: np.ndarray | None = None
    timings: dict = dataclasses.field(default_factory=lambda: {"limb": 0.0, "ccd": 0.0, "feet": 0.0})
    pinned: np.ndarray | None = None
    anchors: list = dataclasses.field(default_factory=list)  # (side, first pinned frame, stop)
    foot_err: float = 0.0
    n_feet: int = 0
    independent: bool = False


def _edit_of(motion, effector, target, t0, tc, options, roles, contacts, foot_offsets) -> _Edit:
    """The checked arguments and the input's hit trajectory ``p(t)``."""
    o = AdaptOptions() if options is None else options
    if not isinstance(o, AdaptOptions):
        raise MotionError(f"options must be an AdaptOptions or None, got {type(o).__name__}")
    rig = rig_of(motion, roles)
    ch = rig.chain(effector, o.hit_point)
    F = motion.n_frames
    X = vec3("target", target)
    t0 = as_int(t0, "t0", 0, F - 1, error=MotionError)
    tc = as_int(tc, "tc", 0, F - 1, error=MotionError)
    if t0 > tc:
        raise MotionError(f"t0={t0} is after the contact frame tc={tc}")
    contacts = rig.contacts if contacts is None else _check_contacts(contacts, F)
    if foot_offsets is not None:
        foot_offsets = _check_offsets(foot_offsets, F, (F, 2, 3), "foot_offsets")
    n_release = _release_frames(o.release, motion.frame_time)
    tol = default_tol(rig, ch) if o.tol is None else o.tol
    spec = ccd_spec(rig, ch, o.chain, o.limits, o.hinge_range_deg)
    gq, gp = rig.globals
    p = gp[:, ch.hit] + qrot(gq[:, ch.hit], ch.hit_offset)
    return _Edit(o, motion, rig, ch, effector, X, t0, tc, contacts, foot_offsets, n_release, tol, spec, p, gp)


def _shift_root(e: _Edit, root_offsets) -> None:
    """The root moved by ``root_offsets`` after ``t0``: the motion solved; goals and foot anchors stay the input's."""
    F = e.motion.n_frames
    e.shifted = np.zeros(F, dtype=bool)
    if root_offsets is None:
        return
    off = _check_offsets(root_offsets, F, (F, 3), "root_offsets")
    e.shifted = np.any(off != 0.0, axis=1)
    e.shifted[: e.t0 + 1] = False
    off[~e.shifted] = 0.0
    pos = np.array(e.motion.positions)
    pos[:, 0] += off
    e.off = off
    e.motion = dataclasses.replace(e.motion, positions=pos)
    e.rig = e.rig.moved(e.motion)  # skeleton, roles and chains shared with the input's rig
    e.ch = e.rig.chain(e.effector, e.o.hit_point)


def _offset_goals(e: _Edit, frames) -> None:
    """``d(t)`` from ``t_start`` (the kicking foot's pin eased out with ``"plant"``), the goals, the frames to edit."""
    F = e.motion.n_frames
    e.t_start = start_frame(e.contacts, e.ch, e.t0, e.tc)
    e.d = offset_curve(e.t_start, e.tc, e.X - e.p[e.tc], F, kind=e.o.kind, release=e.n_release)
    floor = None
    if e.o.floor is not None and e.ch.kind == "leg":  # the kicking foot's floor
        n_blend = int(round(e.o.foot_blend / e.motion.frame_time))
        floor = floor_heights(e.rig, e.ch.side, e.ref_gp, e.t0, e.o.floor, n_blend)
    if e.o.feet == "plant":
        e.d += liftoff_offset(e.rig, e.ch, e.contacts, e.ref_gp, e.t0, e.t_start, e.tc, floor, e.o.kind)
    if floor is not None:  # a kicking foot is not driven below the floor
        on = np.any(e.d != 0.0, axis=1)
        on[: e.t0 + 1] = False
        e.d += floor_offset(e.rig, e.ch, e.ref_gp, e.p, e.p + e.d, on, floor)
    e.goals = e.p + e.d
    edit = np.flatnonzero(np.any(e.d != 0.0, axis=1))
    edit = edit[edit > e.t0] if e.tc > e.t0 else edit[edit >= e.t0]
    e.stop = int(edit.max()) + 1 if edit.size else e.t_start + 1
    if frames is not None:  # a streamed solve: these frames only (each frame is solved on its own)
        e.only = np.zeros(F, dtype=bool)
        e.only[check_frames(frames, F)[0]] = True
        edit = edit[e.only[edit]]
    e.edit = edit


def _feet_of(e: _Edit, rot: np.ndarray, pinned: np.ndarray, anchors: list, only) -> tuple[float, int]:
    return solve_feet(e.rig, e.ch, e.motion, rot, e.o.feet, e.o.foot_blend, e.t0, e.stop, pinned, anchors,
                       contacts=e.contacts, ref_gp=e.ref_gp, shifted=e.shifted, floor=e.o.floor,
                       t_start=e.t_start, only=only, foot_offsets=e.foot_offsets)


def _solve(e: _Edit) -> bool:
    """The hit solve and the feet (in ``e``); False when a bounded trial's support foot misses its bound.

    The feet go first when they cannot depend on the hit solve: the two passes then read and
    write disjoint joints, so the order does not change a number, and a bounded trial whose
    support foot no longer follows stops before the (costly) hit solve.
    """
    F = e.motion.n_frames
    e.rot = np.array(e.motion.rotations)
    e.solver = np.full(F, "", dtype="<U4")
    e.iters = np.zeros(F, dtype=np.intp)
    e.pinned = np.zeros((F, 2), dtype=bool)
    e.independent = feet_independent(e.rig, e.ch, e.spec)
    bounded = e.o.max_foot_error is not None and e.o.feet is not None
    feet_first = bounded and e.independent
    if feet_first:
        _solve_feet_timed(e)
        if e.foot_err > float(e.o.max_foot_error):
            return False
    elif bounded and e.edit.size and _leg_trial_fails(e):
        return False
    if e.edit.size:
        _solve_hit(e.rig, e.ch, e.motion, e.rot, e.edit, e.goals, e.spec, e.o.max_iter, e.tol, e.o.max_extension,
                   e.solver, e.iters, e.timings, e.o.compiled)
    if e.o.feet is not None and not feet_first:
        _solve_feet_timed(e)
    return True


def _solve_feet_timed(e: _Edit) -> None:
    t1 = time.perf_counter()
    e.foot_err, e.n_feet = _feet_of(e, e.rot, e.pinned, e.anchors, None if e.independent else e.only)
    e.timings["feet"] = time.perf_counter() - t1


def _leg_trial_fails(e: _Edit) -> bool:
    """A leg effector's bounded trial: whether its feet miss the bound on the frames CCD will not touch.

    CCD turns the pelvis, which moves the support leg, but only on the frames the limb step
    cannot reach; on every other frame the feet are independent of the hit solve, and a foot
    error above the bound there is one of the result.
    """
    F = e.motion.n_frames
    r = e.rot[e.edit].copy()
    trans = e.rig.trans[e.edit]
    _, res = solve_limb(e.ch, r, trans, e.goals[e.edit], dmax=limb_dmax(e.ch, r, trans, e.o.max_extension))
    safe = np.ones(F, dtype=bool)
    safe[e.edit[res > e.tol]] = False
    probe, _ = _feet_of(e, e.rot.copy(), np.zeros((F, 2), dtype=bool), [], safe)
    return probe > float(e.o.max_foot_error) * (1.0 + 1e-9)  # a margin far above any rounding


def _result(e: _Edit, t_total: float) -> Adaptation:
    """The adapted motion and its measures: forward kinematics only where the pose changed."""
    rig, ch, motion, rot = e.rig, e.ch, e.motion, e.rot
    gq, gp = rig.globals
    changed = np.any(rot != np.asarray(motion.rotations), axis=(1, 2)) | e.shifted
    out = _adapted_motion(motion, rot, changed)
    cf = np.flatnonzero(changed)
    gq2, gp2 = gq.copy(), gp.copy()
    if cf.size:
        gq2[cf], gp2[cf] = fk_arrays(rig.levels, rot[cf], rig.trans[cf])
    hit_new = e.p.copy()
    hit_new[cf] = gp2[cf, ch.hit] + qrot(gq2[cf, ch.hit], ch.hit_offset)
    err = np.linalg.norm(hit_new - e.goals, axis=-1)
    bone_err = float(
        np.max(np.abs(_bone_lengths(gp2[cf], motion.parents) - _bone_lengths(gp[cf], motion.parents)), initial=0.0)
    )
    slide, slide_o = foot_slides(rig, e.anchors, gp2, e.ref_gp)
    timings = e.timings
    timings["total"] = time.perf_counter() - t_total
    timings.update(frames_limb=int(e.edit.size), frames_ccd=int(np.sum(e.solver == "ccd")), frames_feet=int(e.n_feet))
    return Adaptation(
        motion=out,
        effector=e.effector,
        hit_joint=rig.sk.joint_names[ch.hit],
        target=e.X,
        t0=e.t0,
        tc=e.tc,
        t_start=e.t_start,
        stop=e.stop,
        offsets=e.d,
        original_hit=e.p,
        goals=e.goals,
        hit_positions=hit_new,
        hit_error=err,
        solver=e.solver,
        ccd_iterations=e.iters,
        reached=bool(err[e.tc] <= e.tol),
        residual=float(err[e.tc]),
        foot_pinned=e.pinned,
        foot_slide=slide,
        foot_slide_original=slide_o,
        foot_error=e.foot_err,
        bone_length_error=bone_err,
        changed=changed,
        timings=timings,
        tol=e.tol,
        root_offsets=None if e.off is None else np.where(e.shifted[:, None], e.off, 0.0),
        contacts=e.contacts,
        feet_independent=e.independent,
    )


def _release_frames(release: float | None, frame_time: float) -> int | None:
    if release is None:
        return None
    # a release longer than any clip is a release that never ends within it: bounded, not overflowed
    return int(round(min(release / frame_time, 2.0**62)))


def _solve_hit(rig, ch, motion, rot, edit, goals, spec, max_iter, tol, ext, solver, iters, timings,
               compiled: bool = True) -> None:
    """The limb step on the edited frames, then CCD and the limb again where it cannot reach (in place)."""
    gq = rig.globals[0]
    t1 = time.perf_counter()
    r = rot[edit]
    trans = rig.trans[edit]
    dmax = limb_dmax(ch, r, trans, ext)
    hit, res = solve_limb(ch, r, trans, goals[edit], dmax=dmax)
    timings["limb"] = time.perf_counter() - t1
    solver[edit] = "limb"
    bad = res > tol
    if bad.any():
        t1 = time.perf_counter()
        fb = edit[bad]
        rb = r[bad]
        tb = trans[bad]
        it, _ = ccd_sweeps(
            rig, ch, rb, tb, goals[fb], np.asarray(motion.rotations[fb]), spec, max_iter, tol, True, dmax[bad], compiled
        )
        dw = gq[fb, ch.dist]  # the hand / foot keeps its original world orientation
        _, res_b = solve_limb(ch, rb, tb, goals[fb], distal_world=dw, dmax=dmax[bad])
        far = res_b > tol
        if ext < 1.0 and far.any():  # best effort: full reach
            rf = rb[far]
            solve_limb(ch, rf, tb[far], goals[fb[far]], distal_world=dw[far])
            rb[far] = rf
        r[bad] = rb
        iters[fb] = it
        solver[fb] = "ccd"
        timings["ccd"] = time.perf_counter() - t1
    rot[edit] = r


def _check_contacts(contacts, F: int) -> np.ndarray:
    try:
        c = np.asarray(contacts)
    except (TypeError, ValueError):
        c = None
    if c is None or c.shape != (F, 2) or c.dtype != bool:
        raise MotionError(f"contacts must be an ({F}, 2) bool array of planted frames (left, right), "
                          f"got {getattr(c, 'shape', type(contacts).__name__)} {getattr(c, 'dtype', '')}")
    return c


def _check_offsets(offsets, F: int, shape: tuple, name: str) -> np.ndarray:
    try:  # strings, None, complex values refused (never a silently dropped imaginary part)
        o = np.array(as_real_array(offsets, name, error=MotionError, finite=False))
    except MotionError:
        o = None
    if o is None or o.shape != shape or not np.all(np.isfinite(o)):
        raise MotionError(f"{name} must be a finite {shape} array, got "
                          f"{getattr(o, 'shape', type(offsets).__name__)}")
    return o


def _adapted_motion(motion: Motion, rot: np.ndarray, changed: np.ndarray) -> Motion:
    # re-normalise the changed frames only: the constructor would move unchanged frames
    # by one ulp; they keep the input's exact values (frames <= t0 are bit-identical)
    out = np.array(motion.rotations)
    r = rot[changed]
    out[changed] = r / np.linalg.norm(r, axis=-1, keepdims=True)
    return motion.with_unit_rotations(out)


