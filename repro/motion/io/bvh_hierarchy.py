"""The HIERARCHY section of a BVH file: its joints, offsets, channels and End Sites.

The first part of a BVH file (Biovision; M. Meredith and S. Maddock, "Motion Capture
File Formats Explained", University of Sheffield, 2001), the storage format of the
motion database of Pronost et al. (Section 3.2.1): ``ROOT`` and ``JOINT`` blocks
nested in braces, each with an ``OFFSET`` and its ``CHANNELS``, leaves closed by an
``End Site`` with its own ``OFFSET``.  It is read one statement at a time, with a stack
of the open blocks (no recursion, however deep the hierarchy); every malformed
statement raises :class:`repro.errors.BVHError` naming the line.  :mod:`repro.motion.io.bvh`
reads the MOTION section after it.
"""

from __future__ import annotations

import re

from repro.errors import BVHError
from repro.motion.core.channels import POSITION_CHANNELS, ROTATION_CHANNELS
from repro.motion.io.tokens import INTEGER, finite_float

__all__ = ["Hierarchy", "parse_hierarchy"]

_CANONICAL_CHANNEL = {c.lower(): c for c in POSITION_CHANNELS + ROTATION_CHANNELS}


class Hierarchy:
    """The parsed HIERARCHY section, as plain lists (:mod:`repro.motion.io.bvh` makes the Motion).

    Attributes
    ----------
    names, parents, offsets, channels : lists
        Per joint, in file order: its name, its parent's index (-1 for the root), its
        ``OFFSET`` and its canonical ``CHANNELS`` names.
    end_parents, end_offsets : lists
        Per End Site: the joint it ends and its ``OFFSET``.
    """

    def __init__(self) -> None:
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_parents: list[int] = []
        self.end_offsets: list[tuple[float, float, float]] = []


def _parse_channels(tok: list[str], where: str) -> tuple[str, ...]:
    if len(tok) < 2:
        raise BVHError(f"{where}: CHANNELS needs a count")
    if not INTEGER.fullmatch(tok[1]):
        raise BVHError(f"{where}: channel count {tok[1][:40]!r} is not an integer")
    n = int(tok[1]) if len(tok[1]) <= 20 else 7  # no int() of thousands of digits
    if n < 0 or n > 6:
        raise BVHError(f"{where}: channel count {tok[1][:40]} is out of range 0..6")
    if len(tok) - 2 != n:
        raise BVHError(f"{where}: CHANNELS declares {n} channels but names {len(tok) - 2}")
    out = []
    for name in tok[2:]:
        canon = _CANONICAL_CHANNEL.get(name.lower())
        if canon is None:
            raise BVHError(
                f"{where}: unknown channel name {name!r} "
                f"(expected one of {', '.join(POSITION_CHANNELS + ROTATION_CHANNELS)})"
            )
        if canon in out:
            raise BVHError(f"{where}: channel {canon} is listed twice")
        out.append(canon)
    return tuple(out)


class _Block:
    """A ``ROOT``/``JOINT`` or ``End Site`` block of the hierarchy and what it has held so far."""

    __slots__ = ("kind", "index", "line", "has_offset", "has_channels", "has_children")

    def __init__(self, kind: str, index: int, line: int) -> None:
        self.kind = kind  # "joint" or "end"
        self.index = index  # the joint (of an End Site: its parent joint)
        self.line = line  # the line of its keyword
        self.has_offset = self.has_channels = self.has_children = False


