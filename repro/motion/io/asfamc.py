"""Reading Acclaim ASF/AMC motion capture (the originals of the CMU database).

The Acclaim format (Acclaim Entertainment; described in M. Meredith and S. Maddock,
"Motion Capture File Formats Explained", University of Sheffield, 2001, and used by the
CMU Graphics Lab Motion Capture Database, http://mocap.cs.cmu.edu) splits a take into an
ASF skeleton (bones with a global ``direction``, a ``length``, a local frame ``axis`` and
the ``dof`` the motion drives) and an AMC motion (per frame, one line of dof values per
bone).  The CMU BVH files used for the database of Pronost et al. (Section 3.2) were
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
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from repro.checks import as_real, describe
from repro.errors import BVHError
from repro.io import read_bytes
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import euler_to_quat, quat_multiply
from repro.motion.io.tokens import finite_float

__all__ = [
    "AsfBone",
    "AsfSkeleton",
    "read_asf",
    "read_amc",
    "read_asf_amc",
    "CMU_FRAME_TIME",
    "MAX_ASF_BYTES",
    "MAX_AMC_BYTES",
]

#: CMU captures at 120 Hz; AMC files carry no frame rate.
CMU_FRAME_TIME: float = 1.0 / 120.0

_ROTATION_DOFS = ("rx", "ry", "rz")
_ROOT_DOFS = ("TX", "TY", "TZ", "RX", "RY", "RZ")

#: Most bytes (after gzip is undone) an ASF file may hold: 64 MiB, some 400,000 bones.
MAX_ASF_BYTES = 64 << 20
#: Most bytes (after gzip is undone) an AMC file may hold: 1 GiB (CMU takes are 1-40 MB).
MAX_AMC_BYTES = 1 << 30
#: The arrays of the motion (rotations and positions, 56 bytes per joint and frame) may
#: take at most this many times the AMC file's bytes, or 256 MiB if that is more.  Only
#: joints without dofs, which take no AMC text, can make a motion much larger than its file.
_MOTION_BYTES_PER_AMC_BYTE = 64
_MOTION_BYTES_FLOOR = 256 << 20

#: A plain ASCII integer (Python's int() also takes '1_0', ' 7', Arabic-Indic digits ...).
_INT_RE = re.compile(r"[+-]?[0-9]{1,18}")
_UINT_RE = re.compile(r"[0-9]{1,18}")


@dataclass(frozen=True, eq=False)
class AsfBone:
    """One ``:bonedata`` entry of an ASF file.

    Attributes
    ----------
    name : str
    id : int or None
    direction : (3,) array
        Direction of the bone in world coordinates at rest.
    length : float
        Bone length, ASF units.
    axis : (3,) array
        Angles of the bone's local frame, in degrees (radians if ``:units angle rad``).
    axis_order : str
        Order of the ``axis`` rotations, e.g. ``"XYZ"`` (applied X first).
    dofs : tuple of str
        Rotational degrees of freedom driven by the AMC file, in order (``"rx"`` ...).
    limits : tuple of (float, float)
        Joint limits per dof (informational).
    line : int
        Line of the bone's ``begin``.
    """

    name: str
    id: int | None
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str
    dofs: tuple[str, ...]
    limits: tuple[tuple[float, float], ...]
    line: int

    @property
    def vector(self) -> np.ndarray:
        """``direction * length``: the bone in world coordinates at rest."""
        return self.direction * self.length


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An Acclaim ASF skeleton.

    Attributes
    ----------
    name : str
        The ``:name`` field ("" if absent).
    length_unit : float
        The ``:units length`` factor (CMU: 0.45, meaning lengths are inches x 0.45).
    angle_unit : str
        ``"deg"`` or ``"rad"`` (``:units angle``).
    root_order : tuple of str
        Order of the root's values on each AMC ``root`` line (``("TX", ..., "RZ")``).
    root_axis : str
        Order of the root rotations (``"XYZ"``).
    root_position, root_orientation : (3,) arrays
        Rest translation and orientation of the root.
    bones : dict of str to AsfBone
        The bones, in file order.
    children : dict of str to list of str
        The ``:hierarchy`` section: children of ``"root"`` and of each bone.
    """

    name: str
    length_unit: float
    angle_unit: str
    root_order: tuple[str, ...]
    root_axis: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    bones: dict[str, AsfBone]
    children: dict[str, list[str]]

    @property
    def joint_names(self) -> list[str]:
        """``"root"`` then the bones in depth-first order (the Motion's joint order)."""
        order, stack = [], ["root"]
        while stack:
            b = stack.pop()
            order.append(b)
            stack.extend(reversed(self.children.get(b, [])))
        return order

    @property
    def parents(self) -> np.ndarray:
        """Parent index of each joint of :attr:`joint_names` (-1 for the root)."""
        names = self.joint_names
        index = {n: i for i, n in enumerate(names)}
        par = np.full(len(names), -1, dtype=np.intp)
        for p, kids in self.children.items():
            for k in kids:
                par[index[k]] = index[p]
        return par

    def _angles_to_quat(self, order: str, angles) -> np.ndarray:
        return euler_to_quat(order.lower(), angles, degrees=self.angle_unit == "deg")

    def axis_quaternions(self) -> np.ndarray:
        """(J, 4) quaternions of the local frames ``C`` (root: its ``orientation``)."""
        names = self.joint_names
        bones = [self.bones[n] for n in names[1:]]
        orders = np.array([self.root_axis] + [b.axis_order for b in bones])
        angles = np.array([self.root_orientation] + [b.axis for b in bones], dtype=float).reshape(-1, 3)
        out = np.empty((len(names), 4))
        for order in np.unique(orders):  # one vectorised call per axis order
            sel = orders == order
            out[sel] = self._angles_to_quat(str(order), angles[sel])
        return out

    def offsets(self) -> np.ndarray:
        """(J, 3) BVH offsets: the parent bone's ``direction x length`` (root: ``position``)."""
        names = self.joint_names
        vectors = np.zeros((len(names), 3))  # the root has no bone vector
        if len(names) > 1:
            vectors[1:] = [self.bones[n].vector for n in names[1:]]
        out = vectors[self.parents]
        out[0] = self.root_position
        return out


