"""A mutator of the glTF JSON structure (issue 23, section 8), beside the byte mutators of :mod:`tests.fuzz.mutate`.

Byte mutants rarely make a well-formed document that lies: this mutator edits the parsed
JSON of the glTF fixtures (``tests/data/gltf``, each GLB turned into a ``.gltf`` with its
buffer in a ``.bin`` file beside it) the way a hostile file would:

* accessor aliasing (every target of many primitives pointing at one accessor), zero-filled
  accessors (no ``bufferView``) of huge counts, counts of every type and size;
* sparse accessors (counts, indices out of range or unsorted, their views and offsets);
* ``bufferViews`` offsets, lengths and strides; ``buffers[].byteLength``;
* buffer ``uri``s with ``..``, percent-encoding, absolute paths, ``file:``, paths climbing to
  ``/etc/passwd``, ``/proc/self/environ`` or ``/dev/zero``, symlinks out of (and inside) the
  folder, FIFOs and folders;
* node counts, cycles and references; mesh, primitive and target counts; many objects; long
  lists inside objects (an accessor's ``max``, a node's children, a mesh's weights).

:func:`structure_mutant` is deterministic: mutant ``n`` is a function of ``n`` only.  It
returns the document, the files to lay out beside it (bytes, or the special files
``("fifo",)``, ``("dir",)``, ``("symlink", target)``) and whether the document names a file
outside its folder (``escapes``: then loading it must be refused).  The folder's parent holds
:data:`SENTINEL_NAME`, a valid buffer for the ``face`` seed whose positions are all
:data:`SENTINEL_VALUE`: a model built from it would show that a read left the folder.
"""

from __future__ import annotations

import base64
import json
import random
import struct
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
GLTF_DIR = REPO / "tests" / "data" / "gltf"
GLB_SEEDS = ("face.glb", "face_quantized.glb", "face_sparse.glb", "face_meshopt.glb", "face_node.glb",
             "face_meshes.glb", "face_gltfpack.glb")
#: The file planted beside (outside) each mutant's folder, and the value of all its positions.
SENTINEL_NAME = "outside.bin"
SENTINEL_VALUE = 4242.0

_HUGE = (2**31, 2**32 + 3, 2**53, 2**63, 2**64 + 1, 10**30)
_ODD = (-1, 0, None, True, 1.5, "3", [1], {"a": 1})


def _glb_parts(data: bytes) -> tuple[dict, bytes | None]:
    length = struct.unpack_from("<I", data, 8)[0]
    pos, js, bin_ = 12, None, None
    while pos + 8 <= length:
        clen, ctype = struct.unpack_from("<II", data, pos)
        chunk = data[pos + 8 : pos + 8 + clen]
        if ctype == 0x4E4F534A:
            js = json.loads(chunk)
        elif ctype == 0x004E4942 and bin_ is None:
            bin_ = chunk
        pos += 8 + clen
    return js, bin_


def seeds() -> list[tuple[str, dict, dict[str, bytes]]]:
    """``(name, document, {file name: bytes})`` of the fixtures, every buffer in a file beside the document."""
    out = [("face", json.loads((GLTF_DIR / "face.gltf").read_text()), {"face.bin": (GLTF_DIR / "face.bin").read_bytes()})]
    for name in GLB_SEEDS:
        doc, bin_ = _glb_parts((GLTF_DIR / name).read_bytes())
        stem = name.removesuffix(".glb")
        files = {}
        for b in doc.get("buffers", []):
            if "uri" not in b and bin_ is not None and not files:
                b["uri"] = f"{stem}.bin"
                files[b["uri"]] = bin_
        out.append((stem, doc, files))
    return out


def sentinel_bytes() -> bytes:
    """The ``face`` seed's buffer with every POSITION of its neutral set to :data:`SENTINEL_VALUE`."""
    doc = json.loads((GLTF_DIR / "face.gltf").read_text())
    data = bytearray((GLTF_DIR / "face.bin").read_bytes())
    acc = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    view = doc["bufferViews"][acc["bufferView"]]
    off = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    n = acc["count"] * 3
    data[off : off + 4 * n] = np.full(n, SENTINEL_VALUE, dtype="<f4").tobytes()
    return bytes(data)


# ------------------------------------------------------------------ mutations
#: A mutation that would make the document's JSON larger than this is skipped (mutants stay small:
#: the reader's bounds, not the size of the file, are under test).
MAX_JSON = 4 << 20


