"""The :class:`Motion` type: a skeleton, its per-frame local pose, and forward kinematics.

A :class:`Motion` is what the motion-capture readers produce (:func:`repro.motion.read_bvh`,
:func:`repro.motion.read_asf_amc`) and what :func:`repro.motion.write_bvh` writes.  Its
layout follows the BVH format (Biovision Hierarchy; see M. Meredith and S. Maddock,
"Motion Capture File Formats Explained", University of Sheffield, 2001): joints in the
file's depth-first order, each with a rest ``OFFSET`` from its parent, a list of
``CHANNELS`` and, per frame, the values of those channels.  BVH is the format of the
motion database of Pronost et al., "Interactive Animation of Virtual Characters:
Application to Virtual Kung-fu Fighting" (Section 3.2.1: "motion capture data stored in
the BVH standard format"); this module is the first brick of that database.

Instead of the raw channel table, a motion keeps a structured pose:

* ``rotations`` — (F, J, 4) local joint rotations as unit quaternions, scalar-last
  ``(x, y, z, w)`` (the convention of :class:`scipy.spatial.transform.Rotation`);
  identity for joints without rotation channels;
* ``positions`` — (F, J, 3) values of the position channels, for the components flagged
  in :attr:`Motion.position_mask`; other entries are ignored (the readers fill them with
  the offset).

Forward kinematics (the BVH convention): with ``t_j`` the local translation of joint
``j`` (its OFFSET, except that position channels *replace* the corresponding
components — the convention of the Bandai Namco files, where every joint has
position channels equal to its offset, and of the independent reader ``bvhio``) and
``q_j`` its local rotation,

    ``G_j = G_parent(j) * T(t_j) * R(q_j)``,

so a joint's world position is ``p_parent + R_parent t_j`` and its world rotation
``R_parent R(q_j)``.  The computation is vectorised over frames; the only Python loop
runs over the depth levels of the tree.

Lengths are in the file's units (CMU: 1/0.45 inch, :data:`CMU_UNIT_M` metres; Bandai
Namco: centimetres, :data:`BANDAI_UNIT_M`); :meth:`Motion.scaled` and
:meth:`Motion.to_metres` convert.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from repro.checks import as_real, as_real_array, describe, read_only
from repro.errors import BVHError, MotionError
from repro.motion.core.cache import LRUCache
from repro.motion.core.channels import channel_layout, channel_table
from repro.motion.core.kinematics import (LEVEL_LOOP_MAX_DEPTH, MAX_COORDINATE, check_joint_names, depth_levels,
                                          forward_kinematics)
from repro.motion.core.quaternion import quat_rotate

__all__ = [
    "Motion",
    "CMU_UNIT_M",
    "BANDAI_UNIT_M",
    "finite_vector3",
    "MAX_COORDINATE",
    "LEVEL_LOOP_MAX_DEPTH",
    "UnknownJointError",
]

#: Metres per CMU length unit.  CMU ASF files declare ``:units length 0.45``: lengths
#: are in inches multiplied by 0.45, so one unit is 1/0.45 inch = 0.0254/0.45 m
#: (about 0.056444 m; see ``mocap/cmu/PROVENANCE.md``).
CMU_UNIT_M: float = 0.0254 / 0.45

#: Metres per Bandai Namco length unit (centimetres; ``mocap/bandai/PROVENANCE.md``).
BANDAI_UNIT_M: float = 0.01


#: Below this sum of all local translation lengths, world positions cannot overflow
#: (a rotated vector's intermediate terms stay under 5 times its length).
_SAFE_LENGTH_SUM = 1e300

#: The joint structures (names and channels) already validated, with their channel layout: a
#: motion rebuilt on the same skeleton (a pose edited, a clip cut, placed or retargeted) is not
#: checked and parsed again.  Keyed by the validated names and channels (plain strings), so only
#: an input equal to them, element for element, finds its entry; a few skeletons are in play at
#: once (the database's actors, the characters on screen): the 64 most recent are kept.
_STRUCTURES: LRUCache = LRUCache(64)


def _structure_key(joint_names, channels) -> tuple | None:
    """``(names, channels)`` as a hashable key of :data:`_STRUCTURES`; None when they cannot be one
    (not lists or tuples, unhashable channel entries): then they are validated without the memo."""
    if type(joint_names) not in (list, tuple) or type(channels) not in (list, tuple):
        return None
    key = (tuple(joint_names), tuple(channels))
    try:
        hash(key)
    except TypeError:
        return None
    return key


def finite_vector3(value, name: str, error=None) -> np.ndarray:
    """``value`` as a finite float 3-vector, or ``error`` (default :class:`MotionError`) naming ``name``.

    The one check every 3-D input of the motion library goes through (targets,
    offsets, positions), so bad input gets the same clear message everywhere.
    """
    error = MotionError if error is None else error
    try:  # no strings, None, booleans or complex parts taken for numbers
        a = as_real_array(value, name, error=error, finite=False)
    except error as e:
        raise error(f"{name} must be a 3-vector of numbers: {e}") from None
    if a.shape != (3,):
        raise error(f"{name} must be a 3-vector, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise error(f"{name} contains NaN or inf: {a.tolist()}")
    if np.abs(a).max() > MAX_COORDINATE:
        raise error(f"{name} has coordinates beyond {MAX_COORDINATE:g} ({a.tolist()}): their squares overflow "
                    "float64 in every distance")
    return a


class UnknownJointError(MotionError, KeyError):
    """No joint of that name (:meth:`Motion.joint_index`): a MotionError, and a KeyError as lookups raise."""

    def __str__(self) -> str:  # the message, not KeyError's quoted repr of it
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True, eq=False)
class Motion:
    """A skeleton and its animation, in the layout of a BVH file.

    Instances are immutable (arrays are read-only copies); derive new motions with
    :meth:`scaled`, :meth:`to_metres` or :func:`dataclasses.replace`.

    Parameters
    ----------
    joint_names : sequence of str
        J unique joint names (End Sites excluded), parents before children
        (the readers give the file's depth-first order).
    parents : (J,) int array
        Parent index of each joint, ``-1`` for the root (exactly one root, index 0);
        ``parents[j] < j``.
    offsets : (J, 3) array
        Rest offset of each joint from its parent (BVH ``OFFSET``), file units.
    channels : sequence of sequence of str
        Per joint, the BVH channel names in file order (``"Xposition"`` ...
        ``"Zrotation"``), each at most once.  The order of the rotation channels is
        the Euler order: ``("Zrotation", "Xrotation", "Yrotation")`` means
        ``R = Rz Rx Ry`` (intrinsic ZXY).
    frame_time : float
        Seconds per frame, > 0.
    rotations : (F, J, 4) array
        Local joint rotations, unit quaternions ``(x, y, z, w)``; normalised on
        construction.  A joint without rotation channels should keep the identity
        (:func:`~repro.motion.write_bvh` refuses a rotation its channels cannot express).
    positions : (F, J, 3) array
        Position-channel values; only the entries where :attr:`position_mask` is true
        are used, others are ignored.
    end_site_parents : (E,) int array, optional
        Joint index carrying each End Site.
    end_site_offsets : (E, 3) array, optional
        Offset of each End Site from its joint.
    unit_m : float or None, optional
        Metres per length unit of the data when known (e.g. :data:`CMU_UNIT_M`),
        used by :meth:`to_metres`.
    up : {"y", "z"} or None, optional
        The world's up axis when known (given, or inferred by
        :func:`repro.motion.body.units.infer_units`); None means the BVH convention, Y.
    source : str or None, optional
        Where the motion was read from (informational; :func:`write_bvh` refuses to
        overwrite existing files unless asked).

    Raises
    ------
    repro.errors.BVHError
        When the arrays are inconsistent (shapes, non-finite values, zero quaternions,
        a bad parent array, duplicate names, unknown channels).
    """

    joint_names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    frame_time: float
    rotations: np.ndarray
    positions: np.ndarray
    end_site_parents: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    end_site_offsets: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    unit_m: float | None = None
    source: str | None = None
    up: str | None = None

    #: Largest ``| |q| - 1 |`` :meth:`from_unit_rotations` accepts as a unit quaternion.
    UNIT_TOLERANCE = 1e-6

    @classmethod
    def from_unit_rotations(cls, **fields) -> Motion:
        """The trusted constructor: a Motion whose ``rotations`` are unit quaternions already.

        Same fields and checks as the constructor, except that the rotations are kept
        bit for bit instead of being re-normalised (which can move a quaternion by one
        ulp); their norms must be within :data:`UNIT_TOLERANCE` of 1, else
        :class:`~repro.errors.BVHError`.  For results computed from unit quaternions (a
        database's stored clips, the adaptation's unchanged frames).
        """
        obj = cls.__new__(cls)
        for f in dataclasses.fields(cls):
            if f.name in fields:
                value = fields.pop(f.name)
            elif f.default is not dataclasses.MISSING:
                value = f.default
            elif f.default_factory is not dataclasses.MISSING:
                value = f.default_factory()
            else:
                raise TypeError(f"Motion.from_unit_rotations() missing field {f.name!r}")
            object.__setattr__(obj, f.name, value)
        if fields:
            raise TypeError(f"Motion.from_unit_rotations() got unexpected fields {sorted(fields)}")
        obj._validate(renormalise=False)
        return obj

    def with_unit_rotations(self, rotations) -> Motion:
        """This motion with other ``rotations``, unit quaternions kept bit for bit (:meth:`from_unit_rotations`)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        fields["rotations"] = rotations
        return type(self).from_unit_rotations(**fields)

    def __post_init__(self) -> None:
        self._validate(renormalise=True)

    def _validate(self, renormalise: bool) -> None:
        key = _structure_key(self.joint_names, self.channels)
        known = key is not None and key in _STRUCTURES
        if known:  # names and channels equal to validated ones: their checks pass, their layout is known
            names_t, channels_t, (mask, seqs) = _STRUCTURES.get(key, self._structure)
            names, channels, layout = list(names_t), list(channels_t), (mask.copy(), list(seqs))
        else:
            names = self._checked_names()
        J = len(names)
        parents, offsets = self._checked_tree(J)
        if not known:
            channels, layout = self._checked_channels(names)
        ft = as_real(self.frame_time, "frame_time (seconds)", error=BVHError, finite=False)
        if not np.isfinite(ft) or ft <= 0 or not np.isfinite(1.0 / ft):
            raise BVHError(f"frame_time must be finite and > 0 with a finite frame rate, got {self.frame_time!r}")
        rot = as_real_array(self.rotations, "rotations", error=BVHError, finite=False)
        if rot.ndim != 3 or rot.shape[1:] != (J, 4):
            raise BVHError(f"rotations must be (F, {J}, 4), got shape {rot.shape}")
        F = rot.shape[0]
        if not np.isfinite(F * ft):
            raise BVHError(f"{F} frames of {ft!r} s: the duration overflows")
        if not np.all(np.isfinite(rot)):
            raise BVHError("rotations contain NaN or inf")
        norm = np.linalg.norm(rot, axis=-1, keepdims=True)
        if np.any(norm < 1e-12):
            raise BVHError("rotations contain a zero quaternion")
        if renormalise:
            rot = rot / norm
        elif not np.all(np.abs(norm - 1.0) <= self.UNIT_TOLERANCE):
            raise BVHError(f"rotations are not unit quaternions (|q| - 1 up to {float(np.abs(norm - 1.0).max()):.3g})")
        pos = as_real_array(self.positions, "positions", error=BVHError, finite=False)
        if pos.shape != (F, J, 3):
            raise BVHError(f"positions must be ({F}, {J}, 3), got shape {pos.shape}")
        if not np.all(np.isfinite(pos)):
            raise BVHError("positions contain NaN or inf")
        esp = as_real_array(self.end_site_parents, "end_site_parents", error=BVHError, integer=True)
        eso = as_real_array(self.end_site_offsets, "end_site_offsets", error=BVHError, finite=False)
        if esp.size == 0:
            esp = np.zeros(0, dtype=np.intp)
        if esp.ndim != 1 or not np.issubdtype(esp.dtype, np.integer) or np.any((esp < 0) | (esp >= J)):
            raise BVHError(f"end_site_parents must be joint indices in [0, {J})")
        if eso.shape != (esp.size, 3) or not np.all(np.isfinite(eso)):
            raise BVHError(f"end_site_offsets must be a finite ({esp.size}, 3) array, got {eso.shape}")
        if self.unit_m is not None:
            as_real(self.unit_m, "unit_m (metres per unit)", error=BVHError, lo=0.0, lo_open=True)
        if self.source is not None and not isinstance(self.source, str):
            raise BVHError(f"source must be None or a string (where the motion comes from), got {describe(self.source)}")
        if self.up is not None and not isinstance(self.up, str):
            raise BVHError(f"up must be 'y', 'z' or None, got {describe(self.up)}")
        set_ = object.__setattr__
        set_(self, "joint_names", names)
        set_(self, "parents", read_only(parents))
        set_(self, "offsets", read_only(offsets))
        set_(self, "channels", channels)
        self.__dict__["_layout"] = layout  # the cached_property's value
        set_(self, "frame_time", ft)
        set_(self, "rotations", read_only(rot))
        set_(self, "positions", read_only(pos))
        set_(self, "end_site_parents", read_only(esp.astype(np.intp)))
        set_(self, "end_site_offsets", read_only(eso))
        set_(self, "unit_m", None if self.unit_m is None else float(self.unit_m))
        if self.up is not None and self.up not in ("y", "z"):
            raise BVHError(f"up must be 'y', 'z' or None, got {self.up!r}")
        self._check_finite_kinematics()

    def _checked_names(self) -> list[str]:
        """The joint names as a list of str, unique and at least one (else BVHError)."""
        names = check_joint_names(self.joint_names, error=BVHError)
        if not names:
            raise BVHError("a motion needs at least one joint")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise BVHError(f"duplicate joint names: {dup}")
        return names

    def _checked_tree(self, J: int) -> tuple[np.ndarray, np.ndarray]:
        """``(parents, offsets)`` of ``J`` joints checked: a tree rooted at joint 0, finite offsets (else BVHError)."""
        parents = as_real_array(self.parents, "parents", error=BVHError, integer=True)
        if parents.shape != (J,) or not np.issubdtype(parents.dtype, np.integer):
            raise BVHError(f"parents must be a ({J},) int array, got shape {parents.shape} dtype {parents.dtype}")
        parents = parents.astype(np.intp)
        if parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, J)):
            raise BVHError("parents must be -1 for joint 0 (the only root) and parents[j] < j for the others")
        offsets = as_real_array(self.offsets, "offsets", error=BVHError, finite=False)
        if offsets.shape != (J, 3) or not np.all(np.isfinite(offsets)):
            raise BVHError(f"offsets must be a finite ({J}, 3) array, got shape {offsets.shape}")
        return parents, offsets

    def _checked_channels(self, names: list[str]) -> tuple[list[tuple[str, ...]], tuple[np.ndarray, list[str]]]:
        """The channels as tuples of str, one per joint, none repeated, and their layout (else BVHError);
        remembered in :data:`_STRUCTURES` with the names."""
        try:
            channels = [tuple(str(c) for c in ch) for ch in self.channels]
        except TypeError:
            raise BVHError(f"channels must list each joint's channel names, got {describe(self.channels)}") from None
        if len(channels) != len(names):
            raise BVHError(f"channels must list {len(names)} joints, got {len(channels)}")
        for name, ch in zip(names, channels):
            if len(set(ch)) != len(ch):
                raise BVHError(f"joint {name!r}: repeated channel in {list(ch)}")
        mask, seqs = channel_layout(channels)
        value = (tuple(names), tuple(channels), (read_only(mask), tuple(seqs)))
        _STRUCTURES.get(value[:2], lambda: value)
        return channels, (mask, seqs)

    def _structure(self) -> tuple:
        """The value of :data:`_STRUCTURES` for this motion's names and channels (validated)."""
        names = self._checked_names()
        channels, (mask, seqs) = self._checked_channels(names)
        return tuple(names), tuple(channels), (read_only(mask), tuple(seqs))

    def _check_finite_kinematics(self) -> None:
        """Raise BVHError when finite lengths add up to infinite world positions.

        Rotations are unit quaternions, so no world position (joint or End Site) is
        larger than the sum over joints of the largest local translation, plus the End
        Site offsets: when that bound is below :data:`_SAFE_LENGTH_SUM` nothing can
        overflow and the check costs one pass over the positions.  Only above it is
        forward kinematics run, to name the first joint and frame that overflow.
        """
        with np.errstate(over="ignore", invalid="ignore"):
            local = np.abs(self.offsets)
            if self.n_frames:
                local = np.where(self.position_mask, np.abs(self.positions).max(axis=0), local)
            bound = float(local.sum()) + float(np.abs(self.end_site_offsets).sum())
            if bound < _SAFE_LENGTH_SUM:
                return
            gq, gp = self.global_transforms()
            bad = ~np.isfinite(gp).all(axis=-1)
            where = "world position"
            if not bad.any() and self.end_site_parents.size:
                par = self.end_site_parents
                ends = gp[:, par] + quat_rotate(gq[:, par], self.end_site_offsets[None])
                bad = ~np.isfinite(ends).all(axis=-1)
                where = "End Site position"
        if bad.any():
            f, j = (int(v[0]) for v in np.nonzero(bad))
            name = self.joint_names[j if where == "world position" else int(self.end_site_parents[j])]
            raise BVHError(
                f"joint {name!r}, frame {f}: {where} overflows to infinity (offsets and position values "
                f"are finite but too large: largest {float(local.max()):.3g}, sum {bound:.3g}; expected "
                "lengths whose sum stays far below 1.8e308)"
            )

    # ------------------------------------------------------------------ basics
    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.rotations.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints J (End Sites excluded)."""
        return len(self.joint_names)

    @property
    def fps(self) -> float:
        """Frames per second, ``1 / frame_time``."""
        return 1.0 / self.frame_time

    @property
    def duration(self) -> float:
        """Length of the clip in seconds, ``n_frames * frame_time``."""
        return self.n_frames * self.frame_time

    @property
    def n_channels(self) -> int:
        """Total number of BVH channels per frame."""
        return sum(len(c) for c in self.channels)

    @property
    def end_sites(self) -> list[tuple[int, np.ndarray]]:
        """End Sites as ``(parent joint index, offset (3,))`` pairs, in file order."""
        return [(int(p), o) for p, o in zip(self.end_site_parents, self.end_site_offsets)]

    def joint_index(self, name: str) -> int:
        """Index of joint ``name`` in :attr:`joint_names`.

        Raises
        ------
        UnknownJointError
            If there is no such joint (the message lists the known names); a
            :class:`~repro.errors.MotionError` and a ``KeyError``.
        """
        if not isinstance(name, str):
            raise UnknownJointError(f"a joint name must be a string, got {describe(name)}")
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise UnknownJointError(f"no joint {name!r}; joints: {self.joint_names}") from None

    @cached_property
    def _layout(self) -> tuple[np.ndarray, list[str]]:
        return channel_layout(self.channels)

    @property
    def position_mask(self) -> np.ndarray:
        """(J, 3) bool: which local-translation components come from position channels."""
        return self._layout[0]

    @property
    def rotation_orders(self) -> list[str]:
        """Per joint, the Euler order of its rotation channels, e.g. ``"ZYX"`` (``""`` if none).

        Uppercase letters mean *intrinsic* rotations in scipy's convention:
        ``Rotation.from_euler("ZYX", [z, y, x])`` is ``Rz Ry Rx``, the BVH convention.
        """
        return self._layout[1]

    @cached_property
    def _depth_levels(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return depth_levels(self.parents)

    @property
    def n_depth_levels(self) -> int:
        """Depth levels of the joint tree (forward kinematics runs one step per level)."""
        return len(self._depth_levels)

    # ---------------------------------------------------------- kinematics
    def local_translations(self) -> np.ndarray:
        """(F, J, 3) local translation of every joint: offsets, with position channels replacing components."""
        return np.where(self.position_mask[None], self.positions, self.offsets[None])

    @property
    def root_positions(self) -> np.ndarray:
        """(F, 3) world position of the root joint (its local translation)."""
        return self.local_translations()[:, 0]

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotations and positions of every joint, every frame (forward kinematics).

        Returns
        -------
        rotations : (F, J, 4) array
            World rotation of each joint's frame, unit quaternions ``(x, y, z, w)``
            (``scipy.spatial.transform.Rotation.from_quat(r.reshape(-1, 4))`` converts).
        positions : (F, J, 3) array
            World position of each joint, file units, in :attr:`joint_names` order.
        """
        # core.kinematics.forward_kinematics: the level loop, or pointer doubling beyond
        # LEVEL_LOOP_MAX_DEPTH levels; local_translations() is a fresh array, filled in place
        return forward_kinematics(self.parents, self.rotations, self.local_translations(),
                                  levels=self._depth_levels, copy=False)

    def global_positions(self) -> np.ndarray:
        """(F, J, 3) world positions of the joints, file units, in :attr:`joint_names` order."""
        return self.global_transforms()[1]

    def end_site_positions(self) -> np.ndarray:
        """(F, E, 3) world positions of the End Sites, in :attr:`end_sites` order."""
        gq, gp = self.global_transforms()
        par = self.end_site_parents
        return gp[:, par] + quat_rotate(gq[:, par], self.end_site_offsets[None])

    def channel_values(self) -> np.ndarray:
        """(F, C) BVH channel table: position values and Euler angles in degrees.

        Angles are recovered from :attr:`rotations` in each joint's declared order with
        :meth:`scipy.spatial.transform.Rotation.as_euler`, so they lie in scipy's
        principal ranges and may differ from the angles of the file read (by multiples
        of 360 degrees, or by the equivalent triple at gimbal lock) while describing the
        same rotation.

        Raises
        ------
        repro.errors.BVHError
            If a joint with fewer than three rotation channels has a rotation those
            axes cannot express.
        """
        return channel_table(self)

    # ---------------------------------------------------------------- units
    def scaled(self, factor: float, unit_m: float | None = None) -> Motion:
        """A copy with every length (offsets, positions, End Sites) multiplied by ``factor``.

        Parameters
        ----------
        factor : float
            Finite, > 0.
        unit_m : float, optional
            Metres per unit of the result; by default ``self.unit_m / factor`` when
            ``self.unit_m`` is known, else None.
        """
        factor = as_real(factor, "scale factor", error=BVHError, lo=0.0, lo_open=True)
        if unit_m is not None:
            unit_m = as_real(unit_m, "unit_m (metres per unit)", error=BVHError, lo=0.0, lo_open=True)
        if unit_m is None and self.unit_m is not None:
            unit_m = self.unit_m / factor
        return dataclasses.replace(
            self,
            offsets=self.offsets * factor,
            positions=self.positions * factor,
            end_site_offsets=self.end_site_offsets * factor,
            unit_m=unit_m,
        )

    def to_metres(self, unit_m: float | None = None) -> Motion:
        """A copy in metres: lengths multiplied by ``unit_m`` (default :attr:`unit_m`).

        Raises
        ------
        repro.errors.BVHError
            If neither ``unit_m`` nor :attr:`unit_m` is known.
        """
        unit_m = self.unit_m if unit_m is None else as_real(unit_m, "unit_m (metres per unit)", error=BVHError,
                                                             lo=0.0, lo_open=True)
        if unit_m is None:
            raise BVHError(
                "the length unit of this motion is unknown; pass unit_m "
                "(e.g. repro.motion.CMU_UNIT_M or BANDAI_UNIT_M)"
            )
        return self.scaled(unit_m, unit_m=1.0)

    def __repr__(self) -> str:
        return (
            f"Motion({self.n_joints} joints, {self.n_frames} frames at {self.fps:.4g} fps, "
            f"{self.n_channels} channels, source={self.source!r})"
        )
