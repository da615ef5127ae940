"""Skeletons, sizes and characters of other morphologies.

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", animate characters whose morphology differs from the actor's:

* Section 3.3 rescales a target by the ratio of sizes, Eq. 1:
  ``c_r = c * size_a / size_c`` (``c`` in the character's root frame, ``size_a`` the
  actor's size, ``size_c`` the character's) -- :func:`rescale_constraint`,
  :attr:`Skeleton.size`;
* Section 3.4.1 retargets motions with the morphology-independent representation of
  Kulpa et al. (2005), which needs to know which joints are the shoulders, elbows,
  wrists, hips, knees and ankles of any skeleton -- :func:`repro.motion.body.roles.find_roles`,
  whose role table a :class:`Skeleton` keeps -- and the limb
  lengths of the target -- :class:`Skeleton`;
* Section 3.1: "the morphology of the virtual fighter is selected by the supervisor into a
  database composed of various skeletons" -- :func:`scale_skeleton` makes such
  characters (other stature, other arm/leg proportions) from a captured skeleton.

All lengths are in the skeleton's file units; ``unit_m`` (metres per unit, from
:attr:`repro.motion.Motion.unit_m`) converts.  The world is Y-up (BVH convention, true of
the CMU, Bandai Namco and Mixamo files).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from repro.checks import as_int, as_real, as_real_array, check_alloc, describe, read_only
from repro.errors import MotionError, UnitWarning
from repro.motion.core.kinematics import check_indices, check_joint_names, rest_positions
from repro.motion.core.motion import Motion
from repro.motion.body.roles import LIMBS, REQUIRED_ROLES, bone_lengths_of, find_roles
from repro.motion.body.stature import Stature, infer_unit, measure_stature

__all__ = [
    "Skeleton",
    "skeleton_of",
    "scale_skeleton",
    "rescale_constraint",
]

@dataclass(frozen=True, eq=False)
class Skeleton:
    """A character: joint tree, rest offsets, End Sites, units and body-part roles.

    This is a :class:`~repro.motion.Motion` without frames (same layout and conventions:
    ``offsets[j]`` is joint ``j``'s rest offset from its parent, End Sites likewise), plus
    the role table of :func:`find_roles`.  Build one with :meth:`from_motion` or
    :func:`skeleton_of`, derive characters with :func:`scale_skeleton`.

    Sizes (all from the offsets, so they do not depend on the rest *posture*: the CMU rest
    pose has the legs abducted by about 20 degrees, the Bandai Namco rest pose is a
    straight line along +X):

    * bone length of joint ``j`` = ``|offsets[j]|``; :attr:`limb_lengths` gives the upper
      arm (``|offset(elbow)|``), forearm (``|offset(wrist)|``), thigh
      (``|offset(knee)|``), shin (``|offset(ankle)|``) of each side and the limb lengths
      ``arm = upper arm + forearm`` and ``leg = thigh + shin`` -- the "limb length" that
      normalises the limbs in Kulpa et al. (2005) (Section 3.4.1);
    * :attr:`height` -- the stature, measured one way on every rig (:attr:`stature`,
      :attr:`stature_method`, :mod:`repro.motion.body.stature`); :attr:`size` is the same in
      metres: this is the ``size`` of Eq. 1;
    * :attr:`hip_height` -- pelvis height of the straightened skeleton, the size that
      normalises the root trajectory in :mod:`repro.motion.retargeting.morphology`.

    Parameters
    ----------
    joint_names, parents, offsets, channels, end_site_parents, end_site_offsets, unit_m
        As in :class:`~repro.motion.Motion`.
    roles : mapping role -> joint name, optional
        Default: :func:`find_roles` on the names, parents and rest offsets (roles from
        the structure first, the names second).

    Raises
    ------
    repro.errors.MotionError
        Non-finite offsets, a bad parent array, a missing role, or a zero-length bone
        where a role needs a length (upper arm, forearm, thigh, shin).
    """

    joint_names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]] | None = None
    end_site_parents: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    end_site_offsets: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    unit_m: float | None = None
    roles: Mapping[str, str] | None = None

    def __post_init__(self) -> None:
        names = check_joint_names(self.joint_names)
        J = len(names)
        if J == 0 or len(set(names)) != J:
            raise MotionError("a skeleton needs at least one joint and unique joint names")
        parents = as_real_array(self.parents, "parents", error=MotionError, integer=True)
        if parents.shape != (J,):
            raise MotionError(f"parents must be a ({J},) int array, got {parents.shape}")
        if parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, J)):
            raise MotionError("parents must be -1 for joint 0 and parents[j] < j for the others")
        offsets = as_real_array(self.offsets, "offsets", error=MotionError, finite=False)
        if offsets.shape != (J, 3):
            raise MotionError(f"offsets must be ({J}, 3), got {offsets.shape}")
        if not np.all(np.isfinite(offsets)):
            raise MotionError("skeleton offsets contain NaN or inf")
        # lengths of any magnitude, without overflow: a skeleton too large or small to compute
        # with is named as such, not reported as having zero-length bones
        lengths = bone_lengths_of(offsets)
        total = float(lengths.sum())
        try:
            channels = None if self.channels is None else [tuple(str(c) for c in ch) for ch in self.channels]
        except TypeError:
            raise MotionError(f"channels must list each joint's channel names, got {describe(self.channels)}") from None
        if channels is not None and len(channels) != J:
            raise MotionError(f"channels must list {J} joints, got {len(channels)}")
        esp = check_indices(self.end_site_parents, "end_site_parents", J)
        eso = as_real_array(self.end_site_offsets, "end_site_offsets", error=MotionError, finite=False)
        if eso.size % 3:
            raise MotionError(f"end_site_offsets must be an (E, 3) array, got shape {eso.shape}")
        eso = eso.reshape(-1, 3)
        if eso.shape[0] != esp.size or np.any((esp < 0) | (esp >= J)) or not np.all(np.isfinite(eso)):
            raise MotionError("end_site_parents / end_site_offsets are inconsistent or not finite")
        if self.unit_m is not None:
            as_real(self.unit_m, "unit_m (metres per unit)", error=MotionError, lo=0.0, lo_open=True)
        check_role_table(self.roles)
        roles = (dict(self.roles) if self.roles is not None
                 else find_roles(names, parents, offsets=offsets, end_site_parents=esp))
        bad = [f"{r}->{j}" for r, j in roles.items() if j not in names]
        if bad:
            raise MotionError(f"roles name unknown joints: {bad}")
        missing = [r for r in REQUIRED_ROLES if r not in roles]
        if missing:
            raise MotionError(f"skeleton lacks the roles {missing}; joints: {names}")
        set_ = object.__setattr__
        set_(self, "joint_names", names)
        set_(self, "parents", np.asarray(parents, dtype=np.intp).copy())
        self.parents.flags.writeable = False
        set_(self, "offsets", read_only(offsets, float))
        set_(self, "channels", channels)
        esp = esp.copy()
        esp.flags.writeable = False
        set_(self, "end_site_parents", esp)
        set_(self, "end_site_offsets", read_only(eso, float))
        set_(self, "unit_m", None if self.unit_m is None else float(self.unit_m))
        set_(self, "roles", dict(roles))
        # zero-length bones where a role needs a length
        scale = max(total, 1e-300)
        zero = []
        for limb, (_, mid, dist) in LIMBS.items():
            for r in (mid, dist):
                if lengths[names.index(roles[r])] <= 1e-9 * scale:
                    zero.append(f"{roles[r]} ({r}, {limb})")
        if zero:
            raise MotionError(f"zero-length limb bones (offset of {', '.join(zero)}); cannot normalise or solve IK")

    # ------------------------------------------------------------ construction
    @classmethod
    def from_motion(cls, motion, roles: Mapping[str, str] | None = None, *, overrides=None) -> Skeleton:
        """The skeleton of a :class:`~repro.motion.Motion` (its rest offsets, End Sites, units).

        Parameters
        ----------
        motion : Motion
        roles : mapping, optional
            Complete role table; default :func:`find_roles` (with ``overrides``).
        overrides : mapping, optional
            Passed to :func:`find_roles`.
        """
        if not isinstance(motion, Motion):
            raise MotionError(f"Skeleton.from_motion needs a Motion, got {describe(motion)}")
        roles = check_role_table(roles)
        if roles is None:
            roles = find_roles(motion.joint_names, motion.parents, overrides=overrides, offsets=motion.offsets,
                               end_site_parents=motion.end_site_parents)
        sk = cls(
            joint_names=list(motion.joint_names),
            parents=motion.parents,
            offsets=motion.offsets,
            channels=list(motion.channels),
            end_site_parents=motion.end_site_parents,
            end_site_offsets=motion.end_site_offsets,
            unit_m=motion.unit_m,
            roles=roles,
        )
        if sk.unit_m is None:
            # no unit given: inferred from the stature (repro.motion.body.stature), with a UnitWarning;
            # left unknown when the stature fits no unit (to_metres then says so)
            try:
                u, name = infer_unit(sk.height)
            except MotionError:
                return sk
            warnings.warn(
                f"{getattr(motion, 'source', None) or 'motion'}: no unit_m given; inferred {name} "
                f"({u:g} m per unit) from the stature of {sk.height:.4g} units ({sk.stature_method})",
                UnitWarning,
                stacklevel=2,
            )
            sk = dataclasses.replace(sk, unit_m=u)
        return sk

    def with_offsets(self, offsets, end_site_offsets=None, unit_m=None) -> Skeleton:
        """Same joints, roles and channels with new offsets (and End Site offsets, units)."""
        return dataclasses.replace(
            self,
            offsets=offsets,
            end_site_offsets=self.end_site_offsets if end_site_offsets is None else end_site_offsets,
            unit_m=self.unit_m if unit_m is None else unit_m,
        )

    # ------------------------------------------------------------------ basics
    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)

    def index(self, name_or_role: str) -> int:
        """Joint index of a joint name or of a role (``"left_knee"``)."""
        if not isinstance(name_or_role, str):
            raise MotionError(f"a joint name or role must be a string, got {describe(name_or_role)}")
        name = self.roles.get(name_or_role, name_or_role)
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise MotionError(f"no joint or role {name_or_role!r}; joints: {self.joint_names}") from None

    def role_index(self) -> dict[str, int]:
        """Role -> joint index."""
        return {r: self.joint_names.index(j) for r, j in self.roles.items()}

    @cached_property
    def bone_lengths(self) -> np.ndarray:
        """(J,) ``|offsets[j]|``: length of the bone from joint j's parent to joint j (no overflow: the
        constructor refused lengths beyond :data:`repro.motion.body.roles.MAX_LENGTH_SUM`)."""
        return np.linalg.norm(self.offsets, axis=1)

    def bone_length(self, name_or_role: str) -> float:
        """Length of the bone ending at a joint (``|offset|``), file units."""
        return float(self.bone_lengths[self.index(name_or_role)])

    def segment_lengths(self, top, bottom) -> np.ndarray:
        """Rest distances from joints ``top`` down to joints ``bottom`` (indices, broadcast): the bone
        ending at ``bottom`` when ``top`` is its parent, else across the twist joints between them
        (MakeHuman ``upperarm02.L``), which lie on the bone."""
        top, bottom = np.asarray(top, dtype=np.intp), np.asarray(bottom, dtype=np.intp)
        P = self._rest_positions
        return np.where(self.parents[bottom] == top, self.bone_lengths[bottom],
                        np.linalg.norm(P[bottom] - P[top], axis=-1))

    def _segment(self, top: str, role: str) -> float:
        """:meth:`segment_lengths` from joint or role ``top`` down to ``role``."""
        return float(self.segment_lengths(self.index(top), self.index(role)))

    def rest_positions(self) -> np.ndarray:
        """(J, 3) joint positions of the rest pose (all rotations identity), file units."""
        return self._rest_positions.copy()

    @cached_property
    def _rest_positions(self) -> np.ndarray:
        return rest_positions(self.parents, self.offsets)

    def path(self, ancestor: str, descendant: str) -> list[int]:
        """Joint indices from ``ancestor`` (excluded) down to ``descendant`` (included)."""
        a, d = self.index(ancestor), self.index(descendant)
        chain = []
        while d != a:
            if d < 0:
                raise MotionError(f"{ancestor!r} is not an ancestor of {descendant!r}")
            chain.append(d)
            d = int(self.parents[d])
        return chain[::-1]

    def is_compatible(self, other) -> bool:
        """Same joint names and parents (same topology) as ``other`` (Skeleton or Motion)."""
        if not hasattr(other, "joint_names") or not hasattr(other, "parents"):
            raise MotionError(f"is_compatible needs a Skeleton or a Motion, got {describe(other)}")
        return list(other.joint_names) == self.joint_names and np.array_equal(other.parents, self.parents)

    # ------------------------------------------------------------------- sizes
    @cached_property
    def limb_lengths(self) -> dict[str, float]:
        """Segment and limb lengths, file units.

        Keys ``{side}_upper_arm`` (shoulder->elbow), ``{side}_forearm`` (elbow->wrist),
        ``{side}_arm`` (their sum), ``{side}_thigh`` (hip->knee), ``{side}_shin``
        (knee->ankle), ``{side}_leg`` (their sum), ``{side}_foot`` (ankle->toe, 0 when
        there is no toe joint), for ``side`` in ``left``/``right``.
        """
        out = {}
        for side in ("left", "right"):
            ua = self._segment(f"{side}_shoulder", f"{side}_elbow")
            fa = self._segment(f"{side}_elbow", f"{side}_wrist")
            th = self._segment(f"{side}_hip", f"{side}_knee")
            sh = self._segment(f"{side}_knee", f"{side}_ankle")
            ft = self.bone_length(f"{side}_toe") if f"{side}_toe" in self.roles else 0.0
            out.update(
                {
                    f"{side}_upper_arm": ua,
                    f"{side}_forearm": fa,
                    f"{side}_arm": ua + fa,
                    f"{side}_thigh": th,
                    f"{side}_shin": sh,
                    f"{side}_leg": th + sh,
                    f"{side}_foot": ft,
                }
            )
        return out

    @cached_property
    def arm_length(self) -> float:
        """Mean of the two arm lengths (upper arm + forearm), file units."""
        return 0.5 * (self.limb_lengths["left_arm"] + self.limb_lengths["right_arm"])

    @cached_property
    def leg_length(self) -> float:
        """Mean of the two leg lengths (thigh + shin), file units."""
        return 0.5 * (self.limb_lengths["left_leg"] + self.limb_lengths["right_leg"])

    @cached_property
    def trunk_axis(self) -> np.ndarray:
        """Unit vector pelvis -> head in the rest pose (the body's "up" at rest)."""
        p = self._rest_positions
        v = p[self.index("head")] - p[self.index("pelvis")]
        n = np.linalg.norm(v)
        if n <= 1e-12 * max(self.bone_lengths.sum(), 1e-300):
            raise MotionError("head and pelvis coincide in the rest pose; cannot tell the body's axis")
        return v / n

    @cached_property
    def trunk_length(self) -> float:
        """Sum of the bone lengths from the pelvis to the head joint (spine straightened)."""
        return float(sum(self.bone_lengths[j] for j in self.path("pelvis", "head")))

    @cached_property
    def hip_drop(self) -> float:
        """Height of the pelvis joint above the hip joints at rest, along the trunk axis.

        Mean over sides of ``-(hip - pelvis) . u`` with ``u`` the rest pelvis->head
        direction (the pelvis-to-hip link is rigid and usually not straight down, so
        only its component along the body axis counts), clipped at 0.
        """
        p = self._rest_positions
        u = self.trunk_axis
        pel = p[self.index("pelvis")]
        d = [-(p[self.index(f"{s}_hip")] - pel) @ u for s in ("left", "right")]
        return float(max(0.0, np.mean(d)))

    @cached_property
    def head_top(self) -> float:
        """Head joint -> top of the head along the body's axis, file units (:attr:`stature`'s part:
        from the head's End Site or head-top joint, else estimated)."""
        return self.stature.head_top

    @cached_property
    def ankle_height(self) -> float:
        """Height of the ankle above the sole, file units: the stature's first part
        (:attr:`stature`, ``sole_to_ankle``), so :attr:`hip_height` and :attr:`height` stand on
        the same sole.

        The lowest of the ankle's descendant joints and End Sites along the rest shin (a foot
        without a toe joint, its End Site under the ankle, counts: DAZ ``rFoot``); estimated
        from the leg when the rest foot continues the shin (Bandai Namco's rest pose along +X),
        as :func:`repro.motion.body.stature.measure_stature` does (it counted 0 there, and
        Bandai's hip height fell 6.4 cm short of its sole).
        """
        return self.stature.sole_to_ankle

    @cached_property
    def hip_height(self) -> float:
        """Pelvis height of the straightened skeleton: ``ankle_height + leg_length + hip_drop``.

        The size that normalises the root trajectory in
        :func:`repro.motion.retargeting.morphology.encode`: with the root height scaled by the ratio
        of hip heights, a character standing with straight legs keeps its soles on the
        floor whatever its leg/trunk proportions.  File units.
        """
        return self.ankle_height + self.leg_length + self.hip_drop

    @cached_property
    def stature(self) -> Stature:
        """The stature and its parts, measured one way on every rig
        (:func:`repro.motion.body.stature.measure_stature`), file units."""
        return measure_stature(self)

    @property
    def stature_method(self) -> str:
        """How :attr:`height` was measured (:attr:`repro.motion.body.stature.Stature.method`)."""
        return self.stature.method

    @property
    def height(self) -> float:
        """Stature, file units: floor to the top of the head of the body standing straight.

        ``sole -> ankle + ankle -> knee -> hip + hips -> head joint + head joint -> head top``,
        the same measure on every rig (:mod:`repro.motion.body.stature`): lengths between
        joints of the rest pose, so the rest *posture* does not matter (CMU's legs abducted
        ~20 degrees, A and N poses, Bandai Namco's rest pose along +X) nor helper joints (twist
        joints in a limb, folded spine bones); the ankle height and the head top come from the
        rig (foot joints and End Sites, a head End Site or head-top joint) and are estimated
        from anthropometry where the rig does not tell them (Bandai Namco: no head top, the
        foot continuing the shin).  :attr:`stature_method` says which.

        Why the paper's ``size`` (Eq. 1) is the stature: "a constraint placed at 1-meter in
        front of the virtual fighter does not have the same influence if the latter is 2m or
        1.5m tall".  Subject 135 of CMU measures 28.96 units = 1.634 m (its rest pose's
        head-top-to-toe height is 28.15 units), the Bandai Namco actor 1.464 m with the head top
        estimated (1.462 m on the one take whose head has an End Site).
        """
        return self.stature.height

    def to_metres(self, value: float) -> float:
        """``value`` (file units) in metres.

        Raises
        ------
        repro.errors.MotionError
            If :attr:`unit_m` is unknown.
        """
        if self.unit_m is None:
            raise MotionError(
                "the length unit of this skeleton is unknown; read the motion with "
                "read_bvh(..., unit_m=repro.motion.CMU_UNIT_M) (or BANDAI_UNIT_M), or use Motion.to_metres()"
            )
        return as_real(value, "value (a length in file units)", error=MotionError) * self.unit_m

    @property
    def size(self) -> float:
        """The paper's size of an actor or character (Eq. 1), in metres: :attr:`height` × ``unit_m``.

        Raises
        ------
        repro.errors.MotionError
            If :attr:`unit_m` is unknown.
        """
        return self.to_metres(self.height)

    def summary(self) -> dict[str, float]:
        """Sizes in file units (and metres when the unit is known), for reports."""
        out = {
            "height": self.height,
            "hip_height": self.hip_height,
            "leg_length": self.leg_length,
            "arm_length": self.arm_length,
            "trunk_length": self.trunk_length,
        }
        if self.unit_m is not None:
            out.update({k + "_m": v * self.unit_m for k, v in list(out.items())})
        return out

    def rest_motion(self, n_frames: int = 1, frame_time: float = 1.0 / 30.0):
        """A :class:`~repro.motion.Motion` holding this skeleton in its rest pose (for :func:`write_bvh`)."""
        if self.channels is None:
            raise MotionError("this skeleton has no channel layout; build it with Skeleton.from_motion")
        J = self.n_joints
        n_frames = as_int(n_frames, "n_frames", 1, error=MotionError)
        # rotations (4), positions (3) and the Motion's own copies of them, per joint and frame
        check_alloc(2 * n_frames * J * 7 * 8, f"rest_motion(n_frames={n_frames})", error=MotionError)
        rot = np.zeros((n_frames, J, 4))
        rot[..., 3] = 1.0
        return self.motion_with(rot, np.broadcast_to(self.offsets, (n_frames, J, 3)), frame_time=frame_time)

    def motion_with(self, rotations, positions, *, frame_time: float, channels=None, up: str | None = None,
                    source: str | None = None):
        """A :class:`~repro.motion.Motion` on this skeleton (joints, offsets, End Sites, unit) with
        the given local ``rotations`` (F, J, 4) and ``positions`` (F, J, 3); ``channels``
        default this skeleton's.  The one place retargeting results are made
        (:mod:`repro.motion.retargeting.morphology`, :mod:`repro.motion.retargeting.trees`)."""
        from repro.motion.core.motion import Motion

        return Motion(
            joint_names=list(self.joint_names),
            parents=self.parents,
            offsets=self.offsets,
            channels=self.channels if channels is None else channels,
            frame_time=frame_time,
            rotations=rotations,
            positions=positions,
            end_site_parents=self.end_site_parents,
            end_site_offsets=self.end_site_offsets,
            unit_m=self.unit_m,
            up=up,
            source=source,
        )

    def __repr__(self) -> str:
        h = f"{self.size:.3f} m" if self.unit_m is not None else f"{self.height:.4g} units"
        return f"Skeleton({self.n_joints} joints, height {h}, pelvis={self.roles['pelvis']!r})"


def check_role_table(roles, name: str = "roles"):
    """``roles`` if it is None or a mapping role name -> joint name (strings), else MotionError naming ``name``."""
    if roles is None:
        return None
    if not isinstance(roles, Mapping):
        raise MotionError(f"{name} must be a mapping role -> joint name (or None), got {describe(roles)}")
    bad = [(k, v) for k, v in roles.items() if not (isinstance(k, str) and isinstance(v, str))]
    if bad:
        raise MotionError(f"{name} must map role names to joint names (strings), got {describe(bad[0])}")
    return roles


def skeleton_of(x, roles: Mapping[str, str] | None = None) -> Skeleton:
    """``x`` if it is a :class:`Skeleton`, else :meth:`Skeleton.from_motion` of the motion ``x``."""
    roles = check_role_table(roles)
    if isinstance(x, Skeleton):
        return x if roles is None else dataclasses.replace(x, roles=roles)
    if hasattr(x, "rotations") and hasattr(x, "offsets"):
        return Skeleton.from_motion(x, roles=roles)
    raise MotionError(f"expected a Skeleton or a Motion, got {type(x).__name__}")


def _positive(name: str, v) -> float:
    return as_real(v, name, error=MotionError, lo=0.0, lo_open=True)


def scale_skeleton(
    skeleton,
    height: float | None = None,
    *,
    scale: float | None = None,
    arm_scale: float = 1.0,
    leg_scale: float = 1.0,
    trunk_scale: float = 1.0,
    bone_scales: Mapping[str, float] | None = None,
) -> Skeleton:
    """A character of another morphology: same joints and topology, new offsets.

    First the proportions change -- each bone's offset is multiplied by its factor,
    keeping its direction: ``arm_scale`` for the upper arm and forearm (offsets of the
    elbow and wrist joints), ``leg_scale`` for the thigh and shin (offsets of knee and
    ankle), ``trunk_scale`` for the bones from the pelvis to the head and the head's End
    Site, ``bone_scales[joint]`` (multiplied in) for any named joint's offset.  Then the
    whole skeleton (offsets and End Sites) is scaled uniformly so that its
    :attr:`Skeleton.height` is ``height`` metres, or by ``scale``.  So ``height=1.2 *
    h, leg_scale=1.25`` is a character 1.2 times taller than the original whose legs are
    25% longer *relative to the rest of the body* than the original's.

    Parameters
    ----------
    skeleton : Skeleton or Motion
    height : float, optional
        Target :attr:`Skeleton.size` (stature) in metres (needs
        ``unit_m``); the paper's fighters are 1.5 to 2 m.
    scale : float, optional
        Uniform factor instead of ``height`` (not both).  Default: no uniform scaling.
    arm_scale, leg_scale, trunk_scale : float
        Proportion factors (> 0; e.g. 0.75 to 1.25 for "±25%").
    bone_scales : mapping joint name -> float, optional

    Returns
    -------
    Skeleton
        Same ``joint_names``, ``parents``, ``channels``, ``roles`` and ``unit_m``.

    Raises
    ------
    repro.errors.MotionError
        Non-positive or non-finite factors / height, both ``height`` and ``scale``, a
        height without a known unit, unknown joints in ``bone_scales``, or a zero-length
        limb bone (which no factor can fix).
    """
    sk = skeleton_of(skeleton)
    if height is not None and scale is not None:
        raise MotionError("give height or scale, not both")
    arm_scale = _positive("arm_scale", arm_scale)
    leg_scale = _positive("leg_scale", leg_scale)
    trunk_scale = _positive("trunk_scale", trunk_scale)
    f = np.ones(sk.n_joints)
    for side in ("left", "right"):  # the limb's bones, twist joints inside them included
        f[sk.path(f"{side}_shoulder", f"{side}_wrist")] *= arm_scale
        f[sk.path(f"{side}_hip", f"{side}_ankle")] *= leg_scale
    trunk = sk.path("pelvis", "head")
    f[trunk] *= trunk_scale
    if bone_scales is not None and not isinstance(bone_scales, Mapping):
        raise MotionError(f"bone_scales must be a mapping joint name -> factor, got {describe(bone_scales)}")
    for name, s in (bone_scales or {}).items():
        if name not in sk.joint_names:
            raise MotionError(f"bone_scales: no joint {name!r}; joints: {sk.joint_names}")
        f[sk.joint_names.index(name)] *= _positive(f"bone_scales[{name!r}]", s)
    offsets = sk.offsets * f[:, None]
    head = sk.index("head")
    es = sk.end_site_offsets * np.where(sk.end_site_parents == head, trunk_scale, 1.0)[:, None]
    out = sk.with_offsets(offsets, es)
    if height is not None:
        height = _positive("height", height)
        k = height / out.size
    elif scale is not None:
        k = _positive("scale", scale)
    else:
        k = 1.0
    return out.with_offsets(out.offsets * k, out.end_site_offsets * k)


def rescale_constraint(c, size_actor: float, size_character: float) -> np.ndarray:
    """Eq. 1 of Pronost et al. (Section 3.3): ``c_r = c * size_a / size_c``.

    Parameters
    ----------
    c : (..., 3) array
        Constraint (e.g. the target of a punch) relative to the character, expressed in
        the character's root reference frame.
    size_actor, size_character : float
        :attr:`Skeleton.size` of the actor of the database motion and of the animated
        character (same unit).

    Returns
    -------
    (..., 3) array
        The constraint for the actor's skeleton ("an adimensional constraint which is
        multiplied by the size of the actor").
    """
    c = as_real_array(c, "constraint c", error=MotionError, finite=False)
    if c.ndim == 0 or c.shape[-1] != 3:
        raise MotionError(f"constraint c must be a (..., 3) array, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise MotionError("constraint contains NaN or inf")
    k = _positive("size_actor", size_actor) / _positive("size_character", size_character)
    with np.errstate(over="ignore"):  # an overflow is refused just below, named
        out = c * k
    if not np.all(np.isfinite(out)):  # e.g. a size_character of 1e-320: the ratio overflows
        raise MotionError(f"c * size_actor / size_character overflows (size_actor={size_actor!r}, "
                          f"size_character={size_character!r})")
    return out
