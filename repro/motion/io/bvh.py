"""Reading and writing BVH (Biovision Hierarchy) motion-capture files.

The BVH format (Biovision; described in M. Meredith and S. Maddock, "Motion Capture
File Formats Explained", University of Sheffield, 2001) is the storage format of the
motion database of Pronost et al., "Interactive Animation of Virtual Characters:
Application to Virtual Kung-fu Fighting", Section 3.2.1.  A file has two parts::

    HIERARCHY
    ROOT Hips
    {
        OFFSET 0 0 0
        CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
        JOINT Spine
        {
            OFFSET 0 5.2 0
            CHANNELS 3 Zrotation Yrotation Xrotation
            End Site
            {
                OFFSET 0 4.1 0
            }
        }
    }
    MOTION
    Frames: 2
    Frame Time: 0.0083333
    <one line of channel values per frame, joints in hierarchy order>

Conventions implemented here (and checked against the independent reader ``bvhio``
in the tests):

* rotation channels are Euler angles in degrees, applied in the listed order as
  *intrinsic* rotations: ``Zrotation Xrotation Yrotation`` is ``R = Rz Rx Ry``, i.e.
  ``scipy.spatial.transform.Rotation.from_euler("ZXY", ...)`` (uppercase = intrinsic;
  computed by :func:`repro.motion.core.quaternion.euler_to_quat`, equal to scipy's to 1e-12 and
  about 20 times faster here);
* position channels *replace* the matching components of the joint's OFFSET (for the
  CMU root the offset is zero; the Bandai Namco, mocopi and Blender files give every joint
  position channels equal to its offset), except in files written the other way: MakeHuman's
  exporter writes, below the root, the displacement from the OFFSET (zeros in the rest pose).
  A file whose position channels below the root stay near zero while their OFFSETs do not
  (:data:`DISPLACEMENT_RATIO`) is read that way: channel added to OFFSET.  Read as a
  replacement, such a file's skeleton collapses into a point;
* End Sites are kept (parent joint and offset) so that :func:`write_bvh` writes them back.

The HIERARCHY section is read by :mod:`repro.motion.io.bvh_hierarchy`.  The frame block
is checked with numpy (values per line, number of lines) and then parsed, both in
chunks of a few MB, so that memory stays proportional to the file and nothing is
allocated for frames the file does not hold; every malformed input raises
:class:`repro.errors.BVHError` naming the line or the field (or the joint and frame,
for lengths so large that world positions overflow).  Text after the declared frames
(some Second Life / QAvimator exporters append keyframe lists) is ignored with a
:class:`repro.errors.BVHWarning`, or rejected with ``strict=True``.  Reading, writing
and forward kinematics take time linear in the number of joints and never recurse,
however deep the hierarchy.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import warnings
from pathlib import Path

import numpy as np

from repro.checks import as_bool, as_int, as_real, describe
from repro.errors import BVHError, BVHWarning
from repro.io import atomic_path, read_bytes
from repro.motion.core.channels import POSITION_CHANNELS, joint_columns
from repro.motion.core.kinematics import children_of
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import euler_to_quat, slerp
from repro.motion.io.bvh_hierarchy import Hierarchy, parse_hierarchy
from repro.motion.io.tokens import INTEGER

__all__ = ["read_bvh", "write_bvh", "MAX_FRAMES"]

#: Largest frame count accepted (10 million frames: a day of 120 Hz capture is 10.4 M).
MAX_FRAMES = 10_000_000

#: Joint-frames (frames x joints) a file may always ask for, whatever its size:
#: 4 Mi joint-frames is about 235 MB of pose arrays.  Above it, a file must hold at
#: least one byte of frame data per joint-frame (real files hold 24 to 60).
_POSE_FLOOR = 1 << 22
#: Bytes of the frame block handled at a time (bounds the temporary arrays).
_CHUNK = 1 << 22
#: a frame line short or long by at most this fraction of the channels (at least one value) is repaired
REPAIR_SLACK = 0.1
#: at most this fraction of a file's frames are repaired; more such lines are an error
REPAIR_FRACTION = 0.01
#: Writers indent at most this many levels (deeper joints keep this indentation),
#: so that the text of a deep chain grows linearly with its depth.
_MAX_INDENT = 32

_MOTION_RE = re.compile(rb"^[ \t]*MOTION[ \t]*\r?$", re.M)
_FRAMES_RE = re.compile(r"^Frames\s*:\s*(\S+)$")
_FRAME_TIME_RE = re.compile(r"^Frame\s+Time\s*:\s*(\S+)$")
_TOKEN_RE = re.compile(rb"[^ \t\n\r\x0b\x0c]+")  # the tokens of bytes.split()
_NOT_SPACE = np.ones(256, dtype=bool)
_NOT_SPACE[[9, 10, 11, 12, 13, 32]] = False  # the ASCII whitespace bytes.split() splits on


# ------------------------------------------------------ input: the frame block
def _next_line(data: bytes, pos: int) -> tuple[str, int, int]:
    """Next non-empty line from ``pos``: (stripped text, lines consumed, new pos)."""
    consumed = 0
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        line = data[pos:end].strip()
        consumed += 1
        pos = end + 1
        if line:
            try:
                return line.decode("ascii"), consumed, pos
            except UnicodeDecodeError:
                return line.decode("latin-1"), consumed, pos
    return "", consumed, pos


def _chunks(data: bytes, start: int, stop: int):
    """``(begin, end)`` byte ranges of about :data:`_CHUNK` covering ``data[start:stop]``, each cut after a newline."""
    while start < stop:
        end = min(start + _CHUNK, stop)
        if end < stop:
            nl = data.rfind(b"\n", start, end)
            if nl < 0:  # a line longer than a chunk: take it whole
                nl = data.find(b"\n", end, stop)
                end = stop if nl < 0 else nl + 1
            else:
                end = nl + 1
        yield start, end
        start = end


def _line_counts(data: bytes, begin: int, end: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lines of ``data[begin:end]`` that hold tokens: (their index in the chunk, token counts, newline offsets)."""
    b = np.frombuffer(data, dtype=np.uint8, count=end - begin, offset=begin)
    nonws = _NOT_SPACE[b]
    starts = np.flatnonzero(nonws[1:] & ~nonws[:-1]) + 1
    if nonws[:1].any():
        starts = np.concatenate(([0], starts))
    newlines = np.flatnonzero(b == 10)
    tok_line = np.searchsorted(newlines, starts)  # newlines before each token = its line
    if not tok_line.size:
        return tok_line, tok_line, newlines
    brk = np.flatnonzero(tok_line[1:] != tok_line[:-1]) + 1  # sorted: run lengths, no np.unique sort
    edges = np.concatenate(([0], brk, [tok_line.size]))
    return tok_line[edges[:-1]], np.diff(edges), newlines


