"""Cyclic Coordinate Descent over a longer chain (Section 3.4.2, after Welman 1993, the paper's [21]): :func:`ccd`.

For frames where the limb alone cannot reach.  The default chain (:func:`default_chain`)
is elbow, shoulder, clavicle and the spine joints up to (not including) the pelvis for a
punch, and knee, hip and pelvis for a kick.  Each sweep visits the chain from distal to
proximal and turns each joint by the smallest rotation that points it at its goal.

"Derived from" CCD as in the paper: since the limb has an exact analytic solver
(:mod:`.limb`), the joints *above* the limb do not aim the hit point at the target but
the limb's root (shoulder / hip) at the nearest point from which the limb reaches the
target (the objective is the distance of the target beyond the limb's reach), and the
limb step then places the hit point exactly.  This converges in a few sweeps where plain
CCD creeps (measured on CMU 135_09, frame 303, fist moved 5 / 10 cm beyond the extended
arm: 4 / 8 sweeps to 1e-11 m, against 48 / 65 sweeps of plain CCD to 5e-5 m);
``finish_with_limb=False`` gives plain CCD on the hit point over the whole chain.  With
the finish, a sweep's forward kinematics stops at the limb's root, the only point it reads.

Joint limits: the elbow / knee is a hinge (rotation about its clip-wide bending axis only,
flexion within ``hinge_range_deg``, 0 = straight: it never hyperextends); every other
joint stays within a cone of ``limits`` degrees around its original local rotation
(:data:`DEFAULT_LIMITS_DEG`).  A sweep that makes a frame worse is undone; a frame stops
when its goal is reached, when a sweep gains less than 5 % of the remaining objective
(creeping along joint limits) or after ``max_iter`` sweeps.  Vectorised over frames, each
solved independently: a finished frame is left untouched, so a frame's solution does not
depend on the frames solved with it.  Solutions are per frame (no temporal filtering):
continuous in the goal, but joint velocities can increase.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from repro.checks import as_bool, as_int, as_real, as_real_array, describe
from repro.errors import MotionError
from repro.motion.adaptation.limb import limb_dmax, limb_lengths, solve_limb
from repro.motion.adaptation.rig import (
    Chain,
    Rig,
    check_extension,
    check_frames,
    check_targets,
    default_tol,
    rig_of,
    start_rotations,
)
from repro.motion.core.kinematics import chain_fk, chain_fk_from
from repro.motion.core.kinematics import dot, matvec, matvec_t
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import cross, matrix_to_quat, min_rotation, quat_multiply, quat_to_matrix, vector_norm
from repro.motion.core.quaternion import quat_conjugate as qinv

__all__ = [
    "DEFAULT_LIMITS_DEG",
    "DEFAULT_HINGE_RANGE_DEG",
    "CCDSolution",
    "default_chain",
    "chain_joints",
    "ccd_spec",
    "ccd_sweeps",
    "ccd",
    "cone_limits",
]

#: Default CCD joint limits: largest rotation (degrees) of a joint's local rotation away
#: from its original value, by kind of joint.  ``spine`` covers every joint between the
#: pelvis and the chest (chest included).
DEFAULT_LIMITS_DEG: dict[str, float] = {
    "shoulder": 100.0,
    "hip": 60.0,
    "clavicle": 20.0,
    "spine": 15.0,
    "pelvis": 25.0,
    "other": 15.0,
}

#: Default flexion range (degrees) of the elbow / knee hinge in :func:`ccd`; 0 is straight.
DEFAULT_HINGE_RANGE_DEG: tuple[float, float] = (0.0, 160.0)


@dataclass(frozen=True, eq=False)
class CCDSolution:
    """Result of :func:`ccd`.

    Attributes
    ----------
    frames, rotations, hit_positions, residual, reached
        As in :class:`LimbSolution`.
    iterations : (n,) int
        CCD sweeps used per frame (0 when the limb alone could reach).
    chain : list of str
        The joints CCD rotated, distal to proximal.
    """

    frames: np.ndarray
    rotations: np.ndarray
    hit_positions: np.ndarray
    residual: np.ndarray
    reached: np.ndarray
    iterations: np.ndarray
    chain: list = field(default_factory=list)


# ------------------------------------------------------------------------ CCD
def default_chain(motion: Motion, effector: str, *, include_pelvis: bool | None = None, roles=None) -> list[str]:
    """Default CCD chain of an effector, distal to proximal, as joint names.

    Arm: elbow, shoulder, clavicle, then every joint between the pelvis and the clavicle
    (CMU: ``rradius, rhumerus, rclavicle, thorax, upperback, lowerback``).  Leg: knee,
    hip, pelvis (CMU: ``rtibia, rfemur, root``; the fixed ``rhipjoint`` bone between them
    is skipped).  ``include_pelvis`` (default: False for arms, True for legs) adds or
    removes the pelvis: rotating it moves the other leg, which :func:`adapt` repairs with
    its foot step.  Joints without three rotation channels are skipped.
    """
    rig = rig_of(motion, roles)
    if include_pelvis is not None:
        include_pelvis = as_bool(include_pelvis, "include_pelvis", error=MotionError)
    return chain_joints(rig, rig.chain(effector), include_pelvis)


def chain_joints(rig: Rig, ch: Chain, include_pelvis: bool | None = None) -> list[str]:
    sk = rig.sk
    pelvis = sk.index("pelvis")
    if include_pelvis is None:
        include_pelvis = ch.kind == "leg"
    out = [ch.mid, ch.prox]
    anc = [int(j) for j in ch.path[: ch.k_prox][::-1]]  # prox's parent .. root
    if pelvis not in anc:
        raise MotionError("the pelvis is not an ancestor of the limb")
    if ch.kind == "arm":
        out += anc[: anc.index(pelvis)]
    if include_pelvis:
        out.append(pelvis)
    return [sk.joint_names[j] for j in out if rig.full_rotation[j]]


def _check_limits(rig: Rig, limits: Mapping[str, float] | None) -> dict[str, float]:
    """Validated limits in radians: defaults by kind, overridden by kind, role or joint name."""
    lim = {k: float(np.radians(v)) for k, v in DEFAULT_LIMITS_DEG.items()}
    if limits is None:
        return lim
    if not isinstance(limits, Mapping):
        raise MotionError(f"limits must be a mapping of joint / role / kind -> degrees, got {type(limits).__name__}")
    for k, v in limits.items():
        if k not in DEFAULT_LIMITS_DEG and k not in rig.sk.roles and k not in rig.sk.joint_names:
            raise MotionError(
                f"limits: {k!r} is neither a kind {sorted(DEFAULT_LIMITS_DEG)}, a role nor a joint name"
            )
        v = as_real(v, f"limit for {k!r} (degrees)", error=MotionError, lo=0.0, hi=180.0)
        lim[k] = float(np.radians(v))
    return lim


def _limit_of(rig: Rig, j: int, lim: dict[str, float]) -> float:
    """Cone limit (radians) of joint ``j``: by joint name, else role, else kind."""
    sk = rig.sk
    name = sk.joint_names[j]
    aliases = ("left_fist", "right_fist", "left_foot", "right_foot")
    roles = [r for r, n in sk.roles.items() if n == name and r not in aliases]
    for key in [name] + roles:
        if key in lim and key not in DEFAULT_LIMITS_DEG:
            return lim[key]
    for r in roles:
        stem = r.split("_", 1)[1] if r.startswith(("left_", "right_")) else r
        if stem in ("shoulder", "hip", "clavicle", "pelvis"):
            return lim[stem]
    if any(r in ("spine", "chest") for r in roles) or j in _spine_joints(rig):
        return lim["spine"]
    return lim["other"]


def _spine_joints(rig: Rig) -> set[int]:
    sk = rig.sk
    try:
        return set(sk.path("pelvis", "chest"))
    except MotionError:
        return set()


def ccd_spec(rig: Rig, ch: Chain, chain, limits, hinge_range_deg):
    sk = rig.sk
    if isinstance(chain, str):
        raise MotionError(f"chain must be a sequence of joint names or roles, got the string {chain!r}")
    if chain is not None and (not isinstance(chain, (list, tuple, np.ndarray)) or getattr(chain, "ndim", 1) != 1
                              or not all(isinstance(n, (str, np.str_)) for n in chain)):
        raise MotionError(f"chain must be a sequence of joint names or roles, got {describe(chain)}")
    names = chain_joints(rig, ch) if chain is None else [str(n) for n in chain]
    if not names:
        raise MotionError("the CCD chain is empty")
    pl = [int(j) for j in ch.path]
    lim = _check_limits(rig, limits)
    spec = []
    h = as_real_array(hinge_range_deg, "hinge_range_deg (lo, hi) in degrees", error=MotionError, shape=(2,))
    lo, hi = (float(np.radians(x)) for x in h)
    if not lo < hi:
        raise MotionError(f"hinge_range_deg must be two finite numbers lo < hi, got {hinge_range_deg!r}")
    for nm in names:
        try:
            j = sk.index(nm)
        except MotionError:
            raise MotionError(f"CCD chain: no joint or role {nm!r}") from None
        if j not in pl[: ch.k_dist]:
            raise MotionError(
                f"CCD chain: {sk.joint_names[j]!r} is not an ancestor of the {ch.effector} above the "
                f"{'wrist' if ch.kind == 'arm' else 'ankle'} (path: {[sk.joint_names[i] for i in pl]})"
            )
        if not rig.full_rotation[j]:
            raise MotionError(f"CCD chain: {sk.joint_names[j]!r} has no 3-axis rotation channels")
        k = pl.index(j)
        if j == ch.mid:
            spec.append((k, "hinge", (lo, hi)))
        else:
            spec.append((k, "ball", _limit_of(rig, j, lim)))
    if len({k for k, _, _ in spec}) != len(spec):
        raise MotionError("CCD chain lists a joint twice")
    spec.sort(key=lambda s: -s[0])  # distal first
    return spec


def _distal_world(ch: Chain, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(n, 4) world orientation of the limb's distal joint in the pose ``rot``."""
    P = ch.path[: ch.k_dist + 1]
    rw, _ = chain_fk(quat_to_matrix(rot[:, P]), trans[:, P])
    return matrix_to_quat(rw[:, -1])


