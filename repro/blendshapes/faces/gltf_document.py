"""One glTF 2.0 document: its container (JSON or GLB), buffers, buffer views and accessors.

:class:`GltfDocument` is what :func:`repro.blendshapes.faces.gltf.read_gltf` reads a face
through: every error names the file, and nothing escapes the file's bounds (issue 23): a
buffer is read only from a regular file inside the file's folder, at most its
``byteLength``, and the JSON's counts are bounded before the document is built.

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
"""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path

import numpy as np

from repro.checks import describe
from repro.errors import ModelError
from repro.io import inside, open_regular

__all__ = [
    "GltfDocument",
    "GLB_MAGIC",
    "CHUNK_JSON",
    "CHUNK_BIN",
    "SUPPORTED_EXTENSIONS",
    "MAX_NODES",
    "MAX_MESHES",
    "MAX_PRIMITIVES",
    "MAX_TARGETS",
    "MAX_OBJECTS",
    "MAX_VALUES",
]

#: GLB framing: the file magic and the two chunk types (glTF 2.0 spec, "Binary glTF Layout").
GLB_MAGIC, CHUNK_JSON, CHUNK_BIN = b"glTF", 0x4E4F534A, 0x004E4942
#: Extensions whose use this reader honours when a file lists them as required.
SUPPORTED_EXTENSIONS = ("KHR_mesh_quantization", "EXT_meshopt_compression")
#: Required extensions that only touch materials, textures or lights: the geometry reads the same.
_GEOMETRY_NEUTRAL_PREFIXES = ("KHR_materials_", "KHR_texture_", "EXT_texture_", "KHR_lights_", "EXT_lights_")
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
#: meshopt-decoded buffer views may take, together, at most this many times the file's size.
_MESHOPT_MAX_RATIO = 256
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


class GltfDocument:
    """One glTF document: buffers, buffer views and accessors, every error naming the file."""

    def __init__(self, path: Path, raw: bytes, max_bytes: int):
        self.path, self.where = path, str(path)
        self.budget = max(len(raw), 1 << 16)  # bound on decoded sizes, from the file's size
        self.max_bytes = max_bytes
        self.read_total = len(raw)  # bytes of the file and its buffers read: at most max_bytes
        self.decoded = 0  # bytes decoded from meshopt-compressed views, for the whole file
        self.glb_bin: bytes | None = None
        glb = raw[:4] == GLB_MAGIC or path.suffix.lower() in (".glb", ".vrm")  # a VRM is a GLB
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
                raise self.err(f"has {count} {what}, more than the {limit} this reader accepts (gltf_document.MAX_{what.split()[-1].upper()}); refusing")
        targets = 0
        for j, p in enumerate(prims):
            t = n(p.get("targets")) if isinstance(p, dict) else 0
            if t > MAX_TARGETS:
                raise self.err(f"a mesh primitive (number {j} over all meshes) has {t} targets (morph targets), more than "
                               f"the {MAX_TARGETS} this reader accepts (gltf_document.MAX_TARGETS); refusing")
            targets += t
        total = sum(n(v) for v in obj.values()) + len(prims) + targets
        if total > MAX_OBJECTS:
            raise self.err(f"has {total} glTF objects (items of its top-level arrays, mesh primitives and morph targets), "
                           f"more than the {MAX_OBJECTS} this reader accepts (gltf_document.MAX_OBJECTS); refusing")
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
                               f"extensions), more than this reader accepts (gltf_document.MAX_VALUES); refusing")

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
    @staticmethod
    def _once(store: dict, i: int, read):
        if i not in store:
            store[i] = read(i)
        return store[i]

    def _sized(self, kind: str, i: int):
        """Item ``i`` of ``kind`` (``buffers``, ``bufferViews``) and its ``byteLength`` (at least 1)."""
        item = self.item(kind, i)
        return item, self.integer(item.byteLength, f"{kind}[{i}].byteLength", lo=1)

    def buffer(self, i: int) -> bytes:
        """Buffer ``i``'s bytes (read once)."""
        return self._once(self._buffers, i, self._read_buffer)

    def _read_buffer(self, i: int) -> bytes:
        buf, length = self._sized("buffers", i)
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
        """Buffer view ``i``'s bytes (decoded once when meshopt-compressed)."""
        return self._once(self._views, i, self._read_view)

    def _read_view(self, i: int) -> memoryview:
        bv, length = self._sized("bufferViews", i)
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