def _is_frame(line: bytes, n_channels: int) -> bool:
    """Whether ``line`` holds exactly ``n_channels`` finite numbers, i.e. looks like one more frame."""
    tokens = line.split()
    if len(tokens) != n_channels or b"_" in line:
        return False
    try:
        return bool(np.isfinite(np.array(tokens, dtype=np.float64)).all())
    except ValueError:
        return False


def _scan_frames(data: bytes, start: int, first: int, n_frames: int, n_channels: int, strict: bool):
    """Check the frame lines after ``Frame Time`` (token counts only, in bounded memory).

    With channels a frame is a non-empty line (blank lines are skipped); without any
    channel every line is a frame (an empty one), so the file must hold ``n_frames``
    lines.  ``first`` is the number of the line starting at ``start``.  Returns the byte
    offset where the declared frames end, and the non-empty content after them as
    ``(line number, number of lines, first line)`` or None.
    """
    stop = len(data)
    if n_channels == 0:
        n_lines = data.count(b"\n", start) + (1 if stop > start and not data.endswith(b"\n") else 0)
        if n_frames > n_lines:
            raise BVHError(
                f"line {first + n_lines}: 'Frames: {n_frames}' declared but {n_lines} frame lines present "
                "(no joint has channels, so each frame is an empty line; truncated file?)"
            )
    k = 0  # frames found so far (with channels)
    line_base = 0  # lines before the current chunk
    frames_end = start
    trail: tuple[int, bytes] | None = None  # first non-empty line after the frames
    n_trail = 0
    run, run_open = 0, True  # frame-like lines right after the declared frames
    repaired: list[tuple[int, int, int, int, int]] = []  # frame lines to repair (see _keep_repairable)
    for begin, end in _chunks(data, start, stop):
        lines, counts, newlines = _line_counts(data, begin, end)
        if n_channels:
            take = min(lines.size, n_frames - k)
            frame_no = k + 1 + np.arange(lines.size)
        else:  # lines whose index is below n_frames are frames
            take = int(np.searchsorted(lines, n_frames - line_base))
            frame_no = line_base + lines + 1
        for i in np.flatnonzero(counts[: lines.size if strict else take] != n_channels):
            bad = (int(frame_no[i]) - 1, first + line_base + int(lines[i]), int(counts[i]),
                   *_line_span(data, begin, end, newlines, int(lines[i])))
            _keep_repairable(repaired, bad, n_frames, n_channels, strict)
        if n_channels and take and k + take == n_frames:
            last = int(lines[take - 1])
            frames_end = begin + (int(newlines[last]) + 1 if last < newlines.size else end - begin)
        if lines.size > take:
            if trail is None:
                i = int(lines[take])
                lb, le = _line_span(data, begin, end, newlines, i)
                trail = (first + line_base + i, data[lb:le].strip())
            if run_open:
                other = np.flatnonzero(counts[take:] != n_channels)
                run += int(other[0]) if other.size else lines.size - take
                run_open = not other.size
            n_trail += lines.size - take
        k += take
        line_base += newlines.size
    if n_channels and k < n_frames:
        raise BVHError(
            f"line {first + line_base}: 'Frames: {n_frames}' declared but {k} frame lines present (truncated file?)"
        )
    if trail is not None and n_channels and (strict or _is_frame(trail[1], n_channels)):
        # one more frame than declared: the count is wrong, this is not an appendix
        present = n_frames + (n_trail if strict else run)
        raise BVHError(f"line {trail[0]}: 'Frames: {n_frames}' declared but {present} frame lines present")
    return frames_end, (None if trail is None else (trail[0], n_trail, trail[1])), repaired