def ccd_sweeps(
    rig: Rig, ch: Chain, rot, trans, goal, ref, spec, max_iter: int, tol: float, finish: bool = True, dmax=None,
    compiled: bool = True,
):
    """Vectorised CCD; ``rot`` (n, J, 4) modified in place.  Returns (iterations, hit).

    ``dmax`` (n,): largest proximal->distal distance the limb step may use (default the
    limb length); with ``finish`` the objective is the distance of the goal beyond it.
    ``compiled``: the sweeps by :func:`repro.motion.adaptation.ccd_kernel.ccd_frames` (numba),
    else by numpy over all frames at once (the same poses to rounding).
    """
    kp, kd = ch.k_prox, ch.k_dist
    Wg_fixed = pw = None
    if finish:
        # the sweeps turn only joints above the limb and read only its root (shoulder / hip):
        # forward kinematics stops there; the hand / foot keeps its start world orientation
        # (the limb step restores it), so the distal joint's goal does not move while the trunk turns
        rw, pw = chain_fk(quat_to_matrix(rot[:, ch.path]), trans[:, ch.path])
        Wg_fixed = goal - (pw[:, -1] + matvec(rw[:, -1], ch.hit_offset) - pw[:, kd])
        P = ch.path[: kp + 1]
    else:
        P = ch.path
    # across twist joints inside the bones too (then from the positions the finish computed, if it did)
    l1, l2 = limb_lengths(ch, rot, trans, None if pw is None else pw[:, : kd + 1])
    L = l1 + l2
    reach_max = L if dmax is None else np.minimum(dmax, L)
    # with the analytic finish, the limb's own joints are left to the limb step: only
    # the joints above the limb change how far the goal is out of the limb's reach
    sweep = [s for s in spec if not (finish and s[0] >= kp)]
    args = (rot[:, P], ref[:, P], trans[:, P], goal, Wg_fixed, l1, l2, reach_max, 1e-9 * L, sweep, max_iter, tol)
    ql, iters, hit = (_compiled_sweeps if compiled else _numpy_sweeps)(ch, finish, *args)
    rot[:, P] = ql
    if finish:  # the hit point of the turned trunk, the limb as it was
        rw, pw = chain_fk(quat_to_matrix(rot[:, ch.path]), trans[:, ch.path])
        hit = _hit(ch, rw, pw)
    return iters, hit


