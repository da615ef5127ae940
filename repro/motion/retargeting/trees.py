"""Retargeting onto a character whose joint tree differs from the motion's (Section 3.4.1).

Kulpa et al. (2005), on which Pronost et al. build, store a motion so that characters with
*different skeletons* can play it.  :mod:`repro.motion.retargeting.morphology` keeps the joint tree
(it copies local rotations); this module goes through the body-part roles
(:func:`repro.motion.body.roles.find_roles`) instead, so the character may have more or fewer
spine joints, clavicles or none, hand/toe joints or none, fingers, face joints, twist
bones and props, another rest pose (A- vs T-pose, other bone axes) and another up axis.
The name: the one thing it adds to ``morphology`` is the change of joint tree.

What is carried per frame, in the motion's world mapped onto the character's world by the
rotation ``C`` between the two rest *body frames* (left, up, forward; up = the inferred up
axis, left from the hips, forward = left x up... see :func:`body_frame`):

* the **root path**: the pelvis position divided by the source's hip height, multiplied
  by the character's (so a planted foot stays on the floor plane through the origin);
* the **trunk**: the pelvis, chest and head orientations; the character's extra spine
  (neck) joints share the pelvis-to-chest (chest-to-head) bend equally;
* each **limb** (Kulpa's representation): the distal point relative to the proximal one
  divided by the limb length, and the bend plane of the middle joint (the swivel); the
  character's middle joint is placed by two-bone IK (law of cosines) in that plane;
* the **end segments** (clavicles, hands, feet, toes) as directions.

Every orientation is decoded as a *global direction*: a character joint ``j`` takes the
source's world rotation of the same role composed with the smallest rotation taking the
character's rest bone direction to the (mapped) source rest bone direction, so rest poses
with different bone axes give the same pose.  Joints without a role (fingers, face,
twist bones, props) keep their rest rotation relative to their parent.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from repro.checks import as_bool, as_choice, as_real, describe
from repro.errors import MotionError
from repro.motion.core.cache import LRUCache
from repro.motion.core.kinematics import (
    chain_positions,
    check_pose_arrays,
    depth_levels,
    fk_arrays,
    normalize,
    world_of,
)
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import cross, matrix_to_quat, min_rotation, quat_multiply
from repro.motion.core.quaternion import quat_conjugate as qinv
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.body.feet import foot_contacts, foot_goals
from repro.motion.body.roles import check_roles
from repro.motion.body.skeleton import Skeleton, check_role_table, skeleton_of
from repro.motion.body.units import infer_up
from repro.motion.retargeting.representation import limb_segments

__all__ = ["TreePlan", "body_frame", "rest_axes", "retarget_across"]

_ROT = ("Zrotation", "Xrotation", "Yrotation")
_POS = ("Xposition", "Yposition", "Zposition")
_AXIS = {"y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


def _check_skeleton(sk) -> None:
    if not isinstance(sk, Skeleton):
        raise MotionError(f"expected a Skeleton (repro.motion.body.skeleton.skeleton_of), got {describe(sk)}")


def body_frame(sk: Skeleton, up: str) -> np.ndarray:
    """(3, 3) columns left, up, forward of a skeleton's rest pose (``up`` = world axis).

    Left comes from the rest hips and shoulders (across the up axis).  A rest pose whose
    trunk does not stand along the world up axis (Bandai Namco's lies along +X, every
    bone on its local X) cannot tell where the body faces in the world: then left is the
    world X axis (forward = left x up: +Z when Y is up, -Y when Z is up)."""
    _check_skeleton(sk)
    u = _AXIS[as_choice(up, "up", tuple(_AXIS), error=MotionError)]
    p = sk.rest_positions()
    trunk = _unit(p[sk.index("head")] - p[sk.index("pelvis")])
    if abs(float(trunk @ u)) < np.cos(np.radians(45.0)):
        left = np.array([1.0, 0.0, 0.0])
        return np.stack([left, u, np.cross(left, u)], axis=1)
    lat = p[sk.index("left_hip")] - p[sk.index("right_hip")]
    lat = lat + p[sk.index("left_shoulder")] - p[sk.index("right_shoulder")]
    lat = lat - (lat @ u) * u
    n = np.linalg.norm(lat)
    if n <= 1e-9 * max(float(np.ptp(p, axis=0).max()), 1e-300):
        raise MotionError(
            f"left and right hips/shoulders coincide across the up axis {up.upper()} in the rest pose of "
            f"{sk.roles['pelvis']!r}'s skeleton; cannot tell its facing direction"
        )
    left = lat / n
    fwd = np.cross(left, u)
    return np.stack([left, u, fwd], axis=1)


def rest_axes(sk: Skeleton) -> dict[str, np.ndarray]:
    """Rest body axes of each part, rig coordinates: ``{"leg": (3, 3), "arm": (3, 3)}``, rows
    left, up, forward.

    Up is the rest pelvis -> head direction; left is the line between the joints rigidly
    carried by the part's root (the hips for the pelvis and the legs; the clavicles, else
    the shoulders, for the chest, the neck, the head and the arms), made orthogonal to up.
    They fix the twist of a segment about its bone when rest poses differ by more than
    their bone directions (Bandai Namco: the pelvis' left is -Y at rest, the chest's +Z)."""
    _check_skeleton(sk)
    p = sk.rest_positions()
    r = sk.roles
    up = _unit(p[sk.index("head")] - p[sk.index("pelvis")])
    tol = 1e-6 * max(sk.height, 1e-300)
    out = {}
    for part, pairs in (("leg", ("hip",)), ("arm", ("clavicle", "shoulder", "hip"))):
        for stem in pairs:  # CMU's clavicles both start at the thorax: then the shoulders
            if f"left_{stem}" not in r or f"right_{stem}" not in r:
                continue
            lat = p[sk.index(f"left_{stem}")] - p[sk.index(f"right_{stem}")]
            lat = lat - (lat @ up) * up
            if np.linalg.norm(lat) > tol:
                break
        else:
            raise MotionError(f"the rest pose of {r['pelvis']!r}'s skeleton has no left-right extent across "
                              "its trunk (hips, clavicles and shoulders on the pelvis -> head line)")
        lat = _unit(lat)
        out[part] = np.stack([lat, up, np.cross(lat, up)])
    return out


def _frame(d: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(3, 3) orthonormal columns: ``d``, ``ref`` made orthogonal to it, their cross product."""
    e1 = _unit(d)
    e2 = _unit(ref - (ref @ e1) * e1)
    out = np.empty((3, 3))
    out[:, 0], out[:, 1], out[:, 2] = e1, e2, cross(e1, e2)
    return out


