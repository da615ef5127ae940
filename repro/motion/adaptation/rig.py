"""The per-motion rig the solvers share: effector chains, cached globals, argument checks.

A :class:`Rig` caches, per :class:`~repro.motion.core.motion.Motion` (weakly), the skeleton
roles, local translations, global transforms, foot contacts and one :class:`Chain` per
effector (the path root -> hit point, the hit point on the effector joint, the limb's proximal /
middle / distal joints and the clip-wide bending axis of the middle joint).  Forward kinematics
along such a path is :func:`repro.motion.core.kinematics.chain_fk` /
:func:`~repro.motion.core.kinematics.chain_fk_from`.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from repro.checks import as_real, as_real_array
from repro.errors import MotionError
from repro.motion.body.feet import foot_contacts
from repro.motion.body.hit_points import hit_offset
from repro.motion.core.kinematics import depth_levels
from repro.motion.core.quaternion import cross
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.core.motion import MAX_COORDINATE, Motion, finite_vector3
from repro.motion.body.skeleton import Skeleton

__all__ = [
    "EFFECTOR_STEMS",
    "Chain",
    "Rig",
    "rig_of",
    "vec3",
    "check_frames",
    "check_targets",
    "start_rotations",
    "check_extension",
    "default_tol",
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


def vec3(name: str, v) -> np.ndarray:
    return finite_vector3(v, name, MotionError)


# --------------------------------------------------------------- the rig
@dataclass(eq=False)
class Chain:
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


class Rig:
    """Per-motion cache: skeleton roles, local translations, effector chains."""

    def __init__(self, motion: Motion, roles=None):
        # a weak reference: the rig is the value of a WeakKeyDictionary keyed by the motion
        self._motion = weakref.ref(motion)
        self.sk = _skeleton_of(motion, roles)
        self.trans = motion.local_translations()
        self.trans.flags.writeable = False
        self.chains: dict[tuple[str, str], Chain] = {}
        self.levels = depth_levels(self.sk.parents)
        self._globals = None
        self._contacts = None
        self._foot_drops: dict[str, np.ndarray] = {}
        self._unshifted: Rig | None = None  # a root-shifted rig's input (moved): the foot drops are its
        orders = motion.rotation_orders
        self.full_rotation = np.array([len(set(o)) == 3 for o in orders])

    @property
    def motion(self) -> Motion:
        return self._motion()

    def moved(self, motion: Motion) -> Rig:
        """The rig of ``motion``, the same clip with only its root positions changed (a root shift).

        Shares what does not depend on the root trajectory: the skeleton and its roles,
        the depth levels and the effector chains (their paths, hit offsets and hinge axes
        come from the joint tree, the rotations and the non-root translations); the local
        translations and the global transforms are the new motion's.  Not cached in
        :func:`rig_of` (one root-shift trial uses it once).
        """
        new = Rig.__new__(Rig)
        new._motion = weakref.ref(motion)
        new.sk = self.sk
        new.trans = motion.local_translations()
        new.trans.flags.writeable = False
        new.chains = dict(self.chains)
        new.levels = self.levels
        new._globals = None
        new._contacts = None
        new._foot_drops = {}
        new._unshifted = self if self._unshifted is None else self._unshifted  # same rotations, same drops
        new.full_rotation = self.full_rotation
        return new

    @property
    def globals(self) -> tuple[np.ndarray, np.ndarray]:
        if self._globals is None:
            self._globals = self.motion.global_transforms()
        return self._globals

    @property
    def contacts(self) -> np.ndarray:
        if self._contacts is None:
            self._contacts = foot_contacts(self.motion, global_positions=self.globals[1], skeleton=self.sk)
        return self._contacts

    def foot_drop(self, side: str) -> np.ndarray:
        """(F,) how far the foot reaches below its ankle, per frame: the lowest of the ankle, the joints
        below it and their End Sites (the toe tips), minus the ankle's height (<= 0).

        Depends on the rotations only: it holds wherever the foot keeps its world orientation
        (the limb step and the foot pins keep it), so an ankle goal ``g`` puts the foot's lowest
        point at ``g[1] + foot_drop``.
        """
        if self._unshifted is not None:  # the same numbers however the trials are ordered
            return self._unshifted.foot_drop(side)
        drop = self._foot_drops.get(side)
        if drop is None:
            ank = self.sk.index(f"{side}_ankle")
            gq, gp = self.globals
            below = np.zeros(self.sk.n_joints, dtype=bool)
            below[ank] = True
            for j in range(ank + 1, self.sk.n_joints):  # parents come before their children
                below[j] = below[self.sk.parents[j]]
            low = gp[:, below, 1].min(axis=1)
            motion = self.motion
            ends = np.flatnonzero(below[motion.end_site_parents])
            if ends.size:
                par = motion.end_site_parents[ends]
                tips = gp[:, par] + qrot(gq[:, par], motion.end_site_offsets[ends][None])
                low = np.minimum(low, tips[..., 1].min(axis=1))
            drop = low - gp[:, ank, 1]
            drop.flags.writeable = False
            self._foot_drops[side] = drop
        return drop

    def path_to(self, j: int) -> np.ndarray:
        out = [j]
        par = self.sk.parents
        while par[out[-1]] >= 0:
            out.append(int(par[out[-1]]))
        return np.array(out[::-1], dtype=np.intp)

    def chain(self, effector: str, hit_point: str = "joint") -> Chain:
        if not isinstance(effector, str):  # before the cache lookup: a list is no key
            raise MotionError(f"effector must be a role name such as 'right_fist', got {effector!r}")
        if not isinstance(hit_point, str):
            raise MotionError(f"hit_point must be 'joint' or 'end_site', got {hit_point!r}")
        key = (effector, hit_point)
        ch = self.chains.get(key)
        if ch is None:
            ch = self._make_chain(effector, hit_point)
            self.chains[key] = ch
        return ch

    def _make_chain(self, effector: str, hit_point: str) -> Chain:
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
        # the middle and proximal joints above the distal one; twist joints between them are carried
        # along by the limb step (repro.motion.adaptation.limb)
        k_mid = pl.index(mid) if mid in pl[:k_dist] else -1
        k_prox = pl.index(prox) if prox in pl[:max(k_mid, 0)] else -1
        if k_prox < 1:
            raise MotionError(f"{side} {kind}: {names} are not a chain down the tree below the root")
        for j in (prox, mid, dist):
            if not self.full_rotation[j]:
                raise MotionError(
                    f"joint {sk.joint_names[j]!r} has no 3-axis rotation channels; the limb cannot be adapted"
                )
        if hit_point == "joint":
            off = np.zeros(3)
        elif hit_point == "end_site":  # the tip: its End Site, else its fingers' knuckles (a hand), ...
            off = hit_offset(sk, hit)[0]
        else:
            raise MotionError(f"hit_point must be 'joint' or 'end_site', got {hit_point!r}")
        hinge, bend = self._hinge(prox, mid, dist) if k_dist - k_prox == 2 else self._hinge_of_segments(prox, mid, dist)
        return Chain(
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
        lower = qrot(self.motion.rotations[:, mid], self.trans[:, dist])  # lower bone, proximal frame
        return self._hinge_of(u, lower)

    def _hinge_of_segments(self, prox: int, mid: int, dist: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_hinge` of a limb with twist joints inside its bones: the proximal->middle and
        middle->distal segments from the world transforms, in the proximal frame."""
        gq, gp = self.globals
        inv = gq[:, prox] * np.array([-1.0, -1.0, -1.0, 1.0])
        return self._hinge_of(qrot(inv, gp[:, mid] - gp[:, prox]), qrot(inv, gp[:, dist] - gp[:, mid]))

    @staticmethod
    def _hinge_of(u: np.ndarray, lower: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bending axis and bend side, in the proximal frame, of upper and lower bones ``u``, ``lower`` (F, 3)."""
        c = cross(u, lower)
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


#: Most skeletons :func:`_skeleton_of` keeps (one per character and database actor in use).
MAX_CACHED_SKELETONS: int = 64
#: what :meth:`Skeleton.from_motion` reads of a motion -> its skeleton (every clip of one character shares it)
_SKELETONS: dict = {}


def _skeleton_of(motion: Motion, roles) -> Skeleton:
    """``Skeleton.from_motion(motion, roles=roles)``, made once per skeleton: a character's clips (every
    order's) share their joints, offsets, End Sites and unit, and the roles found on them.  A motion
    without a unit (its inference warns on each call) or with a role table is not cached."""
    if roles is not None or motion.unit_m is None:
        return Skeleton.from_motion(motion, roles=roles)
    key = (tuple(motion.joint_names), motion.parents.tobytes(), motion.offsets.tobytes(), tuple(motion.channels),
           motion.end_site_parents.tobytes(), motion.end_site_offsets.tobytes(), motion.unit_m)
    sk = _SKELETONS.get(key)
    if sk is None:
        sk = Skeleton.from_motion(motion)
        if len(_SKELETONS) >= MAX_CACHED_SKELETONS:  # the oldest goes
            _SKELETONS.pop(next(iter(_SKELETONS)))
        _SKELETONS[key] = sk
    return sk


#: one :class:`Rig` per live motion (:func:`rig_of` without ``roles``), bounded by the motions' lifetime:
#: weak keys, and a rig holds its motion weakly, so an entry (its translations, globals, contacts: a few
#: arrays of the motion's own size) goes when the motion is freed, and never outlives it
_RIGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def rig_of(motion: Motion, roles=None) -> Rig:
    if not isinstance(motion, Motion):
        raise MotionError(f"expected a Motion, got {type(motion).__name__}")
    if roles is not None:
        return Rig(motion, roles)
    r = _RIGS.get(motion)
    if r is None:
        r = Rig(motion)
        _RIGS[motion] = r
    return r


def check_frames(frames, F: int) -> tuple[np.ndarray, bool]:
    scalar = isinstance(frames, (int, np.integer)) and not isinstance(frames, (bool, np.bool_))
    if isinstance(frames, (bool, np.bool_)):
        raise MotionError(f"frames must be an integer frame index or a non-empty 1-D sequence of them, got {frames!r}")
    try:  # (a range of 10**12 frames is refused against the memory budget, not expanded)
        arr = np.atleast_1d(as_real_array(frames, "frames", error=MotionError, integer=True))
    except MotionError as e:
        raise MotionError(f"frames must be an integer frame index or a non-empty 1-D sequence of them: {e}") from None
    if arr.ndim != 1 or arr.size == 0 or not (np.issubdtype(arr.dtype, np.integer)):
        raise MotionError(f"frames must be an integer frame index or a non-empty 1-D sequence of them, got {frames!r}")
    if np.any((arr < 0) | (arr >= F)):
        bad = arr[(arr < 0) | (arr >= F)]
        raise MotionError(f"frames {bad.tolist()[:5]} out of range [0, {F - 1}]")
    return arr.astype(np.intp), scalar


def check_targets(targets, n: int) -> np.ndarray:
    t = as_real_array(targets, "targets", error=MotionError, finite=False)
    if t.shape == (3,):
        t = np.broadcast_to(t, (n, 3))
    if t.shape != (n, 3):
        raise MotionError(f"targets must be (3,) or ({n}, 3), got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise MotionError("targets contain NaN or inf")
    if t.size and np.abs(t).max() > MAX_COORDINATE:
        raise MotionError(f"targets have coordinates beyond {MAX_COORDINATE:g}: their squares overflow float64")
    return t


def start_rotations(motion: Motion, idx: np.ndarray, rotations) -> np.ndarray:
    if rotations is None:
        return np.array(motion.rotations[idx])
    r = np.array(as_real_array(rotations, "rotations", error=MotionError, finite=False))
    if r.shape != (len(idx), motion.n_joints, 4):
        raise MotionError(f"rotations must be ({len(idx)}, {motion.n_joints}, 4), got {r.shape}")
    if not np.all(np.isfinite(r)):
        raise MotionError("rotations contain NaN or inf")
    n = np.linalg.norm(r, axis=-1, keepdims=True)
    if not np.all((n > 1e-12) & np.isfinite(n)):  # a zero (or overflowing) quaternion is no rotation
        raise MotionError("rotations must be non-zero quaternions of finite length")
    return r / n


def check_extension(v) -> float:
    return as_real(v, "max_extension", error=MotionError, lo=0.0, hi=1.0, lo_open=True)


def default_tol(rig: Rig, ch: Chain) -> float:
    L = rig.sk.limb_lengths[ch.limb]
    return 1e-4 * L