def _line_span(data: bytes, begin: int, end: int, newlines: np.ndarray, i: int) -> tuple[int, int]:
    """Byte range of line ``i`` of the chunk ``data[begin:end]`` (its newline excluded)."""
    return (begin + (int(newlines[i - 1]) + 1 if i > 0 else 0),
            begin + (int(newlines[i]) if i < newlines.size else end - begin))


def _keep_repairable(repaired: list, bad: tuple, n_frames: int, n_channels: int, strict: bool) -> None:
    """Add ``bad`` = (frame index, line number, values, byte range) to ``repaired``, or raise its BVHError.

    A frame line with the wrong number of values is repaired (by :func:`_interpolate_frames`) only
    when reading leniently, when it is short or long by at most :data:`REPAIR_SLACK` of the channels
    (a value lost or doubled by an exporter, as in files whose lines hold 65 of 66 values), and when
    such lines are at most :data:`REPAIR_FRACTION` of the frames; else it is an error, as is every
    such line with ``strict=True``.
    """
    frame, line, count, _, _ = bad
    error = BVHError(f"line {line}: frame {frame + 1} has {count} values, expected {n_channels} "
                     "(channel count mismatch or truncated line)")
    if strict or not n_channels or abs(count - n_channels) > max(1, int(REPAIR_SLACK * n_channels)):
        raise error
    repaired.append(bad)
    limit = int(REPAIR_FRACTION * n_frames)
    if len(repaired) > limit:
        first = repaired[0]
        raise BVHError(
            f"line {first[1]}: frame {first[0] + 1} has {first[2]} values, expected {n_channels} (channel count "
            f"mismatch or truncated line); {len(repaired)} frame lines have the wrong number of values, more than "
            f"the {limit} a read repairs ({REPAIR_FRACTION:.0%} of {n_frames} frames)"
        )


