"""Reading Acclaim ASF skeletons (the originals of the CMU database).

An ASF file (Acclaim Entertainment; described in M. Meredith and S. Maddock, "Motion
Capture File Formats Explained", University of Sheffield, 2001, and used by the CMU
Graphics Lab Motion Capture Database, http://mocap.cs.cmu.edu) is the skeleton of a
take: its ``:units``, the ``:root`` (the order of its AMC values, its axis, rest
position and orientation), the ``:bonedata`` (per bone a global ``direction``, a
``length``, a local frame ``axis`` and the ``dof`` the motion drives) and the
``:hierarchy``.  :mod:`repro.motion.io.asfamc` reads an AMC motion for it into a
:class:`~repro.motion.Motion`.  Malformed files raise :class:`repro.errors.BVHError`
naming the line.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from repro.errors import BVHError
from repro.io import read_bytes
from repro.motion.core.quaternion import euler_to_quat
from repro.motion.io.tokens import finite_float

__all__ = ["AsfBone", "AsfSkeleton", "read_asf", "MAX_ASF_BYTES", "acclaim_text", "acclaim_lines"]

_ROTATION_DOFS = ("rx", "ry", "rz")
_ROOT_DOFS = ("TX", "TY", "TZ", "RX", "RY", "RZ")

#: Most bytes (after gzip is undone) an ASF file may hold: 64 MiB, some 400,000 bones.
MAX_ASF_BYTES = 64 << 20

#: A plain ASCII integer (Python's int() also takes '1_0', ' 7', Arabic-Indic digits ...).
_INT_RE = re.compile(r"[+-]?[0-9]{1,18}")


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


def acclaim_text(src, max_bytes: int) -> tuple[str, str | None, int]:
    """Decoded text of a path or stream, its name and its size in bytes (errors name the path)."""
    data, name = read_bytes(src, error=BVHError, max_bytes=max_bytes)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise BVHError(f"{name or '<stream>'}, line {line}: not valid UTF-8 text") from None
    return text, name, len(data)


def acclaim_lines(text: str) -> Iterator[tuple[int, list[str]]]:
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


def _bone_field(bone: dict, key: str, tok: list[str], where: str) -> None:
    """One field line of a ``:bonedata`` block (``id``, ``name``, ``direction``, ``length``,
    ``axis``, ``dof``, ``limits``; ``bodymass`` and ``cofmass`` are ignored), into ``bone``."""
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
    elif key not in ("bodymass", "cofmass"):
        raise BVHError(f"{where}: unknown bone field {tok[0]!r}")


def _asf_bone(bone: dict, lineno: int, bones: dict[str, AsfBone]) -> AsfBone:
    """The bone of a ``:bonedata`` block ended at line ``lineno``: all its fields, a new name, a finite vector."""
    for key in ("name", "direction", "length", "axis"):
        if key not in bone:
            raise BVHError(f"line {lineno}: bone starting at line {bone['line']} has no {key!r}")
    if len(bone["limits"]) not in (0, len(bone["dofs"])):
        raise BVHError(
            f"line {lineno}: bone {bone['name']!r} has {len(bone['dofs'])} dofs but {len(bone['limits'])} limits"
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
    return AsfBone(
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


class _AsfReader:
    """Reads the lines of an ASF file into an :class:`AsfSkeleton`, one section at a time.

    ``:units``, ``:root``, ``:bonedata`` (``begin`` ... ``end`` blocks, one per bone) and
    ``:hierarchy`` (``begin``, lines ``parent child...``, ``end``) are read; other
    sections (``:version``, ``:documentation``, ``:skin`` ...) are free text, ignored.
    """

    def __init__(self) -> None:
        self.section: str | None = None
        self.name = ""
        self.units: dict[str, str] = {}
        self.units_line: dict[str, int] = {}
        self.root: dict[str, object] = {}
        self.bones: dict[str, AsfBone] = {}
        self.bone: dict | None = None  # the bone block being read
        self.last_key: str | None = None  # its last field ('limits' continues on lines '(min max)')
        self.children: dict[str, list[str]] = {}
        self.child_line: dict[str, int] = {}
        self.in_hier = False
        self.seen_sections: set[str] = set()
        self.section_line: dict[str, int] = {}

    def read(self, lines) -> int:
        """Read ``lines`` ((line number, tokens) pairs); returns the last line number (0: no line)."""
        lineno = 0
        for lineno, tok in lines:
            where = f"line {lineno}"
            section = self.section
            if tok[0].startswith(":"):
                self._section(tok, where, lineno)
            elif section == ":units":
                self._unit(tok, where, lineno)
            elif section == ":root":
                self._root_field(tok, where)
            elif section == ":bonedata":
                self._bone_line(tok, where, lineno)
            elif section == ":hierarchy":
                self._hierarchy_line(tok, where, lineno)
            elif section == ":hierarchy-done":
                raise BVHError(f"{where}: unexpected {' '.join(tok)!r} after the :hierarchy 'end'")
            elif section is None:
                raise BVHError(f"{where}: unexpected {' '.join(tok)!r} before the first section")
        return lineno

    def _section(self, tok: list[str], where: str, lineno: int) -> None:
        """A ``:section`` line (``:name`` holds its value on the line)."""
        head = tok[0]
        if self.bone is not None:
            raise BVHError(f"{where}: section {head} inside the bone block begun at line {self.bone['line']}")
        if self.in_hier:
            raise BVHError(f"{where}: section {head} inside the :hierarchy block (missing 'end')")
        section = head.lower()
        if section in self.seen_sections and section in (":root", ":bonedata", ":hierarchy", ":units"):
            raise BVHError(f"{where}: second {head} section")
        self.section = section
        self.seen_sections.add(section)
        self.section_line[section] = lineno
        if section == ":name":
            self.name = " ".join(tok[1:])

    def _unit(self, tok: list[str], where: str, lineno: int) -> None:
        """A ``<unit> <value>`` line of ``:units`` (checked once the file is read)."""
        if len(tok) != 2:
            raise BVHError(f"{where}: expected '<unit> <value>' in :units, got {' '.join(tok)!r}")
        self.units[tok[0].lower()] = tok[1]
        self.units_line[tok[0].lower()] = lineno

    def _root_field(self, tok: list[str], where: str) -> None:
        """An ``order``, ``axis``, ``position`` or ``orientation`` line of ``:root``."""
        key = tok[0].lower()
        if key == "order":
            order = tuple(t.upper() for t in tok[1:])
            bad = [t for t in order if t not in _ROOT_DOFS]
            if bad or len(set(order)) != len(order):
                raise BVHError(f"{where}: bad root order {' '.join(tok[1:])!r} (use TX TY TZ RX RY RZ, each once)")
            self.root["order"] = order
        elif key == "axis":
            if len(tok) != 2:
                raise BVHError(f"{where}: root axis needs one order like XYZ")
            self.root["axis"] = _axis_order(tok[1], where)
        elif key in ("position", "orientation"):
            self.root[key] = _floats(tok[1:], 3, where, f"root {key}")
        else:
            raise BVHError(f"{where}: unknown :root field {tok[0]!r}")

    def _bone_line(self, tok: list[str], where: str, lineno: int) -> None:
        """A line of ``:bonedata``: a bone block's ``begin`` or ``end``, or one of its fields."""
        key = tok[0].lower()
        if self.bone is None:
            if tok != ["begin"]:
                raise BVHError(f"{where}: expected 'begin' in :bonedata, got {' '.join(tok)!r}")
            self.bone = {"line": lineno, "dofs": [], "limits": []}
            self.last_key = None
        elif key == "end" and len(tok) == 1:
            bone = _asf_bone(self.bone, lineno, self.bones)
            self.bones[bone.name] = bone
            self.bone = None
        elif key == "begin":
            raise BVHError(f"{where}: 'begin' inside the bone block begun at line {self.bone['line']} (missing 'end')")
        elif tok[0].startswith("(") and self.last_key == "limits":  # one more limit of the 'limits' field
            self.bone["limits"].append(_parse_limits(tok, where))
        else:
            _bone_field(self.bone, key, tok, where)
            self.last_key = key

    def _hierarchy_line(self, tok: list[str], where: str, lineno: int) -> None:
        """A line of ``:hierarchy``: its ``begin``, ``end``, or a bone (or ``root``) and its children."""
        if not self.in_hier:
            if tok != ["begin"]:
                raise BVHError(f"{where}: expected 'begin' in :hierarchy, got {' '.join(tok)!r}")
            self.in_hier = True
            return
        if tok == ["end"]:
            self.in_hier = False
            self.section = ":hierarchy-done"
            return
        parent = tok[0]
        if parent != "root" and parent not in self.bones:
            raise BVHError(f"{where}: unknown parent bone {parent!r} in :hierarchy")
        if len(tok) < 2:
            raise BVHError(f"{where}: hierarchy line lists no children of {parent!r}")
        for child in tok[1:]:
            if child not in self.bones:
                raise BVHError(f"{where}: unknown bone {child!r} in :hierarchy")
            if child in self.child_line:
                raise BVHError(f"{where}: bone {child!r} already has a parent (line {self.child_line[child]})")
            self.child_line[child] = lineno
            self.children.setdefault(parent, []).append(child)

    def _check_complete(self, last: int, source: str | None) -> None:
        """Check, after the last line (``last``), that no block is open and no section missing."""
        if not last:
            raise BVHError(f"{source or '<stream>'}, line 1: empty ASF file")
        if self.bone is not None:
            raise BVHError(
                f"line {last + 1}: end of file inside the bone block begun at line {self.bone['line']} (truncated?)"
            )
        if self.in_hier:
            raise BVHError(f"line {last + 1}: end of file inside :hierarchy (missing 'end'; truncated?)")
        for sec in (":root", ":bonedata", ":hierarchy"):
            if sec not in self.seen_sections:
                raise BVHError(f"line {last + 1}: missing {sec} section (truncated?)")
        if self.section != ":hierarchy-done":
            raise BVHError(f"line {last + 1}: :hierarchy section not terminated (truncated?)")
        if "order" not in self.root or "axis" not in self.root:
            raise BVHError(f"line {self.section_line[':root']}: the :root section needs 'order' and 'axis'")

    def _unit_values(self) -> tuple[str, float]:
        """The ``:units`` angle (``"deg"`` or ``"rad"``, default deg) and length factor (> 0, default 1)."""
        angle = self.units.get("angle", "deg").lower()
        if angle not in ("deg", "rad"):
            raise BVHError(f"line {self.units_line['angle']}: :units angle must be deg or rad, got {angle!r}")
        length_text = self.units.get("length", "1")
        try:
            length_unit = float(length_text)
        except ValueError:
            length_unit = float("nan")
        if "_" in length_text or not length_text.isascii():  # float() takes '1_0' and other scripts' digits
            length_unit = float("nan")
        if not math.isfinite(length_unit) or length_unit <= 0:
            raise BVHError(
                f"line {self.units_line['length']}: :units length must be a number > 0, got {self.units['length']!r}"
            )
        return angle, length_unit

    def skeleton(self, last: int, source: str | None) -> AsfSkeleton:
        """The skeleton, once the file is read (``last``: its last line with tokens): complete, all bones reachable."""
        self._check_complete(last, source)
        angle, length_unit = self._unit_values()
        bones, root = self.bones, self.root
        loose = [b for b in bones if b not in self.child_line]
        if loose:
            raise BVHError(
                f"line {bones[loose[0]].line}: bones not connected to the root in :hierarchy "
                f"(line {self.section_line[':hierarchy']}): {loose}"
            )
        skel = AsfSkeleton(
            name=self.name,
            length_unit=length_unit,
            angle_unit=angle,
            root_order=tuple(root["order"]),
            root_axis=str(root["axis"]),
            root_position=np.asarray(root.get("position", np.zeros(3)), dtype=float),
            root_orientation=np.asarray(root.get("orientation", np.zeros(3)), dtype=float),
            bones=bones,
            children=self.children,
        )
        reach = skel.joint_names
        if len(reach) != len(bones) + 1:
            missing = sorted(set(bones) - set(reach))
            raise BVHError(
                f"line {self.section_line[':hierarchy']}: bones not reachable from the root "
                f"(a cycle in :hierarchy?): {missing}"
            )
        return skel


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
    text, source, _ = acclaim_text(src, MAX_ASF_BYTES)
    reader = _AsfReader()
    return reader.skeleton(reader.read(acclaim_lines(text)), source)
