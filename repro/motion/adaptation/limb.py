"""The limb step of Section 3.4.2: analytic two-bone IK of the arm or leg (:func:`reach_limb`).

The hand / foot keeps its world orientation, so the hit point keeps its offset from the
wrist / ankle; the elbow / knee keeps its swivel (its bend direction is parallel
transported from the input's proximal->distal axis to the new one); the proximal and
middle joints turn by the smallest rotations that place the middle and distal joints,
so the twist of the upper arm / thigh is kept.

Joints between the proximal and middle joints, or the middle and distal ones (twist
segments inside the limb chain, MakeHuman ``upperarm02.L`` between ``upperarm01.L`` and
``lowerarm01.L``), are carried along: they keep their local rotations, so the segment
from the proximal to the middle joint is rigid and its length is the distance of the two
joints in the pose, not the middle joint's offset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from repro.checks import as_real
from repro.errors import MotionError

from repro.motion.adaptation.rig import (
    Chain,
    check_extension,
    check_frames,
    check_targets,
    default_tol,
    rig_of,
    start_rotations,
)
from repro.motion.core.kinematics import chain_fk, dot, matvec, matvec_t, normalize, transport
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import matrix_to_quat, min_rotation, quat_multiply, quat_to_matrix, vector_norm
from repro.motion.core.quaternion import quat_rotate as qrot

__all__ = ["LimbSolution", "reach_limb", "solve_limb", "limb_dmax"]


# ------------------------------------------------------------------ results
@dataclass(frozen=True, eq=False)
class LimbSolution:
    """Result of :func:`reach_limb`.

    Attributes
    ----------
    frames : (n,) int
        The solved frames.
    rotations : (n, J, 4)
        Local rotations of every joint on those frames (only the limb's proximal, middle
        and distal joints differ from the input).
    hit_positions : (n, 3)
        World position of the hit point after the solve.
    residual : (n,)
        Distance from the hit point to its target (0 to rounding when reachable; the
        excess distance when the limb is too short, or too long to fold that close).
    reached : (n,) bool
        ``residual <= tol``.
    """

    frames: np.ndarray
    rotations: np.ndarray
    hit_positions: np.ndarray
    residual: np.ndarray
    reached: np.ndarray


# ------------------------------------------------------- limb: batched numpy
def solve_limb(
    ch: Chain,
    rot: np.ndarray,
    trans: np.ndarray,
    goal: np.ndarray,
    distal_world: np.ndarray | None = None,
    max_extension: float = 1.0,
    dmax: np.ndarray | None = None,
):
    """Two-bone IK of the limb of ``ch`` on n frames.

    ``rot`` (n, J, 4) is modified in place.  ``goal`` (n, 3) is the goal of the hit point.
    The distal joint keeps its world orientation, or takes ``distal_world`` (n, 4).  The
    proximal->distal distance is limited to ``dmax`` (n,) (default
    ``min(L, max(max_extension * L, start distance))``).  Returns (hit positions,
    residuals).
    """
    P = ch.path[: ch.k_hit + 1]
    ml = quat_to_matrix(rot[:, P])
    rw, pw = chain_fk(ml, trans[:, P])
    kp, km, kd = ch.k_prox, ch.k_mid, ch.k_dist
    S, E0, W0 = pw[:, kp], pw[:, km], pw[:, kd]
    hit_rel = pw[:, -1] + matvec(rw[:, -1], ch.hit_offset) - W0
    if distal_world is not None:  # the hit point turns with the distal joint's new orientation
        hit_rel = qrot(distal_world, matvec_t(rw[:, kd], hit_rel))
    Wg = goal - hit_rel
    # lengths (from the pose: equal to the offsets unless position channels say otherwise)
    e0 = E0 - S
    le = W0 - E0
    l1 = vector_norm(e0)
    l2 = vector_norm(le)
    w0 = W0 - S
    a_orig, n0 = normalize(w0)
    ax = Wg - S
    a, dn = normalize(ax)
    a = np.where((dn > 1e-12 * l1)[:, None], a, a_orig)
    # original swivel: side of the elbow / knee w.r.t. the proximal->distal axis
    ep = e0 - dot(e0, a_orig)[:, None] * a_orig
    r = vector_norm(ep)
    fb = matvec(rw[:, kp], ch.bend_loc)
    fb = fb - dot(fb, a_orig)[:, None] * a_orig
    b0 = np.where((r > 1e-6 * l1)[:, None], ep, fb)
    b0 = normalize(b0)[0]
    u = transport(a_orig, b0, a)
    if dmax is None:
        dmax = np.minimum(l1 + l2, np.maximum(max_extension * (l1 + l2), n0))
    dc = np.clip(dn, np.abs(l1 - l2), np.maximum(dmax, np.abs(l1 - l2)))
    cosb = np.clip((l1 * l1 + dc * dc - l2 * l2) / (2.0 * l1 * np.maximum(dc, 1e-300)), -1.0, 1.0)
    sinb = np.sqrt(1.0 - cosb * cosb)
    Es = S + (l1 * cosb)[:, None] * a + (l1 * sinb)[:, None] * u
    Wr = S + dc[:, None] * a
    q1 = min_rotation(e0, Es - S)
    W1 = S + qrot(q1, w0)
    q2 = min_rotation(W1 - Es, Wr - Es)
    # local corrections: a world rotation D applied below joint j is, in j's parent
    # frame with world rotation R, the quaternion (R^T d_v, d_w)
    # (the middle joint's parent is the proximal joint, or the last twist segment after it,
    # which turned with it by q1; the distal joint's parent likewise turned by q2 q1)
    d1 = np.concatenate([matvec_t(rw[:, kp - 1], q1[:, :3]), q1[:, 3:]], axis=-1)
    r_prox_new = quat_to_matrix(q1) @ rw[:, km - 1]
    d2 = np.concatenate([matvec_t(r_prox_new, q2[:, :3]), q2[:, 3:]], axis=-1)
    q21 = quat_multiply(q2, q1)
    pr, md, ds = ch.prox, ch.mid, ch.dist
    if distal_world is None:
        d3 = np.concatenate([matvec_t(rw[:, kd - 1], -q21[:, :3]), q21[:, 3:]], axis=-1)
        new = quat_multiply(np.stack([d1, d2, d3], axis=1), rot[:, [pr, md, ds]])
        rot[:, [pr, md, ds]] = new
    else:
        new = quat_multiply(np.stack([d1, d2], axis=1), rot[:, [pr, md]])
        rot[:, [pr, md]] = new
        r_mid_new = quat_to_matrix(q21) @ rw[:, kd - 1]
        rot[:, ds] = matrix_to_quat(np.swapaxes(r_mid_new, -1, -2) @ quat_to_matrix(distal_world))
    hit = Wr + hit_rel
    return hit, np.abs(dn - dc)


def limb_lengths(ch: Chain, rot: np.ndarray, trans: np.ndarray, pw: np.ndarray | None = None):
    """Per frame ``(l1, l2)``: the proximal->middle and middle->distal lengths of the pose ``rot``.  The
    bones' offsets; with twist joints inside the bones, the distances between the limb's joints (``pw``
    the world positions along ``ch.path`` up to the distal joint, computed when not given)."""
    if ch.k_mid - ch.k_prox == 1 and ch.k_dist - ch.k_mid == 1:
        return vector_norm(trans[:, ch.mid]), vector_norm(trans[:, ch.dist])
    if pw is None:
        P = ch.path[: ch.k_dist + 1]
        _, pw = chain_fk(quat_to_matrix(rot[:, P]), trans[:, P])
    return vector_norm(pw[:, ch.k_mid] - pw[:, ch.k_prox]), vector_norm(pw[:, ch.k_dist] - pw[:, ch.k_mid])


def limb_dmax(ch: Chain, ref: np.ndarray, trans: np.ndarray, max_extension: float) -> np.ndarray:
    """Per frame ``min(L, max(max_extension * L, |distal - proximal|))`` in the pose ``ref``
    (``L`` the limb's two lengths, :func:`limb_lengths`)."""
    P = ch.path[: ch.k_dist + 1]
    _, pw = chain_fk(quat_to_matrix(ref[:, P]), trans[:, P])
    l1, l2 = limb_lengths(ch, ref, trans, pw)
    L = l1 + l2
    d = vector_norm(pw[:, ch.k_dist] - pw[:, ch.k_prox])
    return np.minimum(L, np.maximum(max_extension * L, d))


# ------------------------------------------------------ limb: scalar (1 frame)
# Kept next to the batched solver because it is measurably faster for one frame (the
# paper's frame-by-frame use, "88 us"): measured in one process with timeit (best of 15 x
# 2000 calls) on CMU 135_09, frame 303, right fist, on the shared 2-core test machine
# (load ~12): scalar 169 us, batched numpy (solve_limb on 1 frame) 2511 us; the two agree
# to 9e-16 m there and to rounding in tests/motion/adaptation/test_adaptation.py.  For n frames the
# batched path is used (numpy's per-call overhead is paid once per step, not per frame).
def _s_qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _s_rot(q, v):
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def _s_cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _s_dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _s_sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _s_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _s_scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def _s_norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _s_minrot(u, v):
    c = _s_cross(u, v)
    w = _s_norm(u) * _s_norm(v) + _s_dot(u, v)
    n = math.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2] + w * w)
    if n <= 1e-12 * max(_s_norm(u) * _s_norm(v), 1e-300):
        return tuple(min_rotation(np.array(u), np.array(v)).tolist())
    return (c[0] / n, c[1] / n, c[2] / n, w / n)


