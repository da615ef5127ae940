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

This module implements that pipeline:

* :func:`offset_curve` -- ``d(t)``: 0 up to ``t_0``, ``d(t_c)`` at ``t_c``, an easing
  curve (linear, smoothstep or smootherstep) in between, and after ``t_c`` either held or
  released back to 0 over a given number of frames (the paper does not say what happens
  after the contact; holding the offset forever would displace the whole rest of a long
  clip, so :func:`adapt` releases it by default).
* :func:`reach_limb` -- the limb step: analytic two-bone IK of the arm
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
* :func:`ccd` -- Cyclic Coordinate Descent (Welman 1993, the paper's [21]) over a longer
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
* :func:`adapt` -- the whole Section 3.4.2 edit of a clip: ``d(t)``, per frame the limb
  step and CCD where needed, then the feet: the actor's planted feet (contacts detected
  on the original motion by :func:`repro.motion.morphology.foot_contacts`) are kept on
  the ground without sliding by a leg IK (the same two-bone solver) that pins each
  planted ankle, for every contact phase overlapping the edited frames, at its position
  at the start of the phase (or at ``t_0`` if the phase started earlier, so the frame
  ``t_0`` is unchanged), with the foot's original world orientation.  Returns an
  :class:`Adaptation` with the adapted motion (same skeleton; only local rotations
  change, so bone lengths are unchanged by construction -- and checked), per-frame hit
  errors and solver used, and summary numbers.

Targets beyond reach (even with CCD at its joint limits) are not an error: the result is
the best effort with ``reached=False`` and the residual distance.  Bad inputs (NaN
targets, unknown effectors, ``t_0 > t_c``, frames out of range, chains that are not on
the effector's path) raise :class:`repro.errors.MotionError`.

Effectors are roles of :func:`repro.motion.skeleton.find_roles`: ``{side}_fist``,
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

from __future__ import annotations

import dataclasses
import math
import time
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from repro.errors import MotionError
from repro.motion.kinematics import cross as _cross
from repro.motion.kinematics import depth_levels as _levels
from repro.motion.kinematics import fk_arrays as _fk
from repro.motion.kinematics import min_rotation as _min_rotation
from repro.motion.kinematics import normalize as _normalize
from repro.motion.kinematics import qrot as _qrot
from repro.motion.kinematics import transport as _transport
from repro.motion.morphology import foot_contacts
from repro.motion.motion import Motion, finite_vector3, quat_multiply
from repro.motion.skeleton import Skeleton

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

#: Effector role stems and the limb they belong to (``"right_fist"`` -> right arm).
EFFECTOR_STEMS: dict[str, str] = {
    "fist": "arm",
    "hand": "arm",
    "wrist": "arm",
    "foot": "leg",
    "toe": "leg",
    "ankle": "leg",
}

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

_KINDS = ("linear", "smoothstep", "smootherstep")


# ---------------------------------------------------------------------- d(t)
def _ease(u: np.ndarray, kind: str) -> np.ndarray:
    if kind == "linear":
        return u
    if kind == "smoothstep":
        return u * u * (3.0 - 2.0 * u)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)  # smootherstep


def _check_int(name: str, v, lo: int, hi: int) -> int:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise MotionError(f"{name} must be an integer frame index, got {v!r}")
    v = int(v)
    if not lo <= v <= hi:
        raise MotionError(f"{name}={v} is out of range [{lo}, {hi}]")
    return v


def _vec3(name: str, v) -> np.ndarray:
    return finite_vector3(v, name, MotionError)


def offset_curve(
    t0: int, tc: int, d_tc, frames: int, kind: str = "smoothstep", release: int | None = None
) -> np.ndarray:
    """The continuous constraint offset ``d(t)`` of Section 3.4.2.

    ``d(t) = 0`` for ``t <= t0``, ``d(t) = s((t - t0) / (tc - t0)) d(tc)`` for
    ``t0 < t < tc`` with an easing ``s`` (``s(0) = 0``, ``s(1) = 1``, increasing), and
    ``d(tc)`` at ``tc``.  After ``tc``: held at ``d(tc)`` (``release=None``) or brought
    back to 0 over ``release`` frames with the mirrored easing (``d(tc + release) = 0``;
    the paper does not say what happens after the contact).  With ``t0 == tc`` the
    offset jumps to ``d(tc)`` at ``tc``.

    Parameters
    ----------
    t0, tc : int
        Current frame and contact frame, ``0 <= t0 <= tc < frames``.
    d_tc : (3,) array
        ``X - M(tc)``: the target minus the hit point's position at ``tc``.
    frames : int
        Number of frames F of the clip (> 0).
    kind : {"smoothstep", "linear", "smootherstep"}
        Easing: ``u``, ``3u^2 - 2u^3`` (C1: zero velocity at both ends) or
        ``6u^5 - 15u^4 + 10u^3`` (C2).  All are monotone on [0, 1].
    release : int or None
        Frames after ``tc`` over which ``d`` returns to 0 (``0``: immediately after
        ``tc``); ``None`` holds ``d(tc)`` to the end of the clip.

    Returns
    -------
    (F, 3) array

    Raises
    ------
    repro.errors.MotionError
        Non-integer or out-of-range frames, ``t0 > tc``, non-finite ``d_tc``, unknown
        ``kind``, negative ``release``.
    """
    F = _check_int("frames", frames, 1, 2**62)
    t0 = _check_int("t0", t0, 0, F - 1)
    tc = _check_int("tc", tc, 0, F - 1)
    if t0 > tc:
        raise MotionError(f"t0={t0} is after the contact frame tc={tc}; the offset must grow towards the contact")
    d_tc = _vec3("d_tc", d_tc)
    if kind not in _KINDS:
        raise MotionError(f"kind must be one of {list(_KINDS)}, got {kind!r}")
    if release is not None:
        release = _check_int("release", release, 0, 2**62)
    t = np.arange(F, dtype=float)
    if tc > t0:
        w = _ease(np.clip((t - t0) / (tc - t0), 0.0, 1.0), kind)
    else:
        w = (t >= tc).astype(float)
    w[tc] = 1.0
    if release is None:
        w[tc:] = 1.0
    elif release == 0:
        w[tc + 1:] = 0.0
    else:
        after = t > tc
        w[after] = 1.0 - _ease(np.clip((t[after] - tc) / release, 0.0, 1.0), kind)
    return w[:, None] * d_tc[None, :]