def _up_of(x, sk: Skeleton) -> str:
    up = getattr(x, "up", None)
    if up is not None:
        return up
    return infer_up(x if isinstance(x, Motion) else None, sk)


def _arc(P: np.ndarray, chain: list[int]) -> np.ndarray:
    """Normalised rest arc length at each joint of a chain (0 at its start, 1 at its end)."""
    seg = np.linalg.norm(np.diff(P[chain], axis=0), axis=1)
    u = np.concatenate([[0.0], np.cumsum(seg)])
    return u / u[-1] if u[-1] > 0 else np.linspace(0.0, 1.0, len(chain))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


#: TreePlan's constants per pair of skeletons (body frames, rest axes, bone-frame rotations); a few
#: pairs are in play at once (the database's actors by the characters on screen): the 32 most recent are kept
_PAIRS: LRUCache = LRUCache(32)


def _skeleton_key(sk: Skeleton) -> tuple:
    """Everything of a skeleton the constants of :func:`_pair` read (its cache key)."""
    return (tuple(sk.joint_names), np.asarray(sk.parents).tobytes(), np.asarray(sk.offsets, dtype=float).tobytes(),
            np.asarray(sk.end_site_parents).tobytes(), np.asarray(sk.end_site_offsets, dtype=float).tobytes(),
            tuple(sorted(sk.roles.items())), None if sk.channels is None else tuple(map(tuple, sk.channels)),
            sk.unit_m)


def _checked_pair(motion, character, roles, character_roles):
    """``(src, tgt, up_s, up_t, pair)`` of :class:`TreePlan`: both skeletons with their roles checked for
    retargeting, their up axes, and :func:`_pair` of the two."""
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a Motion, got {type(motion).__name__}")
    roles = check_role_table(roles, "roles")
    character_roles = check_role_table(character_roles, "character_roles")
    src = Skeleton.from_motion(motion, roles=roles)
    tgt = skeleton_of(character, roles=character_roles)
    check_roles(src.roles, "retargeting", src.joint_names)
    check_roles(tgt.roles, "retargeting", tgt.joint_names)
    up_s, up_t = _up_of(motion, src), _up_of(character, tgt)
    return src, tgt, up_s, up_t, _pair(src, tgt, up_s, up_t)


#: the bones (role -> role) whose rest frames turn the fixed joints and the limbs (:func:`_bone_frames`)
_DELTA_BONES: tuple[tuple[str, str], ...] = (("pelvis", "chest"), ("chest", "head")) + tuple(
    (f"{side}_{a}", f"{side}_{b}") for side in ("left", "right")
    for a, b in (("clavicle", "shoulder"), ("shoulder", "elbow"), ("elbow", "wrist"), ("wrist", "hand"),
                 ("hip", "knee"), ("knee", "ankle"), ("ankle", "toe")))


