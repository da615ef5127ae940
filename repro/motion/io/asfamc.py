"""Reading Acclaim ASF/AMC motion capture (the originals of the CMU database).

The Acclaim format (Acclaim Entertainment; described in M. Meredith and S. Maddock,
"Motion Capture File Formats Explained", University of Sheffield, 2001, and used by the
CMU Graphics Lab Motion Capture Database, http://mocap.cs.cmu.edu) splits a take into an
ASF skeleton (bones with a global ``direction``, a ``length``, a local frame ``axis`` and
the ``dof`` the motion drives; read by :mod:`repro.motion.io.asf`) and an AMC motion (per
frame, one line of dof values per bone; read here).  The CMU BVH files used for the database of Pronost et al. (Section 3.2) were
converted from these originals, so reading both and comparing the forward kinematics is
an end-to-end check of both readers.

Conversion to a :class:`~repro.motion.Motion` (the convention of
``mocap/cmu/PROVENANCE.md``, with which the staged BVH files were made):

* one joint per ASF bone, placed at the bone's start, plus the root; joints in
  depth-first order of the ``:hierarchy`` section (children in listed order);
* joint ``OFFSET`` = parent bone's ``direction x length`` (zero below the root; the
  root's offset is the ASF root ``position``); leaf bones get an End Site at their own
  ``direction x length``;
* bone axis ``C`` from ``axis ax ay az XYZ``: the rotations are applied in the listed
  order about fixed axes, ``C = Rz(az) Ry(ay) Rx(ax)``; motion ``M`` from the AMC values
  likewise in the order of the bone's ``dof`` list (``dof rx ry rz`` gives
  ``M = Rz Ry Rx``, missing dofs are 0);
* local joint rotation ``C M C^-1`` (for the root, ``C`` from the root ``orientation``
  and ``axis``, ``M`` from the ``R*`` entries of the root ``order``), written as
  ``Zrotation Yrotation Xrotation`` channels; the root also gets position channels
  for the ``T*`` entries of its ``order``, holding the AMC root translation untouched.

Lengths stay in ASF units (CMU: ``:units length 0.45``, one unit = 1/0.45 inch, see
:data:`~repro.motion.CMU_UNIT_M`).  Malformed files raise
:class:`repro.errors.BVHError` naming the line.
"""

from __future__ import annotations

import math
import re

import numpy as np

from repro.checks import as_real, describe
from repro.errors import BVHError
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import euler_to_quat, quat_multiply
from repro.motion.io.asf import AsfSkeleton, acclaim_lines, acclaim_text, read_asf

# the skeleton's names (from asf) are listed too: repro.motion imports them from here
__all__ = [
    "read_amc",
    "read_asf_amc",
    "CMU_FRAME_TIME",
    "MAX_AMC_BYTES",
]

#: CMU captures at 120 Hz; AMC files carry no frame rate.
CMU_FRAME_TIME: float = 1.0 / 120.0

#: The channels of every joint's rotation (the root's follow its position channels).
_ROTATION_CHANNELS = ("Zrotation", "Yrotation", "Xrotation")

#: Most bytes (after gzip is undone) an AMC file may hold: 1 GiB (CMU takes are 1-40 MB).
MAX_AMC_BYTES = 1 << 30
#: The arrays of the motion (rotations and positions, 56 bytes per joint and frame) may
#: take at most this many times the AMC file's bytes, or 256 MiB if that is more.  Only
#: joints without dofs, which take no AMC text, can make a motion much larger than its file.
_MOTION_BYTES_PER_AMC_BYTE = 64
_MOTION_BYTES_FLOOR = 256 << 20

#: A plain ASCII frame number (Python's int() also takes '1_0', ' 7', Arabic-Indic digits ...).
_UINT_RE = re.compile(r"[0-9]{1,18}")


def _numberish(tok: str) -> bool:
    """Whether a token looks like a (malformed) number: digits of any script, ``_``, ``.``, a sign."""
    body = tok.lstrip("+-")
    return bool(body) and any(c.isnumeric() for c in body) and all(c.isnumeric() or c in "_." for c in body)


def _plain_numbers(tokens: list[str], strict: bool = False) -> bool:
    """Whether the tokens hold only ASCII and no ``_`` (``strict``: and each is a finite float)."""
    joined = "".join(tokens)
    if "_" in joined or not joined.isascii():
        return False
    if strict:
        try:
            return all(math.isfinite(float(t)) for t in tokens)
        except ValueError:
            return False
    return True