def _fits(doc, part, factor: int) -> bool:
    """Whether repeating ``part`` ``factor`` times keeps the document under :data:`MAX_JSON`."""
    return len(json.dumps(doc)) + len(json.dumps(part)) * factor <= MAX_JSON

def _prims(doc):
    return [p for m in doc.get("meshes", []) for p in m.get("primitives", [])]


def _target_prim(r, doc):
    prims = [p for p in _prims(doc) if p.get("targets")]
    return r.choice(prims) if prims else None


def _alias(r, doc, files, ctx):
    p = _target_prim(r, doc)
    if p is None:
        return "alias: no targets"
    a = r.choice([p["attributes"]["POSITION"]] + [t.get("POSITION") for t in p["targets"] if "POSITION" in t])
    p["targets"] = [dict(t, POSITION=a) for t in p["targets"]]
    k = r.choice([1, 2, 10, 20, 40])
    if not _fits(doc, p, k):
        k = 1
    for m in doc["meshes"]:
        if p in m["primitives"]:
            m["primitives"] = [p] * k
    return f"alias: every target -> accessor {a}, {k} primitives sharing it"


def _zero_fill(r, doc, files, ctx):
    p = _target_prim(r, doc)
    if p is None:
        return "zero_fill: no targets"
    a = p["attributes"]["POSITION"]
    count = r.choice([87_000, 10**6, 2**31, doc["accessors"][a]["count"]])
    doc["accessors"][a] = {"componentType": 5126, "type": "VEC3", "count": count}
    p["targets"] = [{"POSITION": a}] * r.choice([len(p["targets"]), 32, 200])
    p.pop("indices", None)
    if r.random() < 0.5 and _fits(doc, p, 20):
        for m in doc["meshes"]:
            if p in m["primitives"]:
                m["primitives"] = [p] * r.choice([10, 20])
    return f"zero_fill: accessor {a} of {count} zero vertices for every target"


def _count(r, doc, files, ctx):
    i = r.randrange(len(doc["accessors"]))
    c = doc["accessors"][i].get("count", 1) if isinstance(doc["accessors"][i].get("count"), int) else 1
    v = r.choice([c - 1, c + 1, 2 * c, 1, *_HUGE, *_ODD])
    doc["accessors"][i]["count"] = v
    return f"count: accessors[{i}].count = {v!r}"


def _data_uri(b: bytes) -> str:
    return "data:application/octet-stream;base64," + base64.b64encode(b).decode()


def _sparse(r, doc, files, ctx):
    i = r.randrange(len(doc["accessors"]))
    acc = doc["accessors"][i]
    count = acc.get("count", 1) if isinstance(acc.get("count"), int) else 1
    n = r.choice([1, 2, 3, count, count + 1, 2**40, 0, -1, None])
    kind = r.choice(["out_of_range", "unsorted", "repeated", "fine", "views"])
    idx = {"out_of_range": [0, 1, count + 5], "unsorted": [2, 0, 1], "repeated": [1, 1, 2],
           "fine": [0, 1, 2], "views": [0, 1, 2]}[kind]
    idx_bytes = np.array((idx * 4)[: max(1, min(abs(n) if isinstance(n, int) else 3, 12))], dtype="<u4").tobytes()
    vals = np.full(3 * 4 * 12, 0.5, dtype="<f4").tobytes()
    doc.setdefault("buffers", []).append({"uri": _data_uri(idx_bytes + vals), "byteLength": len(idx_bytes) + len(vals)})
    b = len(doc["buffers"]) - 1
    doc.setdefault("bufferViews", []).append({"buffer": b, "byteOffset": 0, "byteLength": len(idx_bytes)})
    doc["bufferViews"].append({"buffer": b, "byteOffset": len(idx_bytes), "byteLength": len(vals)})
    vi, vv = len(doc["bufferViews"]) - 2, len(doc["bufferViews"]) - 1
    sp = {"count": n, "indices": {"bufferView": vi, "componentType": r.choice([5125, 5125, 5123, 5126, 1])},
          "values": {"bufferView": vv}}
    if kind == "views":
        sp["indices"]["byteOffset"] = r.choice([4, 1 << 20, -4, 2**64])
        sp["values"]["bufferView"] = r.choice([vv, 10**6, -1, None])
    acc["sparse"] = sp
    if r.random() < 0.5:
        acc.pop("bufferView", None)
    return f"sparse: accessors[{i}] {kind}, count {n!r}, componentType {sp['indices']['componentType']}"