def _text(src, max_bytes: int) -> tuple[str, str | None, int]:
    """Decoded text of a path or stream, its name and its size in bytes (errors name the path)."""
    data, name = read_bytes(src, error=BVHError, max_bytes=max_bytes)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise BVHError(f"{name or '<stream>'}, line {line}: not valid UTF-8 text") from None
    return text, name, len(data)


def _lines(text: str) -> Iterator[tuple[int, list[str]]]:
    """(1-based line number, tokens) of each line with tokens, comments (``#``) removed.

    A generator, so that the token lists of the whole file are never held at once.
    """
    for i, ln in enumerate(text.split("\n")):
        if "#" in ln:
            ln = ln.split("#", 1)[0]
        tok = ln.split()
        if tok:
            yield i + 1, tok


def _floats(tok: list[str], n: int, where: str, what: str) -> np.ndarray:
    if len(tok) != n:
        raise BVHError(f"{where}: {what} needs {n} numbers, got {len(tok)}")
    return np.array([finite_float(t, f"{where}: {what} value") for t in tok])


def _axis_order(tok: str, where: str) -> str:
    order = tok.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise BVHError(f"{where}: axis order {tok!r} is not a permutation of XYZ")
    return order


def _parse_limits(tok: list[str], where: str) -> tuple[float, float]:
    s = " ".join(tok).replace("(", " ").replace(")", " ").split()
    if len(s) != 2:
        raise BVHError(f"{where}: a limit needs '(min max)', got {' '.join(tok)!r}")
    try:
        lo, hi = float(s[0]), float(s[1])
    except ValueError:
        raise BVHError(f"{where}: limit {' '.join(tok)!r} is not numeric") from None
    if "_" in s[0] + s[1] or not (s[0] + s[1]).isascii():
        raise BVHError(f"{where}: limit {' '.join(tok)!r} is not numeric")
    if math.isnan(lo) or math.isnan(hi):
        raise BVHError(f"{where}: limit {' '.join(tok)!r} is NaN")
    return lo, hi