def _bad_value(chunk: bytes, tokens: list[bytes], t0: int, line0: int, n_channels: int) -> BVHError:
    """The error for the first non-numeric or non-finite token of a chunk of frame lines."""
    for t, tok in enumerate(tokens):
        try:
            finite = bool(np.isfinite(float(tok))) and b"_" not in tok
            what = "not finite"
        except ValueError:
            finite, what = False, "not a number"
        if not finite:
            break
    else:  # pragma: no cover - only called when some token is bad
        return BVHError(f"line {line0}: bad frame values")
    pos = next(m for i, m in enumerate(_TOKEN_RE.finditer(chunk)) if i == t).start()
    g = t0 + t
    line = line0 + chunk.count(b"\n", 0, pos)
    return BVHError(
        f"line {line}: value {tok[:40].decode('latin-1')!r} is {what} "
        f"(channel {g % n_channels + 1} of frame {g // n_channels + 1})"
    )


def _parse_values(data: bytes, start: int, stop: int, first: int, n_frames: int, n_channels: int,
                  repaired=()) -> np.ndarray:
    """The (F, C) table of the frame lines in ``data[start:stop]`` (already checked by :func:`_scan_frames`).

    The lines of ``repaired`` (:func:`_keep_repairable`) are read as zeros, to be interpolated.
    """
    values = np.empty((n_frames, n_channels))
    flat = values.reshape(-1)
    t0 = line0 = 0
    zeros = b" ".join([b"0"] * n_channels)
    for begin, end in _chunks(data, start, stop):
        chunk = data[begin:end]
        for _, _, _, lb, le in reversed([r for r in repaired if begin <= r[3] < end]):
            chunk = chunk[: lb - begin] + zeros + chunk[le - begin :]
        tokens = chunk.split()
        if t0 + len(tokens) > flat.size:  # pragma: no cover - _scan_frames counted them
            raise BVHError(f"line {first + line0}: more frame values than declared")
        try:
            arr = np.array(tokens, dtype=np.float64)
            ok = b"_" not in chunk and bool(np.isfinite(arr).all())
        except ValueError:
            ok = False
        if not ok:
            raise _bad_value(chunk, tokens, t0, first + line0, n_channels)
        flat[t0 : t0 + arr.size] = arr
        t0 += arr.size
        line0 += chunk.count(b"\n")
    if t0 != flat.size:  # pragma: no cover - _scan_frames counted them
        raise BVHError(f"line {first + line0}: fewer frame values than declared")
    return values


def _header_line(data: bytes, pos: int, lineno: int, pattern, missing: str, expected: str):
    """The next line matched by ``pattern`` (a MOTION header): (match, position after it, its line number)."""
    line, k, pos = _next_line(data, pos)
    lineno += k
    if not line:
        raise BVHError(f"line {lineno}: missing {missing} (truncated file?)")
    m = pattern.match(line)
    if m is None:
        raise BVHError(f"line {lineno}: expected {expected}, got {line[:80]!r}")
    return m, pos, lineno