def _amc_header(head: str, lineno: int, frame_no: int | None, degrees: bool | None) -> bool | None:
    """A ``:keyword`` line of the AMC header; returns ``degrees`` as ``:DEGREES`` / ``:RADIANS`` set it."""
    if frame_no is not None:
        raise BVHError(f"line {lineno}: header line {head!r} after the first frame")
    if head.upper() == ":DEGREES":
        return True
    if head.upper() == ":RADIANS":
        return False
    return degrees


def _frame_number(head: str, lineno: int) -> int:
    """The number of a frame line: plain ASCII digits, at most 18."""
    if not _UINT_RE.fullmatch(head):
        if _numberish(head):  # '²', Arabic-Indic digits, '1_0', '-3', 30 digits ...
            raise BVHError(
                f"line {lineno}: frame number {head[:40]!r} is not a plain integer (ASCII digits 0-9, at most 18)"
            )
        raise BVHError(f"line {lineno}: {head[:40]!r} is neither a frame number nor a bone of the skeleton")
    return int(head)


def _check_frame(required: set[str], seen: set[str], lineno: int, frame_no: int, frame_line: int) -> None:
    """Check that the frame begun at ``frame_line`` had a line for every bone with dofs (and the root)."""
    missing = required - seen
    if missing:
        raise BVHError(
            f"line {lineno}: frame {frame_no} (line {frame_line}) lacks values for "
            f"{sorted(missing)} (truncated file?)"
        )


def _bad_bone_line(tok: list[str], lineno: int, frame_no: int | None, ndof: dict[str, int], seen: set[str]) -> BVHError:
    """The error for a bone line that is not one more bone of the current frame with its dofs' values."""
    head = tok[0]
    if frame_no is None:
        return BVHError(f"line {lineno}: {head!r} before the first frame number")
    if head not in ndof:
        return BVHError(f"line {lineno}: unknown bone {head!r} (frame {frame_no})")
    if head in seen:
        return BVHError(f"line {lineno}: bone {head!r} appears twice in frame {frame_no}")
    return BVHError(
        f"line {lineno}: bone {head!r} has {len(tok) - 1} values, expected {ndof[head]} (frame {frame_no})"
    )


def _amc_frames(text: str, ndof: dict[str, int]) -> tuple[dict[str, list[str]], dict[str, list[int]], bool | None, int]:
    """Read the AMC lines: per bone its flat value tokens (row ``k`` of bone ``b`` is
    ``tokens[b][k*n:(k+1)*n]``: compact, converted by one numpy call per bone) and the line
    of each row; whether the header says degrees (None: it does not say); the frame count."""
    required = {b for b, n in ndof.items() if n > 0} | {"root"}
    tokens: dict[str, list[str]] = {b: [] for b in ndof}
    rows_line: dict[str, list[int]] = {b: [] for b in ndof}
    degrees: bool | None = None
    frame_no: int | None = None
    frame_line = n_frames = last = 0
    seen: set[str] = set()
    for lineno, tok in acclaim_lines(text):
        last = lineno
        head = tok[0]
        if head.startswith(":"):
            degrees = _amc_header(head, lineno, frame_no, degrees)
            continue
        if len(tok) == 1 and (head not in ndof or _UINT_RE.fullmatch(head)):
            k = _frame_number(head, lineno)
            if frame_no is not None:
                _check_frame(required, seen, lineno, frame_no, frame_line)
                if k != frame_no + 1:
                    raise BVHError(f"line {lineno}: frame number {k} follows frame {frame_no}")
            frame_no, frame_line = k, lineno
            n_frames += 1
            seen = set()
            continue
        if frame_no is None or head not in ndof or head in seen or len(tok) - 1 != ndof[head]:
            raise _bad_bone_line(tok, lineno, frame_no, ndof, seen)
        seen.add(head)
        if ndof[head]:
            tokens[head] += tok[1:]
            rows_line[head].append(lineno)
    if frame_no is None:
        raise BVHError(f"line {last + 1}: AMC file has no frames")
    _check_frame(required, seen, last + 1, frame_no, frame_line)
    return tokens, rows_line, degrees, n_frames