def _s_transport(a0, r0, a):
    w = _s_cross(a0, a)
    c = _s_dot(a0, a)
    if c <= -1.0 + 1e-12:
        r = r0
    else:
        wr = _s_cross(w, r0)
        r = _s_add(_s_add(r0, wr), _s_scale(_s_cross(w, wr), 1.0 / (1.0 + c)))
    r = _s_sub(r, _s_scale(a, _s_dot(r, a)))
    n = _s_norm(r)
    return _s_scale(r, 1.0 / max(n, 1e-300))


def _limb_scalar(ch: Chain, rot: np.ndarray, trans: np.ndarray, goal, max_extension: float = 1.0):
    """One-frame version of :func:`solve_limb` (no ``distal_world``) in Python floats.

    ``rot`` (J, 4) is modified in place; returns (hit position tuple, residual).
    """
    P = ch.path.tolist()
    ql = rot[P].tolist()
    tl = trans[P].tolist()
    qw = [None] * len(P)
    pw = [None] * len(P)
    qw[0] = tuple(ql[0])
    pw[0] = tuple(tl[0])
    for i in range(1, len(P)):
        pw[i] = _s_add(pw[i - 1], _s_rot(qw[i - 1], tl[i]))
        qw[i] = _s_qmul(qw[i - 1], ql[i])
    kp, km, kd = ch.k_prox, ch.k_mid, ch.k_dist
    S, E0, W0 = pw[kp], pw[km], pw[kd]
    off = ch.hit_offset
    hit0 = _s_add(pw[-1], _s_rot(qw[-1], (float(off[0]), float(off[1]), float(off[2]))))
    hit_rel = _s_sub(hit0, W0)
    Wg = _s_sub(tuple(goal), hit_rel)
    e0 = _s_sub(E0, S)
    w0 = _s_sub(W0, S)
    l1 = _s_norm(e0)
    l2 = _s_norm(_s_sub(W0, E0))
    n0 = _s_norm(w0)
    a_orig = _s_scale(w0, 1.0 / max(n0, 1e-300))
    ax = _s_sub(Wg, S)
    dn = _s_norm(ax)
    a = _s_scale(ax, 1.0 / dn) if dn > 1e-12 * l1 else a_orig
    ep = _s_sub(e0, _s_scale(a_orig, _s_dot(e0, a_orig)))
    r = _s_norm(ep)
    if r > 1e-6 * l1:
        b0 = _s_scale(ep, 1.0 / r)
    else:
        bl = ch.bend_loc
        fb = _s_rot(qw[kp], (float(bl[0]), float(bl[1]), float(bl[2])))
        fb = _s_sub(fb, _s_scale(a_orig, _s_dot(fb, a_orig)))
        b0 = _s_scale(fb, 1.0 / max(_s_norm(fb), 1e-300))
    u = _s_transport(a_orig, b0, a)
    dmax = min(l1 + l2, max(max_extension * (l1 + l2), n0))
    dc = min(max(dn, abs(l1 - l2)), max(dmax, abs(l1 - l2)))
    cosb = min(1.0, max(-1.0, (l1 * l1 + dc * dc - l2 * l2) / (2.0 * l1 * max(dc, 1e-300))))
    sinb = math.sqrt(1.0 - cosb * cosb)
    Es = _s_add(S, _s_add(_s_scale(a, l1 * cosb), _s_scale(u, l1 * sinb)))
    Wr = _s_add(S, _s_scale(a, dc))
    q1 = _s_minrot(e0, _s_sub(Es, S))
    W1 = _s_add(S, _s_rot(q1, w0))
    q2 = _s_minrot(_s_sub(W1, Es), _s_sub(Wr, Es))
    inv = lambda q: (-q[0], -q[1], -q[2], q[3])  # noqa: E731
    qpar = qw[kp - 1]
    d1 = _s_qmul(_s_qmul(inv(qpar), q1), qpar)
    gp_new = _s_qmul(q1, qw[km - 1])  # the middle joint's parent (the proximal joint, or a twist segment)
    d2 = _s_qmul(_s_qmul(inv(gp_new), q2), gp_new)
    q21 = _s_qmul(q2, q1)
    gm = qw[kd - 1]  # the distal joint's parent
    d3 = _s_qmul(_s_qmul(inv(gm), inv(q21)), gm)
    rot[ch.prox] = _s_qmul(d1, ql[kp])
    rot[ch.mid] = _s_qmul(d2, ql[km])
    rot[ch.dist] = _s_qmul(d3, ql[kd])
    return _s_add(Wr, hit_rel), abs(dn - dc)