def _compiled_sweeps(ch, finish, ql, q0, tl, goal, Wg_fixed, l1, l2, reach_max, tiny, sweep, max_iter, tol):
    """:func:`ccd_sweeps`' loop by the compiled kernel: ``(ql, iterations, hit or None)``."""
    from repro.motion.adaptation.ccd_kernel import BALL, HINGE, ccd_frames  # numba: imported on first use

    n = goal.shape[0]
    c = np.ascontiguousarray
    joints = np.array([k for k, _, _ in sweep], dtype=np.intp)
    kinds = np.array([HINGE if kind == "hinge" else BALL for _, kind, _ in sweep], dtype=np.intp)
    lo = np.array([lim[0] if kind == "hinge" else lim for _, kind, lim in sweep], dtype=float)
    hi = np.array([lim[1] if kind == "hinge" else lim for _, kind, lim in sweep], dtype=float)
    ql = c(ql, dtype=float)
    wg = np.zeros((n, 3)) if Wg_fixed is None else c(Wg_fixed, dtype=float)
    iters = np.zeros(n, dtype=np.intp)
    hit = np.empty((n, 3))
    ccd_frames(ql, c(q0, dtype=float), c(tl, dtype=float), c(goal, dtype=float), wg, c(l1, dtype=float),
               c(l2, dtype=float), c(reach_max, dtype=float), c(tiny, dtype=float), joints, kinds, lo, hi,
               c(ch.hinge_loc, dtype=float), c(ch.hit_offset, dtype=float), int(ch.k_prox), bool(finish),
               int(max_iter), float(tol), iters, hit)
    return ql, iters, hit