def _parse_motion_block(data: bytes, pos: int, lineno: int, n_channels: int, n_joints: int = 1, strict: bool = False):
    """Parse ``Frames:``, ``Frame Time:`` and the frame lines after MOTION.

    ``lineno`` is the number of the MOTION line.  Returns (values (F, C), frame time,
    line number of the first frame line, trailing content or None, the repaired frame lines as
    ``(frame index, line number, values found)``).
    """
    m, pos, lineno = _header_line(data, pos, lineno, _FRAMES_RE, "'Frames:' after MOTION", "'Frames: <count>'")
    count = m.group(1)
    if not INTEGER.fullmatch(count):
        raise BVHError(f"line {lineno}: frame count {count[:40]!r} is not an integer")
    digits = count.lstrip("+-").lstrip("0")
    if len(digits) > 18:  # no int() of thousands of digits (Python refuses over 4300)
        raise BVHError(f"line {lineno}: frame count {count[:40]}{'...' if len(count) > 40 else ''} is out of range 0..{MAX_FRAMES}")
    n_frames = int(digits or "0") * (-1 if count.startswith("-") else 1)
    if n_frames < 0 or n_frames > MAX_FRAMES:
        raise BVHError(f"line {lineno}: frame count {n_frames} is out of range 0..{MAX_FRAMES}")
    frames_line = lineno
    m, pos, lineno = _header_line(data, pos, lineno, _FRAME_TIME_RE, "'Frame Time:'", "'Frame Time: <seconds>'")
    try:
        frame_time = float(m.group(1))
    except ValueError:
        raise BVHError(f"line {lineno}: frame time {m.group(1)[:40]!r} is not a number") from None
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise BVHError(f"line {lineno}: frame time must be finite and > 0, got {m.group(1)[:40]!r}")
    with np.errstate(over="ignore", divide="ignore"):
        if not (np.isfinite(1.0 / frame_time) and np.isfinite(frame_time * max(n_frames, 1))):
            raise BVHError(
                f"line {lineno}: frame time {m.group(1)[:40]} s gives an infinite frame rate or duration "
                "(expected a positive frame time with a finite 1 / frame time)"
            )
    first = lineno + 1  # number of the line starting at ``pos``
    pos = min(pos, len(data))
    frames_end, trailing, repaired = _scan_frames(data, pos, first, n_frames, n_channels, strict)
    # bound the pose arrays (F x J quaternions and translations) by what the file holds
    size = len(data) - pos
    if n_frames * n_joints > max(_POSE_FLOOR, size):
        raise BVHError(
            f"line {frames_line}: {n_frames} frames of {n_joints} joints would need {n_frames * n_joints} joint "
            f"poses ({n_frames * n_joints * 56 / 2**30:.2g} GiB), more than {size} bytes of frame data can "
            f"describe (limit: {_POSE_FLOOR}, or one joint pose per byte of frame data); the frame or joint "
            "count is wrong"
        )
    if n_channels:
        values = _parse_values(data, pos, frames_end, first, n_frames, n_channels, repaired)
    else:
        values = np.zeros((n_frames, 0))
    return values, frame_time, first, trailing, [(f, line, count) for f, line, count, _, _ in repaired]