def read_asf(src) -> AsfSkeleton:
    """Read an Acclaim ASF skeleton.

    Parameters
    ----------
    src : str, os.PathLike or file object
        A path (``.gz`` is decompressed) or a binary/text stream, e.g.
        ``repro.data.open_file("mocap/cmu/source/135.asf")``.

    Returns
    -------
    AsfSkeleton

    Raises
    ------
    repro.errors.BVHError
        If the file is malformed (missing ``:root``/``:hierarchy``, a bone without
        ``name``, ``direction``, ``length`` or ``axis``, unsupported translation or
        length dofs, non-numeric or non-finite values, duplicate or unknown bone names,
        bones not connected to the root, a bone with two parents, an unterminated
        ``begin`` block, a bone ``id`` that is not a plain ASCII integer, numbers with
        ``_`` or non-ASCII digits); the message names the line.  Also a missing or
        unreadable file, a folder, a corrupt gzip stream, or more than
        :data:`MAX_ASF_BYTES` of content; the message names the path.

    Notes
    -----
    Linear in the number of bones, without recursion (a chain of 100,000 bones reads).
    """
    text, source, _ = _text(src, MAX_ASF_BYTES)
    section = None
    name = ""
    units: dict[str, str] = {}
    root: dict[str, object] = {}
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
    child_line: dict[str, int] = {}
    bone: dict | None = None  # bone being read
    in_hier = False
    seen_sections: set[str] = set()
    section_line: dict[str, int] = {}
    units_line: dict[str, int] = {}
    last = 0  # last line with tokens

    def finish_bone(lineno: int) -> None:
        for key in ("name", "direction", "length", "axis"):
            if key not in bone:
                raise BVHError(f"line {lineno}: bone starting at line {bone['line']} has no {key!r}")
        if len(bone["limits"]) not in (0, len(bone["dofs"])):
            raise BVHError(
                f"line {lineno}: bone {bone['name']!r} has {len(bone['dofs'])} dofs but "
                f"{len(bone['limits'])} limits"
            )
        if bone["name"] in bones:
            raise BVHError(f"line {bone['line']}: duplicate bone name {bone['name']!r}")
        with np.errstate(over="ignore", invalid="ignore"):
            vector = bone["direction"] * bone["length"]
        if not np.all(np.isfinite(vector)):
            raise BVHError(
                f"line {bone['line']}: bone {bone['name']!r}: direction x length overflows "
                f"({bone['direction'].tolist()} x {bone['length']:.6g}); expected a finite bone vector "
                "(values far below 1.8e308)"
            )
        bones[bone["name"]] = AsfBone(
            name=bone["name"],
            id=bone.get("id"),
            direction=bone["direction"],
            length=bone["length"],
            axis=bone["axis"],
            axis_order=bone["axis_order"],
            dofs=tuple(bone["dofs"]),
            limits=tuple(bone["limits"]),
            line=bone["line"],
        )

    last_key = None
    for lineno, tok in _lines(text):
        last = lineno
        where = f"line {lineno}"
        head = tok[0]
        if head.startswith(":"):
            if bone is not None:
                raise BVHError(f"{where}: section {head} inside the bone block begun at line {bone['line']}")
            if in_hier:
                raise BVHError(f"{where}: section {head} inside the :hierarchy block (missing 'end')")
            section = head.lower()
            if section in seen_sections and section in (":root", ":bonedata", ":hierarchy", ":units"):
                raise BVHError(f"{where}: second {head} section")
            seen_sections.add(section)
            section_line[section] = lineno
            if section == ":name":
                name = " ".join(tok[1:])
            continue
        if section == ":units":
            if len(tok) != 2:
                raise BVHError(f"{where}: expected '<unit> <value>' in :units, got {' '.join(tok)!r}")
            units[tok[0].lower()] = tok[1]
            units_line[tok[0].lower()] = lineno
        elif section == ":root":
            key = head.lower()
            if key == "order":
                order = tuple(t.upper() for t in tok[1:])
                bad = [t for t in order if t not in _ROOT_DOFS]
                if bad or len(set(order)) != len(order):
                    raise BVHError(f"{where}: bad root order {' '.join(tok[1:])!r} (use TX TY TZ RX RY RZ, each once)")
                root["order"] = order
            elif key == "axis":
                if len(tok) != 2:
                    raise BVHError(f"{where}: root axis needs one order like XYZ")
                root["axis"] = _axis_order(tok[1], where)
            elif key in ("position", "orientation"):
                root[key] = _floats(tok[1:], 3, where, f"root {key}")
            else:
                raise BVHError(f"{where}: unknown :root field {head!r}")
        elif section == ":bonedata":
            key = head.lower()
            if bone is None:
                if tok != ["begin"]:
                    raise BVHError(f"{where}: expected 'begin' in :bonedata, got {' '.join(tok)!r}")
                bone = {"line": lineno, "dofs": [], "limits": []}
                last_key = None
                continue
            if key == "end" and len(tok) == 1:
                finish_bone(lineno)
                bone = None
                continue
            if key == "begin":
                raise BVHError(f"{where}: 'begin' inside the bone block begun at line {bone['line']} (missing 'end')")
            if key == "id":
                if len(tok) != 2 or not _INT_RE.fullmatch(tok[1]):
                    raise BVHError(
                        f"{where}: bone id must be an integer of at most 18 digits, got {' '.join(tok[1:])[:40]!r}"
                    )
                bone["id"] = int(tok[1])
            elif key == "name":
                if len(tok) != 2:
                    raise BVHError(f"{where}: bone name must be one word")
                if tok[1].lower() == "root":
                    raise BVHError(f"{where}: a bone may not be called 'root'")
                bone["name"] = tok[1]
            elif key == "direction":
                bone["direction"] = _floats(tok[1:], 3, where, "direction")
            elif key == "length":
                v = _floats(tok[1:], 1, where, "length")[0]
                if v < 0:
                    raise BVHError(f"{where}: negative bone length {v}")
                bone["length"] = float(v)
            elif key == "axis":
                if len(tok) != 5:
                    raise BVHError(f"{where}: axis needs 3 angles and an order, e.g. 'axis 0 0 20 XYZ'")
                bone["axis"] = _floats(tok[1:4], 3, where, "axis")
                bone["axis_order"] = _axis_order(tok[4], where)
            elif key == "dof":
                dofs = [t.lower() for t in tok[1:]]
                bad = [d for d in dofs if d not in _ROTATION_DOFS]
                if bad:
                    raise BVHError(f"{where}: unsupported dof {bad} (only rx ry rz are supported)")
                if len(set(dofs)) != len(dofs):
                    raise BVHError(f"{where}: repeated dof in {dofs}")
                bone["dofs"] = dofs
            elif key == "limits":
                bone["limits"].append(_parse_limits(tok[1:], where))
            elif head.startswith("(") and last_key == "limits":
                bone["limits"].append(_parse_limits(tok, where))
                continue
            elif key in ("bodymass", "cofmass"):
                pass
            else:
                raise BVHError(f"{where}: unknown bone field {head!r}")
            last_key = key
        elif section == ":hierarchy":
            if not in_hier:
                if tok != ["begin"]:
                    raise BVHError(f"{where}: expected 'begin' in :hierarchy, got {' '.join(tok)!r}")
                in_hier = True
                continue
            if tok == ["end"]:
                in_hier = False
                section = ":hierarchy-done"
                continue
            parent = head
            if parent != "root" and parent not in bones:
                raise BVHError(f"{where}: unknown parent bone {parent!r} in :hierarchy")
            if len(tok) < 2:
                raise BVHError(f"{where}: hierarchy line lists no children of {parent!r}")
            for child in tok[1:]:
                if child not in bones:
                    raise BVHError(f"{where}: unknown bone {child!r} in :hierarchy")
                if child in child_line:
                    raise BVHError(f"{where}: bone {child!r} already has a parent (line {child_line[child]})")
                child_line[child] = lineno
                children.setdefault(parent, []).append(child)
        elif section == ":hierarchy-done":
            raise BVHError(f"{where}: unexpected {' '.join(tok)!r} after the :hierarchy 'end'")
        elif section is None:
            raise BVHError(f"{where}: unexpected {' '.join(tok)!r} before the first section")
        # other sections (:version, :documentation, :skin ...) are free text: ignored

    if not last:
        raise BVHError(f"{source or '<stream>'}, line 1: empty ASF file")
    if bone is not None:
        raise BVHError(f"line {last + 1}: end of file inside the bone block begun at line {bone['line']} (truncated?)")
    if in_hier:
        raise BVHError(f"line {last + 1}: end of file inside :hierarchy (missing 'end'; truncated?)")
    for sec in (":root", ":bonedata", ":hierarchy"):
        if sec not in seen_sections:
            raise BVHError(f"line {last + 1}: missing {sec} section (truncated?)")
    if section != ":hierarchy-done":
        raise BVHError(f"line {last + 1}: :hierarchy section not terminated (truncated?)")
    if "order" not in root or "axis" not in root:
        raise BVHError(f"line {section_line[':root']}: the :root section needs 'order' and 'axis'")
    angle = units.get("angle", "deg").lower()
    if angle not in ("deg", "rad"):
        raise BVHError(f"line {units_line['angle']}: :units angle must be deg or rad, got {angle!r}")
    length_text = units.get("length", "1")
    try:
        length_unit = float(length_text)
    except ValueError:
        length_unit = float("nan")
    if "_" in length_text or not length_text.isascii():  # float() takes '1_0' and other scripts' digits
        length_unit = float("nan")
    if not math.isfinite(length_unit) or length_unit <= 0:
        raise BVHError(f"line {units_line['length']}: :units length must be a number > 0, got {units['length']!r}")
    loose = [b for b in bones if b not in child_line]
    if loose:
        raise BVHError(
            f"line {bones[loose[0]].line}: bones not connected to the root in :hierarchy "
            f"(line {section_line[':hierarchy']}): {loose}"
        )
    skel = AsfSkeleton(
        name=name,
        length_unit=length_unit,
        angle_unit=angle,
        root_order=tuple(root["order"]),
        root_axis=str(root["axis"]),
        root_position=np.asarray(root.get("position", np.zeros(3)), dtype=float),
        root_orientation=np.asarray(root.get("orientation", np.zeros(3)), dtype=float),
        bones=bones,
        children=children,
    )
    reach = skel.joint_names
    if len(reach) != len(bones) + 1:
        missing = sorted(set(bones) - set(reach))
        raise BVHError(
            f"line {section_line[':hierarchy']}: bones not reachable from the root "
            f"(a cycle in :hierarchy?): {missing}"
        )
    return skel