def _numpy_sweeps(ch, finish, ql, q0, tl, goal, Wg_fixed, l1, l2, reach_max, tiny, sweep, max_iter, tol):
    """:func:`ccd_sweeps`' loop in numpy, all frames at once (a finished frame left untouched):
    ``(ql, iterations, hit)``."""
    kp = ch.k_prox
    n = goal.shape[0]
    ql = ql.copy()
    ml = quat_to_matrix(ql)
    rw, pw = chain_fk(ml, tl)
    active = np.ones(n, dtype=bool)
    iters = np.zeros(n, dtype=np.intp)
    best_err = np.full(n, np.inf)
    best_ql = ql.copy()
    for it in range(max_iter + 1):
        if finish:
            # objective: how far the goal is out of the limb's reach (the analytic limb
            # step then places the hit point exactly)
            dW = vector_norm(Wg_fixed - pw[:, kp])
            err = np.maximum(np.maximum(dW - reach_max, np.abs(l1 - l2) - dW), 0.0)
            done = err <= 0.0
        else:
            err = vector_norm(_hit(ch, rw, pw) - goal)
            done = err <= tol
        better = err < best_err
        worse = active & ~better
        if worse.any():  # a sweep that made things worse is undone, and the frame stops
            ql[worse] = best_ql[worse]
            ml[worse] = quat_to_matrix(ql[worse])
            rw[worse], pw[worse] = chain_fk(ml[worse], tl[worse])
        # a sweep that gains less than 5 % of the remaining objective is creeping along
        # joint limits (a converging sweep gains a constant, large fraction)
        creeping = better & (best_err - err < np.maximum(0.05 * np.where(np.isfinite(best_err), best_err, 0.0), tiny))
        best_ql[better] = ql[better]
        best_err = np.minimum(best_err, err)
        active &= better & ~done & ~creeping
        if not active.any() or it == max_iter or not sweep:
            break
        iters += active
        for k, kind, lim in sweep:
            _turn_joint(ch, k, kind, lim, goal, Wg_fixed, (l1, l2, reach_max), q0, ql, ml, tl, rw, pw, active)
    return ql, iters, _hit(ch, rw, pw)


def _hit(ch: Chain, rw: np.ndarray, pw: np.ndarray) -> np.ndarray:
    """The hit point of the chain's last joint (world rotations ``rw``, positions ``pw``)."""
    return pw[:, -1] + matvec(rw[:, -1], ch.hit_offset)