# ------------------------------------------------------------- small helpers
def _qmat(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions ``(x, y, z, w)``, (..., 4) -> (..., 3, 3)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    x2, y2, z2 = x + x, y + y, z + z
    xx, yy, zz = x * x2, y * y2, z * z2
    xy, xz, yz = x * y2, x * z2, y * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1.0 - (yy + zz)
    m[..., 0, 1] = xy - wz
    m[..., 0, 2] = xz + wy
    m[..., 1, 0] = xy + wz
    m[..., 1, 1] = 1.0 - (xx + zz)
    m[..., 1, 2] = yz - wx
    m[..., 2, 0] = xz - wy
    m[..., 2, 1] = yz + wx
    m[..., 2, 2] = 1.0 - (xx + yy)
    return m


def _mv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-vector product broadcast over leading axes."""
    return np.matmul(m, v[..., None])[..., 0]


def _mtv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transposed-matrix-vector product ``m^T v``."""
    return np.matmul(v[..., None, :], m)[..., 0, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _path_fk(ml: np.ndarray, tl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (n, P, 3, 3) and positions (n, P, 3) along a root->joint chain."""
    rw = np.empty_like(ml)
    pw = np.empty_like(tl)
    rw[:, 0] = ml[:, 0]
    pw[:, 0] = tl[:, 0]
    _path_fk_from(ml, tl, rw, pw, 1)
    return rw, pw


def _path_fk_from(ml, tl, rw, pw, k: int) -> None:
    """Recompute world transforms of chain positions ``>= k`` in place."""
    if k == 0:
        rw[:, 0] = ml[:, 0]
        pw[:, 0] = tl[:, 0]
        k = 1
    for i in range(k, ml.shape[1]):
        pw[:, i] = pw[:, i - 1] + _mv(rw[:, i - 1], tl[:, i])
        rw[:, i] = rw[:, i - 1] @ ml[:, i]


def _mat_to_quat(m: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    shape = m.shape[:-2]
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat().reshape(shape + (4,))


def _conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


# --------------------------------------------------------------- the rig
@dataclass(eq=False)
class _Chain:
    """Kinematic facts about one effector of one motion."""

    effector: str  # role
    limb: str  # e.g. "right_arm"
    side: str
    kind: str  # "arm" | "leg"
    hit: int  # effector joint index
    hit_offset: np.ndarray  # (3,) in the hit joint's frame (0 for the joint itself)
    path: np.ndarray  # joint indices root .. hit
    k_prox: int  # positions in path
    k_mid: int
    k_dist: int
    prox: int
    mid: int
    dist: int
    hinge_loc: np.ndarray  # (3,) bending axis of the middle joint, in the proximal frame
    bend_loc: np.ndarray  # (3,) side of the middle joint w.r.t. the limb axis, proximal frame

    @property
    def k_hit(self) -> int:
        return len(self.path) - 1


class _Rig:
    """Per-motion cache: skeleton roles, local translations, effector chains."""

    def __init__(self, motion: Motion, roles=None):
        # a weak reference: the rig is the value of a WeakKeyDictionary keyed by the motion
        self._motion = weakref.ref(motion)
        self.sk = Skeleton.from_motion(motion, roles=roles)
        self.trans = motion.local_translations()
        self.trans.flags.writeable = False
        self.chains: dict[tuple[str, str], _Chain] = {}
        self.levels = _levels(self.sk.parents)
        self._globals = None
        self._contacts = None
        orders = motion.rotation_orders
        self.full_rotation = np.array([len(set(o)) == 3 for o in orders])

    @property
    def motion(self) -> Motion:
        return self._motion()

    @property
    def globals(self) -> tuple[np.ndarray, np.ndarray]:
        if self._globals is None:
            self._globals = self.motion.global_transforms()
        return self._globals

    @property
    def contacts(self) -> np.ndarray:
        if self._contacts is None:
            self._contacts = foot_contacts(self.motion, _globals=self.globals[1], _skeleton=self.sk)
        return self._contacts

    def path_to(self, j: int) -> np.ndarray:
        out = [j]
        par = self.sk.parents
        while par[out[-1]] >= 0:
            out.append(int(par[out[-1]]))
        return np.array(out[::-1], dtype=np.intp)

    def chain(self, effector: str, hit_point: str = "joint") -> _Chain:
        key = (effector, hit_point)
        ch = self.chains.get(key)
        if ch is None:
            ch = self._make_chain(effector, hit_point)
            self.chains[key] = ch
        return ch

    def _make_chain(self, effector: str, hit_point: str) -> _Chain:
        sk = self.sk
        if not isinstance(effector, str):
            raise MotionError(f"effector must be a role name such as 'right_fist', got {effector!r}")
        side, _, stem = effector.partition("_")
        valid = [f"{s}_{t}" for s in ("left", "right") for t in EFFECTOR_STEMS]
        if side not in ("left", "right") or stem not in EFFECTOR_STEMS:
            raise MotionError(f"unknown effector {effector!r}; effectors are {valid}")
        if effector not in sk.roles:
            raise MotionError(
                f"effector {effector!r} is not found on this skeleton (roles found: {sorted(sk.roles)})"
            )
        kind = EFFECTOR_STEMS[stem]
        names = ("shoulder", "elbow", "wrist") if kind == "arm" else ("hip", "knee", "ankle")
        prox, mid, dist = (sk.index(f"{side}_{n}") for n in names)
        hit = sk.index(effector)
        path = self.path_to(hit)
        pl = list(path)
        if dist not in pl:
            raise MotionError(f"effector {effector!r} ({sk.joint_names[hit]}) is not the {names[2]} or below it")
        k_dist = pl.index(dist)
        k_mid, k_prox = k_dist - 1, k_dist - 2
        if k_prox < 1 or pl[k_mid] != mid or pl[k_prox] != prox:
            raise MotionError(f"{side} {kind}: {names} are not a parent-child chain below the root")
        for j in (prox, mid, dist):
            if not self.full_rotation[j]:
                raise MotionError(
                    f"joint {sk.joint_names[j]!r} has no 3-axis rotation channels; the limb cannot be adapted"
                )
        if hit_point == "joint":
            off = np.zeros(3)
        elif hit_point == "end_site":
            es = [o for p, o in zip(sk.end_site_parents, sk.end_site_offsets) if p == hit]
            if not es:
                raise MotionError(f"hit_point='end_site' but joint {sk.joint_names[hit]!r} has no End Site")
            off = np.array(es[0], dtype=float)
        else:
            raise MotionError(f"hit_point must be 'joint' or 'end_site', got {hit_point!r}")
        hinge, bend = self._hinge(prox, mid, dist)
        return _Chain(
            effector=effector,
            limb=f"{side}_{kind}",
            side=side,
            kind=kind,
            hit=hit,
            hit_offset=off,
            path=path,
            k_prox=k_prox,
            k_mid=k_mid,
            k_dist=k_dist,
            prox=prox,
            mid=mid,
            dist=dist,
            hinge_loc=hinge,
            bend_loc=bend,
        )

    def _hinge(self, prox: int, mid: int, dist: int) -> tuple[np.ndarray, np.ndarray]:
        """Clip-wide bending axis of the middle joint and bend side, in the proximal frame."""
        u = self.trans[:, mid]  # upper bone, proximal frame
        lower = _qrot(self.motion.rotations[:, mid], self.trans[:, dist])  # lower bone, proximal frame
        c = _cross(u, lower)
        nu = np.linalg.norm(u, axis=-1) * np.linalg.norm(lower, axis=-1)
        s = np.linalg.norm(c, axis=-1) / np.maximum(nu, 1e-300)
        good = s > np.sin(np.radians(10.0))
        u0 = np.mean(u, axis=0)
        u0 = u0 / np.linalg.norm(u0)
        h = np.sum(c[good] / np.linalg.norm(c[good], axis=-1, keepdims=True), axis=0) if good.any() else np.zeros(3)
        h = h - (h @ u0) * u0
        if np.linalg.norm(h) < 1e-9:
            k = int(np.argmin(np.abs(u0)))
            e = np.zeros(3)
            e[k] = 1.0
            h = np.cross(u0, e)
        h = h / np.linalg.norm(h)
        bend = -np.cross(h, u0)
        return h, bend / np.linalg.norm(bend)


_RIGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _rig(motion: Motion, roles=None) -> _Rig:
    if not isinstance(motion, Motion):
        raise MotionError(f"expected a Motion, got {type(motion).__name__}")
    if roles is not None:
        return _Rig(motion, roles)
    r = _RIGS.get(motion)
    if r is None:
        r = _Rig(motion)
        _RIGS[motion] = r
    return r


def _frames(frames, F: int) -> tuple[np.ndarray, bool]:
    scalar = isinstance(frames, (int, np.integer)) and not isinstance(frames, (bool, np.bool_))
    arr = np.atleast_1d(np.asarray(frames))
    if arr.ndim != 1 or arr.size == 0 or not (np.issubdtype(arr.dtype, np.integer)):
        raise MotionError(f"frames must be an integer frame index or a non-empty 1-D sequence of them, got {frames!r}")
    if np.any((arr < 0) | (arr >= F)):
        bad = arr[(arr < 0) | (arr >= F)]
        raise MotionError(f"frames {bad.tolist()[:5]} out of range [0, {F - 1}]")
    return arr.astype(np.intp), scalar


def _targets(targets, n: int) -> np.ndarray:
    try:
        t = np.asarray(targets, dtype=float)
    except (TypeError, ValueError):
        raise MotionError(f"targets must be numbers, got {targets!r}") from None
    if t.shape == (3,):
        t = np.broadcast_to(t, (n, 3))
    if t.shape != (n, 3):
        raise MotionError(f"targets must be (3,) or ({n}, 3), got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise MotionError("targets contain NaN or inf")
    return t


def _start_rotations(motion: Motion, idx: np.ndarray, rotations) -> np.ndarray:
    if rotations is None:
        return np.array(motion.rotations[idx])
    r = np.array(rotations, dtype=float)
    if r.shape != (len(idx), motion.n_joints, 4):
        raise MotionError(f"rotations must be ({len(idx)}, {motion.n_joints}, 4), got {r.shape}")
    if not np.all(np.isfinite(r)):
        raise MotionError("rotations contain NaN or inf")
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


# ------------------------------------------------------- limb: batched numpy
def _limb_batch(
    ch: _Chain,
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
    ml = _qmat(rot[:, P])
    rw, pw = _path_fk(ml, trans[:, P])
    kp, km, kd = ch.k_prox, ch.k_mid, ch.k_dist
    S, E0, W0 = pw[:, kp], pw[:, km], pw[:, kd]
    hit_rel = pw[:, -1] + _mv(rw[:, -1], ch.hit_offset) - W0
    if distal_world is not None:  # the hit point turns with the distal joint's new orientation
        hit_rel = _qrot(distal_world, _mtv(rw[:, kd], hit_rel))
    Wg = goal - hit_rel
    # lengths (from the pose: equal to the offsets unless position channels say otherwise)
    e0 = E0 - S
    le = W0 - E0
    l1 = np.linalg.norm(e0, axis=-1)
    l2 = np.linalg.norm(le, axis=-1)
    w0 = W0 - S
    a_orig, n0 = _normalize(w0)
    ax = Wg - S
    a, dn = _normalize(ax)
    a = np.where((dn > 1e-12 * l1)[:, None], a, a_orig)
    # original swivel: side of the elbow / knee w.r.t. the proximal->distal axis
    ep = e0 - _dot(e0, a_orig)[:, None] * a_orig
    r = np.linalg.norm(ep, axis=-1)
    fb = _mv(rw[:, kp], ch.bend_loc)
    fb = fb - _dot(fb, a_orig)[:, None] * a_orig
    b0 = np.where((r > 1e-6 * l1)[:, None], ep, fb)
    b0 = _normalize(b0)[0]
    u = _transport(a_orig, b0, a)
    if dmax is None:
        dmax = np.minimum(l1 + l2, np.maximum(max_extension * (l1 + l2), n0))
    dc = np.clip(dn, np.abs(l1 - l2), np.maximum(dmax, np.abs(l1 - l2)))
    cosb = np.clip((l1 * l1 + dc * dc - l2 * l2) / (2.0 * l1 * np.maximum(dc, 1e-300)), -1.0, 1.0)
    sinb = np.sqrt(1.0 - cosb * cosb)
    Es = S + (l1 * cosb)[:, None] * a + (l1 * sinb)[:, None] * u
    Wr = S + dc[:, None] * a
    q1 = _min_rotation(e0, Es - S)
    W1 = S + _qrot(q1, w0)
    q2 = _min_rotation(W1 - Es, Wr - Es)
    # local corrections: a world rotation D applied below joint j is, in j's parent
    # frame with world rotation R, the quaternion (R^T d_v, d_w)
    d1 = np.concatenate([_mtv(rw[:, kp - 1], q1[:, :3]), q1[:, 3:]], axis=-1)
    r_prox_new = _qmat(q1) @ rw[:, kp]
    d2 = np.concatenate([_mtv(r_prox_new, q2[:, :3]), q2[:, 3:]], axis=-1)
    q21 = quat_multiply(q2, q1)
    pr, md, ds = ch.prox, ch.mid, ch.dist
    if distal_world is None:
        d3 = np.concatenate([_mtv(rw[:, km], -q21[:, :3]), q21[:, 3:]], axis=-1)
        new = quat_multiply(np.stack([d1, d2, d3], axis=1), rot[:, [pr, md, ds]])
        rot[:, [pr, md, ds]] = new
    else:
        new = quat_multiply(np.stack([d1, d2], axis=1), rot[:, [pr, md]])
        rot[:, [pr, md]] = new
        r_mid_new = _qmat(q21) @ rw[:, km]
        rot[:, ds] = _mat_to_quat(np.swapaxes(r_mid_new, -1, -2) @ _qmat(distal_world))
    hit = Wr + hit_rel
    return hit, np.abs(dn - dc)


# ------------------------------------------------------ limb: scalar (1 frame)
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
        return tuple(_min_rotation(np.array(u), np.array(v)).tolist())
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


def _limb_scalar(ch: _Chain, rot: np.ndarray, trans: np.ndarray, goal, max_extension: float = 1.0):
    """One-frame version of :func:`_limb_batch` (no ``distal_world``) in Python floats.

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
    gp_new = _s_qmul(q1, qw[kp])
    d2 = _s_qmul(_s_qmul(inv(gp_new), q2), gp_new)
    q21 = _s_qmul(q2, q1)
    gm = qw[km]
    d3 = _s_qmul(_s_qmul(inv(gm), inv(q21)), gm)
    rot[ch.prox] = _s_qmul(d1, ql[kp])
    rot[ch.mid] = _s_qmul(d2, ql[km])
    rot[ch.dist] = _s_qmul(d3, ql[kd])
    return _s_add(Wr, hit_rel), abs(dn - dc)


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


def _check_extension(v) -> float:
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise MotionError(f"max_extension must be a number in (0, 1], got {v!r}") from None
    if not (0.0 < v <= 1.0):
        raise MotionError(f"max_extension must be in (0, 1], got {v!r}")
    return v


def _default_tol(rig: _Rig, ch: _Chain) -> float:
    L = rig.sk.limb_lengths[ch.limb]
    return 1e-4 * L


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
        Role table (default: :func:`~repro.motion.skeleton.find_roles`).

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
    rig = _rig(motion, roles)
    ch = rig.chain(effector, hit_point)
    idx, scalar = _frames(frames, motion.n_frames)
    goal = _targets(targets, len(idx))
    tol = _default_tol(rig, ch) if tol is None else float(tol)
    ext = _check_extension(max_extension)
    rot = _start_rotations(motion, idx, rotations)
    if len(idx) == 1:
        hit, res = _limb_scalar(ch, rot[0], rig.trans[idx[0]], goal[0].tolist(), ext)
        hit = np.array([hit])
        res = np.array([res])
    else:
        hit, res = _limb_batch(ch, rot, rig.trans[idx], goal, max_extension=ext)
    return LimbSolution(frames=idx, rotations=rot, hit_positions=hit, residual=res, reached=res <= tol)


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
    rig = _rig(motion, roles)
    return _default_chain(rig, rig.chain(effector), include_pelvis)


def _default_chain(rig: _Rig, ch: _Chain, include_pelvis: bool | None = None) -> list[str]:
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


def _check_limits(rig: _Rig, limits: Mapping[str, float] | None) -> dict[str, float]:
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
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise MotionError(f"limit for {k!r} must be a number of degrees, got {v!r}") from None
        if not (np.isfinite(v) and 0 <= v <= 180):
            raise MotionError(f"limit for {k!r} must be in [0, 180] degrees, got {v!r}")
        lim[k] = float(np.radians(v))
    return lim


def _limit_of(rig: _Rig, j: int, lim: dict[str, float]) -> float:
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


def _spine_joints(rig: _Rig) -> set[int]:
    sk = rig.sk
    try:
        return set(sk.path("pelvis", "chest"))
    except MotionError:
        return set()


def _ccd_spec(rig: _Rig, ch: _Chain, chain, limits, hinge_range_deg):
    sk = rig.sk
    if isinstance(chain, str):
        raise MotionError(f"chain must be a sequence of joint names or roles, got the string {chain!r}")
    names = _default_chain(rig, ch) if chain is None else list(chain)
    if not names:
        raise MotionError("the CCD chain is empty")
    pl = [int(j) for j in ch.path]
    lim = _check_limits(rig, limits)
    spec = []
    try:
        lo, hi = (float(np.radians(float(x))) for x in hinge_range_deg)
    except (TypeError, ValueError):
        raise MotionError(f"hinge_range_deg must be two numbers (lo, hi) in degrees, got {hinge_range_deg!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
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


def _limb_dmax(ch: _Chain, ref: np.ndarray, trans: np.ndarray, max_extension: float) -> np.ndarray:
    """Per frame ``min(L, max(max_extension * L, |distal - proximal|))`` in the pose ``ref``."""
    P = ch.path[: ch.k_dist + 1]
    _, pw = _path_fk(_qmat(ref[:, P]), trans[:, P])
    L = np.linalg.norm(trans[:, ch.mid], axis=-1) + np.linalg.norm(trans[:, ch.dist], axis=-1)
    d = np.linalg.norm(pw[:, ch.k_dist] - pw[:, ch.k_prox], axis=-1)
    return np.minimum(L, np.maximum(max_extension * L, d))


def _distal_world(ch: _Chain, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(n, 4) world orientation of the limb's distal joint in the pose ``rot``."""
    P = ch.path[: ch.k_dist + 1]
    rw, _ = _path_fk(_qmat(rot[:, P]), trans[:, P])
    return _mat_to_quat(rw[:, -1])


def _ccd_batch(
    rig: _Rig, ch: _Chain, rot, trans, goal, ref, spec, max_iter: int, tol: float, finish: bool = True, dmax=None
):
    """Vectorised CCD; ``rot`` (n, J, 4) modified in place.  Returns (iterations, hit).

    ``dmax`` (n,): largest proximal->distal distance the limb step may use (default the
    limb length); with ``finish`` the objective is the distance of the goal beyond it.
    """
    P = ch.path
    n = goal.shape[0]
    ql = rot[:, P].copy()
    q0 = ref[:, P]
    ml = _qmat(ql)
    tl = trans[:, P]
    rw, pw = _path_fk(ml, tl)
    kp, km, kd = ch.k_prox, ch.k_mid, ch.k_dist
    l1 = np.linalg.norm(tl[:, km], axis=-1)
    l2 = np.linalg.norm(tl[:, kd], axis=-1)
    L = l1 + l2
    reach_max = L if dmax is None else np.minimum(dmax, L)
    tiny = 1e-9 * L
    active = np.ones(n, dtype=bool)
    iters = np.zeros(n, dtype=np.intp)
    best_err = np.full(n, np.inf)
    best_ql = ql.copy()
    h_loc = ch.hinge_loc
    # with the analytic finish, the limb's own joints are left to the limb step: only
    # the joints above the limb change how far the goal is out of the limb's reach
    sweep = [s for s in spec if not (finish and s[0] >= kp)]

    def hitpos():
        return pw[:, -1] + _mv(rw[:, -1], ch.hit_offset)

    # with the finish, the hand / foot keeps its start world orientation (the limb step
    # restores it), so the distal joint's goal does not move while the trunk turns
    Wg_fixed = goal - (hitpos() - pw[:, kd])
    for it in range(max_iter + 1):
        hit = hitpos()
        if finish:
            # objective: how far the goal is out of the limb's reach (the analytic limb
            # step then places the hit point exactly)
            dW = np.linalg.norm(Wg_fixed - pw[:, kp], axis=-1)
            err = np.maximum(np.maximum(dW - reach_max, np.abs(l1 - l2) - dW), 0.0)
            done = err <= 0.0
        else:
            err = np.linalg.norm(hit - goal, axis=-1)
            done = err <= tol
        better = err < best_err
        worse = active & ~better
        if worse.any():  # a sweep that made things worse is undone, and the frame stops
            ql[worse] = best_ql[worse]
            ml[worse] = _qmat(ql[worse])
            rw[worse], pw[worse] = _path_fk(ml[worse], tl[worse])
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
            hit = hitpos()
            pj = pw[:, k]
            if finish and k < kp:
                # above the limb: bring the proximal joint (shoulder / hip) to the nearest
                # point from which the limb reaches the goal
                S = pw[:, kp]
                sw = S - Wg_fixed
                dist = np.linalg.norm(sw, axis=-1)
                want = np.clip(dist, np.abs(l1 - l2), np.maximum(reach_max, np.abs(l1 - l2)))
                e = S - pj
                g = Wg_fixed + (want / np.maximum(dist, 1e-300))[:, None] * sw - pj
            else:
                e = hit - pj
                g = goal - pj
            if kind == "hinge":
                h = _mv(rw[:, k - 1], h_loc)
                ep = e - _dot(e, h)[:, None] * h
                gp = g - _dot(g, h)[:, None] * h
                theta = np.arctan2(_dot(h, _cross(ep, gp)), _dot(ep, gp))
                up = tl[:, k]
                lw = _mv(ml[:, k], tl[:, k + 1])
                up = up - (up @ h_loc)[:, None] * h_loc
                lw = lw - (lw @ h_loc)[:, None] * h_loc
                phi = np.arctan2(_cross(up, lw) @ h_loc, _dot(up, lw))
                lo = np.minimum(lim[0], phi)
                hi = np.maximum(lim[1], phi)
                th = np.where(active, np.clip(phi + theta, lo, hi) - phi, 0.0)
                dq = np.concatenate([np.sin(0.5 * th)[:, None] * h_loc, np.cos(0.5 * th)[:, None]], axis=-1)
                qn = quat_multiply(dq, ql[:, k])
            else:
                q = _min_rotation(e, g)
                v = q[:, :3] if k == 0 else _mtv(rw[:, k - 1], q[:, :3])
                qn = quat_multiply(np.concatenate([v, q[:, 3:]], axis=-1), ql[:, k])
                dev = quat_multiply(qn, _conj(q0[:, k]))
                dev = np.where(dev[:, 3:] < 0, -dev, dev)
                s = np.linalg.norm(dev[:, :3], axis=-1)
                ang = 2.0 * np.arctan2(s, dev[:, 3])
                over = ang > lim
                if over.any():
                    axis = dev[over, :3] / s[over, None]
                    cos_half = np.full((axis.shape[0], 1), np.cos(0.5 * lim))
                    dl = np.concatenate([axis * np.sin(0.5 * lim), cos_half], axis=-1)
                    qn[over] = quat_multiply(dl, q0[over, k])
                qn = np.where(active[:, None], qn, ql[:, k])
            qn = qn / np.linalg.norm(qn, axis=-1, keepdims=True)
            ql[:, k] = qn
            ml[:, k] = _qmat(qn)
            _path_fk_from(ml, tl, rw, pw, k)
    rot[:, P] = ql
    return iters, hitpos()


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
) -> CCDSolution:
    """Cyclic Coordinate Descent over a longer chain (Section 3.4.2, after Welman 1993).

    Used "when the constraint is not reachable by only using the corresponding limb".
    Each sweep visits the joints of ``chain`` from distal to proximal and turns each by
    the smallest rotation that points it at its goal; ball joints are then clamped to a
    cone of ``limits`` around their *original* local rotation (the motion's, not
    ``rotations``); the middle joint of the limb (elbow / knee) is a hinge: it turns
    only about its clip-wide bending axis and its flexion stays within
    ``hinge_range_deg`` (0 = straight), so it bends one way and never hyperextends.

    With ``finish_with_limb`` (default) the joints above the limb aim the limb's root
    (shoulder / hip) at the nearest point from which the limb reaches the goal, the
    objective being the distance of the goal beyond the limb's reach with the hand /
    foot keeping its start world orientation; the limb's own joints are left to the
    analytic limb step (:func:`reach_limb`), which then places the hit point exactly when
    it can.  Without it, plain CCD: every chain joint aims the hit point at the goal.

    A sweep that makes a frame's objective worse is undone.  Sweeps stop, per frame, when
    the goal is reached, when a sweep gains less than 5 % of the remaining objective
    (creeping along joint limits), or after ``max_iter`` sweeps -- so it always
    terminates.
    Frames are solved independently but together (vectorised over frames).

    Parameters
    ----------
    motion : Motion
    frames : int or sequence of int
    effector : str
        Effector role, e.g. ``"right_fist"``.
    targets : (3,) or (n, 3) array
        Goals of the hit point, motion units.
    rotations : (n, J, 4), optional
        Start pose (e.g. the :func:`reach_limb` result); default the motion's.
    chain : sequence of str, optional
        Joint names or roles, each an ancestor of the wrist / ankle (default
        :func:`default_chain`).
    limits : mapping, optional
        Degrees, keyed by joint name, role, or kind (``"shoulder"``, ``"hip"``,
        ``"clavicle"``, ``"spine"``, ``"pelvis"``, ``"other"``); defaults
        :data:`DEFAULT_LIMITS_DEG`.
    hinge_range_deg : (float, float)
        Flexion range of the elbow / knee (a pose already outside is not pushed
        further out).
    max_iter : int
        Maximum sweeps (>= 0).
    tol : float, optional
        Motion units; default 1e-4 of the limb length.
    finish_with_limb : bool
        With it, CCD works until the goal is within the limb's reach (the objective is
        the distance beyond it) and the limb step finishes; without it, CCD alone works
        on the hit point's distance to the goal.
    max_extension : float, default 1
        Reach allowed to the limb step, fraction of the limb length, never less than the
        motion's own extension on the frame (see :func:`reach_limb`).  Frames still out
        of reach after CCD are finished with the full reach (best effort).
    hit_point : {"joint", "end_site"}
    roles : mapping, optional

    Returns
    -------
    CCDSolution
        Unreachable goals give the best effort, ``reached=False`` and the residual.

    Raises
    ------
    repro.errors.MotionError
        Unknown effector, frames out of range, NaN targets, a chain joint that is not an
        ancestor of the limb's distal joint, bad limits.
    """
    rig = _rig(motion, roles)
    ch = rig.chain(effector, hit_point)
    idx, _ = _frames(frames, motion.n_frames)
    goal = np.array(_targets(targets, len(idx)))
    tol = _default_tol(rig, ch) if tol is None else float(tol)
    max_iter = _check_int("max_iter", max_iter, 0, 10**6)
    ext = _check_extension(max_extension)
    rot = _start_rotations(motion, idx, rotations)
    spec = _ccd_spec(rig, ch, chain, limits, hinge_range_deg)
    trans = rig.trans[idx]
    ref = np.asarray(motion.rotations[idx])
    dmax = _limb_dmax(ch, ref, trans, ext)
    dw = _distal_world(ch, rot, trans) if finish_with_limb else None
    iters, hit = _ccd_batch(rig, ch, rot, trans, goal, ref, spec, max_iter, tol, finish_with_limb, dmax)
    if finish_with_limb:
        hit, res = _limb_batch(ch, rot, trans, goal, distal_world=dw, dmax=dmax)
        far = res > tol
        if ext < 1.0 and far.any():
            r = rot[far]
            hit[far], _ = _limb_batch(ch, r, trans[far], goal[far], distal_world=dw[far])
            rot[far] = r
    res = np.linalg.norm(hit - goal, axis=-1)
    return CCDSolution(
        frames=idx,
        rotations=rot,
        hit_positions=hit,
        residual=res,
        reached=res <= tol,
        iterations=iters,
        chain=[rig.sk.joint_names[int(ch.path[k])] for k, _, _ in spec],
    )


# ---------------------------------------------------------------------- adapt
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
    rig = _rig(motion, roles)
    ch = rig.chain(effector, hit_point)
    F = motion.n_frames
    X = _vec3("target", target)
    t0 = _check_int("t0", t0, 0, F - 1)
    tc = _check_int("tc", tc, 0, F - 1)
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
    tol = _default_tol(rig, ch) if tol is None else float(tol)
    if not np.isfinite(tol) or tol <= 0:
        raise MotionError(f"tol must be finite and > 0, got {tol!r}")
    ext = _check_extension(max_extension)
    spec = _ccd_spec(rig, ch, chain, limits, hinge_range_deg)
    max_iter = _check_int("max_iter", max_iter, 0, 10**6)

    gq, gp = rig.globals
    p = gp[:, ch.hit] + _qrot(gq[:, ch.hit], ch.hit_offset)
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
        dmax = _limb_dmax(ch, r, trans, ext)
        hit, res = _limb_batch(ch, r, trans, goals[edit], dmax=dmax)
        timings["limb"] = time.perf_counter() - t1
        solver[edit] = "limb"
        bad = res > tol
        if bad.any():
            t1 = time.perf_counter()
            fb = edit[bad]
            rb = r[bad]
            tb = trans[bad]
            it, _ = _ccd_batch(
                rig, ch, rb, tb, goals[fb], np.asarray(motion.rotations[fb]), spec, max_iter, tol, True, dmax[bad]
            )
            dw = gq[fb, ch.dist]  # the hand / foot keeps its original world orientation
            _, res_b = _limb_batch(ch, rb, tb, goals[fb], distal_world=dw, dmax=dmax[bad])
            far = res_b > tol
            if ext < 1.0 and far.any():  # best effort: full reach
                rf = rb[far]
                _limb_batch(ch, rf, tb[far], goals[fb[far]], distal_world=dw[far])
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
                hit, res = _limb_batch(leg, rf, rig.trans[fr], goal[fr], distal_world=gq[fr, ank])
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
        gq2[cf], gp2[cf] = _fk(rig.levels, rot[cf], rig.trans[cf])
    hit_new = p.copy()
    hit_new[cf] = gp2[cf, ch.hit] + _qrot(gq2[cf, ch.hit], ch.hit_offset)
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


# ------------------------------------------------------------------- timing
def time_adaptation(motion: Motion, effector: str, *, frames=None, offset=(0.0, 0.0, 0.1), repeats: int = 7) -> dict:
    """Best-of-``repeats`` wall time per frame of the solvers (seconds), for reports.

    The paper: "If only the limb is involved, this method only requires 88 us" per frame.
    Measures, on ``frames`` (default: every frame) with goals = original hit point +
    ``offset``:

    * ``limb_batch_per_frame``: :func:`reach_limb` on all frames at once, divided by the
      number of frames;
    * ``limb_single_frame``: :func:`reach_limb` on one frame (median over the frames of a
      sample of 200), the frame-by-frame use of the paper;
    * ``ccd_batch_per_frame``: :func:`ccd` (from the limb result, then the limb again)
      on all frames at once, per frame, with goals moved 3 times as far, and the mean
      number of sweeps ``ccd_mean_iterations``.

    The tests never assert on time.
    """
    rig = _rig(motion)
    ch = rig.chain(effector)
    idx = np.arange(motion.n_frames) if frames is None else _frames(frames, motion.n_frames)[0]
    gq, gp = rig.globals
    p = gp[idx, ch.hit] + _qrot(gq[idx, ch.hit], ch.hit_offset)
    off = _vec3("offset", offset)
    goal = p + off
    best_b = best_c = np.inf
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        reach_limb(motion, idx, effector, goal)
        best_b = min(best_b, time.perf_counter() - t)
    pos = np.linspace(0, len(idx) - 1, min(200, len(idx))).astype(int)
    single = []
    for f, g in zip(idx[pos], goal[pos]):
        reach_limb(motion, int(f), effector, g)  # warm
        t = time.perf_counter()
        reach_limb(motion, int(f), effector, g)
        single.append(time.perf_counter() - t)
    goal_far = p + 3.0 * off
    its = None
    for _ in range(max(1, min(repeats, 3))):
        lr = reach_limb(motion, idx, effector, goal_far)
        t = time.perf_counter()
        sol = ccd(motion, idx, effector, goal_far, rotations=lr.rotations)
        best_c = min(best_c, time.perf_counter() - t)
        its = sol.iterations
    n = len(idx)
    return {
        "frames": float(n),
        "limb_batch_per_frame": best_b / n,
        "limb_single_frame": float(np.median(single)),
        "ccd_batch_per_frame": best_c / n,
        "ccd_mean_iterations": float(np.mean(its)),
        "ccd_frames_iterating": float(np.sum(its > 0)),
    }