def _bone_values(b: str, flat: list[str], n: int, n_frames: int, rows_line: list[int]) -> np.ndarray:
    """The (F, n) values of bone ``b`` from its flat tokens; an error names the line of a bad one."""
    if not n:
        return np.zeros((n_frames, 0))
    if len(flat) != n_frames * n:  # pragma: no cover - guaranteed by _check_frame
        raise BVHError(f"bone {b!r} has {len(flat) // n} frames of values, expected {n_frames}")
    try:
        v = np.array(flat, dtype=float).reshape(n_frames, n)
        bad_row = None if np.all(np.isfinite(v)) else int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
    except ValueError:
        v, bad_row = None, None
    # float() accepts '1_0' and non-ASCII digits ('\u0663'); AMC files do not
    if v is None or (bad_row is None and not _plain_numbers(flat)):
        bad_row = next(i for i in range(n_frames) if not _plain_numbers(flat[i * n : (i + 1) * n], strict=True))
    if bad_row is not None:
        row = flat[bad_row * n : (bad_row + 1) * n]
        raise BVHError(
            f"line {rows_line[bad_row]}: bone {b!r} has a value that is not a finite number: {' '.join(row)[:80]!r}"
        )
    return v


def _amc_values(src, skel: AsfSkeleton) -> tuple[dict[str, np.ndarray], bool | None, str | None, int]:
    """Per bone (and "root"), the (F, n_dofs) AMC values; whether angles are degrees; the
    source name; the file's size in bytes."""
    text, source, nbytes = acclaim_text(src, MAX_AMC_BYTES)
    ndof = {"root": len(skel.root_order)}
    ndof.update({b: len(bone.dofs) for b, bone in skel.bones.items()})
    tokens, rows_line, degrees, n_frames = _amc_frames(text, ndof)
    values = {b: _bone_values(b, flat, ndof[b], n_frames, rows_line[b]) for b, flat in tokens.items()}
    return values, degrees, source, nbytes


def read_amc(src, skeleton: AsfSkeleton, *, frame_time: float = CMU_FRAME_TIME, unit_m: float | None = None) -> Motion:
    """Read an Acclaim AMC motion for ``skeleton`` into a :class:`~repro.motion.Motion`.

    Parameters
    ----------
    src : str, os.PathLike or file object
        A path (``.gz`` is decompressed) or a binary/text stream.
    skeleton : AsfSkeleton
        From :func:`read_asf`.
    frame_time : float, default 1/120
        Seconds per frame (AMC files do not store it; CMU captured at 120 Hz).
    unit_m : float, optional
        Metres per ASF unit, stored on the motion (CMU: :data:`~repro.motion.CMU_UNIT_M`).

    Returns
    -------
    Motion
        Same joints, offsets, channels and End Sites as the CMU BVH conversion
        (module docstring); its :meth:`~Motion.global_positions` match those of the
        staged BVH of the same take.

    Raises
    ------
    repro.errors.BVHError
        If the file is malformed (unknown bone, wrong number of values on a line,
        non-numeric or non-finite values, a bone twice in a frame, a frame lacking a
        bone that has dofs — e.g. a truncated last frame —, non-consecutive frame
        numbers, a frame number that is not plain ASCII digits, no frames); the
        message names the line.  A file cut exactly between two frames cannot be told
        from a shorter take.  Also a missing or unreadable file, a folder, a corrupt
        gzip stream, more than :data:`MAX_AMC_BYTES` of content, or a motion whose
        arrays (56 bytes per joint and frame) would exceed 64 times the file's size
        (at least 256 MiB are always allowed) -- checked before allocating them.
    """
    if not isinstance(skeleton, AsfSkeleton):
        raise BVHError(f"skeleton must be an AsfSkeleton (read_asf), got {describe(skeleton)}")
    frame_time = as_real(frame_time, "frame_time (s)", lo=0.0, lo_open=True, error=BVHError)
    if unit_m is not None:
        unit_m = as_real(unit_m, "unit_m (metres per file unit)", lo=0.0, lo_open=True, error=BVHError)
    values, degrees, source, nbytes = _amc_values(src, skeleton)
    if degrees is None:
        degrees = skeleton.angle_unit == "deg"
    names = skeleton.joint_names
    J = len(names)
    F = values["root"].shape[0]
    _check_motion_size(F, J, nbytes, source)
    axis_q = skeleton.axis_quaternions()  # C, (J, 4)
    offsets = skeleton.offsets()
    positions = np.broadcast_to(offsets, (F, J, 3)).copy()
    channels, groups = _joint_channels(skeleton, names, values, positions)
    ends = [(j, skeleton.bones[n].vector) for j, n in enumerate(names) if n != "root" and not skeleton.children.get(n)]
    return Motion(
        joint_names=names,
        parents=skeleton.parents,
        offsets=offsets,
        channels=channels,
        frame_time=frame_time,
        rotations=_local_rotations(groups, axis_q, F, J, degrees),
        positions=positions,
        end_site_parents=np.array([j for j, _ in ends], dtype=np.intp),
        end_site_offsets=np.array([o for _, o in ends], dtype=float).reshape(-1, 3),
        unit_m=unit_m,
        source=source,
    )


