"""CCD's sweeps compiled (numba): :func:`ccd_frames`, the loop of :func:`repro.motion.adaptation.ccd_solver.ccd_sweeps`.

The same algorithm as the numpy sweeps (Section 3.4.2, after Welman 1993; the module
docstring of :mod:`.ccd_solver` states it), frame by frame: each frame runs its own sweeps
(distal to proximal, one joint turned at a time, forward kinematics along the path from that
joint on), is undone when a sweep makes it worse, and stops when reached, creeping or after
``max_iter`` sweeps.  The numpy sweeps solve all frames at once, leaving the finished ones
untouched, so each frame's result is its own there too: the two give the same poses, to the
rounding of the 3x3 products (BLAS in numpy, loops here), about 1e-15; tested on real rigs.

Why compiled: CCD runs on the few frames the limb cannot reach (5-10 of an order's), up to 50
sweeps of up to 8 joints, each a dozen small numpy calls: measured on a 2-core VM, the numpy
sweeps took 60-170 ms of the slowest orders (a mocopi rig with a long spine, ~300 joint steps),
about 0.2 ms a joint step in call overhead alone; compiled, a joint step costs about a
microsecond.  Compiled once per machine and source (``cache=True``, as
:mod:`repro.motion.search.kernel`): a few seconds on a fresh install, then loaded from numba's
cache; :func:`compile_ccd` does it before the first order (the fighter calls it at set-up).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["BALL", "HINGE", "ccd_frames", "compile_ccd"]

#: joint kinds of the sweep (``kinds`` of :func:`ccd_frames`)
BALL: int = 0
HINGE: int = 1


@numba.njit(cache=True, nogil=True)
def _norm3(x, y, z):  # pragma: no cover - compiled
    return math.sqrt(x * x + y * y + z * z)


@numba.njit(cache=True, nogil=True)
def _qmul(a, b, out):  # pragma: no cover - compiled
    """Hamilton product ``a * b`` (scalar last) into ``out``: :func:`~repro.motion.core.quaternion.quat_multiply`'s terms."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    out[0] = aw * bx + ax * bw + ay * bz - az * by
    out[1] = aw * by - ax * bz + ay * bw + az * bx
    out[2] = aw * bz + ax * by - ay * bx + az * bw
    out[3] = aw * bw - ax * bx - ay * by - az * bz


@numba.njit(cache=True, nogil=True)
def _to_matrix(q, m):  # pragma: no cover - compiled
    """:func:`~repro.motion.core.quaternion.quat_to_matrix` of one quaternion into ``m`` (3, 3)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    x2, y2, z2 = x + x, y + y, z + z
    xx, yy, zz = x * x2, y * y2, z * z2
    xy, xz, yz = x * y2, x * z2, y * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    m[0, 0] = 1.0 - (yy + zz)
    m[0, 1] = xy - wz
    m[0, 2] = xz + wy
    m[1, 0] = xy + wz
    m[1, 1] = 1.0 - (xx + zz)
    m[1, 2] = yz - wx
    m[2, 0] = xz - wy
    m[2, 1] = yz + wx
    m[2, 2] = 1.0 - (xx + yy)


@numba.njit(cache=True, nogil=True)
def _fk_from(ml, tl, rw, pw, k):  # pragma: no cover - compiled
    """:func:`~repro.motion.core.kinematics.chain_fk_from` on one frame: path positions ``>= k``."""
    if k == 0:
        rw[0] = ml[0]
        pw[0] = tl[0]
        k = 1
    for i in range(k, ml.shape[0]):
        for r in range(3):
            pw[i, r] = pw[i - 1, r] + (rw[i - 1, r, 0] * tl[i, 0] + rw[i - 1, r, 1] * tl[i, 1]
                                       + rw[i - 1, r, 2] * tl[i, 2])
            for c in range(3):
                rw[i, r, c] = rw[i - 1, r, 0] * ml[i, 0, c] + rw[i - 1, r, 1] * ml[i, 1, c] + rw[i - 1, r, 2] * ml[i, 2, c]


@numba.njit(cache=True, nogil=True)
def _hit(rw, pw, off, out):  # pragma: no cover - compiled
    """The hit point of the path's last joint: its position plus its rotation times ``off``."""
    P = pw.shape[0] - 1
    for r in range(3):
        out[r] = pw[P, r] + (rw[P, r, 0] * off[0] + rw[P, r, 1] * off[1] + rw[P, r, 2] * off[2])