def _amc_values(src, skel: AsfSkeleton) -> tuple[dict[str, np.ndarray], bool | None, str | None, int]:
    """Per bone (and "root"), the (F, n_dofs) AMC values; whether angles are degrees; the
    source name; the file's size in bytes."""
    text, source, nbytes = _text(src, MAX_AMC_BYTES)
    ndof = {"root": len(skel.root_order)}
    ndof.update({b: len(bone.dofs) for b, bone in skel.bones.items()})
    required = {b for b, n in ndof.items() if n > 0} | {"root"}
    # flat value tokens per bone (row k of bone b is values[b][k*n:(k+1)*n]) and the
    # line of each row: compact, and converted by one numpy call per bone
    values: dict[str, list[str]] = {b: [] for b in ndof}
    rows_line: dict[str, list[int]] = {b: [] for b in ndof}
    degrees: bool | None = None
    frame_no: int | None = None
    frame_line = 0
    n_frames = 0
    seen: set[str] = set()
    last = 0

    def close_frame(lineno: int) -> None:
        missing = required - seen
        if missing:
            raise BVHError(
                f"line {lineno}: frame {frame_no} (line {frame_line}) lacks values for "
                f"{sorted(missing)} (truncated file?)"
            )

    for lineno, tok in _lines(text):
        last = lineno
        head = tok[0]
        if head.startswith(":"):
            if frame_no is not None:
                raise BVHError(f"line {lineno}: header line {head!r} after the first frame")
            if head.upper() == ":DEGREES":
                degrees = True
            elif head.upper() == ":RADIANS":
                degrees = False
            continue
        if len(tok) == 1 and (head not in ndof or _UINT_RE.fullmatch(head)):
            if not _UINT_RE.fullmatch(head):
                if _numberish(head):  # '²', Arabic-Indic digits, '1_0', '-3', 30 digits ...
                    raise BVHError(
                        f"line {lineno}: frame number {head[:40]!r} is not a plain integer "
                        f"(ASCII digits 0-9, at most 18)"
                    )
                raise BVHError(
                    f"line {lineno}: {head[:40]!r} is neither a frame number nor a bone of the skeleton"
                )
            k = int(head)
            if frame_no is not None:
                close_frame(lineno)
                if k != frame_no + 1:
                    raise BVHError(f"line {lineno}: frame number {k} follows frame {frame_no}")
            frame_no, frame_line = k, lineno
            n_frames += 1
            seen = set()
            continue
        if frame_no is None:
            raise BVHError(f"line {lineno}: {head!r} before the first frame number")
        if head not in ndof:
            raise BVHError(f"line {lineno}: unknown bone {head!r} (frame {frame_no})")
        if head in seen:
            raise BVHError(f"line {lineno}: bone {head!r} appears twice in frame {frame_no}")
        if len(tok) - 1 != ndof[head]:
            raise BVHError(
                f"line {lineno}: bone {head!r} has {len(tok) - 1} values, expected {ndof[head]} (frame {frame_no})"
            )
        seen.add(head)
        if ndof[head]:
            values[head] += tok[1:]
            rows_line[head].append(lineno)
    if frame_no is None:
        raise BVHError(f"line {last + 1}: AMC file has no frames")
    close_frame(last + 1)

    out = {}
    for b, flat in values.items():
        n = ndof[b]
        if not n:
            out[b] = np.zeros((n_frames, 0))
            continue
        if len(flat) != n_frames * n:  # pragma: no cover - guaranteed by close_frame
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
                f"line {rows_line[b][bad_row]}: bone {b!r} has a value that is not a finite number: "
                f"{' '.join(row)[:80]!r}"
            )
        out[b] = v
    return out, degrees, source, nbytes


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
    need = F * J * 7 * 8  # rotations (F, J, 4) and positions (F, J, 3)
    allowed = max(_MOTION_BYTES_FLOOR, _MOTION_BYTES_PER_AMC_BYTE * nbytes)
    if need > allowed:
        raise BVHError(
            f"{source or '<stream>'}: {F} frames x {J} joints would need {need / 2**20:.0f} MiB of motion "
            f"arrays, more than the {allowed / 2**20:.0f} MiB allowed for an AMC file of {nbytes} bytes "
            f"(a skeleton with many bones without dofs?)"
        )
    axis_q = skeleton.axis_quaternions()  # C, (J, 4)
    conj = np.array([-1.0, -1.0, -1.0, 1.0])
    rotations = np.zeros((F, J, 4))
    rotations[..., 3] = 1.0
    offsets = skeleton.offsets()
    positions = np.broadcast_to(offsets, (F, J, 3)).copy()
    channels: list[tuple[str, ...]] = []
    rot_channels = ("Zrotation", "Yrotation", "Xrotation")
    groups: dict[str, list[tuple[int, np.ndarray]]] = {}  # dof sequence -> (joint, (F, n) angles)
    for j, name in enumerate(names):
        if name == "root":
            order = skeleton.root_order
            v = values["root"]
            pos_ch = []
            for k, d in enumerate(order):
                if d.startswith("T"):
                    axis = "XYZ".index(d[1])
                    positions[:, 0, axis] = v[:, k]
                    pos_ch.append(f"{d[1]}position")
            rk = [k for k, d in enumerate(order) if d.startswith("R")]
            seq = "".join(order[k][1].lower() for k in rk)
            ang = v[:, rk]
            channels.append(tuple(pos_ch) + rot_channels)
        else:
            bone = skeleton.bones[name]
            seq = "".join(d[1] for d in bone.dofs)
            ang = values[name]
            channels.append(rot_channels)
        if seq:  # no motion: C I C^-1 = I
            groups.setdefault(seq, []).append((j, ang))
    for seq, members in groups.items():  # one vectorised product per dof sequence
        js = np.array([j for j, _ in members], dtype=np.intp)
        m = euler_to_quat(seq, np.stack([a for _, a in members], axis=1), degrees=degrees)  # (F, G, 4)
        c = axis_q[js]
        rotations[:, js] = quat_multiply(quat_multiply(c, m), c * conj)
    ends = [(j, skeleton.bones[n].vector) for j, n in enumerate(names) if n != "root" and not skeleton.children.get(n)]
    return Motion(
        joint_names=names,
        parents=skeleton.parents,
        offsets=offsets,
        channels=channels,
        frame_time=frame_time,
        rotations=rotations,
        positions=positions,
        end_site_parents=np.array([j for j, _ in ends], dtype=np.intp),
        end_site_offsets=np.array([o for _, o in ends], dtype=float).reshape(-1, 3),
        unit_m=unit_m,
        source=source,
    )


def read_asf_amc(asf, amc, *, frame_time: float = CMU_FRAME_TIME, unit_m: float | None = None) -> Motion:
    """Read an ASF skeleton and an AMC motion into a :class:`~repro.motion.Motion`.

    ``read_asf_amc(asf, amc)`` is ``read_amc(amc, read_asf(asf))``; both arguments take
    paths (``.gz`` decompressed) or streams such as
    ``repro.data.open_file("mocap/cmu/source/135_04.amc")``.  See :func:`read_amc`.
    """
    return read_amc(amc, read_asf(asf), frame_time=frame_time, unit_m=unit_m)