def _view(r, doc, files, ctx):
    if not doc.get("bufferViews"):
        return "view: none"
    i = r.randrange(len(doc["bufferViews"]))
    bv = doc["bufferViews"][i]
    key = r.choice(["byteOffset", "byteLength", "byteStride", "buffer"])
    cur = bv.get(key, 0) if isinstance(bv.get(key, 0), int) else 0
    v = r.choice([cur - 1, cur + 1, cur + 4, 3, 4, 252, 256, *_HUGE[:3], *_ODD])
    bv[key] = v
    return f"view: bufferViews[{i}].{key} = {v!r}"


def _byte_length(r, doc, files, ctx):
    if not doc.get("buffers"):
        return "byte_length: no buffers"
    b = doc["buffers"][0]
    cur = b.get("byteLength", 0) if isinstance(b.get("byteLength"), int) else 0
    v = r.choice([cur - 1, cur + 1, 1, 2**31, 2**62, *_ODD])
    b["byteLength"] = v
    return f"byte_length: buffers[0].byteLength = {v!r}"


def _uri(r, doc, files, ctx):
    bufs = [b for b in doc.get("buffers", []) if isinstance(b.get("uri"), str) and not b["uri"].startswith("data:")]
    if not bufs:
        return "uri: no external buffer", False
    b = bufs[0]
    own = b["uri"]
    ups = "../" * ctx["depth"]
    choices = [
        ("../" + SENTINEL_NAME, True), ("%2e%2e/" + SENTINEL_NAME, True), ("%2E%2E%2F" + SENTINEL_NAME, True),
        ("sub/../../" + SENTINEL_NAME, True), ("./../" + SENTINEL_NAME, True),
        (ups + "etc/passwd", True), (ups.replace("..", "%2e%2e") + "etc/passwd", True),
        (ups + "proc/self/environ", True), (ups + "dev/zero", True), (ups + "dev/urandom", True),
        (str(ctx["sentinel"]), True), ("file://" + str(ctx["sentinel"]), True), ("//" + SENTINEL_NAME, True),
        ("link.bin", "symlink_out"), ("link.bin", "symlink_in"), ("link.bin", "symlink_zero"),
        ("pipe.bin", "fifo"), ("dir.bin", "dir"), ("", False), ("missing.bin", False), ("a%00b.bin", False),
        ("x" * 5000, False), ("data:application/octet-stream;base64,!!!", False), (123, False), (None, False),
    ]
    uri, how = r.choice(choices)
    if how == "symlink_out":
        files["link.bin"] = ("symlink", str(ctx["sentinel"]))
    elif how == "symlink_zero":
        files["link.bin"] = ("symlink", "/dev/zero")
    elif how == "symlink_in":
        files["link.bin"] = ("symlink", own)
    elif how in ("fifo", "dir"):
        files[uri] = (how,)
    escapes = how is True or how in ("symlink_out", "symlink_zero")
    if uri is None:
        b.pop("uri")
    else:
        b["uri"] = uri
    return f"uri: {uri!r:.80} ({how})", escapes


def _nodes(r, doc, files, ctx):
    kind = r.choice(["many", "too_many", "huge", "cycle", "bad_child", "bad_mesh"])
    nodes = doc.setdefault("nodes", [{"mesh": 0}])
    if kind in ("many", "too_many", "huge"):
        k = {"many": 500, "too_many": 4097, "huge": 100_000}[kind]
        nodes += [{"name": f"n{i}"} for i in range(k)]
        if r.random() < 0.5:  # a chain (deep hierarchy)
            base = len(nodes) - k
            for i in range(base, len(nodes) - 1):
                nodes[i]["children"] = [i + 1]
    elif kind == "cycle":
        nodes[0]["children"] = [0]
    elif kind == "bad_child":
        nodes[0]["children"] = [r.choice([len(nodes), -1, 2**40, "1", None])]
    else:
        nodes[0]["mesh"] = r.choice([len(doc.get("meshes", [])), -1, "0", None, 2**64])
    return f"nodes: {kind} ({len(nodes)} nodes)"