def _turn_joint(ch, k, kind, lim, goal, Wg_fixed, reach, q0, ql, ml, tl, rw, pw, active) -> None:
    """One CCD step of path joint ``k`` on the active frames; ``ql``, ``ml``, ``rw``, ``pw`` updated in place.

    ``Wg_fixed`` (the analytic finish's fixed distal goal) set: a joint above the limb brings
    the proximal joint (shoulder / hip) to the nearest point from which the limb reaches the
    goal; otherwise the hit point turns towards ``goal``.
    """
    pj = pw[:, k]
    kp = ch.k_prox
    if Wg_fixed is not None and k < kp:
        l1, l2, reach_max = reach
        S = pw[:, kp]
        sw = S - Wg_fixed
        dist = vector_norm(sw)
        want = np.clip(dist, np.abs(l1 - l2), np.maximum(reach_max, np.abs(l1 - l2)))
        e = S - pj
        g = Wg_fixed + (want / np.maximum(dist, 1e-300))[:, None] * sw - pj
    else:
        e = _hit(ch, rw, pw) - pj
        g = goal - pj
    if kind == "hinge":
        qn = _hinge_step(e, g, rw[:, k - 1], ml[:, k], tl[:, k], tl[:, k + 1], ch.hinge_loc, lim, active, ql[:, k],
                         None if kp == k - 1 else rw[:, kp])
    else:
        qn = _ball_step(e, g, None if k == 0 else rw[:, k - 1], ql[:, k], q0[:, k], lim, active)
    # only the active frames change (not even by the normalisation's ulp): a frame's
    # solution does not depend on which other frames are solved with it
    qn = np.where(active[:, None], qn / vector_norm(qn, keepdims=True), ql[:, k])
    ql[:, k] = qn
    ml[:, k] = quat_to_matrix(qn)
    chain_fk_from(ml, tl, rw, pw, k)


def _hinge_step(e, g, r_parent, m_joint, up, low, h_loc, lim, active, q, r_prox=None):
    """Turn a hinge about its axis to point ``e`` at ``g``, flexion kept within ``lim``.

    ``h_loc``: the axis in the proximal joint's frame, the hinge's parent unless ``r_prox`` (its world rotation)
    is given: twist joints between them, and the axis in the parent's frame turns with their twist."""
    if r_prox is None:
        h = matvec(r_parent, h_loc)
    else:
        h = matvec(r_prox, h_loc)
        h_loc = matvec_t(r_parent, h)  # (n, 3): per frame
    ep = e - dot(e, h)[:, None] * h
    gp = g - dot(g, h)[:, None] * h
    theta = np.arctan2(dot(h, cross(ep, gp)), dot(ep, gp))
    lw = matvec(m_joint, low)
    if r_prox is None:
        up = up - (up @ h_loc)[:, None] * h_loc
        lw = lw - (lw @ h_loc)[:, None] * h_loc
        phi = np.arctan2(cross(up, lw) @ h_loc, dot(up, lw))
    else:
        up = up - dot(up, h_loc)[:, None] * h_loc
        lw = lw - dot(lw, h_loc)[:, None] * h_loc
        phi = np.arctan2(dot(cross(up, lw), h_loc), dot(up, lw))
    lo = np.minimum(lim[0], phi)
    hi = np.maximum(lim[1], phi)
    th = np.where(active, np.clip(phi + theta, lo, hi) - phi, 0.0)
    dq = np.concatenate([np.sin(0.5 * th)[:, None] * h_loc, np.cos(0.5 * th)[:, None]], axis=-1)
    return quat_multiply(dq, q)


def _ball_step(e, g, r_parent, q, q_orig, lim, active):
    """Smallest rotation pointing ``e`` at ``g``, clamped to a cone of ``lim`` about ``q_orig``."""
    qm = min_rotation(e, g)
    v = qm[:, :3] if r_parent is None else matvec_t(r_parent, qm[:, :3])
    qn = quat_multiply(np.concatenate([v, qm[:, 3:]], axis=-1), q)
    dev = quat_multiply(qn, qinv(q_orig))
    dev = np.where(dev[:, 3:] < 0, -dev, dev)
    s = vector_norm(dev[:, :3])
    ang = 2.0 * np.arctan2(s, dev[:, 3])
    over = ang > lim
    if over.any():
        axis = dev[over, :3] / s[over, None]
        cos_half = np.full((axis.shape[0], 1), np.cos(0.5 * lim))
        dl = np.concatenate([axis * np.sin(0.5 * lim), cos_half], axis=-1)
        qn[over] = quat_multiply(dl, q_orig[over])
    return np.where(active[:, None], qn, q)