class _HierarchyReader:
    """Reads the lines of the HIERARCHY section into a :class:`Hierarchy`, one statement at a time.

    The open blocks are a stack (no recursion, however deep the hierarchy) and the joint
    names so far a set (a list lookup would make deep files quadratic).
    """

    def __init__(self) -> None:
        self.h = Hierarchy()
        self.seen: set[str] = set()
        self.stack: list[_Block] = []
        self.pending: _Block | None = None  # at the end: a ROOT/JOINT/End Site still waiting for its '{'
        self.root_done = False

    def read(self, lines, lineno: int) -> int:
        """Read the statements of ``lines`` ((line number, tokens) pairs, after the one
        numbered ``lineno``); returns the number of the last line."""
        stack = self.stack
        pending = None  # a ROOT/JOINT/End Site waiting for its '{'
        for lineno, tok in lines:
            where = f"line {lineno}"
            if pending is not None:
                if tok != ["{"]:
                    raise BVHError(f"{where}: expected '{{' after line {pending.line}, got {' '.join(tok)!r}")
                stack.append(pending)
                pending = None
                continue
            head = tok[0]
            if self.root_done:
                raise BVHError(
                    f"{where}: unexpected {' '.join(tok)!r} after the root joint was closed "
                    "(expected MOTION; only one ROOT is supported; unbalanced '}'?)"
                )
            opens = tok[-1] == "{" and len(tok) > 1
            body = tok[:-1] if opens else tok
            if head in ("ROOT", "JOINT"):
                block = self._joint(head, body, lineno)
            elif head == "End" and _is_end_site(body):
                block = self._end_site(lineno)
            elif head == "OFFSET":
                self._offset(tok, where)
                continue
            elif head == "CHANNELS":
                self._channels(tok, where)
                continue
            elif tok == ["}"]:
                self._close(lineno)
                continue
            elif tok == ["{"]:
                raise BVHError(f"{where}: unexpected '{{'")
            elif head == "HIERARCHY":
                raise BVHError(f"{where}: second HIERARCHY")
            else:
                raise BVHError(f"{where}: unexpected {' '.join(tok)!r} in the hierarchy")
            if opens:  # the new block is open now, or at the next line, which must be '{'
                stack.append(block)
            else:
                pending = block
        self.pending = pending
        return lineno

    def _what(self, block: _Block) -> str:
        if block.kind == "end":
            return f"End Site of joint {self.h.names[block.index]!r} (line {block.line})"
        return f"joint {self.h.names[block.index]!r} (line {block.line})"

    def _complete(self, block: _Block, lineno: int, doing: str) -> None:
        """Check that ``block`` has had its OFFSET (and, for a joint, its CHANNELS) before ``doing``."""
        if not block.has_offset:
            raise BVHError(f"line {lineno}: {self._what(block)} has no OFFSET before {doing}")
        if block.kind == "joint" and not block.has_channels:
            raise BVHError(f"line {lineno}: {self._what(block)} has no CHANNELS before {doing}")

    def _joint(self, head: str, body: list[str], lineno: int) -> _Block:
        """A ``ROOT`` or ``JOINT`` line: a new joint, child of the open joint."""
        where = f"line {lineno}"
        h, stack = self.h, self.stack
        if head == "ROOT" and h.names:
            raise BVHError(f"{where}: second ROOT (only one ROOT is supported)")
        if head == "JOINT":
            if not stack or stack[-1].kind != "joint":
                raise BVHError(f"{where}: JOINT outside a joint (or inside an End Site)")
            self._complete(stack[-1], lineno, "its child joints")
            stack[-1].has_children = True
        elif stack:  # pragma: no cover - unreachable (a second ROOT is caught above)
            raise BVHError(f"{where}: ROOT inside a joint")
        name = " ".join(body[1:])
        if not name:
            raise BVHError(f"{where}: {head} without a name")
        if name in self.seen:
            raise BVHError(f"{where}: duplicate joint name {name!r}")
        self.seen.add(name)
        h.names.append(name)
        h.parents.append(stack[-1].index if stack else -1)
        h.offsets.append((0.0, 0.0, 0.0))
        h.channels.append(())
        return _Block("joint", len(h.names) - 1, lineno)

    def _end_site(self, lineno: int) -> _Block:
        """An ``End Site`` line: a leaf of the open joint."""
        stack = self.stack
        if not stack or stack[-1].kind != "joint":
            raise BVHError(f"line {lineno}: End Site outside a joint (or inside an End Site)")
        self._complete(stack[-1], lineno, "its End Site")
        stack[-1].has_children = True
        self.h.end_parents.append(stack[-1].index)
        self.h.end_offsets.append((0.0, 0.0, 0.0))
        return _Block("end", stack[-1].index, lineno)

    def _offset(self, tok: list[str], where: str) -> None:
        """An ``OFFSET x y z`` line of the open joint or End Site."""
        if not self.stack:
            raise BVHError(f"{where}: OFFSET outside a joint")
        top = self.stack[-1]
        if top.has_offset:
            raise BVHError(f"{where}: second OFFSET in {self._what(top)}")
        if top.has_children:
            raise BVHError(f"{where}: OFFSET after the children of {self._what(top)}")
        if len(tok) != 4:
            raise BVHError(f"{where}: OFFSET needs 3 numbers, got {len(tok) - 1}")
        off = tuple(finite_float(t, f"{where} (OFFSET):") for t in tok[1:4])
        if top.kind == "end":
            self.h.end_offsets[-1] = off
        else:
            self.h.offsets[top.index] = off
        top.has_offset = True

    def _channels(self, tok: list[str], where: str) -> None:
        """A ``CHANNELS n name...`` line of the open joint."""
        if not self.stack:
            raise BVHError(f"{where}: CHANNELS outside a joint")
        top = self.stack[-1]
        if top.kind == "end":
            raise BVHError(f"{where}: CHANNELS in an End Site")
        if top.has_channels:
            raise BVHError(f"{where}: second CHANNELS in {self._what(top)}")
        if top.has_children:
            raise BVHError(f"{where}: CHANNELS after the children of {self._what(top)}")
        self.h.channels[top.index] = _parse_channels(tok, where)
        top.has_channels = True

    def _close(self, lineno: int) -> None:
        """A ``}`` line: the open block ends (the root's ends the hierarchy)."""
        if not self.stack:
            raise BVHError(f"line {lineno}: unbalanced '}}' (no open joint)")
        self._complete(self.stack[-1], lineno, "its closing '}'")
        self.stack.pop()
        if not self.stack:
            self.root_done = True

    def finish(self, last_line: int, motion_found: bool) -> Hierarchy:
        """The hierarchy, after its last line (``last_line``): a root, every block closed, MOTION next."""
        if not self.h.names:
            raise BVHError(f"line {last_line}: empty hierarchy (no ROOT joint)")
        if self.pending is not None or self.stack:
            what = self._what(self.pending if self.pending is not None else self.stack[-1])
            end = "MOTION" if motion_found else "end of file"
            raise BVHError(
                f"line {last_line + 1}: {end} reached inside {what}: missing '}}' (truncated or unbalanced braces)"
            )
        if not motion_found:
            raise BVHError(f"line {last_line + 1}: missing MOTION section (truncated file?)")
        return self.h


def parse_hierarchy(header: str, motion_found: bool) -> Hierarchy:
    """The HIERARCHY section: ``header`` is the text before the MOTION line (if ``motion_found``)."""
    # lazily, one line's tokens at a time: a list of every line's tokens would keep
    # hundreds of thousands of containers alive for the garbage collector to rescan
    lines = ((i + 1, t) for i, ln in enumerate(header.split("\n")) if (t := ln.split()))
    n0, t0 = next(lines, (0, None))
    if t0 is None:
        raise BVHError("line 1: empty file (expected HIERARCHY)")
    if t0 != ["HIERARCHY"]:
        raise BVHError(f"line {n0}: expected 'HIERARCHY', got {' '.join(t0)!r}")
    reader = _HierarchyReader()
    return reader.finish(reader.read(lines, n0), motion_found)


def _is_end_site(body: list[str]) -> bool:
    """``End Site``, and the variants two exporters write: a name after it (``End Site Head_end``) and a
    number glued to it (``End Site4``).  The name or number is not kept: End Sites are unnamed leaves."""
    if len(body) == 2:
        return re.fullmatch(r"Site\d*", body[1]) is not None
    return len(body) == 3 and body[1] == "Site"