def read_bvh(src, *, unit_m: float | None = None, strict: bool = False) -> Motion:
    """Read a BVH file into a :class:`~repro.motion.Motion`.

    Parameters
    ----------
    src : str, os.PathLike or file object
        A path (``.gz`` files are decompressed) or a binary/text stream, e.g.
        ``repro.data.open_file("mocap/cmu/135_04.bvh")``.
    unit_m : float, optional
        Metres per length unit of the file, stored on the motion for
        :meth:`Motion.to_metres` (e.g. :data:`~repro.motion.CMU_UNIT_M` for the CMU
        files, :data:`~repro.motion.BANDAI_UNIT_M` for Bandai Namco's).
    strict : bool, default False
        Some exporters (Second Life / QAvimator tools) append text after the declared
        frames (keyframe lists, a readme line).  By default it is ignored with a
        :class:`~repro.errors.BVHWarning` saying how many lines were skipped; with
        ``strict=True`` it is an error.  In both modes a line after the declared frames
        that holds one more complete frame is an error (the frame count is wrong).

    Returns
    -------
    Motion
        Joints in file order (End Sites kept separately), local rotations as
        quaternions, position-channel values, frame time.

    Raises
    ------
    repro.errors.BVHError
        If the file cannot be read (missing, a folder, corrupt gzip: the message names
        the path) or is malformed: the message names the line (truncation, unbalanced
        braces, a joint without OFFSET or CHANNELS, unknown channel names, duplicate
        joint names, an empty hierarchy, a frame line with the wrong number of values,
        non-numeric or non-finite values, a frame count that is negative, above
        :data:`MAX_FRAMES`, different from the number of frame lines or larger than
        the file can hold, a frame time that is not finite and positive or whose frame
        rate is infinite) or the joint and frame (offsets and positions so large that
        world positions overflow).
    """
    strict = as_bool(strict, "strict", error=BVHError)
    if unit_m is not None:
        unit_m = as_real(unit_m, "unit_m (metres per file unit)", lo=0.0, lo_open=True, error=BVHError)
    data, name = read_bytes(src, error=BVHError)
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    m = _MOTION_RE.search(data)
    header_bytes = data[: m.start()] if m else data
    try:
        header = header_bytes.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = header_bytes[: exc.start].count(b"\n") + 1
        raise BVHError(f"line {line}: the hierarchy is not valid UTF-8 text") from None
    h = parse_hierarchy(header, motion_found=m is not None)
    n_channels = sum(len(c) for c in h.channels)
    motion_line = header_bytes.count(b"\n") + 1
    values, frame_time, _, trailing, repaired = _parse_motion_block(
        data, m.end() + 1, motion_line, n_channels, len(h.names), strict
    )
    motion = _motion_from_table(h, values, frame_time, unit_m=unit_m, source=name,
                                repaired=[f for f, _, _ in repaired])
    if repaired:
        lines = ", ".join(f"line {line} ({count} values)" for _, line, count in repaired[:5])
        warnings.warn(
            f"{name or '<stream>'}: repaired {len(repaired)} frame line{'s' if len(repaired) != 1 else ''} with "
            f"the wrong number of values ({lines}{', ...' if len(repaired) > 5 else ''}; expected {n_channels}): "
            "each such frame is interpolated from its neighbouring frames; pass strict=True to make this an error",
            BVHWarning,
            stacklevel=2,
        )
    if trailing is not None:
        line, n, text = trailing
        warnings.warn(
            f"{name or '<stream>'}: ignored {n} line{'s' if n != 1 else ''} of text after the "
            f"{values.shape[0]} declared frames, from line {line} "
            f"({text[:60].decode('latin-1')!r}); pass strict=True to make this an error",
            BVHWarning,
            stacklevel=2,
        )
    return motion


#: Position channels below the root are displacements from the joints' OFFSETs (not replacements) when the
#: sum over them of ``|median over frames of the channel|`` is below this fraction of the sum of
#: ``|median - OFFSET|``.  Measured on the data here: 1.2e-5 for MakeHuman's default rig; for the files that
#: replace, 12.7 (a Bandai Namco punch, whose translations move about their OFFSETs) to infinite (mocopi, whose
#: channels equal them): the two conventions are far apart.
DISPLACEMENT_RATIO = 0.05


def _displacements(offsets: np.ndarray, parents, values: np.ndarray, pos_j, pos_axis, pos_col) -> np.ndarray:
    """Which position channels (a bool per channel) are read as displacements from their joint's OFFSET:
    those below the root, in a file whose channels below the root stay near zero while their OFFSETs do not."""
    below = np.array([parents[j] >= 0 for j in pos_j], dtype=bool)
    out = np.zeros(len(pos_j), dtype=bool)
    if not below.any() or values.shape[0] == 0:
        return out
    v = np.median(values[:, np.asarray(pos_col)[below]], axis=0)
    o = offsets[np.asarray(pos_j)[below], np.asarray(pos_axis)[below]]
    with np.errstate(over="ignore"):  # lengths near the float limit: an infinite sum still compares
        to_zero, to_offset = float(np.abs(v).sum()), float(np.abs(v - o).sum())
    if to_zero < DISPLACEMENT_RATIO * to_offset:
        out[below] = True
    return out