def ccd(
    motion: Motion,
    frames,
    effector: str,
    targets,
    *,
    rotations=None,
    chain: Sequence[str] | None = None,
    limits: Mapping[str, float] | None = None,
    hinge_range_deg: tuple[float, float] = DEFAULT_HINGE_RANGE_DEG,
    max_iter: int = 50,
    tol: float | None = None,
    finish_with_limb: bool = True,
    max_extension: float = 1.0,
    hit_point: str = "joint",
    roles=None,
    compiled: bool = True,
) -> CCDSolution:
    """Cyclic Coordinate Descent over a longer chain (Section 3.4.2, after Welman 1993; module docstring).

    For the ``frames`` "where the constraint is not reachable by only using the
    corresponding limb".  ``chain``: joint names or roles, ancestors of the wrist / ankle
    (default :func:`default_chain`); ``limits``: cone limits in degrees by joint, role or
    kind (:data:`DEFAULT_LIMITS_DEG`); ``hinge_range_deg``: the elbow / knee flexion range;
    ``targets`` (3,) or (n, 3) and ``tol`` (default 1e-4 of the limb length) in motion
    units; ``rotations`` (n, J, 4) the start pose (default the motion's); ``compiled`` the sweeps
    by the compiled kernel (False: by numpy, the same poses to rounding).  Always
    terminates (at most ``max_iter`` sweeps).  Returns a :class:`CCDSolution`
    (unreachable: best effort, ``reached=False``).  Raises :class:`repro.errors.MotionError`
    for an unknown effector, frames out of range, NaN targets, a chain joint that is not
    an ancestor of the limb, bad limits.
    """
    rig = rig_of(motion, roles)
    ch = rig.chain(effector, hit_point)
    idx, _ = check_frames(frames, motion.n_frames)
    goal = np.array(check_targets(targets, len(idx)))
    tol = default_tol(rig, ch) if tol is None else as_real(tol, "tol", error=MotionError, lo=0.0, lo_open=True)
    max_iter = as_int(max_iter, "max_iter", 0, 10**6, error=MotionError)
    finish_with_limb = as_bool(finish_with_limb, "finish_with_limb", error=MotionError)
    compiled = as_bool(compiled, "compiled", error=MotionError)
    ext = check_extension(max_extension)
    rot = start_rotations(motion, idx, rotations)
    spec = ccd_spec(rig, ch, chain, limits, hinge_range_deg)
    trans = rig.trans[idx]
    ref = np.asarray(motion.rotations[idx])
    dmax = limb_dmax(ch, ref, trans, ext)
    dw = _distal_world(ch, rot, trans) if finish_with_limb else None
    iters, hit = ccd_sweeps(rig, ch, rot, trans, goal, ref, spec, max_iter, tol, finish_with_limb, dmax, compiled)
    if finish_with_limb:
        hit, res = solve_limb(ch, rot, trans, goal, distal_world=dw, dmax=dmax)
        far = res > tol
        if ext < 1.0 and far.any():
            r = rot[far]
            hit[far], _ = solve_limb(ch, r, trans[far], goal[far], distal_world=dw[far])
            rot[far] = r
    res = vector_norm(hit - goal)
    return CCDSolution(
        frames=idx,
        rotations=rot,
        hit_positions=hit,
        residual=res,
        reached=res <= tol,
        iterations=iters,
        chain=[rig.sk.joint_names[int(ch.path[k])] for k, _, _ in spec],
    )


def cone_limits(motion: Motion, limits: Mapping[str, float] | None = None, *, roles=None) -> np.ndarray:
    """(J,) the cone limit (radians) :func:`ccd` keeps each joint within, around its original local rotation."""
    rig = rig_of(motion, roles)
    lim = _check_limits(rig, limits)
    return np.array([_limit_of(rig, j, lim) for j in range(len(rig.sk.joint_names))])
