"""A small seeded mutation fuzzer for the file readers (issue 9, section 3).

Every mutant is a pure function of ``(seed bytes, format, integer seed)``: the same
call gives the same bytes on every machine and Python version (``random.Random``
seeded with an int; no ``hash()``).  A mutant is 1-3 stacked operators:

* byte level: bit flips, "interesting" byte overwrites, truncation, non-UTF-8 bytes,
  CRLF / CR line endings;
* token level (whitespace-separated tokens and lines): deletion, duplication, line
  deletion / duplication / swap;
* number swaps: a numeric token replaced by ``nan``, ``inf``, ``-inf``, ``1e309``,
  ``1e308``, ``1.7e308``, ``1e-320``, huge counts (``10000000``, ``99999999999``),
  a 4,400-digit integer, ``1_0``, ``²``, ``+-5`` ...;
* format-aware: a 2,000-deep chain of ``JOINT`` blocks (BVH, ``CHANNELS 0`` so the frame
  lines still fit), of bones (ASF), of JSON lists/objects (manifest, npz header);
  ``Frames:`` / ``CHANNELS`` counts; for ``.npz`` files, member-level mutations (a
  member deleted, replaced by NaN/inf/huge values, another dtype or shape, a lying
  ``.npy`` shape header, the JSON header mutated as text);
* glTF: a ``.gltf`` is mutated as JSON text; a ``.glb`` either as raw bytes or chunk-aware
  (its JSON chunk pretty-printed and mutated as JSON text, or values of its BIN chunk
  overwritten with NaN / inf / 3.4e38 / huge indices), then framed again with correct
  lengths so that the mutation reaches the reader past the GLB framing checks;
* wrapping: ``.gz`` (also truncated, with trailing garbage).

:func:`mutant` returns ``(data, suffix, description)``; ``description`` is what a
developer needs to reproduce it (``mutant(seed_data, fmt, n)`` gives it back).
"""

from __future__ import annotations

import gzip
import io
import json
import random
import re
import zipfile

__all__ = ["mutant", "NUMBERS", "FORMATS", "deep_bvh", "deep_asf", "deep_json"]

#: Replacements for numeric tokens.
NUMBERS = [
    "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e309", "-1e309", "1e308", "1.7e308", "-1.7e308",
    "1e-320", "5e-324", "-1e-320", "0", "-0", "-1", "1", "10000000", "99999999999", "2147483648",
    "18446744073709551617", "-99999999999", "9" * 4400, "1_0", "\u00b2", "+-5", "0x10", "1e", "-", ".", "1.5",
    "\u0661", "1e-5", "1e+5",
]
#: Bytes that mean something to the readers.
INTERESTING_BYTES = b"\x00\xff{}\n\r\t -.e#:/\\\x80"
NON_UTF8 = [b"\xff", b"\xfe\xff", b"\xc3\x28", b"\x80", b"\xed\xa0\x80", b"\xf8\x88\x80\x80\x80", b"\xe9"]

#: Formats :func:`mutant` knows; ``gz``: whether gzip wrapping applies.
FORMATS = {
    "bvh": {"suffix": ".bvh", "gz": True},
    "asf": {"suffix": ".asf", "gz": True},
    "amc": {"suffix": ".amc", "gz": True},
    "obj": {"suffix": ".obj", "gz": True},
    "json": {"suffix": ".json", "gz": False},
    "npz": {"suffix": ".npz", "gz": False},
    "gltf": {"suffix": ".gltf", "gz": False},
    "glb": {"suffix": ".glb", "gz": False},
}