def _pair(src: Skeleton, tgt: Skeleton, up_s: str, up_t: str) -> dict:
    """What :class:`TreePlan` reads of two skeletons only (body frames, rest axes, bone-frame rotations), cached."""
    def make() -> dict:  # what depends only on the two skeletons (the same numbers every call)
        C = body_frame(tgt, up_t) @ body_frame(src, up_s).T
        Ps, Pt, ax_s, ax_t = src.rest_positions(), tgt.rest_positions(), rest_axes(src), rest_axes(tgt)
        bones = [(a, b) for a, b in _DELTA_BONES if all(r in src.roles and r in tgt.roles for r in (a, b))]
        frames = [_bone_frames(src, tgt, Ps, Pt, ax_s, ax_t, C, a, b) for a, b in bones]
        q = matrix_to_quat(np.stack([C] + frames))  # the map's quaternion and every bone's, in one call
        return dict(C=C, c=q[0], ci=qinv(q[0]), Ps=Ps, Pt=Pt, delta=dict(zip(bones, q[1:])))

    return _PAIRS.get((_skeleton_key(src), _skeleton_key(tgt), up_s, up_t), make)


def straight_bend(a: np.ndarray, b: np.ndarray, valid: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The bend plane (F, 3) of a limb with straight frames (``valid`` False): the last defined
    bend plane (the first one backward at the start), made orthogonal to the limb axis ``a``; with
    no defined frame at all, any plane through ``a`` (the character's forward axis ``C z``)."""
    F = a.shape[0]
    idx = np.where(valid, np.arange(F), -1)
    idx = np.maximum.accumulate(idx)
    first = int(np.argmax(valid)) if valid.any() else -1
    if first >= 0:
        idx = np.where(idx < 0, first, idx)
        b = b[idx]
        return normalize(b - np.sum(b * a, axis=-1, keepdims=True) * a)[0]
    ref = np.broadcast_to(C @ np.array([0.0, 0.0, 1.0]), a.shape)
    return normalize(cross(a, cross(ref, a)) + 1e-12)[0]


def retarget_across(motion: Motion, character, *, roles=None, character_roles=None, fix_feet: bool = False,
                    blend_time: float = 0.1) -> Motion:
    """``motion`` played by ``character``, whose joint tree may differ (see the module docstring).

    ``TreePlan(motion, character, ...).apply(motion, ...)``: the plan of the two skeletons, applied.

    Parameters
    ----------
    motion : Motion
    character : Skeleton or Motion
        Any humanoid skeleton (its own roles are found, or given as ``character_roles``).
    roles, character_roles : mapping role -> joint, optional
    fix_feet : bool, default False
        Correct the feet artifacts (Section 3.4) as :func:`repro.motion.retargeting.morphology.decode`
        does on one tree: where the source's ankle is planted
        (:func:`~repro.motion.body.feet.foot_contacts`) the character's ankle is pinned to its
        mean position over the contact phase (blended over ``blend_time`` seconds on each
        side), the root lowered where a pinned ankle is out of the leg's reach, and on
        every frame an ankle whose ankle or toe joint would be below the floor (the plane
        through the origin across the up axis) is raised until neither is.

    Returns
    -------
    Motion
        On the character's skeleton (its joints, offsets, End Sites, channels when it has
        them, else 6 channels on the root and ZXY rotations elsewhere; ``unit_m``), writable
        with :func:`~repro.motion.write_bvh`.

    Raises
    ------
    repro.errors.MotionError
        Missing roles on either side (named), a character root without position channels,
        a rest pose whose facing cannot be told.
    """
    fix_feet = as_bool(fix_feet, "fix_feet", error=MotionError)
    blend_time = as_real(blend_time, "blend_time (seconds)", error=MotionError, lo=0.0)
    key = _plan_key(motion, character, roles, character_roles)

    def make() -> TreePlan:
        return TreePlan(motion, character, roles=roles, character_roles=character_roles)

    plan = make() if key is None else _PLANS.get(key, make)
    return plan.apply(motion, fix_feet=fix_feet, blend_time=blend_time)


#: :func:`retarget_across`'s plans by the two skeletons and role tables (:func:`_plan_key`): the
#: fighter puts every retrieved clip on its character with one plan; the 32 most recent are kept
_PLANS: LRUCache = LRUCache(32)


def _plan_key(motion, character, roles, character_roles) -> tuple | None:
    """Everything of :func:`retarget_across`'s arguments a :class:`TreePlan` reads (its cache key), or
    None when the plan is made afresh: it would read the frames (an up axis not given, inferred from
    the poses), warn (a motion without ``unit_m``, its unit inferred) or refuse the arguments."""
    def motion_key(m: Motion) -> tuple | None:
        if m.up is None or m.unit_m is None:
            return None
        return (tuple(m.joint_names), m.parents.tobytes(), m.offsets.tobytes(), m.end_site_parents.tobytes(),
                m.end_site_offsets.tobytes(), tuple(m.channels), m.unit_m, m.up)

    def role_key(r) -> tuple | None:
        return None if r is None else tuple(sorted(r.items()))

    if not isinstance(motion, Motion) or not isinstance(character, (Motion, Skeleton)) or \
            any(r is not None and not isinstance(r, Mapping) for r in (roles, character_roles)):
        return None
    src = motion_key(motion)
    tgt = _skeleton_key(character) if isinstance(character, Skeleton) else motion_key(character)
    if src is None or tgt is None:
        return None
    try:
        key = (src, role_key(roles), type(character).__name__, tgt, role_key(character_roles))
        hash(key)
    except TypeError:  # unorderable or unhashable role tables: refused by the plan
        return None
    return key


class TreePlan:
    """:func:`retarget_across` between two fixed skeletons: what does not depend on the pose, computed once.

    The constructor reads the two skeletons only (the role tables and their checks, the body
    frames and the rotation ``C`` between them, the bone-frame rotations, the spine chains'
    shares, the limbs' joints and lengths, the root path, the depth levels); the per-frame
    arithmetic runs in :meth:`apply` (a Motion: what :func:`retarget_across` returns, which
    is this plan applied) and :meth:`positions` (the world positions only, without making
    the Motion: :meth:`repro.motion.search.retrieval.MotionRetriever.prepare`'s step for
    characters of another joint tree, one pose per query), both through one solve, the like
    operations of the joints stacked into one call each (the fixed orientations, the limbs).

    Parameters
    ----------
    motion : Motion
        On the skeleton the poses are on (its ``up``, else inferred); only its skeleton is read.
    character : Skeleton or Motion
    roles, character_roles : mapping role -> joint, optional
        As :func:`retarget_across`.

    Raises
    ------
    repro.errors.MotionError
        Missing roles on either side (named), a character root without position channels,
        a rest pose whose facing cannot be told.
    """

    def __init__(self, motion: Motion, character, *, roles=None, character_roles=None):
        src, tgt, up_s, up_t, pair = _checked_pair(motion, character, roles, character_roles)
        si = {role: src.joint_names.index(j) for role, j in src.roles.items() if j in src.joint_names}
        ti = {role: tgt.joint_names.index(j) for role, j in tgt.roles.items() if j in tgt.joint_names}
        deltas = pair["delta"]

        def delta(a, b):
            return deltas[(a, b)]

        fixed = _fixed_rotations(src, tgt, pair["Ps"], pair["Pt"], pair["C"], si.__getitem__, ti.__getitem__, delta)
        limbs = _limb_roles(ti)
        self.source, self.target, self.up_source, self.up = src, tgt, up_s, up_t
        self.C, self.c, self.ci = pair["C"], pair["c"], pair["ci"]
        self.CT = np.ascontiguousarray(self.C.T)
        self._root(src, tgt)
        self.parents = np.asarray(tgt.parents)
        self.offsets = np.asarray(tgt.offsets, dtype=float)
        self.n_joints = tgt.n_joints
        self.levels_s = depth_levels(src.parents)
        self.levels_t = depth_levels(tgt.parents)
        self.deep = len(self.levels_t) > 64
        # the limbs solved (a proximal joint without a fixed rotation), the middle joints after them
        act = [j for j in limbs if j not in fixed]
        self._limbs(src, tgt, pair["Pt"], si, ti, delta, act, [limbs[j] for j in act])
        self._middles(pair["Pt"], si, ti, delta, fixed, limbs, [limbs[j] for j in act])
        self._fixed(fixed)
        self._inheritance()

    def _root(self, src: Skeleton, tgt: Skeleton) -> None:
        """The root path: the pelvis position scaled by the hip heights, the offsets above the pelvis."""
        rt = tgt.roles
        self.k = tgt.hip_height / src.hip_height
        root_path = [0] + tgt.path(tgt.joint_names[0], rt["pelvis"])
        if tgt.channels is not None and not all(ch in tgt.channels[0] for ch in _POS):
            raise MotionError(
                f"character root {tgt.joint_names[0]!r} has no position channels (channels "
                f"{list(tgt.channels[0])}); the retargeted motion needs to move it"
            )
        self.root_off = sum(tgt.offsets[j] for j in root_path[1:]) if len(root_path) > 1 else None
        self.s_pelvis = src.joint_names.index(src.roles["pelvis"])

    def _limbs(self, src, tgt, Pt, si, ti, delta, act, rp) -> None:
        """The limbs' joints (source and character), lengths, rest middle offsets and bone-frame rotations."""
        self.l_prox = np.array(act, dtype=np.intp)
        self.l_src = np.array([[si[r] for r in roles3] for roles3 in rp], dtype=np.intp).reshape(-1, 3)
        # the upper and lower bones, proximal -> middle -> distal (twist joints may sit inside them)
        ls1, ls2 = limb_segments(src, *self.l_src.T)
        self.Ls = ls1 + ls2
        lt = np.array([[ti[r] for r in roles3] for roles3 in rp], dtype=np.intp).reshape(-1, 3)
        self.l1, self.l2 = limb_segments(tgt, *lt.T)
        self.bl_src_mid = ls1
        self.cur_p = np.array([Pt[ti[m]] - Pt[ti[p]] for p, m, _d in rp]).reshape(-1, 3)
        self.D_pm = np.array([delta(p, m) for p, m, _d in rp]).reshape(-1, 4)
        # fix_feet's ankle goals: the limbs (rows) ending at the left / right ankle (columns of the goals)
        ends = [d for _p, _m, d in rp]
        sides = [s for s in ("left_ankle", "right_ankle") if s in ends]
        self.leg_rows = np.array([ends.index(s) for s in sides], dtype=np.intp)
        self.leg_cols = np.array([("left_ankle", "right_ankle").index(s) for s in sides], dtype=np.intp)
        self.path_prox = _levels_below(self.parents, [0], self.l_prox)

    def _middles(self, Pt, si, ti, delta, fixed, limbs, rp) -> None:
        """The middle joints turned to their distal goal (in joint order; one with a fixed rotation keeps it)."""
        mids = []
        for n, (_, m, _d) in enumerate(rp):
            j = ti[m]
            if j not in fixed and j not in limbs and self.parents[j] >= 0:
                first = next(v for v in limbs.values() if ti[v[1]] == j)
                if first == rp[n]:
                    mids.append((n, j))
        self.m_limb = np.array([n for n, _ in mids], dtype=np.intp)
        self.m_joint = np.array([j for _, j in mids], dtype=np.intp)
        self.m_src = np.array([si[rp[n][1]] for n, _ in mids], dtype=np.intp)
        self.D_md = np.array([delta(rp[n][1], rp[n][2]) for n, _ in mids]).reshape(-1, 4)
        self.cur_m = np.array([Pt[ti[rp[n][2]]] - Pt[j] for n, j in mids]).reshape(-1, 3)
        self.path_mid = _levels_below(self.parents, self.l_prox.tolist(), self.m_joint)

    def _fixed(self, fixed: dict) -> None:
        """The fixed joints, and one stacked product for every "C G_s C^-1 times a factor": the fixed
        joints', then the limbs' proximal and middle starting rotations."""
        self.f_joint = np.array(list(fixed), dtype=np.intp)
        self.f_src = np.array([v[0] for v in fixed.values()], dtype=np.intp)
        self.D_f = np.array([v[1] for v in fixed.values()]).reshape(-1, 4)
        self.map_src = np.concatenate([self.f_src, self.l_src[:, 0], self.m_src]).astype(np.intp)
        self.map_D = np.concatenate([self.D_f, self.D_pm, self.D_md])
        nf, nl = len(self.f_src), len(self.l_prox)
        self.sl_f, self.sl_p, self.sl_m = slice(0, nf), slice(nf, nf + nl), slice(nf + nl, None)

    def _inheritance(self) -> None:
        """Every other joint (no role: fingers, face, twist bones, props) takes the world rotation of its
        nearest ancestor that has one of its own (index J: the identity), i.e. keeps its rest rotation."""
        J = self.n_joints
        own = np.zeros(J, dtype=bool)
        own[self.f_joint] = True
        own[self.l_prox] = True
        own[self.m_joint] = True
        anchor = np.full(J, J, dtype=np.intp)
        for j in range(J):
            if own[j]:
                anchor[j] = j
            elif self.parents[j] >= 0:
                anchor[j] = anchor[self.parents[j]]
        self.inherit = np.flatnonzero(~own)
        self.anchor = anchor[self.inherit]

    def positions(self, rotations: np.ndarray, translations: np.ndarray, *, source=None) -> np.ndarray:
        """(F, J, 3) world positions of the character's joints (its units, ``up``).

        ``rotations`` (F, J, 4) unit quaternions and ``translations`` (F, J, 3) the local
        translations (:meth:`~repro.motion.core.motion.Motion.local_translations`) of the
        motion's frames: ``retarget_across(...).global_positions()`` of them.  ``source``:
        their world ``(rotations, positions)`` when already made by forward kinematics
        over :func:`~repro.motion.core.kinematics.depth_levels` (what :meth:`apply` runs, and
        :meth:`~repro.motion.core.motion.Motion.global_transforms` on trees up to 64 levels deep).
        """
        rotations, translations = check_pose_arrays(rotations, translations, 1 + sum(len(i) for i, _ in self.levels_s))
        gq_s, gp_s = world_of(self.levels_s, rotations, translations, source)
        root_t = self._root_translation(gp_s)
        loc = self._local(self._solve(gq_s, gp_s, root_t))
        loc = loc / np.linalg.norm(loc, axis=-1, keepdims=True)  # as a new Motion renormalises
        t = self._translations(root_t)
        if self.deep:  # Motion.global_transforms' other path
            return self._motion(loc, t, 1.0).global_positions()
        return fk_arrays(self.levels_t, loc, t, copy=False)[1]

    def apply(self, motion: Motion, *, fix_feet: bool = False, blend_time: float = 0.1) -> Motion:
        """``motion`` (on the plan's source skeleton) played by the character: :func:`retarget_across`.

        ``fix_feet`` and ``blend_time`` as :func:`retarget_across`'s (checked there)."""
        if not isinstance(motion, Motion) or list(motion.joint_names) != list(self.source.joint_names):
            raise MotionError(f"TreePlan.apply: the motion must be on the plan's source skeleton, got {describe(motion)}")
        gq_s, gp_s = fk_arrays(self.levels_s, motion.rotations, motion.local_translations())
        root_t = self._root_translation(gp_s)
        G = self._solve(gq_s, gp_s, root_t)
        if fix_feet:
            root_t, G = self._fix_feet(motion, gq_s, gp_s, root_t, G, blend_time)
        return self._motion(self._local(G), self._translations(root_t), motion.frame_time)

    def _root_translation(self, gp_s: np.ndarray) -> np.ndarray:
        """(F, 3) the character's root: the source pelvis scaled by the hip heights, mapped into its world."""
        pel_goal = qrot(np.broadcast_to(self.c, (gp_s.shape[0], 4)), gp_s[:, self.s_pelvis] * self.k)
        return pel_goal - self.root_off if self.root_off is not None else pel_goal

    def _translations(self, root_t: np.ndarray) -> np.ndarray:
        """(F, J, 3) the character's local translations: its offsets, the root at ``root_t``."""
        t = np.broadcast_to(self.offsets, (root_t.shape[0], self.n_joints, 3)).copy()
        t[:, 0] = root_t
        return t

    def _local(self, G: np.ndarray) -> np.ndarray:
        """(F, J, 4) local rotations of world rotations ``G``."""
        loc = np.empty_like(G)
        loc[:, 0] = G[:, 0]
        loc[:, 1:] = quat_multiply(qinv(G[:, self.parents[1:]]), G[:, 1:])
        return loc

    def _motion(self, loc: np.ndarray, t: np.ndarray, frame_time: float) -> Motion:
        tgt = self.target
        channels = tgt.channels if tgt.channels is not None else [_POS + _ROT] + [_ROT] * (self.n_joints - 1)
        return tgt.motion_with(loc, t, frame_time=frame_time, channels=channels, up=self.up)

    def _solve(self, gq_s: np.ndarray, gp_s: np.ndarray, root_t: np.ndarray, goals=None) -> np.ndarray:
        """(F, J, 4) world rotations of the character's joints; ``goals``: (F, 2, 3) world positions of
        the left / right ankle overriding the representation's (``fix_feet``)."""
        F, J = gq_s.shape[0], self.n_joints
        G = np.zeros((F, J + 1, 4))
        G[..., 3] = 1.0
        mapped = quat_multiply(quat_multiply(self.c[None, None], gq_s[:, self.map_src]), self.ci[None, None])
        G0 = quat_multiply(mapped, self.map_D[None])
        G[:, self.f_joint] = G0[:, self.sl_f]
        G[:, self.inherit] = G[:, self.anchor]
        if len(self.l_prox):
            P = np.empty((F, J, 3))
            P[:, 0] = root_t
            S = self._chain(G, P, self.path_prox)[:, self.l_prox]
            E, W = self._limb_goals(gp_s, S, goals)
            cur = qrot(G0[:, self.sl_p], np.broadcast_to(self.cur_p, (F,) + self.cur_p.shape))
            G[:, self.l_prox] = quat_multiply(min_rotation(cur, E - S), G0[:, self.sl_p])
            if len(self.m_joint):
                G[:, self.inherit] = G[:, self.anchor]
                self._chain(G, P, self.path_mid)
                Gm = G0[:, self.sl_m]
                cur = qrot(Gm, np.broadcast_to(self.cur_m, (F,) + self.cur_m.shape))
                G[:, self.m_joint] = quat_multiply(min_rotation(cur, W[:, self.m_limb] - P[:, self.m_joint]), Gm)
            G[:, self.inherit] = G[:, self.anchor]
        return G[:, :J]

    def _chain(self, G: np.ndarray, P: np.ndarray, levels) -> np.ndarray:
        """``P`` with the world positions of ``levels``' joints (their parents' already in it), in place."""
        for idx, _ in levels:
            P[:, idx] = self.offsets[idx]
        return chain_positions(levels, G, P)

    def _limb_goals(self, gp_s: np.ndarray, S: np.ndarray, goals) -> tuple[np.ndarray, np.ndarray]:
        """(F, L, 3) world goals of the limbs' middle and distal joints from proximal positions ``S``
        (Kulpa: normalised distal vector x limb length, the middle joint in the source's bend plane)."""
        g3 = gp_s[:, self.l_src]  # (F, L, 3, 3): proximal, middle, distal
        we = g3[:, :, 2:0:-1] - g3[:, :, :1]  # (F, L, 2, 3): distal - proximal, middle - proximal
        nl = len(self.l_prox)
        CT = self.CT
        n = np.stack([we[:, i, 0] @ CT / self.Ls[i] for i in range(nl)], axis=1)
        e = np.stack([we[:, i, 1] @ CT for i in range(nl)], axis=1)
        l1, l2 = self.l1[None], self.l2[None]
        want = n * (l1 + l2)[..., None]
        if goals is not None:
            want[:, self.leg_rows] = goals[:, self.leg_cols] - S[:, self.leg_rows]
        a, dn = normalize(want)
        bend = e - np.sum(e * a, axis=-1, keepdims=True) * a
        b, bn = normalize(bend)
        valid = bn > 1e-9 * self.bl_src_mid[None]
        if not valid.all():
            b = b.copy()
            for i in np.flatnonzero(~valid.all(axis=0)).tolist():
                b[:, i] = straight_bend(a[:, i], b[:, i], valid[:, i], self.C)
        d = np.clip(dn, np.abs(l1 - l2), l1 + l2)
        cosb = np.clip((l1**2 + d**2 - l2**2) / (2 * l1 * np.maximum(d, 1e-300)), -1.0, 1.0)
        sinb = np.sqrt(1.0 - cosb**2)
        E = S + a * (l1 * cosb)[..., None] + b * (l1 * sinb)[..., None]
        W = S + a * d[..., None]
        return E, W

    def _fix_feet(self, motion, gq_s, gp_s, root_t, G, blend_time) -> tuple[np.ndarray, np.ndarray]:
        """``fix_feet`` of :func:`retarget_across`: planted ankles pinned, the root lowered where one is
        out of the leg's reach, ankles raised where the ankle or toe would be below the floor."""
        tgt = self.target
        kt = 2 if self.up == "z" else 1
        e_up = _AXIS[self.up]
        ank = [tgt.index("left_ankle"), tgt.index("right_ankle")]
        hips = [tgt.index("left_hip"), tgt.index("right_hip")]
        L = np.array([tgt.limb_lengths[f"{s}_leg"] for s in ("left", "right")])  # across twist joints too
        contacts = foot_contacts(motion, skeleton=self.source, global_positions=gp_s,
                                 up_axis=2 if self.up_source == "z" else 1)
        P = self._world(G, root_t)
        A = P[:, ank]
        n_blend = round(min(blend_time / motion.frame_time, 2.0**53))  # longer than any clip: no overflow
        goal, w = foot_goals(A, contacts, A[..., 1], n_blend)  # every coordinate: the phase mean
        goal = A + w[..., None] * (goal - A)
        r = goal - P[:, hips]
        ry = r[..., kt]
        rh2 = np.sum(r * r, axis=-1) - ry**2
        drop = np.maximum(0.0, -ry - np.sqrt(np.maximum(L[None] ** 2 - rh2, 0.0))).max(axis=1)
        root_t = root_t - drop[:, None] * e_up
        G = self._solve(gq_s, gp_s, root_t, goal)
        P = self._world(G, root_t)
        # no point of the character's own foot below the floor (the ankle, the joints below it and
        # their End Sites: a toe's tip, a toe-less foot's End Site): raise the ankle goal by the depth
        depth = np.stack([np.maximum(0.0, -self._foot_low(G, P, a, kt)) for a in ank], axis=1)
        if np.any(depth > 0):
            G = self._solve(gq_s, gp_s, root_t, P[:, ank] + (depth * (1 + 1e-9))[..., None] * e_up)
        return root_t, G

    def _foot_low(self, G: np.ndarray, P: np.ndarray, ank: int, kt: int) -> np.ndarray:
        """(F,) height (axis ``kt``) of the lowest point of the foot below joint ``ank``: the joint, its
        descendants and their End Sites, for world rotations ``G`` and positions ``P``."""
        tgt = self.target
        below = np.zeros(self.n_joints, dtype=bool)
        below[ank] = True
        for j in range(ank + 1, self.n_joints):  # parents come before their children
            below[j] = below[self.parents[j]]
        low = P[:, below, kt].min(axis=1)
        esp = np.asarray(tgt.end_site_parents, dtype=np.intp)
        ends = np.flatnonzero(below[esp]) if esp.size else esp
        if ends.size:
            par = esp[ends]
            tips = P[:, par] + qrot(G[:, par], np.asarray(tgt.end_site_offsets, dtype=float)[ends][None])
            low = np.minimum(low, tips[..., kt].min(axis=1))
        return low

    def _world(self, G: np.ndarray, root_t: np.ndarray) -> np.ndarray:
        """(F, J, 3) world positions of the character's joints for world rotations ``G``."""
        return chain_positions(self.levels_t, G, self._translations(root_t))


def _limb_roles(ti) -> dict[int, tuple[str, str, str]]:
    """The character's four limbs by proximal joint: (proximal, middle, distal) roles."""
    limbs = {}
    for side in ("left", "right"):
        for p_, m_, d_ in (("shoulder", "elbow", "wrist"), ("hip", "knee", "ankle")):
            roles3 = tuple(f"{side}_{r}" for r in (p_, m_, d_))
            limbs[ti[roles3[0]]] = roles3
    return limbs


def _levels_below(parents, tops, ends) -> list[tuple[np.ndarray, np.ndarray]]:
    """The joints strictly below ``tops`` down to ``ends`` (included), as (joints, parents) by depth."""
    out: set[int] = set()
    for e in ends:
        j = int(e)
        while j not in tops and j >= 0:
            out.add(j)
            j = int(parents[j])
    depth: dict[int, int] = {}
    by: list[list[int]] = []
    for j in sorted(out):  # parents before children (parents[j] < j): each depth in index order
        d = depth[j] = depth.get(int(parents[j]), -1) + 1
        if d == len(by):
            by.append([])
        by[d].append(j)
    return [(np.array(js, dtype=np.intp), np.asarray(parents)[js]) for js in by]


def _fixed_rotations(src, tgt, Ps, Pt, C, si, ti, delta) -> dict[int, tuple[int, np.ndarray]]:
    """The joints whose world rotation is fixed: joint -> (source joint, right factor).

    A fixed joint's world rotation is ``C G_s C^-1`` of its source joint times the factor:
    the pelvis, chest, head, clavicles, wrists, ankles and toes by their bone's rest
    difference (``delta``), and the chains whose joints share a bend (pelvis -> chest,
    chest -> head), where each character bone takes the source's world rotation at the
    same fraction of the chain's length.  ``si`` / ``ti`` give a role's joint index.
    """
    rs, rt = src.roles, tgt.roles
    fixed: dict[int, tuple[int, np.ndarray]] = {}
    fixed[ti("pelvis")] = (si("pelvis"), delta("pelvis", "chest"))
    fixed[ti("chest")] = (si("chest"), delta("chest", "head"))
    fixed[ti("head")] = (si("head"), delta("chest", "head"))
    for side in ("left", "right"):
        for a, b in (("clavicle", "shoulder"), ("wrist", "hand"), ("ankle", "toe"), ("toe", "toe")):
            ra, rb = f"{side}_{a}", f"{side}_{b}"
            if ra in rt and ra in rs:
                if a == "toe":
                    fixed[ti(ra)] = (si(ra), delta(f"{side}_ankle", ra))
                elif rb in rt and rb in rs:
                    fixed[ti(ra)] = (si(ra), delta(ra, rb))
                elif a == "wrist":
                    fixed[ti(ra)] = (si(ra), delta(f"{side}_elbow", ra))
                elif a == "ankle":
                    fixed[ti(ra)] = (si(ra), delta(f"{side}_knee", ra))
    for a, b in (("pelvis", "chest"), ("chest", "head")):
        T = [ti(a)] + tgt.path(rt[a], rt[b])
        Sj = [si(a)] + src.path(rs[a], rs[b])
        ut, us = _arc(Pt, T), _arc(Ps, Sj)
        for i in range(1, len(T) - 1):
            mid = 0.5 * (ut[i] + ut[i + 1])
            k = int(np.clip(np.searchsorted(us, mid, side="right") - 1, 0, len(Sj) - 2))
            dt = Pt[T[i + 1]] - Pt[T[i]]
            ds = C @ (Ps[Sj[k + 1]] - Ps[Sj[k]])
            d = min_rotation(dt, ds) if np.linalg.norm(dt) > 0 and np.linalg.norm(ds) > 0 else np.array([0, 0, 0, 1.0])
            fixed[T[i]] = (Sj[k], d)
    return fixed


def _ref_dir(P, roles_, names, a, b):
    return _unit(P[names.index(roles_[b])] - P[names.index(roles_[a])])


def _bone_frames(src, tgt, Ps, Pt, ax_s, ax_t, C, a, b) -> np.ndarray:
    """(3, 3) rotation taking the character's rest frame of bone a->b to the mapped source one.

    The frame: the bone direction and the part's rest axis (left, up or forward of
    :func:`rest_axes`) least aligned with the bone on both skeletons, so the twist
    about the bone is carried too (the smallest rotation between the bone directions
    alone would leave it to the rest poses' accident)."""
    dt = _ref_dir(Pt, tgt.roles, tgt.joint_names, a, b)
    ds = C @ _ref_dir(Ps, src.roles, src.joint_names, a, b)
    part = "leg" if any(x in a for x in ("pelvis", "hip", "knee", "ankle", "toe")) else "arm"
    at, as_ = ax_t[part], ax_s[part] @ C.T
    k = int(np.argmin(np.maximum(np.abs(at @ dt), np.abs(as_ @ ds))))
    return _frame(ds, as_[k]) @ _frame(dt, at[k]).T