@numba.njit(cache=True, nogil=True)
def _min_rotation(u, v, q):  # pragma: no cover - compiled
    """:func:`~repro.motion.core.quaternion.min_rotation` of one pair into ``q``."""
    nu = _norm3(u[0], u[1], u[2])
    nv = _norm3(v[0], v[1], v[2])
    q[0] = u[1] * v[2] - u[2] * v[1]
    q[1] = u[2] * v[0] - u[0] * v[2]
    q[2] = u[0] * v[1] - u[1] * v[0]
    q[3] = nu * nv + (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
    scale = nu * nv
    qn = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if qn <= 1e-12 * max(scale, 1e-300):  # (nearly) opposite: a half turn about an axis perpendicular to u
        k = 0
        for i in range(1, 3):
            if abs(u[i]) < abs(u[k]):
                k = i
        e = np.zeros(3)
        e[k] = 1.0
        ax = np.empty(3)
        ax[0] = u[1] * e[2] - u[2] * e[1]
        ax[1] = u[2] * e[0] - u[0] * e[2]
        ax[2] = u[0] * e[1] - u[1] * e[0]
        na = max(_norm3(ax[0], ax[1], ax[2]), 1e-300)
        for i in range(3):
            q[i] = ax[i] / na
        q[3] = 0.0
        if scale <= 1e-300:
            q[0], q[1], q[2], q[3] = 0.0, 0.0, 0.0, 1.0
        qn = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for i in range(4):
        q[i] = q[i] / qn


@numba.njit(cache=True, nogil=True)
def _ball_step(e, g, rw, k, q, q_orig, lim, out):  # pragma: no cover - compiled
    """Smallest rotation pointing ``e`` at ``g`` applied to ``q``, clamped to a cone of ``lim`` about ``q_orig``."""
    qm = np.empty(4)
    _min_rotation(e, g, qm)
    a = np.empty(4)
    if k == 0:
        a[:3] = qm[:3]
    else:  # the world axis in the parent's frame: R^T v
        for c in range(3):
            a[c] = qm[0] * rw[k - 1, 0, c] + qm[1] * rw[k - 1, 1, c] + qm[2] * rw[k - 1, 2, c]
    a[3] = qm[3]
    _qmul(a, q, out)
    inv = np.empty(4)
    inv[0], inv[1], inv[2], inv[3] = -q_orig[0], -q_orig[1], -q_orig[2], q_orig[3]
    dev = np.empty(4)
    _qmul(out, inv, dev)
    if dev[3] < 0:
        for i in range(4):
            dev[i] = -dev[i]
    s = _norm3(dev[0], dev[1], dev[2])
    if 2.0 * math.atan2(s, dev[3]) > lim:
        sh, ch = math.sin(0.5 * lim), math.cos(0.5 * lim)
        dl = np.empty(4)
        for i in range(3):
            dl[i] = dev[i] / s * sh
        dl[3] = ch
        _qmul(dl, q_orig, out)


@numba.njit(cache=True, nogil=True)
def _hinge_step(e, g, rw, ml, tl, k, kp, h_prox, lo, hi, q, out):  # pragma: no cover - compiled
    """Turn the hinge at path position ``k`` about its axis to point ``e`` at ``g``, flexion kept in ``[lo, hi]``.

    ``h_prox``: the axis in the frame of the limb's proximal joint (path position ``kp``); with twist joints
    between them, in the hinge's parent's frame (position ``k - 1``) it turns with their twist."""
    h = np.empty(3)
    for r in range(3):
        h[r] = rw[kp, r, 0] * h_prox[0] + rw[kp, r, 1] * h_prox[1] + rw[kp, r, 2] * h_prox[2]
    h_loc = h_prox
    if kp != k - 1:
        h_loc = np.empty(3)
        for r in range(3):
            h_loc[r] = rw[k - 1, 0, r] * h[0] + rw[k - 1, 1, r] * h[1] + rw[k - 1, 2, r] * h[2]
    de = e[0] * h[0] + e[1] * h[1] + e[2] * h[2]
    dg = g[0] * h[0] + g[1] * h[1] + g[2] * h[2]
    ep = e - de * h
    gp = g - dg * h
    cx = ep[1] * gp[2] - ep[2] * gp[1]
    cy = ep[2] * gp[0] - ep[0] * gp[2]
    cz = ep[0] * gp[1] - ep[1] * gp[0]
    theta = math.atan2(h[0] * cx + h[1] * cy + h[2] * cz, ep[0] * gp[0] + ep[1] * gp[1] + ep[2] * gp[2])
    low = tl[k + 1]
    lw = np.empty(3)
    for r in range(3):
        lw[r] = ml[k, r, 0] * low[0] + ml[k, r, 1] * low[1] + ml[k, r, 2] * low[2]
    up = tl[k] - (tl[k, 0] * h_loc[0] + tl[k, 1] * h_loc[1] + tl[k, 2] * h_loc[2]) * h_loc
    lw = lw - (lw[0] * h_loc[0] + lw[1] * h_loc[1] + lw[2] * h_loc[2]) * h_loc
    c0 = up[1] * lw[2] - up[2] * lw[1]
    c1 = up[2] * lw[0] - up[0] * lw[2]
    c2 = up[0] * lw[1] - up[1] * lw[0]
    phi = math.atan2(c0 * h_loc[0] + c1 * h_loc[1] + c2 * h_loc[2], up[0] * lw[0] + up[1] * lw[1] + up[2] * lw[2])
    th = min(max(phi + theta, min(lo, phi)), max(hi, phi)) - phi
    dq = np.empty(4)
    sh = math.sin(0.5 * th)
    for i in range(3):
        dq[i] = sh * h_loc[i]
    dq[3] = math.cos(0.5 * th)
    _qmul(dq, q, out)


@numba.njit(cache=True, nogil=True)
def _turn_joint(f, k, kind, lo, hi, goal, wg, l1, l2, reach_max, kp, finish, h_loc, off, q0, ql, ml, tl, rw,
                pw):  # pragma: no cover - compiled
    """One CCD step of path joint ``k`` on frame ``f`` (:func:`.ccd_solver._turn_joint`); state updated in place."""
    pj = pw[k]
    if finish and k < kp:  # the limb's root towards the nearest point from which the limb reaches the goal
        S = pw[kp]
        sw = S - wg[f]
        dist = _norm3(sw[0], sw[1], sw[2])
        a = abs(l1 - l2)
        want = min(max(dist, a), max(reach_max, a))
        e = S - pj
        g = wg[f] + (want / max(dist, 1e-300)) * sw - pj
    else:  # the hit point towards the goal
        hit = np.empty(3)
        _hit(rw, pw, off, hit)
        e = hit - pj
        g = goal[f] - pj
    qn = np.empty(4)
    if kind == HINGE:
        _hinge_step(e, g, rw, ml, tl, k, kp, h_loc, lo, hi, ql[f, k], qn)
    else:
        _ball_step(e, g, rw, k, ql[f, k], q0[f, k], lo, qn)
    n = math.sqrt(qn[0] * qn[0] + qn[1] * qn[1] + qn[2] * qn[2] + qn[3] * qn[3])
    for i in range(4):
        ql[f, k, i] = qn[i] / n
    _to_matrix(ql[f, k], ml[k])
    _fk_from(ml, tl, rw, pw, k)


@numba.njit(cache=True, nogil=True)
def _objective(f, goal, wg, l1, l2, reach_max, kp, finish, tol, off, rw, pw):  # pragma: no cover - compiled
    """``(err, done)`` of frame ``f``: the goal's distance beyond the limb's reach (finish), else the hit's miss."""
    if finish:
        dW = _norm3(wg[f, 0] - pw[kp, 0], wg[f, 1] - pw[kp, 1], wg[f, 2] - pw[kp, 2])
        err = max(max(dW - reach_max, abs(l1 - l2) - dW), 0.0)
        return err, err <= 0.0
    hit = np.empty(3)
    _hit(rw, pw, off, hit)
    err = _norm3(hit[0] - goal[f, 0], hit[1] - goal[f, 1], hit[2] - goal[f, 2])
    return err, err <= tol


@numba.njit(cache=True, nogil=True)
def _frame(f, ql, q0, tl, goal, wg, l1, l2, reach_max, tiny, joints, kinds, lo, hi, h_loc, off, kp, finish,
           max_iter, tol, ml, rw, pw, best_q):  # pragma: no cover - compiled
    """The sweeps of one frame; returns how many ran (the state ``ql[f]``, ``rw``, ``pw`` updated)."""
    P = ql.shape[1]
    for i in range(P):
        _to_matrix(ql[f, i], ml[i])
    _fk_from(ml, tl, rw, pw, 0)
    best = np.inf
    iters = 0
    for it in range(max_iter + 1):
        err, done = _objective(f, goal, wg, l1[f], l2[f], reach_max[f], kp, finish, tol, off, rw, pw)
        if not err < best:  # a sweep that made things worse is undone, and the frame stops
            ql[f] = best_q
            for i in range(P):
                _to_matrix(ql[f, i], ml[i])
            _fk_from(ml, tl, rw, pw, 0)
            break
        # a sweep that gains less than 5 % of the remaining objective is creeping along joint limits
        creeping = best - err < max(0.05 * (best if np.isfinite(best) else 0.0), tiny[f])
        best_q[:] = ql[f]
        best = err
        if done or creeping or it == max_iter or joints.size == 0:
            break
        iters += 1
        for s in range(joints.size):
            _turn_joint(f, joints[s], kinds[s], lo[s], hi[s], goal, wg, l1[f], l2[f], reach_max[f], kp, finish,
                        h_loc, off, q0, ql, ml, tl, rw, pw)
    return iters


@numba.njit(cache=True, nogil=True)
def ccd_frames(ql, q0, tl, goal, wg, l1, l2, reach_max, tiny, joints, kinds, lo, hi, h_loc, off, kp, finish,
               max_iter, tol, iters, hit):  # pragma: no cover - compiled
    """CCD's sweeps on every frame, each on its own; ``ql`` (n, P, 4) turned in place.

    ``ql`` / ``q0`` the path's local rotations (the start, the original), ``tl`` (n, P, 3) their
    translations, ``goal`` (n, 3) the hit point's goal, ``wg`` (n, 3) the analytic finish's fixed
    distal goal (``finish``: the joints above the limb bring its root, path position ``kp``, to
    where the limb reaches it), ``l1`` / ``l2`` / ``reach_max`` / ``tiny`` (n,) the limb's bones, its
    reach and the smallest gain; the sweep's path positions ``joints``, ``kinds`` (:data:`BALL`,
    :data:`HINGE`), their limits ``lo`` (a ball's cone, a hinge's least flexion) and ``hi``;
    ``h_loc`` the hinge axis, ``off`` the hit offset.  Writes the sweeps run per frame into
    ``iters`` and the hit point of the path's last joint into ``hit``.
    """
    n, P = ql.shape[0], ql.shape[1]
    ml = np.empty((P, 3, 3))
    rw = np.empty((P, 3, 3))
    pw = np.empty((P, 3))
    best_q = np.empty((P, 4))
    for f in range(n):
        iters[f] = _frame(f, ql, q0, tl[f], goal, wg, l1, l2, reach_max, tiny, joints, kinds, lo, hi, h_loc, off,
                          kp, finish, max_iter, tol, ml, rw, pw, best_q)
        _hit(rw, pw, off, hit[f])


def compile_ccd() -> None:
    """Compile :func:`ccd_frames` (or load it from numba's cache) on a one-frame problem with the argument
    types of :func:`~repro.motion.adaptation.ccd_solver.ccd_sweeps`: the first order of a process then
    costs what the others do (the fighter calls it at set-up)."""
    q = np.zeros((1, 3, 4))
    q[..., 3] = 1.0
    t = np.ones((1, 3, 3))
    f1, f3 = np.ones(1), np.zeros((1, 3))
    ccd_frames(q, q.copy(), t, f3, f3, f1, f1, 2.0 * f1, 1e-9 * f1, np.array([1], np.intp), np.array([BALL], np.intp),
               np.ones(1), np.ones(1), np.array([0.0, 0.0, 1.0]), np.zeros(3), 1, True, 1, 1e-4,
               np.zeros(1, np.intp), np.zeros((1, 3)))
