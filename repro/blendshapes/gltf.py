"""glTF 2.0 blendshape faces in and out (morph targets of a mesh primitive).

A glTF face is a mesh primitive whose ``POSITION`` is the neutral ``f0`` and
whose morph ``targets`` hold the deltas ``d_k`` (glTF stores targets as
displacements, exactly the delta form of Lewis et al. 2005, Section 3), named
in ``mesh.extras.targetNames``.  :func:`read_gltf` turns such a file (``.gltf``
with its buffers, or ``.glb``) into a :class:`BlendshapeModel` in metres;
:func:`~repro.blendshapes.gltf_write.write_gltf` (``BlendshapeModel.to_gltf``) writes one back, optionally
with default weights and a weight animation, so a slider session opens in
Blender or a browser viewer.

Container library
-----------------
The JSON and GLB container is parsed with ``pygltflib`` (``GLTF2.from_json`` and
``GLTF2.load_from_bytes``; a GLB's framing -- magic, version, declared length, chunk
lengths -- is checked here first, because the library reports a cut file as a bare
``struct.error`` or reads it short) and the document is built with its dataclasses
and serialised by it (``gltf_to_json``) when writing: a thin,
maintained dataclass mapping of the glTF 2.0 schema that keeps every field,
extension and ``extras`` as written, and leaves the vertex data alone.
``trimesh`` (the other well-kept reader) was not chosen because its glTF
loader builds render meshes (vertices merged by default, one geometry per
primitive) and offers no morph-target basis or weight animation (its
maintainer: "there's no animation or skeletons implemented", mikedh/trimesh
#2026); merged vertices would break the vertex correspondence between the
neutral and its targets that a blendshape model depends on.  Accessors are decoded
here with numpy (strided views, bounds-checked against their buffer views),
so normalised integers (``KHR_mesh_quantization``) and sparse accessors follow
the spec's formulas; ``EXT_meshopt_compression`` buffer views are decoded with
the ``meshopt`` package (meshoptimizer's own codec).

What is read
------------
* The primitive with morph targets (the mesh with the most targets when
  several have some; eyes and teeth without targets are skipped), or the mesh
  named by ``mesh=`` (name or index).  Primitives of that mesh with the same
  number of targets are merged (exporters split a mesh by material), unless
  ``primitive=`` picks one.  The choice is recorded in the model's ``name``:
  ``"<file>:<mesh>/<primitives>"``.
* The mesh's world placement (node ``matrix`` or TRS, through the scene
  graph) is applied to the neutral; the deltas get its linear part.
* Targets' ``NORMAL`` and ``TANGENT`` are ignored.
* Names: ``mesh.extras.targetNames``, else the primitive's, else
  ``target_0, target_1, ...``.
* Sliders and regions: a file written by :func:`~repro.blendshapes.gltf_write.write_gltf` carries the
  model's own (``mesh.extras.repro``); any other face gets the paper's
  sliders through ARKit-style names and regions found from where the named
  shapes move (:func:`arkit_rig`).

Every problem with a file (not glTF, an HTML page saved as ``.glb``, a
truncated GLB, a missing buffer, an unsupported required extension, a
primitive that is not triangles, targets of the wrong length, out-of-bounds
accessors, NaN positions ...) is a :class:`~repro.errors.ModelError` naming the
file.  Nothing escapes the file's bounds (issue 23): a buffer is read only from a
regular file inside the file's folder, at most its ``byteLength``; the JSON's counts
are bounded before the document is built; and what the whole file may make the
loader allocate (every primitive, target and accessor, as float64) is summed and
checked against a cap before anything is allocated (:func:`_plan`).
"""

from __future__ import annotations

import json
import struct
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from repro.blendshapes.gltf_write import CHUNK_JSON, GLB_MAGIC
from repro.blendshapes.model import BlendshapeModel
from repro.checks import MEMORY_BUDGET, as_int, as_real_array, describe
from repro.errors import ModelError
from repro.io import MAX_READ_BYTES, inside, open_regular, read_bytes

__all__ = [
    "read_gltf",
    "arkit_rig",
    "ARKIT_SLIDERS",
    "SUPPORTED_EXTENSIONS",
    "MAX_NODES",
    "MAX_MESHES",
    "MAX_PRIMITIVES",
    "MAX_TARGETS",
    "MAX_OBJECTS",
    "MAX_VALUES",
    "MODEL_BYTES_RATIO",
    "MODEL_BYTES_FLOOR",
]

#: Extensions whose use this reader honours when a file lists them as required.
SUPPORTED_EXTENSIONS = ("KHR_mesh_quantization", "EXT_meshopt_compression")
#: Required extensions that only touch materials, textures or lights: the geometry reads the same.
_GEOMETRY_NEUTRAL_PREFIXES = ("KHR_materials_", "KHR_texture_", "EXT_texture_", "KHR_lights_", "EXT_lights_")


#: The paper's sliders (Lewis et al. 2005, Figs. 3-5) over ARKit-style names, as for ICT
#: (:data:`repro.blendshapes.ict.ICT_SLIDERS`); for each slider the first alternative whose
#: shapes are all in the face is used (ARKit's own ``browInnerUp`` is one shape, ICT splits it).
ARKIT_SLIDERS: dict[str, tuple[dict[str, float], ...]] = {
    "Furrow": ({"browDown_L": 1.0, "browDown_R": 1.0},),
    "SmirkLeft": ({"mouthSmile_L": 1.0},),
    "SmirkRight": ({"mouthSmile_R": 1.0},),
    "Wince": ({"eyeSquint_L": 1.0, "eyeSquint_R": 1.0},),
    "SneerLeft": ({"noseSneer_L": 1.0},),
    "SneerRight": ({"noseSneer_R": 1.0},),
    "JawOpen": ({"jawOpen": 1.0},),
    "MouthStretch": ({"mouthStretch_L": 1.0, "mouthStretch_R": 1.0},),
    "Smile": ({"mouthSmile_L": 1.0, "mouthSmile_R": 1.0},),
    "Blink": ({"eyeBlink_L": 1.0, "eyeBlink_R": 1.0},),
    "BrowUp": (
        {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0, "browOuterUp_L": 1.0, "browOuterUp_R": 1.0},
        {"browInnerUp": 1.0, "browOuterUp_L": 1.0, "browOuterUp_R": 1.0},
    ),
}