def _motion_from_table(h: Hierarchy, values: np.ndarray, frame_time: float, *, unit_m, source,
                       repaired=()) -> Motion:
    F = values.shape[0]
    J = len(h.names)
    offsets = np.array(h.offsets, dtype=float).reshape(J, 3)
    rotations = np.zeros((F, J, 4))
    rotations[..., 3] = 1.0
    positions = np.broadcast_to(offsets, (F, J, 3)).copy()
    pos_j, pos_axis, pos_col = [], [], []
    groups: dict[str, tuple[list[int], list[list[int]]]] = {}
    col = 0
    for j, chans in enumerate(h.channels):
        seq, cols = "", []
        for c in chans:
            if c in POSITION_CHANNELS:
                pos_j.append(j)
                pos_axis.append(POSITION_CHANNELS.index(c))
                pos_col.append(col)
            else:
                seq += c[0]
                cols.append(col)
            col += 1
        if seq:
            g = groups.setdefault(seq, ([], []))
            g[0].append(j)
            g[1].append(cols)
    if pos_j:
        positions[:, pos_j, pos_axis] = values[:, pos_col]
        add = _displacements(offsets, h.parents, values, pos_j, pos_axis, pos_col)
        if add.any():  # MakeHuman's convention: the channel is the displacement from the OFFSET
            jj, aa = np.asarray(pos_j)[add], np.asarray(pos_axis)[add]
            positions[:, jj, aa] += offsets[jj, aa]
    for seq, (joints, cols) in groups.items():
        angles = values[:, np.array(cols)]  # (F, Jg, k)
        if F:
            rotations[:, joints] = euler_to_quat(seq, angles, degrees=True)
    if len(repaired):
        _interpolate_frames(rotations, positions, np.asarray(repaired, dtype=np.intp))
    return Motion(
        joint_names=h.names,
        parents=np.array(h.parents, dtype=np.intp),
        offsets=offsets,
        channels=h.channels,
        frame_time=frame_time,
        rotations=rotations,
        positions=positions,
        end_site_parents=np.array(h.end_parents, dtype=np.intp),
        end_site_offsets=np.array(h.end_offsets, dtype=float).reshape(-1, 3),
        unit_m=unit_m,
        source=source,
    )


def _interpolate_frames(rotations: np.ndarray, positions: np.ndarray, bad: np.ndarray) -> None:
    """Replace frames ``bad`` (sorted) in place by their neighbours: rotations slerped, positions
    interpolated linearly between the nearest good frames before and after (copied at either end)."""
    good = np.setdiff1d(np.arange(rotations.shape[0]), bad)
    k = np.searchsorted(good, bad)
    before, after = good[np.maximum(k - 1, 0)], good[np.minimum(k, good.size - 1)]
    span = after - before
    a = np.where(span > 0, (bad - before) / np.where(span > 0, span, 1), 0.0)
    rotations[bad] = slerp(rotations[before], rotations[after], a[:, None, None])
    positions[bad] = positions[before] + a[:, None, None] * (positions[after] - positions[before])


# ---------------------------------------------------------------------- output
def _dfs_order(parents: np.ndarray) -> tuple[list[int], list[list[int]]]:
    children = children_of(parents)
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children[j]))
    return order, children


def _format_bvh(motion: Motion, precision: int) -> str:
    fmt = f"%.{precision}g"
    for name in motion.joint_names:
        if not name.strip() or any(ch in name for ch in "{}\r\n") or name != " ".join(name.split()):
            raise BVHError(f"joint name {name!r} cannot be written to BVH")
    order, children = _dfs_order(motion.parents)
    ends: list[list[int]] = [[] for _ in motion.joint_names]
    for e, p in enumerate(motion.end_site_parents):
        ends[p].append(e)
    blocks = joint_columns(motion)

    out: list[str] = ["HIERARCHY"]

    def vec(v) -> str:
        return " ".join(fmt % x for x in v)

    # iterative depth-first walk (no recursion limit for deep chains); ``~j`` closes joint j
    stack: list[tuple[int, int]] = [(0, 0)]
    while stack:
        j, depth = stack.pop()
        ind = "\t" * min(depth, _MAX_INDENT)  # capped: the text stays linear in the depth
        if j >= 0:
            out.append(f"{ind}{'ROOT' if depth == 0 else 'JOINT'} {motion.joint_names[j]}")
            out.append(f"{ind}{{")
            out.append(f"{ind}\tOFFSET {vec(motion.offsets[j])}")
            chans = motion.channels[j]
            out.append(f"{ind}\tCHANNELS {len(chans)}" + "".join(" " + c for c in chans))
            stack.append((~j, depth))
            stack.extend((c, depth + 1) for c in reversed(children[j]))
        else:
            j = ~j
            for e in ends[j]:
                out.append(f"{ind}\tEnd Site")
                out.append(f"{ind}\t{{")
                out.append(f"{ind}\t\tOFFSET {vec(motion.end_site_offsets[e])}")
                out.append(f"{ind}\t}}")
            out.append(f"{ind}}}")
    out.append("MOTION")
    out.append(f"Frames: {motion.n_frames}")
    out.append(f"Frame Time: {fmt % motion.frame_time}")
    table = np.concatenate([blocks[j] for j in order], axis=1)
    row = " ".join([fmt] * table.shape[1])
    out.extend(row % tuple(r) for r in table.tolist())
    return "\n".join(out) + "\n"