def _check_motion_size(F: int, J: int, nbytes: int, source: str | None) -> None:
    """Refuse, before allocating, a motion whose arrays would be far larger than its AMC file."""
    need = F * J * 7 * 8  # rotations (F, J, 4) and positions (F, J, 3)
    allowed = max(_MOTION_BYTES_FLOOR, _MOTION_BYTES_PER_AMC_BYTE * nbytes)
    if need > allowed:
        raise BVHError(
            f"{source or '<stream>'}: {F} frames x {J} joints would need {need / 2**20:.0f} MiB of motion "
            f"arrays, more than the {allowed / 2**20:.0f} MiB allowed for an AMC file of {nbytes} bytes "
            f"(a skeleton with many bones without dofs?)"
        )


def _root_channels(order: tuple[str, ...], v: np.ndarray, positions: np.ndarray):
    """The root's channels from its AMC ``order`` (its ``T*`` values written into ``positions``),
    its rotation dof sequence (e.g. ``"xyz"``) and its (F, n) rotation values."""
    pos_ch = []
    for k, d in enumerate(order):
        if d.startswith("T"):
            axis = "XYZ".index(d[1])
            positions[:, 0, axis] = v[:, k]
            pos_ch.append(f"{d[1]}position")
    rk = [k for k, d in enumerate(order) if d.startswith("R")]
    seq = "".join(order[k][1].lower() for k in rk)
    return tuple(pos_ch) + _ROTATION_CHANNELS, seq, v[:, rk]


def _joint_channels(skeleton: AsfSkeleton, names: list[str], values: dict[str, np.ndarray], positions: np.ndarray):
    """Each joint's BVH channels (the root's translation written into ``positions``) and the
    joints with rotation dofs grouped by dof sequence: ``{"xyz": [(joint, (F, 3) angles), ...]}``."""
    channels: list[tuple[str, ...]] = []
    groups: dict[str, list[tuple[int, np.ndarray]]] = {}
    for j, name in enumerate(names):
        if name == "root":
            chans, seq, ang = _root_channels(skeleton.root_order, values["root"], positions)
        else:
            chans, seq, ang = _ROTATION_CHANNELS, "".join(d[1] for d in skeleton.bones[name].dofs), values[name]
        channels.append(chans)
        if seq:  # no motion: C I C^-1 = I
            groups.setdefault(seq, []).append((j, ang))
    return channels, groups


def _local_rotations(groups: dict, axis_q: np.ndarray, F: int, J: int, degrees: bool) -> np.ndarray:
    """The (F, J, 4) local rotations ``C M C^-1`` (identity for joints without dofs), ``M``
    from the grouped angles: one vectorised product per dof sequence."""
    conj = np.array([-1.0, -1.0, -1.0, 1.0])
    rotations = np.zeros((F, J, 4))
    rotations[..., 3] = 1.0
    for seq, members in groups.items():
        js = np.array([j for j, _ in members], dtype=np.intp)
        m = euler_to_quat(seq, np.stack([a for _, a in members], axis=1), degrees=degrees)  # (F, G, 4)
        c = axis_q[js]
        rotations[:, js] = quat_multiply(quat_multiply(c, m), c * conj)
    return rotations


def read_asf_amc(asf, amc, *, frame_time: float = CMU_FRAME_TIME, unit_m: float | None = None) -> Motion:
    """Read an ASF skeleton and an AMC motion into a :class:`~repro.motion.Motion`.

    ``read_asf_amc(asf, amc)`` is ``read_amc(amc, read_asf(asf))``; both arguments take
    paths (``.gz`` decompressed) or streams such as
    ``repro.data.open_file("mocap/cmu/source/135_04.amc")``.  See :func:`read_amc`.
    """
    return read_amc(amc, read_asf(asf), frame_time=frame_time, unit_m=unit_m)