# component types: numpy dtype and the spec's normalisation divisor (None: not normalisable)
_COMPONENTS = {
    5120: (np.int8, 127.0),
    5121: (np.uint8, 255.0),
    5122: (np.int16, 32767.0),
    5123: (np.uint16, 65535.0),
    5125: (np.uint32, None),
    5126: (np.float32, None),
}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES", 5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}
#: meshopt-decoded buffer views may take, together, at most this many times the file's size.
_MESHOPT_MAX_RATIO = 256
#: What one file may make the loader allocate (summed over every primitive, morph target and
#: accessor it materialises, as float64, before anything is allocated): at most this many times
#: the bytes of the file and the buffers it uses (a float32 target takes 2x as float64, a quantised
#: one 4-8x, a sparse one more) ...
MODEL_BYTES_RATIO = 64
#: ... or this many bytes (64 MiB), whichever is more; never more than :data:`repro.checks.MEMORY_BUDGET`.
MODEL_BYTES_FLOOR = 64 << 20
#: Bounds on the glTF JSON's counts, checked on the parsed JSON before the document is handed to
#: pygltflib (whose dataclass mapping costs ~0.5 ms per object: 100,000 nodes took 29 s).  Real
#: avatars (Ready Player Me, VRM) have hundreds of nodes, tens of meshes, 50-100 targets per
#: primitive and a few thousand objects in all.
MAX_NODES = 4096
MAX_MESHES = 1024
#: primitives over all meshes
MAX_PRIMITIVES = 4096
#: morph targets of one primitive
MAX_TARGETS = 1024
#: items of every top-level array (nodes, accessors, bufferViews, materials ...), primitives and morph targets
MAX_OBJECTS = 12_000
#: JSON values (numbers, strings, list items, fields) of the glTF schema's fields, extras and extensions not counted
MAX_VALUES = 100_000