_NUMBER_RE = re.compile(rb"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
_TOKEN_RE = re.compile(rb"\S+")
DEPTH = 2000


# ------------------------------------------------------------------ byte level
def _flip(r: random.Random, d: bytes) -> tuple[bytes, str]:
    if not d:
        return d, "flip(empty)"
    b = bytearray(d)
    where = []
    for _ in range(r.randint(1, 8)):
        i = r.randrange(len(b))
        bit = r.randrange(8)
        b[i] ^= 1 << bit
        where.append(f"{i}^{1 << bit}")
    return bytes(b), "flip " + ",".join(where)


def _byte_set(r: random.Random, d: bytes) -> tuple[bytes, str]:
    if not d:
        return d, "byte_set(empty)"
    b = bytearray(d)
    i = r.randrange(len(b))
    v = r.choice(INTERESTING_BYTES)
    b[i] = v
    return bytes(b), f"byte_set [{i}]={v:#x}"


def _truncate(r: random.Random, d: bytes) -> tuple[bytes, str]:
    n = r.randrange(len(d) + 1)
    return d[:n], f"truncate to {n} bytes"


def _non_utf8(r: random.Random, d: bytes) -> tuple[bytes, str]:
    i = r.randrange(len(d) + 1)
    junk = r.choice(NON_UTF8)
    return d[:i] + junk + d[i:], f"insert {junk!r} at {i}"


def _line_endings(r: random.Random, d: bytes) -> tuple[bytes, str]:
    kind = r.choice(["crlf", "cr", "mixed", "lfcr"])
    if kind == "crlf":
        return d.replace(b"\n", b"\r\n"), "line endings CRLF"
    if kind == "cr":
        return d.replace(b"\n", b"\r"), "line endings CR"
    if kind == "lfcr":
        return d.replace(b"\n", b"\n\r"), "line endings LF CR"
    lines = d.split(b"\n")
    out = b"".join(ln + r.choice([b"\n", b"\r\n", b"\r"]) for ln in lines[:-1]) + lines[-1]
    return out, "line endings mixed"


# ------------------------------------------------------------------ token level
def _spans(regex, d: bytes) -> list[tuple[int, int]]:
    return [m.span() for m in regex.finditer(d)]


def _token_delete(r: random.Random, d: bytes) -> tuple[bytes, str]:
    sp = _spans(_TOKEN_RE, d)
    if not sp:
        return d, "token_delete(none)"
    k = r.randrange(len(sp))
    a, b = sp[k]
    return d[:a] + d[b:], f"delete token {k} {d[a:b][:40]!r}"


def _token_duplicate(r: random.Random, d: bytes) -> tuple[bytes, str]:
    sp = _spans(_TOKEN_RE, d)
    if not sp:
        return d, "token_duplicate(none)"
    k = r.randrange(len(sp))
    a, b = sp[k]
    times = r.choice([1, 1, 2, 50])
    return d[:b] + (b" " + d[a:b]) * times + d[b:], f"duplicate token {k} {d[a:b][:40]!r} x{times}"


def _line_op(r: random.Random, d: bytes) -> tuple[bytes, str]:
    lines = d.split(b"\n")
    if len(lines) < 2:
        return d, "line_op(one line)"
    op = r.choice(["delete", "duplicate", "swap", "delete_block", "duplicate_block"])
    i = r.randrange(len(lines))
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(i, lines[i])
    elif op == "swap":
        j = r.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        op = f"swap with {j}"
    elif op == "delete_block":
        n = r.randint(2, 40)
        del lines[i:i + n]
        op = f"delete {n} lines from"
    else:
        n = r.randint(2, 20)
        lines[i:i] = lines[i:i + n] * r.choice([1, 3])
        op = f"duplicate {n} lines from"
    return b"\n".join(lines), f"line {op} {i + 1}"


def _number_swap(r: random.Random, d: bytes) -> tuple[bytes, str]:
    sp = _spans(_NUMBER_RE, d)
    if not sp:
        return d, "number_swap(none)"
    out = d
    desc = []
    for _ in range(r.choice([1, 1, 1, 2, 3])):
        sp = _spans(_NUMBER_RE, out)
        if not sp:
            break
        k = r.randrange(len(sp))
        a, b = sp[k]
        new = r.choice(NUMBERS).encode("utf-8")
        desc.append(f"number {k} {out[a:b][:20]!r}->{new[:20]!r}{'...' if len(new) > 20 else ''}")
        out = out[:a] + new + out[b:]
    return out, "; ".join(desc)


# ------------------------------------------------------------------ format level
def deep_bvh(depth: int = DEPTH) -> bytes:
    """A chain of ``depth`` joints without channels (inserted after a joint's CHANNELS line)."""
    opens = "".join(f"JOINT fz{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n" for i in range(depth))
    return (opens + "End Site\n{\nOFFSET 0 1 0\n}\n" + "}\n" * depth).encode()


def _bvh_deep(r: random.Random, d: bytes) -> tuple[bytes, str]:
    sp = [m.end() for m in re.finditer(rb"CHANNELS[^\n]*\n", d)]
    if not sp:
        return d, "bvh_deep(no CHANNELS)"
    k = r.randrange(len(sp))
    depth = r.choice([DEPTH, DEPTH, 200])
    return d[: sp[k]] + deep_bvh(depth) + d[sp[k]:], f"insert a {depth}-deep JOINT chain after CHANNELS line #{k}"


def _bvh_counts(r: random.Random, d: bytes) -> tuple[bytes, str]:
    which = r.choice(["frames", "channels", "frame_time"])
    if which == "frames":
        new = r.choice(["10000000", "9999999", "99999999999", "-1", "0", "9" * 4400, "1e3", "2147483648"])
        return re.sub(rb"Frames:[^\n]*", b"Frames: " + new.encode(), d, count=1), f"Frames: {new[:20]}"
    if which == "frame_time":
        new = r.choice(["1e-320", "0", "-0.01", "5e-324", "1e308", "1e-300", "nan", "inf"])
        return re.sub(rb"Frame Time:[^\n]*", b"Frame Time: " + new.encode(), d, count=1), f"Frame Time: {new}"
    sp = [m.span() for m in re.finditer(rb"CHANNELS[ \t]+\d+", d)]
    if not sp:
        return d, "bvh_counts(no CHANNELS)"
    a, b = sp[r.randrange(len(sp))]
    new = r.choice(["0", "-1", "7", "10000000", "99999999999"])
    return d[:a] + b"CHANNELS " + new.encode() + d[b:], f"CHANNELS at byte {a} -> {new}"


def _bvh_no_channels(r: random.Random, d: bytes) -> tuple[bytes, str]:
    """Every joint ``CHANNELS 0``, no frame lines, a large ``Frames:`` (nothing to read, much to allocate)."""
    head, sep, _ = d.partition(b"MOTION")
    if not sep:
        return d, "bvh_no_channels(no MOTION)"
    head = re.sub(rb"CHANNELS[^\n]*", b"CHANNELS 0", head)
    frames = r.choice(["10000000", "9999999", "1000000", "5000000"])
    return head + b"MOTION\nFrames: " + frames.encode() + b"\nFrame Time: 0.0083333\n", \
        f"all CHANNELS 0, no frame lines, Frames: {frames}"


def deep_asf(depth: int = DEPTH) -> tuple[bytes, bytes]:
    """(bonedata blocks, hierarchy lines) of a chain of ``depth`` dof-less bones under root."""
    bones = "".join(f"  begin\n     id {1000 + i}\n     name fz{i}\n     direction 0 1 0\n     length 1\n"
                    f"     axis 0 0 0 XYZ\n  end\n" for i in range(depth))
    hier = "    root fz0\n" + "".join(f"    fz{i} fz{i + 1}\n" for i in range(depth - 1))
    return bones.encode(), hier.encode()


def _asf_deep(r: random.Random, d: bytes) -> tuple[bytes, str]:
    h = d.find(b":hierarchy")
    b = d.find(b"begin", h) if h >= 0 else -1
    if h < 0 or b < 0:
        return d, "asf_deep(no :hierarchy)"
    eol = d.find(b"\n", b) + 1
    depth = r.choice([DEPTH, DEPTH, 200])
    bones, hier = deep_asf(depth)
    return d[:h] + bones + d[h:eol] + hier + d[eol:], f"insert a {depth}-deep bone chain"


def deep_json(depth: int = DEPTH, kind: str = "list") -> bytes:
    if kind == "list":
        return b"[" * depth + b"1" + b"]" * depth
    return b'{"a":' * depth + b"1" + b"}" * depth


def _json_deep(r: random.Random, d: bytes) -> tuple[bytes, str]:
    depth = r.choice([DEPTH, DEPTH, 100000])
    kind = r.choice(["list", "dict"])
    deep = deep_json(depth, kind)
    sp = [m.span() for m in re.finditer(rb'(?<=: )(?:"[^"\n]*"|[-\d.eE+]+|true|false|null|\[\]|\{\})', d)]
    if not sp or r.random() < 0.3:
        return deep, f"whole document a {depth}-deep JSON {kind}"
    a, b = sp[r.randrange(len(sp))]
    return d[:a] + deep + d[b:], f"value at byte {a} -> {depth}-deep JSON {kind}"


def _json_value(r: random.Random, d: bytes) -> tuple[bytes, str]:
    """Replace a JSON value (or the document) by a value of another type."""
    values = [b"[]", b"null", b"{}", b"3", b'"x"', b"true", b"[1, 2]", b'{"file": 3}', b'[{"file": null}]',
              b"NaN", b"Infinity", b"1e400", b'"' + b"\\ud800" + b'"', b'{"fig4_axis_selection": 3}']
    new = r.choice(values)
    sp = [m.span() for m in re.finditer(rb'(?<=: )(?:"[^"\n]*"|[-\d.eE+]+|true|false|null|\[\]|\{\}|\[|\{)', d)]
    if not sp or r.random() < 0.25:
        return new, f"whole document -> {new!r}"
    a, b = sp[r.randrange(len(sp))]
    if d[a:b] in (b"[", b"{"):  # replace the whole container: find its matching close
        depth, j = 0, a
        while j < len(d):
            c = d[j:j + 1]
            if c in (b"[", b"{"):
                depth += 1
            elif c in (b"]", b"}"):
                depth -= 1
                if depth == 0:
                    break
            j += 1
        b = j + 1
    return d[:a] + new + d[b:], f"JSON value at byte {a} ({d[a:b][:30]!r}) -> {new!r}"


_TEXT_OPS = [(_flip, 2), (_byte_set, 2), (_truncate, 2), (_non_utf8, 1), (_line_endings, 1),
             (_token_delete, 3), (_token_duplicate, 2), (_line_op, 3), (_number_swap, 6)]
_FORMAT_OPS = {
    "bvh": [(_bvh_deep, 1), (_bvh_counts, 3), (_bvh_no_channels, 1)],
    "asf": [(_asf_deep, 1)],
    "amc": [],
    "obj": [],
    "json": [(_json_deep, 2), (_json_value, 4)],
    "gltf": [(_json_deep, 1), (_json_value, 5)],
}


def _pick(r: random.Random, ops):
    total = sum(w for _, w in ops)
    x = r.uniform(0, total)
    for op, w in ops:
        x -= w
        if x <= 0:
            return op
    return ops[-1][0]


def _text_mutant(r: random.Random, d: bytes, fmt: str) -> tuple[bytes, list[str]]:
    ops = _TEXT_OPS + _FORMAT_OPS.get(fmt, [])
    desc = []
    for _ in range(r.choice([1, 1, 1, 2, 2, 3])):
        d, what = _pick(r, ops)(r, d)
        desc.append(what)
    return d, desc


# ------------------------------------------------------------------ npz members
def _npy_bytes(a) -> bytes:
    import numpy as np

    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def _zip(members: list[tuple[str, bytes]]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members:
            z.writestr(name, data)
    return buf.getvalue()


def _npz_mutant(r: random.Random, d: bytes) -> tuple[bytes, list[str]]:
    import numpy as np

    try:
        with zipfile.ZipFile(io.BytesIO(d)) as z:
            members = [(i.filename, z.read(i)) for i in z.infolist()]
    except (zipfile.BadZipFile, OSError, EOFError):
        members = []
    if not members or r.random() < 0.2:
        d2, desc = _text_mutant(r, d, "npz")  # raw bytes of the zip
        return d2, ["raw: " + x for x in desc]
    desc = []
    for _ in range(r.choice([1, 1, 2])):
        k = r.randrange(len(members))
        name, data = members[k]
        op = r.choice(["delete", "values", "values", "dtype", "shape", "npy_header", "raw", "header_text",
                       "header_text", "header_json", "rename", "extra"])
        if name == "header.npy" and r.random() < 0.6:
            op = r.choice(["header_text", "header_json", "header_json"])
        try:
            a = np.load(io.BytesIO(data), allow_pickle=False)
        except Exception:  # noqa: BLE001 - an already-mutated member
            a = None
        if op == "delete":
            del members[k]
            desc.append(f"delete member {name}")
            continue
        if op == "rename":
            members[k] = (name.replace(".npy", "x.npy"), data)
            desc.append(f"rename member {name}")
            continue
        if op == "extra":
            members.append(("zzextra.npy", _npy_bytes(np.zeros(3))))
            desc.append("add member zzextra.npy")
            continue
        if op == "raw" or a is None:
            new, what = _pick(r, _TEXT_OPS)(r, data)
            members[k] = (name, new)
            desc.append(f"member {name}: {what}")
            continue
        if op in ("header_text", "header_json") and a.dtype.kind == "U" and a.ndim == 0:
            text = str(a).encode("utf-8")
            if op == "header_json":
                text, what = r.choice([_json_value, _json_value, _json_deep, _number_swap])(r, text)
            else:
                text, w = _text_mutant(r, text, "json")
                what = "; ".join(w)
            try:
                s = text.decode("utf-8")
            except UnicodeDecodeError:
                s = text.decode("latin-1")
            members[k] = (name, _npy_bytes(np.array(s)))
            desc.append(f"member {name} text: {what}")
            continue
        if op == "values":
            v = r.choice([np.nan, np.inf, -np.inf, 1e308, -1e308, 1e300, 0.0, -1.0, 10_000_000, 2**62, -(2**62)])
            b = np.array(a, copy=True)
            if b.size and b.dtype.kind in "fiub":
                flat = b.reshape(-1)
                idx = r.randrange(flat.size)
                try:
                    with np.errstate(all="ignore"):
                        flat[idx] = v
                except (OverflowError, ValueError):
                    flat[idx] = -1
                members[k] = (name, _npy_bytes(b))
                desc.append(f"member {name}[{idx}] = {v}")
            elif b.dtype.kind == "U":
                members[k] = (name, _npy_bytes(np.array(r.choice(["", "[1", "null", "[]", "{}", "nan"]))))
                desc.append(f"member {name} string replaced")
            continue
        if op == "dtype":
            new = r.choice([np.array("abc"), np.array(["a", "b"]), np.zeros(a.shape, np.float32),
                            np.zeros(a.shape, np.int8), np.zeros(a.shape, complex), np.array(b"bytes"),
                            np.zeros(a.shape, bool), np.array(3.5)])
            members[k] = (name, _npy_bytes(new))
            desc.append(f"member {name} -> dtype {new.dtype} shape {new.shape}")
            continue
        if op == "shape":
            flat = np.asarray(a).reshape(-1)
            new = r.choice([flat, flat[: max(0, flat.size - 1)], np.concatenate([flat, flat[:1]]),
                            flat[:0], np.asarray(a)[..., None] if np.ndim(a) else flat, flat.reshape(1, -1)])
            members[k] = (name, _npy_bytes(new))
            desc.append(f"member {name} shape {np.shape(a)} -> {new.shape}")
            continue
        if op == "npy_header":
            # the .npy header claims another shape than the data holds (e.g. 10**10 items)
            shape = r.choice(["(10000000000,)", "(99999999999, 3)", "(0,)", "(2, 2)", "(-1,)", "(4611686018427387904,)"])
            new = re.sub(rb"'shape': \([^)]*\)", b"'shape': " + shape.encode(), data, count=1)
            members[k] = (name, new)
            desc.append(f"member {name} .npy header shape -> {shape}")
            continue
    return _zip(members), desc


# ------------------------------------------------------------------ glb chunks
#: 4-byte values written over BIN chunk data: float32 NaN, +-inf, 3.4e38, -0; uint32 / uint16 huge indices.
_BIN_VALUES = [b"\x00\x00\xc0\x7f", b"\x00\x00\x80\x7f", b"\x00\x00\x80\xff", b"\x99\x76\x7f\x7f",
               b"\x00\x00\x00\x80", b"\xff\xff\xff\xff", b"\xff\xff\x00\x00", b"\x00\x00\x00\x00"]


def _glb_chunks(d: bytes):
    """(JSON text, BIN bytes or None) of a well-framed GLB, else None."""
    import struct

    if len(d) < 20 or d[:4] != b"glTF":
        return None
    n, kind = struct.unpack_from("<II", d, 12)
    if kind != 0x4E4F534A or 20 + n > len(d):
        return None
    js = d[20:20 + n]
    rest = d[20 + n:]
    if len(rest) >= 8:
        m, kind = struct.unpack_from("<II", rest, 0)
        if kind == 0x004E4942 and 8 + m <= len(rest):
            return js, rest[8:8 + m]
    return js, None


def _glb_frame(js: bytes, bin_: bytes | None) -> bytes:
    import struct

    js = js + b" " * (-len(js) % 4)
    out = struct.pack("<II", len(js), 0x4E4F534A) + js
    if bin_ is not None:
        bin_ = bin_ + b"\x00" * (-len(bin_) % 4)
        out += struct.pack("<II", len(bin_), 0x004E4942) + bin_
    return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


def _glb_mutant(r: random.Random, d: bytes) -> tuple[bytes, list[str]]:
    chunks = _glb_chunks(d)
    if chunks is None or r.random() < 0.25:
        ops = [(_flip, 3), (_byte_set, 2), (_truncate, 2), (_non_utf8, 1)]
        desc = []
        for _ in range(r.choice([1, 1, 2])):
            d, what = _pick(r, ops)(r, d)
            desc.append("raw: " + what)
        return d, desc
    js, bin_ = chunks
    if bin_ and r.random() < 0.3:
        b = bytearray(bin_)
        desc = []
        for _ in range(r.choice([1, 1, 3, 20])):
            i = r.randrange(max(1, len(b) // 4)) * 4
            v = r.choice(_BIN_VALUES)
            b[i:i + 4] = v
            desc.append(f"{i}={v.hex()}")
        return _glb_frame(js, bytes(b)), ["BIN chunk: " + ",".join(desc[:5]) + ("..." if len(desc) > 5 else "")]
    try:
        text = json.dumps(json.loads(js), indent=1).encode()  # ': ' separators for the JSON operators
    except ValueError:
        text = js
    text, desc = _text_mutant(r, text, "gltf")
    return _glb_frame(text, bin_), ["JSON chunk: " + x for x in desc]


# ------------------------------------------------------------------ entry point
def _gzip(r: random.Random, d: bytes) -> tuple[bytes, str]:
    g = gzip.compress(d, mtime=0)
    kind = r.choice(["plain", "plain", "plain", "truncated", "garbage", "double"])
    if kind == "truncated":
        n = r.randrange(len(g))
        return g[:n], f"gzip, truncated to {n} bytes"
    if kind == "garbage":
        return g + b"\x00junk", "gzip + trailing garbage"
    if kind == "double":
        return gzip.compress(g, mtime=0), "gzip twice"
    return g, "gzip"


def mutant(seed_data: bytes, fmt: str, n: int) -> tuple[bytes, str, str]:
    """Mutant number ``n`` of ``seed_data`` (format ``fmt``): ``(bytes, file suffix, description)``."""
    r = random.Random(n * 1_000_003 + sum(fmt.encode()))
    if fmt == "npz":
        d, desc = _npz_mutant(r, seed_data)
    elif fmt == "glb":
        d, desc = _glb_mutant(r, seed_data)
    else:
        d, desc = _text_mutant(r, seed_data, fmt)
    suffix = FORMATS[fmt]["suffix"]
    if FORMATS[fmt]["gz"] and r.random() < 0.1:
        d, what = _gzip(r, d)
        desc.append(what)
        suffix += ".gz"
    return d, suffix, " | ".join(desc)