def reach_limb(
    motion: Motion,
    frames,
    effector: str,
    targets,
    *,
    rotations=None,
    hit_point: str = "joint",
    tol: float | None = None,
    max_extension: float = 1.0,
    roles=None,
) -> LimbSolution:
    """Limb step of Section 3.4.2: analytic two-bone IK of the arm or leg to reach targets.

    The hit point of ``effector`` is brought to ``targets`` by changing only the local
    rotations of the limb's shoulder/hip, elbow/knee and wrist/ankle: the hand or foot
    keeps its world orientation (so the hit point keeps its offset from the wrist /
    ankle), the elbow / knee stays on the side it had in the input pose (swivel kept by
    parallel transport of the bend direction from the input's proximal->distal axis to
    the new one; a straight input limb bends towards the clip-wide bend side), and the
    proximal and middle joints turn by the smallest rotations that place the middle and
    distal joints (twist kept).  The paper: "If only the limb is involved, this method
    only requires 88 us."  One frame is solved in Python floats, several with numpy
    vectorised over frames.

    Parameters
    ----------
    motion : Motion
    frames : int or sequence of int
        Frames to solve.
    effector : str
        Effector role (see :data:`EFFECTOR_STEMS`), e.g. ``"right_fist"``, ``"left_foot"``.
    targets : (3,) or (n, 3) array
        World goal of the hit point on each frame, motion units.
    rotations : (n, J, 4) array, optional
        Start pose on those frames instead of the motion's (to chain solvers).
    hit_point : {"joint", "end_site"}
        The effector joint itself, or its (first) End Site.
    tol : float, optional
        Reach tolerance, motion units (default 1e-4 of the limb length).
    max_extension : float, default 1
        Largest proximal->distal distance the solve may use, as a fraction of the limb
        length ``L`` (never less than the distance in the start pose): below 1 the
        elbow / knee is not straightened beyond that (1 = full extension).  Near full
        extension the elbow angle of two-bone IK changes very fast with the distance
        (it is singular at ``L``); :func:`adapt` uses 0.98 and leaves the rest to CCD.
    roles : mapping, optional
        Role table (default: :func:`~repro.motion.body.skeleton.find_roles`).

    Returns
    -------
    LimbSolution
        Unreachable targets are not an error: the limb is fully extended (or folded as
        far as it goes) towards the target, ``reached`` is False and ``residual`` is the
        remaining distance.

    Raises
    ------
    repro.errors.MotionError
        Unknown effector, frames out of range, NaN targets, a bad ``rotations`` array.
    """
    rig = rig_of(motion, roles)
    ch = rig.chain(effector, hit_point)
    idx, scalar = check_frames(frames, motion.n_frames)
    goal = check_targets(targets, len(idx))
    tol = default_tol(rig, ch) if tol is None else as_real(tol, "tol", error=MotionError, lo=0.0, lo_open=True)
    ext = check_extension(max_extension)
    rot = start_rotations(motion, idx, rotations)
    if len(idx) == 1:
        hit, res = _limb_scalar(ch, rot[0], rig.trans[idx[0]], goal[0].tolist(), ext)
        hit = np.array([hit])
        res = np.array([res])
    else:
        hit, res = solve_limb(ch, rot, rig.trans[idx], goal, max_extension=ext)
    return LimbSolution(frames=idx, rotations=rot, hit_positions=hit, residual=res, reached=res <= tol)