def _meshes(r, doc, files, ctx):
    kind = r.choice(["meshes", "too_many_meshes", "primitives", "too_many_primitives", "objects"])
    factor = {"meshes": 60, "too_many_meshes": 1025, "primitives": 200, "too_many_primitives": 4097}.get(kind, 1)
    if not _fits(doc, doc["meshes"][0] if kind.endswith("primitives") else doc["meshes"], factor):
        return f"meshes: {kind} skipped (too big)"
    if kind == "meshes":
        doc["meshes"] = doc["meshes"] * 60
    elif kind == "too_many_meshes":
        doc["meshes"] = doc["meshes"] * 1025
    elif kind == "primitives":
        doc["meshes"][0]["primitives"] = doc["meshes"][0]["primitives"] * 200
    elif kind == "too_many_primitives":
        doc["meshes"][0]["primitives"] = doc["meshes"][0]["primitives"] * 4097
    else:
        doc["materials"] = [{"name": f"m{i}"} for i in range(r.choice([300, 12_001, 50_000]))]
    return f"meshes: {kind}"


def _targets(r, doc, files, ctx):
    p = _target_prim(r, doc)
    if p is None:
        return "targets: none"
    k = r.choice([0, 1, 600, 1024, 1025, 60_000])
    shared = sum(q is p for q in _prims(doc))  # a primitive repeated by reference grows with each copy
    if not _fits(doc, p["targets"][:1], k * shared):
        return f"targets: {k} targets skipped (too big)"
    p["targets"] = (p["targets"] * (k // max(1, len(p["targets"])) + 1))[:k]
    if r.random() < 0.5:
        for m in doc["meshes"]:
            if p in m["primitives"]:
                m.setdefault("extras", {})["targetNames"] = [f"t{i}" for i in range(r.choice([k, k + 1]))]
    return f"targets: {k} targets"


def _long_list(r, doc, files, ctx):
    """A long list inside an object (pygltflib converts each value): an accessor's max, children, weights ..."""
    k = r.choice([50, 5000, 100_001, 300_000])
    where = r.choice(["accessor_max", "children", "scene_nodes", "weights", "attributes"])
    if where == "accessor_max":
        doc["accessors"][0]["max"] = [1.0] * k
    elif where == "children":
        doc.setdefault("nodes", [{}])[0]["children"] = [0] * k
    elif where == "scene_nodes":
        doc["scenes"] = [{"nodes": [0] * k}]
    elif where == "weights":  # (on a copy: the mesh may be repeated by reference)
        doc["meshes"][0] = dict(doc["meshes"][0], weights=[0.0] * k)
    else:
        mesh = doc["meshes"][0] = dict(doc["meshes"][0])
        prim = dict(mesh["primitives"][0])
        prim["attributes"] = dict(prim["attributes"], **{f"_A{i}": 0 for i in range(k)})
        mesh["primitives"] = [prim] + mesh["primitives"][1:]
    return f"long_list: {where} of {k}"


MUTATIONS = (_alias, _zero_fill, _count, _sparse, _view, _byte_length, _uri, _uri, _nodes, _meshes, _targets, _long_list)


def structure_mutant(n: int, depth: int, sentinel: Path):
    """Mutant ``n``: ``(seed name, document, files, description, escapes)``; 1-3 structural mutations.

    ``depth``: how many ``..`` climb from the mutant's folder to ``/``; ``sentinel``: the absolute
    path of the planted outside file.
    """
    r = random.Random(n * 7919 + 17)
    all_seeds = seeds()
    name, doc, files = all_seeds[n % len(all_seeds)]
    ctx = {"depth": depth, "sentinel": sentinel}
    descs, escapes = [], False
    for _ in range(r.choice([1, 1, 2, 3])):
        out = r.choice(MUTATIONS)(r, doc, files, ctx)
        if isinstance(out, tuple):
            out, esc = out
            escapes = escapes or esc
        descs.append(out)
    return name, doc, files, "; ".join(descs), escapes


def lay_out(folder: Path, doc: dict, files: dict) -> Path:
    """Write the document as ``folder/face.gltf`` and its files (bytes or special files) beside it."""
    import os

    folder.mkdir(parents=True, exist_ok=True)
    for name, content in files.items():
        p = folder / name
        if isinstance(content, bytes):
            p.write_bytes(content)
        elif content[0] == "fifo":
            os.mkfifo(p)
        elif content[0] == "dir":
            p.mkdir()
        else:
            p.symlink_to(content[1])
    path = folder / "face.gltf"
    path.write_text(json.dumps(doc))
    return path
