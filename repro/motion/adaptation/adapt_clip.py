"""The whole Section 3.4.2 edit of a clip: :func:`adapt` and its result :class:`Adaptation`."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from repro.errors import MotionError
from repro.motion.adaptation.ccd_solver import DEFAULT_HINGE_RANGE_DEG, ccd_spec, ccd_sweeps
from repro.motion.adaptation.limb import limb_dmax, solve_limb
from repro.motion.adaptation.offset import offset_curve
from repro.motion.adaptation.rig import check_extension, check_int, default_tol, rig_of, vec3
from repro.motion.kinematics import fk_arrays, qrot
from repro.motion.motion import Motion

__all__ = ["Adaptation", "adapt"]


@dataclass(frozen=True, eq=False)
class Adaptation:
    """Result of :func:`adapt` (Section 3.4.2).

    Attributes
    ----------
    motion : Motion
        The adapted motion: same skeleton, channels and root trajectory; only local
        rotations differ from the input.
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

    @property
    def error_at_tc(self) -> float:
        """Hit-point error at the contact frame (same as :attr:`residual`)."""
        return self.residual

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


def _phases(c: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate([[0], c.astype(int), [0]])
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def _bone_lengths(gp: np.ndarray, parents: np.ndarray) -> np.ndarray:
    return np.linalg.norm(gp[:, 1:] - gp[:, parents[1:]], axis=-1)


def adapt(
    motion: Motion,
    effector: str,
    target,
    t0: int,
    tc: int,
    *,
    kind: str = "smoothstep",
    release: float | None = 0.25,
    chain: Sequence[str] | None = None,
    limits: Mapping[str, float] | None = None,
    hinge_range_deg: tuple[float, float] = DEFAULT_HINGE_RANGE_DEG,
    max_iter: int = 50,
    tol: float | None = None,
    max_extension: float = 0.98,
    feet: str | None = "pin",
    foot_blend: float = 0.1,
    hit_point: str = "joint",
    roles=None,
) -> Adaptation:
    """Adapt a selected motion so that its hit point reaches a target at the contact (Section 3.4.2).

    Steps: ``d(t)`` = :func:`offset_curve` from ``t_start`` (``t0``, see below) to
    ``tc`` with ``d(tc) = X - p(tc)``; on every frame where ``d(t) != 0`` the hit point's
    goal is ``p(t) + d(t)``; the limb step (:func:`reach_limb`, all those frames at once)
    is tried first, and on the frames where the limb cannot reach, :func:`ccd` over the
    longer chain (then the limb step again).  Finally the feet (``feet="pin"``): each
    ankle other than the effector's that is planted in the original motion
    (:func:`repro.motion.morphology.foot_contacts`) in a contact phase overlapping the
    edited frames is pinned, for the whole phase from ``max(phase start, t0)``, at its
    position at that frame, by two-bone leg IK with the foot's original world
    orientation; after the phase the pin is released over ``foot_blend`` seconds.  A
    non-planted non-effector foot follows its original world trajectory where CCD moved
    the pelvis.  ``feet="track"`` keeps every non-effector ankle on its original world
    trajectory instead (the edit adds no slide but removes none of the actor's own);
    ``feet=None`` leaves the legs alone.

    On CCD frames the hand / foot keeps its original world orientation.  For a foot
    effector that is planted at some frames of ``[t0, tc)`` (a kick that has not left the
    ground yet), ``d(t)`` starts at its last planted frame (``t_start``), so the kicking
    foot does not slide before lift-off.  Pinned contact phases are pinned to their end,
    so frames after the edited stretch (``stop``) can change too (only the legs).

    Parameters
    ----------
    motion : Motion
        Any skeleton :func:`~repro.motion.skeleton.find_roles` understands; lengths in
        its units (use :meth:`~repro.motion.Motion.to_metres`).
    effector : str
        ``"right_fist"``, ``"left_foot"``, ... (:data:`EFFECTOR_STEMS`).
    target : (3,) array
        The target X, world coordinates, motion units.
    t0, tc : int
        Current frame and contact frame, ``0 <= t0 <= tc < F``.  Frames ``<= t0`` are
        never changed (continuity with what was already played), except the contact
        frame itself when ``t0 == tc`` (then the pose jumps).
    kind : str
        Easing of ``d(t)`` (:func:`offset_curve`).
    release : float or None
        Seconds after ``tc`` over which ``d`` returns to 0 (default 0.25 s); None holds
        it to the end of the clip.
    chain, limits, hinge_range_deg, max_iter
        CCD settings (:func:`ccd`).
    tol : float, optional
        Reach tolerance, motion units (default 1e-4 of the limb length).
    max_extension : float, default 0.98
        The limb step straightens the limb at most to this fraction of its length (or
        to the motion's own extension on that frame if larger); beyond, CCD moves the
        trunk.  Two-bone IK is singular at full extension: letting the limb take the
        last 2 % makes the elbow / knee snap straight over a frame or two (measured on
        CMU 135_09: ~50 degrees in 2 frames at 120 fps) and then stay locked.  Frames
        that stay out of reach after CCD get the full reach (best effort).  1 = the
        plain limb-first rule of the paper.
    feet : {"pin", "track", None}
    foot_blend : float
        Seconds over which a released foot pin blends back to the original trajectory.
    hit_point : {"joint", "end_site"}
    roles : mapping, optional

    Returns
    -------
    Adaptation

    Raises
    ------
    repro.errors.MotionError
        NaN / non-3-vector target, unknown effector, ``t0 > tc``, frames out of range,
        bad options.
    """
    t_total = time.perf_counter()
    rig = rig_of(motion, roles)
    ch = rig.chain(effector, hit_point)
    F = motion.n_frames
    X = vec3("target", target)
    t0 = check_int("t0", t0, 0, F - 1)
    tc = check_int("tc", tc, 0, F - 1)
    if t0 > tc:
        raise MotionError(f"t0={t0} is after the contact frame tc={tc}")
    if feet not in ("pin", "track", None):
        raise MotionError(f"feet must be 'pin', 'track' or None, got {feet!r}")
    if release is not None:
        release = float(release)
        if not np.isfinite(release) or release < 0:
            raise MotionError(f"release must be None or a finite number of seconds >= 0, got {release!r}")
        n_release = int(round(release / motion.frame_time))
    else:
        n_release = None
    foot_blend = float(foot_blend)
    if not np.isfinite(foot_blend) or foot_blend < 0:
        raise MotionError(f"foot_blend must be a finite number of seconds >= 0, got {foot_blend!r}")
    tol = default_tol(rig, ch) if tol is None else float(tol)
    if not np.isfinite(tol) or tol <= 0:
        raise MotionError(f"tol must be finite and > 0, got {tol!r}")
    ext = check_extension(max_extension)
    spec = ccd_spec(rig, ch, chain, limits, hinge_range_deg)
    max_iter = check_int("max_iter", max_iter, 0, 10**6)

    gq, gp = rig.globals
    p = gp[:, ch.hit] + qrot(gq[:, ch.hit], ch.hit_offset)
    contacts = rig.contacts
    side_i = {"left": 0, "right": 1}
    t_start = t0
    if ch.kind == "leg":
        planted = np.flatnonzero(contacts[t0:tc, side_i[ch.side]]) + t0
        if planted.size:
            t_start = int(planted.max())
    d = offset_curve(t_start, tc, X - p[tc], F, kind=kind, release=n_release)
    goals = p + d
    edit = np.flatnonzero(np.any(d != 0.0, axis=1))
    edit = edit[edit > t0] if tc > t0 else edit[edit >= t0]
    stop = int(edit.max()) + 1 if edit.size else t_start + 1

    rot = np.array(motion.rotations)
    solver = np.full(F, "", dtype="<U4")
    iters = np.zeros(F, dtype=np.intp)
    timings = {"limb": 0.0, "ccd": 0.0, "feet": 0.0}
    if edit.size:
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
                rig, ch, rb, tb, goals[fb], np.asarray(motion.rotations[fb]), spec, max_iter, tol, True, dmax[bad]
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

    # ------------------------------------------------------------- feet
    t1 = time.perf_counter()
    pinned = np.zeros((F, 2), dtype=bool)
    foot_err = 0.0
    anchors: list[tuple[int, int, int]] = []  # (side, first pinned frame, stop)
    n_feet = 0
    if feet is not None:
        n_blend = int(round(foot_blend / motion.frame_time))
        for side in ("left", "right"):
            if ch.kind == "leg" and side == ch.side:
                continue
            s = side_i[side]
            leg = rig.chain(f"{side}_ankle")
            ank = leg.dist
            anc = [int(j) for j in leg.path[: leg.k_prox]]  # root .. hip's parent
            orig = gp[:, ank]
            goal = orig.copy()
            w = np.zeros(F)
            need = np.zeros(F, dtype=bool)
            if feet == "pin":
                for a, b in _phases(contacts[:, s]):
                    if b <= t0 + 1 or a >= stop:
                        continue
                    a = max(a, t0)
                    anchors.append((s, a, b))
                    goal[a:b] = orig[a]
                    pinned[a:b, s] = True
                    w[a:b] = 1.0
                    delta = orig[a] - orig[b - 1]
                    for k in range(1, n_blend + 1):
                        f = b - 1 + k
                        if f >= F or pinned[f, s]:
                            break
                        wk = 1.0 - k / (n_blend + 1.0)
                        goal[f] = orig[f] + wk * delta
                        w[f] = max(w[f], wk)
                need |= w > 0
            moved = np.any(rot[:, anc] != np.asarray(motion.rotations)[:, anc], axis=(1, 2))
            need |= moved
            need[: t0 + 1] = False
            fr = np.flatnonzero(need)
            if fr.size:
                n_feet += fr.size
                rf = rot[fr]
                hit, res = solve_limb(leg, rf, rig.trans[fr], goal[fr], distal_world=gq[fr, ank])
                rot[fr] = rf
                foot_err = max(foot_err, float(res.max(initial=0.0)))
    timings["feet"] = time.perf_counter() - t1

    changed = np.any(rot != np.asarray(motion.rotations), axis=(1, 2))
    out = dataclasses.replace(motion, rotations=rot, source=motion.source)
    # the constructor re-normalises every quaternion, which can move unchanged frames by
    # one ulp; keep the input's exact values there (frames <= t0 are bit-identical)
    exact = np.where(changed[:, None, None], out.rotations, motion.rotations)
    exact.flags.writeable = False
    object.__setattr__(out, "rotations", exact)
    cf = np.flatnonzero(changed)
    gq2, gp2 = gq.copy(), gp.copy()  # forward kinematics only where the pose changed
    if cf.size:
        gq2[cf], gp2[cf] = fk_arrays(rig.levels, rot[cf], rig.trans[cf])
    hit_new = p.copy()
    hit_new[cf] = gp2[cf, ch.hit] + qrot(gq2[cf, ch.hit], ch.hit_offset)
    err = np.linalg.norm(hit_new - goals, axis=-1)
    bone_err = float(
        np.max(np.abs(_bone_lengths(gp2[cf], motion.parents) - _bone_lengths(gp[cf], motion.parents)), initial=0.0)
    )
    slide = {"left": 0.0, "right": 0.0}
    slide_o = {"left": 0.0, "right": 0.0}
    horiz = [0, 2]
    for s, a, b in anchors:
        side = ("left", "right")[s]
        ank = rig.sk.index(f"{side}_ankle")
        for g, dct in ((gp2, slide), (gp, slide_o)):
            dd = np.linalg.norm(g[a:b, ank][:, horiz] - g[a, ank][horiz], axis=-1).max()
            dct[side] = max(dct[side], float(dd))
    timings["total"] = time.perf_counter() - t_total
    timings.update(frames_limb=int(edit.size), frames_ccd=int(np.sum(solver == "ccd")), frames_feet=int(n_feet))
    return Adaptation(
        motion=out,
        effector=effector,
        hit_joint=rig.sk.joint_names[ch.hit],
        target=X,
        t0=t0,
        tc=tc,
        t_start=t_start,
        stop=stop,
        offsets=d,
        original_hit=p,
        goals=goals,
        hit_positions=hit_new,
        hit_error=err,
        solver=solver,
        ccd_iterations=iters,
        reached=bool(err[tc] <= tol),
        residual=float(err[tc]),
        foot_pinned=pinned,
        foot_slide=slide,
        foot_slide_original=slide_o,
        foot_error=foot_err,
        bone_length_error=bone_err,
        changed=changed,
        timings=timings,
        tol=tol,
    )