# ====================================================================== reading
class _Reader:
    """One glTF document: buffers, buffer views and accessors, every error naming the file."""

    def __init__(self, path: Path, raw: bytes, max_bytes: int):
        self.path, self.where = path, str(path)
        self.budget = max(len(raw), 1 << 16)  # bound on decoded sizes, from the file's size
        self.max_bytes = max_bytes
        self.read_total = len(raw)  # bytes of the file and its buffers read: at most max_bytes
        self.decoded = 0  # bytes decoded from meshopt-compressed views, for the whole file
        self.glb_bin: bytes | None = None
        glb = raw[:4] == GLB_MAGIC or path.suffix.lower() == ".glb"
        text = self._split_glb(raw) if glb else self._text(raw)
        self.doc = self._parse(text, raw if glb else None)
        self._buffers: dict[int, bytes] = {}
        self._views: dict[int, memoryview] = {}

    def err(self, what: str) -> ModelError:
        return ModelError(f"{self.where}: {what}")

    # ------------------------------------------------------------ container
    def _text(self, raw: bytes) -> str:
        head = raw[:64].lstrip().lower()
        if head.startswith((b"<!doctype", b"<html", b"<?xml", b"<")):
            raise self.err("is an HTML/XML page, not a glTF file (a web page saved instead of the model?)")
        try:
            return raw.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise self.err(f"is neither a binary glTF (.glb, starts with b'glTF') nor UTF-8 JSON ({exc})") from None

    def _split_glb(self, raw: bytes) -> str:
        if raw[:4] != GLB_MAGIC:
            start = raw[:16]
            hint = " (an HTML page saved as .glb?)" if raw[:64].lstrip().lower().startswith((b"<!doctype", b"<html", b"<")) else ""
            raise self.err(f"not a binary glTF: it starts with {start!r}, not b'glTF'{hint}")
        if len(raw) < 20:
            raise self.err(f"truncated binary glTF: {len(raw)} bytes, less than a GLB header and one chunk")
        version, length = struct.unpack_from("<II", raw, 4)
        if version != 2:
            raise self.err(f"binary glTF version {version}; only version 2 is supported")
        if length > len(raw):
            raise self.err(f"truncated binary glTF: its header says {length} bytes, the file has {len(raw)}")
        pos, chunks = 12, []
        while pos < length:
            if pos + 8 > length:
                raise self.err(f"truncated binary glTF: chunk header at byte {pos} runs past the end ({length})")
            clen, ctype = struct.unpack_from("<II", raw, pos)
            if pos + 8 + clen > length:
                raise self.err(
                    f"truncated binary glTF: chunk {len(chunks)} at byte {pos} needs {clen} bytes, "
                    f"only {length - pos - 8} remain"
                )
            chunks.append((ctype, raw[pos + 8 : pos + 8 + clen]))
            pos += 8 + clen
        if not chunks or chunks[0][0] != CHUNK_JSON:
            raise self.err("binary glTF without a JSON chunk first")
        try:
            return chunks[0][1].decode("utf-8")
        except UnicodeDecodeError as exc:
            raise self.err(f"the JSON chunk is not UTF-8 ({exc})") from None

    def _parse(self, text: str, glb: bytes | None):
        import pygltflib

        try:
            obj = json.loads(text)
        except ValueError as exc:
            raise self.err(f"not valid glTF JSON ({exc})") from None
        if not isinstance(obj, dict) or not isinstance(obj.get("asset"), dict):
            raise self.err("not a glTF document (no 'asset' object)")
        version = str(obj["asset"].get("version", ""))
        if not version.startswith("2"):
            raise self.err(f"glTF version {version!r}; only 2.x is supported")
        self._check_counts(obj)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if glb is None:
                    doc = pygltflib.GLTF2.from_json(text, infer_missing=True)
                else:  # framing already checked by _split_glb
                    doc = pygltflib.GLTF2.load_from_bytes(glb)
                    self.glb_bin = doc.binary_blob()
        except Exception as exc:  # the library raises TypeError/KeyError/... on a malformed schema
            raise self.err(f"malformed glTF JSON ({type(exc).__name__}: {exc})") from None
        required = list(doc.extensionsRequired or [])
        bad = [e for e in required if e not in SUPPORTED_EXTENSIONS and not str(e).startswith(_GEOMETRY_NEUTRAL_PREFIXES)]
        if bad:
            raise self.err(
                f"requires the unsupported extension(s) {bad}; supported: {list(SUPPORTED_EXTENSIONS)} "
                "(re-export without them, e.g. without Draco compression)"
            )
        return doc

    def _check_counts(self, obj: dict) -> None:
        """Refuse a document with more nodes, meshes, primitives, targets or objects than the limits (before pygltflib)."""
        def n(v):
            return len(v) if isinstance(v, list) else 0

        meshes = obj.get("meshes")
        prims = [p for m in (meshes if isinstance(meshes, list) else []) if isinstance(m, dict)
                 for p in (m.get("primitives") if isinstance(m.get("primitives"), list) else [])]
        for what, count, limit in (("nodes", n(obj.get("nodes")), MAX_NODES), ("meshes", n(meshes), MAX_MESHES),
                                   ("mesh primitives", len(prims), MAX_PRIMITIVES)):
            if count > limit:
                raise self.err(f"has {count} {what}, more than the {limit} this reader accepts (gltf.MAX_{what.split()[-1].upper()}); refusing")
        targets = 0
        for j, p in enumerate(prims):
            t = n(p.get("targets")) if isinstance(p, dict) else 0
            if t > MAX_TARGETS:
                raise self.err(f"a mesh primitive (number {j} over all meshes) has {t} targets (morph targets), more than "
                               f"the {MAX_TARGETS} this reader accepts (gltf.MAX_TARGETS); refusing")
            targets += t
        total = sum(n(v) for v in obj.values()) + len(prims) + targets
        if total > MAX_OBJECTS:
            raise self.err(f"has {total} glTF objects (items of its top-level arrays, mesh primitives and morph targets), "
                           f"more than the {MAX_OBJECTS} this reader accepts (gltf.MAX_OBJECTS); refusing")
        # pygltflib converts every value of the schema's fields one by one (~20 us each: an accessor
        # "max" of 200,000 numbers took 4 s); extras and extensions pass through untouched
        values, stack = 0, [obj]
        while stack:
            node = stack.pop()
            items = node.items() if isinstance(node, dict) else enumerate(node)
            for key, v in items:
                if key in ("extras", "extensions"):
                    continue
                values += 1
                if isinstance(v, (dict, list)):
                    stack.append(v)
            if values > MAX_VALUES:
                raise self.err(f"has more than {MAX_VALUES} JSON values in its glTF fields (outside extras and "
                               f"extensions), more than this reader accepts (gltf.MAX_VALUES); refusing")

    # -------------------------------------------------------------- helpers
    def item(self, kind: str, index):
        items = getattr(self.doc, kind) or []
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise self.err(f"refers to {kind}[{index!r}], but the file has {len(items)} {kind}")
        if not hasattr(items[index], "extras"):  # null or a scalar where an object belongs
            raise self.err(f"{kind}[{index}] is {items[index]!r:.40}, not a glTF object")
        return items[index]

    def integer(self, value, what: str, *, lo: int = 0, default=None) -> int:
        if value is None and default is not None:
            return default
        if not isinstance(value, int) or isinstance(value, bool) or value < lo:
            raise self.err(f"{what} must be an integer >= {lo}, got {value!r}")
        return value

    # -------------------------------------------------------------- buffers
    def buffer(self, i: int) -> bytes:
        if i in self._buffers:
            return self._buffers[i]
        buf = self.item("buffers", i)
        length = self.integer(buf.byteLength, f"buffers[{i}].byteLength", lo=1)
        if (buf.extensions or {}).get("EXT_meshopt_compression", {}).get("fallback"):
            raise self.err(f"buffers[{i}] is a meshopt fallback buffer without data, read outside a compressed view")
        uri = buf.uri
        if uri is None:
            if self.glb_bin is None:
                raise self.err(f"buffers[{i}] has no uri and the file has no binary (GLB BIN) chunk: missing buffer")
            data = self.glb_bin
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise self.err(f"buffers[{i}]: only base64 data URIs are supported, got {head[:40]!r}")
            import base64
            import binascii

            try:
                data = base64.b64decode(payload, validate=True)
            except (binascii.Error, ValueError) as exc:
                raise self.err(f"buffers[{i}]: corrupt base64 data URI ({exc})") from None
        else:
            data = self._external(i, uri, length)
        if len(data) < length:
            raise self.err(f"buffers[{i}] is {len(data)} bytes, shorter than its byteLength {length}")
        self._buffers[i] = data
        return data

    def _external(self, i: int, uri, length: int) -> bytes:
        """Buffer ``i``'s file: inside the model's folder, a regular file, and only its ``byteLength`` bytes read."""
        from urllib.parse import unquote, urlsplit

        what = f"buffers[{i}] uri"
        if not isinstance(uri, str):
            raise self.err(f"{what} must be a string, got {describe(uri)}")
        if urlsplit(uri).scheme or uri.startswith(("/", "\\")):
            raise self.err(f"{what} {uri[:60]!r} is not a file name relative to the model; only those and data: URIs are read")
        if self.read_total + length > self.max_bytes:
            raise self.err(f"buffers[{i}].byteLength {length} would bring what is read to more than max_bytes={self.max_bytes}; refusing")
        try:
            # after percent-decoding (%2e%2e is ..), with .. and symlinks resolved: inside the folder
            target = inside(self.path.parent, unquote(uri), error=ModelError, what=what)
        except ModelError as exc:
            raise self.err(f"buffer {i} ({uri[:60]!r}) is refused: {exc}") from None
        try:
            fh, size = open_regular(target, error=ModelError, max_bytes=None)  # no FIFO, device, folder
        except ModelError as exc:
            kind = "missing buffer" if str(exc).endswith("no such file") else "unreadable buffer"
            raise self.err(f"{kind} {i} ({uri[:60]!r}): {exc}") from None
        with fh:
            if size < length:
                raise self.err(f"buffers[{i}] file {uri[:60]!r} is {size} bytes, shorter than its byteLength {length}")
            try:
                data = fh.read(length)  # a larger file: only the declared bytes
            except OSError as exc:
                raise self.err(f"buffer {i} ({uri[:60]!r}) cannot be read: {exc}") from None
        self.read_total += len(data)
        self.budget += len(data)
        return data

    def view(self, i: int) -> memoryview:
        if i in self._views:
            return self._views[i]
        bv = self.item("bufferViews", i)
        length = self.integer(bv.byteLength, f"bufferViews[{i}].byteLength", lo=1)
        ext = (bv.extensions or {}).get("EXT_meshopt_compression")
        if ext is not None:
            out = self._meshopt_view(i, bv, ext, length)
        else:
            data = self.buffer(self.integer(bv.buffer, f"bufferViews[{i}].buffer"))
            off = self.integer(bv.byteOffset, f"bufferViews[{i}].byteOffset", default=0)
            if off + length > len(data):
                raise self.err(
                    f"bufferViews[{i}] (bytes {off}..{off + length}) is out of bounds of buffers[{bv.buffer}] "
                    f"({len(data)} bytes)"
                )
            out = memoryview(data)[off : off + length]
        self._views[i] = out
        return out

    def _meshopt_view(self, i: int, bv, ext, length: int) -> memoryview:
        import meshopt

        if not isinstance(ext, dict):
            raise self.err(f"bufferViews[{i}]: malformed EXT_meshopt_compression object")
        what = f"bufferViews[{i}].extensions.EXT_meshopt_compression"
        src = self.buffer(self.integer(ext.get("buffer"), f"{what}.buffer"))
        off = self.integer(ext.get("byteOffset"), f"{what}.byteOffset", default=0)
        clen = self.integer(ext.get("byteLength"), f"{what}.byteLength", lo=1)
        stride = self.integer(ext.get("byteStride"), f"{what}.byteStride", lo=1)
        count = self.integer(ext.get("count"), f"{what}.count", lo=1)
        mode, filt = ext.get("mode"), ext.get("filter", "NONE")
        if mode not in ("ATTRIBUTES", "TRIANGLES", "INDICES"):
            raise self.err(f"{what}.mode must be ATTRIBUTES, TRIANGLES or INDICES, got {mode!r}")
        if off + clen > len(src):
            raise self.err(f"{what}: compressed bytes {off}..{off + clen} are out of bounds of buffers[{ext.get('buffer')}] ({len(src)} bytes)")
        if count * stride > length:
            raise self.err(f"{what}: {count} x {stride} decoded bytes exceed the view's byteLength {length}")
        # bounded per file, not per view: many views may each decode up to the ratio
        if self.decoded + count * stride > _MESHOPT_MAX_RATIO * self.budget:
            raise self.err(f"{what}: {count * stride} decoded bytes from {clen} compressed, {self.decoded + count * stride} "
                           f"for the file's meshopt views so far; refusing (at most {_MESHOPT_MAX_RATIO}x the file's size)")
        self.decoded += count * stride
        try:
            out = meshopt.decode_gltf_buffer(bytes(src[off : off + clen]), count, stride, mode, filt)
        except Exception as exc:  # the decoder reports corrupt data as ValueError/RuntimeError
            raise self.err(f"{what}: meshopt could not decode it ({type(exc).__name__}: {exc})") from None
        raw = np.ascontiguousarray(out).view(np.uint8).tobytes()
        return memoryview(raw + bytes(length - len(raw)))

    # ------------------------------------------------------------ accessors
    def meta(self, i: int, what: str, *, want: tuple[str, ...] | None = None):
        """Accessor ``i``'s checked description, nothing decoded: ``(acc, label, dtype, divisor, ncomp, count)``."""
        acc = self.item("accessors", i)
        label = f"accessors[{i}] ({what})"
        if not isinstance(acc.type, str) or acc.type not in _NCOMP or (want and acc.type not in want):
            raise self.err(f"{label} has type {acc.type!r}, expected {want or list(_NCOMP)}")
        if not isinstance(acc.componentType, int) or acc.componentType not in _COMPONENTS:
            raise self.err(f"{label} has componentType {acc.componentType!r}, not one of {sorted(_COMPONENTS)}")
        dtype, divisor = _COMPONENTS[acc.componentType]
        dtype = np.dtype(dtype).newbyteorder("<")
        count = self.integer(acc.count, f"{label}.count", lo=1)
        return acc, label, dtype, divisor, _NCOMP[acc.type], count

    def buffers_of(self, i: int) -> None:
        """Read the buffers accessor ``i``'s views lie in (so that the size of what the file holds is known)."""
        acc = self.doc.accessors[i]
        views = [acc.bufferView]
        if acc.sparse is not None:
            views += [getattr(acc.sparse.indices, "bufferView", None), getattr(acc.sparse.values, "bufferView", None)]
        for v in views:
            if v is None:
                continue
            bv = self.item("bufferViews", self.integer(v, f"accessors[{i}] bufferView"))
            ext = (bv.extensions or {}).get("EXT_meshopt_compression") if isinstance(bv.extensions, dict) else None
            b = ext.get("buffer") if isinstance(ext, dict) else bv.buffer
            self.buffer(self.integer(b, f"bufferViews[{v}].buffer"))

    def accessor(self, i: int, what: str, *, want: tuple[str, ...] | None = None) -> np.ndarray:
        """Accessor ``i`` as float64 (count, ncomp) (dequantised) -- or int64 for index data."""
        acc, label, dtype, divisor, ncomp, count = self.meta(i, what, want=want)
        esize = ncomp * dtype.itemsize
        if count * esize > 16 * self.budget:
            raise self.err(f"{label}: {count} elements is more than the file's size can hold; refusing")
        if acc.bufferView is None:
            out = np.zeros((count, ncomp), dtype=dtype)
        else:
            view = self.view(self.integer(acc.bufferView, f"{label}.bufferView"))
            bv = self.doc.bufferViews[acc.bufferView]
            off = self.integer(acc.byteOffset, f"{label}.byteOffset", default=0)
            stride = self.integer(bv.byteStride, f"bufferViews[{acc.bufferView}].byteStride", lo=1, default=esize)
            if stride < esize:
                raise self.err(f"bufferViews[{acc.bufferView}].byteStride {stride} is smaller than the element size {esize} of {label}")
            end = off + stride * (count - 1) + esize
            if end > len(view):
                raise self.err(
                    f"{label} reads bytes up to {end}, beyond bufferViews[{acc.bufferView}] "
                    f"({len(view)} bytes): out of bounds"
                )
            if off % dtype.itemsize or stride % dtype.itemsize:
                buf = bytes(view[off:end])  # unaligned: copy, then a strided view of the copy
                off = 0
            else:
                buf = view
            out = np.ndarray((count, ncomp), dtype=dtype, buffer=buf, offset=off, strides=(stride, dtype.itemsize)).copy()
        if acc.sparse is not None:
            out = self._sparse(acc, out, label, dtype, ncomp, count)
        if dtype.kind == "f":
            with np.errstate(invalid="ignore"):  # signalling-NaN bit patterns; NaN is refused by the callers
                return out.astype(np.float64)
        if acc.normalized:
            if divisor is None:
                raise self.err(f"{label} is normalized with componentType {acc.componentType} (only 8/16-bit integers can be)")
            res = out.astype(np.float64) / divisor
            return np.maximum(res, -1.0) if dtype.kind == "i" else res
        return out.astype(np.float64) if want != ("SCALAR",) else out.astype(np.int64)

    def _sparse(self, acc, out, label, dtype, ncomp, count):
        sp = acc.sparse
        n = self.integer(sp.count, f"{label}.sparse.count", lo=1)
        if n > count:
            raise self.err(f"{label}.sparse.count {n} exceeds the accessor's count {count}")
        if sp.indices is None or sp.values is None:
            raise self.err(f"{label}.sparse needs indices and values")
        ictype = sp.indices.componentType
        if ictype not in (5121, 5123, 5125):
            raise self.err(f"{label}.sparse.indices.componentType {ictype!r} must be 5121, 5123 or 5125")
        idt = np.dtype(_COMPONENTS[ictype][0]).newbyteorder("<")

        def block(ref, dt, width, part):
            view = self.view(self.integer(ref.bufferView, f"{label}.sparse.{part}.bufferView"))
            off = self.integer(ref.byteOffset, f"{label}.sparse.{part}.byteOffset", default=0)
            nbytes = n * width * dt.itemsize
            if off + nbytes > len(view):
                raise self.err(f"{label}.sparse.{part} reads bytes up to {off + nbytes}, beyond its bufferView ({len(view)} bytes): out of bounds")
            return np.frombuffer(bytes(view[off : off + nbytes]), dtype=dt).reshape(n, width)

        idx = block(sp.indices, idt, 1, "indices").ravel().astype(np.int64)
        vals = block(sp.values, dtype, ncomp, "values")
        if idx.size and (idx.max() >= count or (n > 1 and np.any(np.diff(idx) <= 0))):
            raise self.err(f"{label}.sparse.indices must increase strictly and stay below {count}")
        out = out.copy()
        out[idx] = vals
        return out


