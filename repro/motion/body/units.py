"""Length unit and up axis of a skeleton, inferred from its stature and rest pose.

A BVH file does not say its unit or its up axis.  A human is 0.5 to 2.5 m tall
(:data:`STATURE_RANGE_M`), so the stature of the skeleton in file units
(:attr:`repro.motion.body.skeleton.Skeleton.height`, measured one way on every rig from the
body-part roles: :mod:`repro.motion.body.stature`) tells the unit among :data:`UNITS` --
metres, centimetres (Mixamo's and Unreal's 100 units per metre), millimetres, inches, the CMU
unit (1/0.45 inch), feet and decimetres (MakeHuman) -- as the one whose stature in metres lies
in that range and is closest (on a log scale) to a typical adult's :data:`TYPICAL_STATURE_M`,
the more conventional one when two are nearly as close (:func:`infer_unit`).  The up axis is the
world axis (Y or Z) closest to the rest pelvis -> head direction; when the rest pose
does not tell (a rig whose rest pose lies along X, as Bandai Namco's), the mean pelvis ->
head direction over the frames.  :func:`infer_units` records both on the
:class:`~repro.motion.Motion` (``unit_m``, ``up``) with a :class:`~repro.errors.UnitWarning`
saying what was chosen; values given by the caller always win.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from repro.errors import MotionError, UnitWarning
from repro.motion.core.motion import Motion
from repro.motion.body.pose_frames import heading_from_hips
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.body.stature import STATURE_RANGE_M, TYPICAL_STATURE_M, UNITS, infer_unit

__all__ = ["STATURE_RANGE_M", "TYPICAL_STATURE_M", "UNITS", "infer_unit", "infer_units", "infer_up", "y_up_metres"]

#: Z-up world -> Y-up world: +Z -> +Y, -Y -> +Z (a Z-up character facing -Y faces +Z after).
_Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

def _axis_of(v: np.ndarray) -> str | None:
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n <= 0:
        return None
    v = v / n
    if max(abs(v[1]), abs(v[2])) < np.cos(np.radians(45.0)):
        return None
    return "y" if abs(v[1]) >= abs(v[2]) else "z"


def infer_up(motion: Motion, skeleton=None) -> str:
    """``"y"`` or ``"z"``: the world axis of the rest pelvis -> head direction (else the frames')."""
    sk = skeleton if skeleton is not None else skeleton_of(motion)
    p = sk.rest_positions()
    pel, head = sk.index("pelvis"), sk.index("head")
    ax = _axis_of(p[head] - p[pel])
    if ax is None and motion is not None and motion.n_frames:
        g = motion.global_positions()
        ax = _axis_of(np.mean(g[:, head] - g[:, pel], axis=0))
    if ax is None:
        raise MotionError(
            f"cannot infer the up axis: pelvis {sk.roles['pelvis']!r} -> head {sk.roles['head']!r} is "
            "along neither Y nor Z in the rest pose or the frames; pass up='y' or up='z'"
        )
    return ax


def infer_units(motion: Motion, *, unit_m: float | None = None, up: str | None = None, warn: bool = True) -> Motion:
    """``motion`` with ``unit_m`` and ``up`` recorded: given values win, missing ones are inferred.

    Parameters
    ----------
    motion : Motion
    unit_m : float, optional
        Metres per file unit; default ``motion.unit_m``, else inferred from the stature.
    up : {"y", "z"}, optional
        Default ``motion.up``, else inferred from the rest pose.
    warn : bool, default True
        Issue a :class:`~repro.errors.UnitWarning` naming what was inferred.

    Raises
    ------
    repro.errors.MotionError
        No body-part roles, a stature that fits no unit, or an up axis that cannot be told.
    """
    if up is not None and up not in ("y", "z"):
        raise MotionError(f"up must be 'y' or 'z', got {up!r}")
    if unit_m is not None:
        unit_m = float(unit_m)
        if not (np.isfinite(unit_m) and unit_m > 0):
            raise MotionError(f"unit_m must be finite and > 0, got {unit_m!r}")
    unit_m = motion.unit_m if unit_m is None else unit_m
    up = motion.up if up is None else up
    said = []
    sk = None
    if unit_m is None:
        sk = skeleton_of(dataclasses.replace(motion, unit_m=1.0))
        unit_m, name = infer_unit(sk.height)
        said.append(f"unit {name} ({unit_m:g} m per unit; stature {sk.height:.4g} units = {sk.height * unit_m:.3f} m, "
                    f"{sk.stature_method})")
    if up is None:
        up = infer_up(motion, sk)
        said.append(f"up axis {up.upper()}")
    if said and warn:
        warnings.warn(
            f"{motion.source or 'motion'}: inferred {' and '.join(said)}; pass unit_m= / up= to choose",
            UnitWarning,
            stacklevel=2,
        )
    if unit_m == motion.unit_m and up == motion.up:
        return motion
    return dataclasses.replace(motion, unit_m=unit_m, up=up)


#: Turns about +Y by multiples of 90 degrees (exact): the rest pose facing +X, -Z, -X made to face +Z.
_YAW_TURNS = {
    "+X": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
    "-Z": np.array([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]),
    "-X": np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
}


def _facing_turn(sk: Skeleton, R: np.ndarray):
    """``(turn, "+X" / "-Z" / "-X")`` making an upright rest pose face +Z (the databases' actors do), or None.

    The facing is the hips' heading (:func:`repro.motion.body.pose_frames.heading_from_hips`), taken
    to the nearest world axis (exporters' rest poses face along one); a rest pose that is not upright
    (Bandai's lies along +X) or whose hips do not tell is left as it is.
    """
    p = sk.rest_positions() @ R.T
    body_up = p[sk.index("head")] - p[sk.index("pelvis")]
    n = float(np.linalg.norm(body_up))
    lateral = p[sk.index("left_hip")] - p[sk.index("right_hip")]
    flat = np.array([lateral[0], 0.0, lateral[2]])
    if not (n > 0 and body_up[1] > np.cos(np.radians(45.0)) * n) or \
            not np.linalg.norm(flat) > 0.5 * np.linalg.norm(lateral) > 0:
        return None
    theta = float(heading_from_hips(p[sk.index("left_hip")], p[sk.index("right_hip")]))
    fx, fz = np.sin(theta), np.cos(theta)
    if abs(fz) >= abs(fx):
        return None if fz > 0 else (_YAW_TURNS["-Z"], "-Z")
    return (_YAW_TURNS["+X"], "+X") if fx > 0 else (_YAW_TURNS["-X"], "-X")


def y_up_metres(character, *, warn: bool = True):
    """``character`` (Skeleton or Motion) in the Y-up, metre convention of the databases.

    The unit is ``unit_m`` when known, else inferred from the stature (:func:`infer_unit`);
    the up axis ``motion.up`` when known, else inferred (:func:`infer_up`; a rest pose along
    neither axis, as Bandai Namco's, counts as Y-up).  A Z-up character is turned about X
    (+Z -> +Y, -Y -> +Z): offsets and End Sites ``R o``, local rotations ``R L R^-1``,
    position channels ``R p`` -- the same body and motion in the turned world, its rest
    pose upright in it.  An upright rest pose facing another horizontal axis than +Z (exporters'
    characters facing -Z or +X) is turned about Y to face +Z, as the databases' actors do, the
    same way (:func:`_facing_turn`).  Returns ``character`` itself when it already is Y-up in
    metres facing +Z;
    a :class:`~repro.errors.UnitWarning` names what was inferred (``warn``).

    Raises
    ------
    repro.errors.MotionError
        No body-part roles, a stature that fits no unit.
    """
    sk = skeleton_of(character)
    said = []
    unit_m = character.unit_m
    if unit_m is None:
        unit_m, name = infer_unit(sk.height)
        said.append(f"unit {name} ({unit_m:g} m per unit; stature {sk.height:.4g} units, {sk.stature_method})")
    up = getattr(character, "up", None)
    if up is None:
        try:
            up = infer_up(character if isinstance(character, Motion) else None, sk)
        except MotionError:
            up = "y"
        if up != "y":
            said.append(f"up axis {up.upper()}")
    R = _Z_TO_Y if up == "z" else np.eye(3)
    turn = _facing_turn(sk, R)
    if turn is not None:
        R = turn[0] @ R
        said.append(f"a rest pose facing {turn[1]} (turned to face +Z)")
    if said and warn:
        warnings.warn(f"character {sk.joint_names[0]!r}: inferred {' and '.join(said)}; converted to Y-up metres",
                      UnitWarning, stacklevel=2)
    if unit_m == 1.0 and up == "y" and turn is None:
        return character
    off = np.asarray(character.offsets, dtype=float) @ R.T * unit_m
    es = np.asarray(character.end_site_offsets, dtype=float).reshape(-1, 3) @ R.T * unit_m
    if isinstance(character, Skeleton):
        return character.with_offsets(off, es, unit_m=1.0)
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R)
    rot = np.asarray(character.rotations, dtype=float)
    rot = (q * Rotation.from_quat(rot.reshape(-1, 4)) * q.inv()).as_quat().reshape(rot.shape)
    pos = np.asarray(character.positions, dtype=float) @ R.T * unit_m
    return dataclasses.replace(character, offsets=off, end_site_offsets=es, rotations=rot, positions=pos,
                               unit_m=1.0, up="y")