def write_bvh(motion: Motion, path, *, overwrite: bool = False, precision: int = 12) -> Path:
    """Write ``motion`` to a BVH file, atomically.

    The text is built completely first, written to a temporary file in the target's
    folder and moved into place (``os.replace``), so a reader never sees a partial file
    and a failure leaves any existing file untouched.

    Parameters
    ----------
    motion : Motion
        The motion; joints are written in depth-first order (children in index order),
        End Sites after a joint's child joints.  Euler angles are recovered from the
        quaternions in each joint's declared channel order (see
        :meth:`Motion.channel_values`).
    path : str or os.PathLike
        Target file (missing parent folders are created).
    overwrite : bool, default False
        **Existing files are never replaced unless this is True** — that includes the
        file the motion was read from (``motion.source``).  Without it, an existing
        target raises :class:`FileExistsError` (checked atomically: the new file is
        hard-linked into place, which fails if the name appeared meanwhile).
    precision : int, default 12
        Significant digits (``%.{precision}g``); 12 keeps a read-write-read round trip
        within about 1e-9 relative, far below the 1e-6 the tests require.

    Returns
    -------
    pathlib.Path
        The written path.

    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is False.
    repro.errors.BVHError
        If the motion cannot be expressed in BVH (a joint name with braces or line
        breaks, a rotation that a joint with fewer than three rotation channels cannot
        express).
    """
    if not isinstance(motion, Motion):
        raise BVHError(f"motion must be a repro.motion.Motion, got {describe(motion)}")
    precision = as_int(precision, "precision (significant digits)", 6, 17, error=BVHError)
    overwrite = as_bool(overwrite, "overwrite", error=BVHError)
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)) or not os.fspath(path) \
            or "\x00" in os.fspath(path):
        raise BVHError(f"path must be a file path (a non-empty str or os.PathLike), got {describe(path)}")
    path = Path(path)
    text = _format_bvh(motion, precision)  # errors surface before the disk is touched
    if path.exists() and not path.is_file():  # a folder, a device, a FIFO: never a BVH target
        raise BVHError(f"{path} exists and is not a regular file; refusing to write a BVH there")
    if not overwrite and path.exists():
        raise FileExistsError(
            errno.EEXIST,
            "target exists; pass overwrite=True to replace it"
            + (" (it is the file this motion was read from)" if motion.source and _same(path, motion.source) else ""),
            str(path),
        )
    mode = stat.S_IMODE(path.stat().st_mode) if path.exists() else 0o644
    try:
        with atomic_path(path, mode=mode, replace=overwrite) as tmp:
            with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
    except FileExistsError as exc:
        if exc.strerror == "target exists":
            raise
        raise FileExistsError(
            errno.EEXIST, "target appeared while writing; pass overwrite=True to replace it", str(path)
        ) from None
    except OSError as exc:  # an unwritable folder, a parent that is a file, a full disk
        raise BVHError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def _same(a: Path, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False