def _node_matrix(node) -> np.ndarray:
    if node.matrix is not None:
        return np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T  # column-major
    t = np.asarray(node.translation if node.translation is not None else [0, 0, 0], dtype=np.float64)
    x, y, z, w = (np.asarray(node.rotation, dtype=np.float64) if node.rotation is not None else np.array([0, 0, 0, 1.0]))
    s = np.asarray(node.scale if node.scale is not None else [1, 1, 1], dtype=np.float64)
    R = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip
    M = np.eye(4)
    M[:3, :3] = R * s
    M[:3, 3] = t
    return M


def _world_of_mesh(r: _Reader, mesh_index: int) -> tuple[np.ndarray, str]:
    """World matrix of the first node (scene order) that instances the mesh, and a label."""
    doc = r.doc
    nodes = doc.nodes or []
    if doc.scenes:
        scene = r.item("scenes", doc.scene if isinstance(doc.scene, int) and 0 <= doc.scene < len(doc.scenes) else 0)
        roots = list(scene.nodes or [])
    else:
        children = {c for n in nodes for c in (n.children or [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    stack = [(i, np.eye(4)) for i in reversed(roots)]
    seen: set[int] = set()
    while stack:
        i, parent = stack.pop()
        node = r.item("nodes", i)
        if i in seen:
            raise r.err(f"the node hierarchy has a cycle through nodes[{i}]")
        seen.add(i)
        try:
            M = parent @ _node_matrix(node)
        except (ValueError, TypeError) as exc:
            raise r.err(f"nodes[{i}] has a malformed transform ({exc})") from None
        if not np.isfinite(M).all():
            raise r.err(f"nodes[{i}] has a non-finite transform")
        if node.mesh == mesh_index:
            return M, f"node {node.name or i}"
        stack.extend((c, M) for c in reversed(node.children or []))
    return np.eye(4), "no node (identity)"


def _target_names(r: _Reader, mesh, prim, m: int) -> list[str]:
    for owner in (mesh, prim):
        names = (owner.extras or {}).get("targetNames") if isinstance(owner.extras, dict) else None
        if names is not None:
            if not isinstance(names, list) or len(names) != m or not all(isinstance(s, str) for s in names):
                raise r.err(f"extras.targetNames of mesh {mesh.name!r} must be {m} strings, one per target, got {names!r:.120}")
            return names
    return [f"target_{k}" for k in range(m)]


def _plan(r: _Reader, mi: int, prims: list[int]) -> tuple[int, int]:
    """Vertices and targets of the chosen primitives, after checking what reading them will allocate.

    Sums, before anything is allocated, every array the loader materialises for this file:
    the neutral and the dense float64 deltas of every primitive (and the model's own copies),
    the faces, and the largest accessor being decoded; refuses the file above
    ``min(MEMORY_BUDGET, max(MODEL_BYTES_RATIO x bytes of the file and its buffers, MODEL_BYTES_FLOOR))``.
    Primitives sharing one accessor (a 7 KB file whose 20 primitives all point at one
    zero-filled 87k-vertex accessor, x 32 targets) count once per use: each use is a copy.
    """
    mesh = r.doc.meshes[mi]
    uses: dict[int, int] = {}
    n_total = faces_total = 0
    m = 0
    for pj in prims:
        prim = mesh.primitives[pj]
        label = f"meshes[{mi}] ({mesh.name!r}) primitive {pj}"
        if not isinstance(prim.targets, list):
            raise r.err(f"{label} targets must be a list, got {prim.targets!r:.60}")
        m = len(prim.targets)
        pos_i = getattr(prim.attributes, "POSITION", None)
        if pos_i is None:
            raise r.err(f"{label} has no POSITION attribute")
        n = r.meta(pos_i, f"{label} POSITION", want=("VEC3",))[5]
        used = [pos_i]
        for k, target in enumerate(prim.targets):
            ti = target.get("POSITION") if isinstance(target, dict) else getattr(target, "POSITION", None)
            if ti is not None:
                c = r.meta(ti, f"{label} target {k} POSITION", want=("VEC3",))[5]
                if c != n:
                    raise r.err(f"{label} target {k} has {c} vertices, the primitive has {n}")
                used.append(ti)
        if prim.indices is None:
            faces_total += n
        else:
            faces_total += r.meta(prim.indices, f"{label} indices", want=("SCALAR",))[5]
            used.append(prim.indices)
        for a in used:
            uses[a] = uses.get(a, 0) + 1
        n_total += n
    for a in sorted(uses):
        r.buffers_of(a)
    transient = 0
    for a in uses:
        acc, _, dtype, _, ncomp, count = r.meta(a, "size")
        copies = 2 if acc.sparse is not None else 1
        transient = max(transient, count * ncomp * (copies * dtype.itemsize + 8))
    dense = n_total * 3 * m * 8
    # deltas and neutral (ours, and the model's copies), their finiteness masks, faces twice, one accessor
    need = 2 * dense + dense // 8 + 2 * n_total * 3 * 8 + 2 * faces_total * 8 + transient
    cap = min(MEMORY_BUDGET, max(MODEL_BYTES_RATIO * r.read_total, MODEL_BYTES_FLOOR))
    if need > cap:
        shared, times = max(uses.items(), key=lambda kv: (kv[1], -kv[0]))
        why = f"; accessor {shared} is used {times} times" if times > 1 else ""
        raise r.err(
            f"asks for {_size(need)} of vertex data across {len(prims)} primitive(s) of meshes[{mi}] "
            f"({n_total} vertices x {m} targets in all, as float64{why}); the cap for this file is {_size(cap)} "
            f"({MODEL_BYTES_RATIO}x the {_size(r.read_total)} of the file and its buffers, at least {_size(MODEL_BYTES_FLOOR)}, "
            f"at most the memory budget {_size(MEMORY_BUDGET)}); refusing"
        )
    return n_total, m


def _size(n: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n >= 1 << shift:
            return f"{n / (1 << shift):.3g} {unit}"
    return f"{n} bytes"


def _read_primitive(r: _Reader, mi: int, pj: int, f0_out: np.ndarray, d_out: np.ndarray) -> tuple[int, np.ndarray]:
    """Primitive ``pj``'s neutral and deltas written into ``f0_out`` / ``d_out`` (n, 3, m); its vertex count and faces."""
    mesh = r.doc.meshes[mi]
    prim = mesh.primitives[pj]
    label = f"meshes[{mi}] ({mesh.name!r}) primitive {pj}"
    mode = 4 if prim.mode is None else prim.mode
    if mode != 4:
        kind = _MODES.get(mode, "unknown") if isinstance(mode, int) else "unknown"
        raise r.err(f"{label} has mode {mode!r} ({kind}); only triangles (mode 4) are supported")
    f0 = r.accessor(prim.attributes.POSITION, f"{label} POSITION", want=("VEC3",))
    n = len(f0)
    if not np.isfinite(f0).all():
        raise r.err(f"{label} POSITION has {np.count_nonzero(~np.isfinite(f0))} NaN/inf values")
    f0_out[:n] = f0
    del f0
    for k, target in enumerate(prim.targets):
        ti = target.get("POSITION") if isinstance(target, dict) else getattr(target, "POSITION", None)
        if ti is None:
            continue  # a target with only normals/tangents moves no vertex
        d = r.accessor(ti, f"{label} target {k} POSITION", want=("VEC3",))
        if len(d) != n:
            raise r.err(f"{label} target {k} has {len(d)} vertices, the primitive has {n}")
        if not np.isfinite(d).all():
            raise r.err(f"{label} target {k} has NaN/inf deltas")
        d_out[:n, :, k] = d
    if prim.indices is None:
        if n % 3:
            raise r.err(f"{label} has no indices and {n} vertices, not a multiple of 3")
        faces = np.arange(n, dtype=np.int64).reshape(-1, 3)
    else:
        idx = r.accessor(prim.indices, f"{label} indices", want=("SCALAR",))
        acc = r.doc.accessors[prim.indices]
        if acc.componentType not in (5121, 5123, 5125) or acc.normalized:
            raise r.err(f"{label} indices must be unsigned integers, got componentType {acc.componentType}")
        idx = np.asarray(idx, dtype=np.int64).ravel()
        if idx.size % 3:
            raise r.err(f"{label} has {idx.size} indices, not a multiple of 3")
        if idx.size and idx.max() >= n:
            raise r.err(f"{label} indices reach vertex {idx.max()}, the primitive has {n}")
        faces = idx.reshape(-1, 3)
    return n, faces


def _choose(r: _Reader, mesh, primitive) -> tuple[int, list[int]]:
    meshes = r.doc.meshes or []
    if not meshes:
        raise r.err("has no meshes")
    if mesh is not None:
        if isinstance(mesh, str):
            hits = [i for i, m in enumerate(meshes) if m.name == mesh]
            if not hits:
                raise r.err(f"has no mesh named {mesh!r}; meshes: {[m.name for m in meshes]}")
            mi = hits[0]
        else:
            mi = r.integer(mesh, "mesh=")
            r.item("meshes", mi)
        candidates = [mi]
    else:
        candidates = [i for i, m in enumerate(meshes) if any(p.targets for p in m.primitives or [])]
        if not candidates:
            raise r.err(
                f"has no morph targets (blendshapes): none of its {len(meshes)} meshes "
                f"{[m.name for m in meshes]} has a primitive with targets"
            )
    def n_targets(i):
        return max((len(p.targets or []) for p in meshes[i].primitives or []), default=0)

    mi = max(candidates, key=lambda i: (n_targets(i), -i))
    prims = meshes[mi].primitives or []
    if not prims:
        raise r.err(f"meshes[{mi}] ({meshes[mi].name!r}) has no primitives")
    m = n_targets(mi)
    if m == 0:
        raise r.err(f"meshes[{mi}] ({meshes[mi].name!r}) has no morph targets (blendshapes)")
    if primitive is not None:
        pj = r.integer(primitive, "primitive=")
        if pj >= len(prims):
            raise r.err(f"meshes[{mi}] has {len(prims)} primitives, no primitive {pj}")
        if not prims[pj].targets:
            raise r.err(f"meshes[{mi}] primitive {pj} has no morph targets (blendshapes)")
        return mi, [pj]
    return mi, [j for j, p in enumerate(prims) if len(p.targets or []) == m]


def read_gltf(
    path, *, mesh: str | int | None = None, primitive: int | None = None, max_bytes: int = MAX_READ_BYTES
) -> BlendshapeModel:
    """A glTF 2.0 face (``.gltf`` or ``.glb``) as a delta blendshape model in metres.

    Parameters
    ----------
    path : path
        The file; a ``.gltf``'s external buffers are read beside it.
    mesh : str or int, optional
        The mesh to read (name or index); default the mesh with the most morph targets.
    primitive : int, optional
        One primitive of that mesh; default all its primitives with that many targets, merged.
    max_bytes : int, default :data:`repro.io.MAX_READ_BYTES`
        Cap on the bytes read: the file and the buffers it uses, together.  What the file may
        make the loader allocate is bounded separately (:data:`MODEL_BYTES_RATIO`), and so are
        its counts (:data:`MAX_NODES`, :data:`MAX_MESHES`, :data:`MAX_PRIMITIVES`,
        :data:`MAX_TARGETS`, :data:`MAX_OBJECTS`).

    Returns
    -------
    BlendshapeModel
        ``units="m"``, ``name="<file>:<mesh>/<primitives>"`` (which mesh and primitives were
        read); neutral and deltas in world placement (the node's transform; deltas get its
        linear part); names from ``extras.targetNames``.  Sliders and regions: the model's own
        when the file was written by :func:`~repro.blendshapes.gltf_write.write_gltf`, else :func:`arkit_rig`.

    Raises
    ------
    ModelError
        Naming the file and the problem; also for an argument of the wrong type (a stream
        instead of a path, ``max_bytes="10"``).  A buffer ``uri`` that leaves the file's
        folder (``..``, ``%2e%2e``, a symlink pointing out), that is not a regular file (a
        FIFO, ``/dev/zero``), or is shorter than its ``byteLength`` is refused before it is
        read; only ``byteLength`` bytes of it are read.
    """
    import os

    if hasattr(path, "read") or not isinstance(path, (str, os.PathLike)):
        # a stream has no folder for the file's buffers, and no size known before reading
        raise ModelError(f"read_gltf reads a path to a .gltf or .glb file (its buffers are found beside it), got {describe(path)}")
    if mesh is not None and not isinstance(mesh, str):
        mesh = as_int(mesh, "mesh= (a mesh's name or index)", lo=0, error=ModelError)
    if primitive is not None:
        primitive = as_int(primitive, "primitive=", lo=0, error=ModelError)
    max_bytes = as_int(max_bytes, "max_bytes", lo=1, error=ModelError)
    p = Path(path)
    raw, _ = read_bytes(p, error=ModelError, max_bytes=max_bytes)
    if not raw:
        raise ModelError(f"{p}: empty file")
    try:
        return _read(p, raw, mesh, primitive, max_bytes)
    except ModelError:
        raise
    except RecursionError:  # json / pygltflib on a deeply nested document
        raise ModelError(f"{p}: malformed glTF (JSON nested too deeply)") from None
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, struct.error) as exc:
        # a field of an unexpected JSON type that no check above caught: still the file's fault
        raise ModelError(f"{p}: malformed glTF ({type(exc).__name__}: {exc})") from None


def _read(p: Path, raw: bytes, mesh, primitive, max_bytes: int) -> BlendshapeModel:
    r = _Reader(p, raw, max_bytes)
    mi, prims = _choose(r, mesh, primitive)
    gmesh = r.doc.meshes[mi]
    n_total, m = _plan(r, mi, prims)  # what this will allocate, checked first
    # one neutral and one delta array for all primitives, filled in place (no per-primitive copies)
    f0 = np.empty((n_total, 3))
    D3 = np.zeros((n_total, 3, m))
    faces_parts, o = [], 0
    for j in prims:
        n, fc = _read_primitive(r, mi, j, f0[o:], D3[o:])
        faces_parts.append(fc + o)
        o += n
    names = _target_names(r, gmesh, gmesh.primitives[prims[0]], m)
    faces = np.concatenate(faces_parts)
    M, _ = _world_of_mesh(r, mi)
    L = M[:3, :3]
    f0 = f0 @ L.T + M[:3, 3]
    if not np.array_equal(L, np.eye(3)):
        step = max(1, (1 << 22) // max(1, 3 * m))  # in place, a block of vertices at a time
        for s in range(0, n_total, step):
            D3[s : s + step] = np.einsum("ij,vjk->vik", L, D3[s : s + step])
    D = D3.reshape(-1, m)
    label = f"{p.name}:{gmesh.name or f'mesh{mi}'}/{','.join(map(str, prims))}"
    extra = (gmesh.extras or {}).get("repro") if isinstance(gmesh.extras, dict) else None
    try:
        if isinstance(extra, dict):
            sliders = extra.get("sliders") or {}
            regions = {k: np.asarray(v, dtype=np.int64) for k, v in (extra.get("regions") or {}).items()}
        else:
            sliders, regions = arkit_rig(f0, D, names)
        return BlendshapeModel(f0=f0, D=D, names=names, faces=faces, name=label, units="m", sliders=sliders, regions=regions)
    except (ModelError, TypeError, ValueError, AttributeError) as exc:
        raise r.err(f"mesh {gmesh.name!r} does not make a blendshape model: {exc}") from None


# ====================================================================== ARKit names
def _canonical(name: str) -> str:
    """ARKit camelCase (``browDownLeft``) as ARKit's own ``browDown_L``; other names unchanged."""
    for long, short in (("Left", "_L"), ("Right", "_R")):
        if name.endswith(long) and len(name) > len(long) and name[0].islower():
            return name[: -len(long)] + short
    return name


def arkit_rig(f0, D, names: Sequence[str]) -> tuple[dict, dict]:
    """The paper's sliders and selection regions of a face with ARKit-style shape names.

    Sliders: :data:`ARKIT_SLIDERS` (the ICT mapping), over the face's own names
    (``browDown_L`` or ``browDownLeft``), those whose shapes are all present.
    Regions, found from where the named shapes move (not from vertex ids), with
    ``|d_k(v)|`` the motion of vertex ``v`` under shape ``k`` at weight 1 and the
    subject's left-right axis running from the motion centroid of the ``_R``
    shape to that of the ``_L`` shape:

    - ``left_eye`` / ``right_eye``: vertices ``eyeBlink_L/R`` moves at least 25% of its peak;
    - ``brow``: vertices ``browDown_L + browDown_R`` moves at least 25% of its peak;
      ``brow_middle`` (Fig. 3): on each side of the midline the vertex nearest to it among
      those that side's ``browDown`` moves at least half its peak (right side first);
    - ``mouth_corners`` (Fig. 4): the vertex ``mouthSmile_R`` moves most, then ``mouthSmile_L``'s;
    - ``under_left_eye`` (Fig. 5): the six vertices where both ``eyeSquint_L`` and
      ``noseSneer_L`` move most (largest ``min`` of the two motions), outside ``left_eye``;
    - ``mouth``, ``nose``: at least 25% of the peak of ``mouthSmile_L + _R`` / ``noseSneer_L + _R``.

    Regions whose shapes the face lacks are left out (scenarios needing them say so).
    """
    f0 = as_real_array(f0, "f0", shape=(None, 3), error=ModelError)
    n = len(f0)
    D = as_real_array(D, "D", error=ModelError)
    if not ((D.ndim == 2 and D.shape[0] == 3 * n) or (D.ndim == 3 and D.shape[:2] == (n, 3))):
        raise ModelError(f"D must have shape (3n, m) or (n, 3, m) for the n = {n} vertices of f0, got {D.shape}")
    D = D.reshape(n, 3, -1)
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence) or len(names) != D.shape[2] \
            or not all(isinstance(s, str) for s in names):
        raise ModelError(f"names must be {D.shape[2]} strings, one per shape, got {describe(names)}")
    by_canon: dict[str, int] = {}
    for k, s in enumerate(names):
        by_canon.setdefault(_canonical(s), k)
    sliders: dict[str, dict[str, float]] = {}
    for slider, options in ARKIT_SLIDERS.items():
        if slider in names:
            continue
        for combo in options:
            if all(s in by_canon for s in combo):
                sliders[slider] = {names[by_canon[s]]: c for s, c in combo.items()}
                break

    def motion(*shapes):
        if not all(s in by_canon for s in shapes):
            return None
        return np.linalg.norm(D[:, :, [by_canon[s] for s in shapes]].sum(axis=2), axis=1)

    def band(mv, frac=0.25):
        if mv is None or mv.max() <= 0:
            return None
        return np.flatnonzero(mv >= frac * mv.max())

    regions: dict[str, np.ndarray] = {}
    for key, shape in (("left_eye", "eyeBlink_L"), ("right_eye", "eyeBlink_R")):
        if (b := band(motion(shape))) is not None:
            regions[key] = b
    if (b := band(motion("browDown_L", "browDown_R"))) is not None:
        regions["brow"] = b
    for key, pair in (("mouth", ("mouthSmile_L", "mouthSmile_R")), ("nose", ("noseSneer_L", "noseSneer_R"))):
        if (b := band(motion(*pair))) is not None:
            regions[key] = b
    mL, mR = motion("browDown_L"), motion("browDown_R")
    if mL is not None and mR is not None and mL.max() > 0 and mR.max() > 0:
        cL, cR = (mL @ f0) / mL.sum(), (mR @ f0) / mR.sum()
        axis = cL - cR
        if np.linalg.norm(axis) > 0:
            axis /= np.linalg.norm(axis)
            side = (f0 - 0.5 * (cL + cR)) @ axis  # > 0 on the subject's left
            pick = []
            for mv, sgn in ((mR, -1.0), (mL, 1.0)):
                cand = np.flatnonzero((mv >= 0.5 * mv.max()) & (sgn * side > 0))
                if cand.size:
                    pick.append(int(cand[np.lexsort((cand, np.abs(side[cand])))][0]))
            if len(pick) == 2:
                regions["brow_middle"] = np.array(pick)
    sR, sL = motion("mouthSmile_R"), motion("mouthSmile_L")
    if sR is not None and sL is not None and sR.max() > 0 and sL.max() > 0:
        regions["mouth_corners"] = np.array([int(np.argmax(sR)), int(np.argmax(sL))])
    sq, sn = motion("eyeSquint_L"), motion("noseSneer_L")
    if sq is not None and sn is not None:
        both = np.minimum(sq, sn)
        if "left_eye" in regions:
            both[regions["left_eye"]] = -1.0
        ids = np.arange(n)
        order = np.lexsort((ids, -both))[:6]
        if both[order].min() > 0:
            regions["under_left_eye"] = np.sort(order)
    return sliders, regions


# ====================================================================== writing
