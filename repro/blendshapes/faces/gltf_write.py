"""glTF 2.0 blendshape faces out: a model's neutral and morph targets, weights and a weight animation.

The writer half of :mod:`repro.blendshapes.faces.gltf` (which says what is read back) and of
:mod:`repro.blendshapes.faces.gltf_document` (the container library, ``pygltflib``, which
serialises the document built here).  Files are written atomically;
:func:`repro.blendshapes.faces.gltf.read_gltf` gives the same model back.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from repro.blendshapes.faces.gltf_document import CHUNK_BIN, CHUNK_JSON, GLB_MAGIC
from repro.blendshapes.model import BlendshapeModel
from repro.checks import as_bool, as_real, as_real_array, describe
from repro.errors import ModelError
from repro.io import atomic_path

__all__ = ["write_gltf", "UNIT_SCALE"]

#: Metres per unit of a model's ``units``, used by :func:`write_gltf` (glTF is metres).
#: The procedural face's "model units" are meant as centimetres (see its module docstring).
UNIT_SCALE = {"m": 1.0, "cm": 0.01, "mm": 0.001, "model units": 0.01}


def _f32(a) -> bytes:
    return np.ascontiguousarray(a, dtype="<f4").tobytes()


class _Builder:
    """Accumulates buffer views and accessors of one binary buffer (4-byte aligned)."""

    def __init__(self):
        import pygltflib

        self.g = pygltflib
        self.blob = bytearray()
        self.views: list = []
        self.accessors: list = []

    def view(self, data: bytes, *, stride: int | None = None, target: int | None = None, count: int = 0, mode: str = "ATTRIBUTES") -> int:
        pad = -len(self.blob) % 4
        self.blob += b"\0" * pad
        bv = self.g.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data), byteStride=stride, target=target)
        bv.extras = {"_meshopt": {"count": count, "stride": stride or (len(data) // max(count, 1)), "mode": mode}}
        self.blob += data
        self.views.append(bv)
        return len(self.views) - 1

    def accessor(self, view: int | None, ctype: int, count: int, typ: str, *, normalized=False, lo=None, hi=None, sparse=None, offset: int = 0) -> int:
        acc = self.g.Accessor(bufferView=view, componentType=ctype, count=count, type=typ, normalized=normalized or None,
                              min=lo or [], max=hi or [], sparse=sparse)
        acc.byteOffset = None if view is None else offset
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _animation_arrays(model: BlendshapeModel, animation) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(animation, Mapping):
        times, frames = animation.get("times"), animation.get("weights")
    else:
        try:
            times, frames = animation
        except (TypeError, ValueError):
            raise ModelError("animation must be (times, weights) or {'times': ..., 'weights': ...}") from None
    try:
        times = np.asarray(times, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ModelError("animation times must be numbers") from None
    if times.size == 0 or not np.isfinite(times).all() or times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ModelError("animation times must be finite, >= 0 and strictly increasing, at least one")
    try:
        frames = [model.check_weights(w) for w in frames]
    except TypeError:
        raise ModelError("animation weights must be a sequence of weight vectors (or mappings)") from None
    if len(frames) != times.size:
        raise ModelError(f"animation has {times.size} times but {len(frames)} weight vectors")
    return times, np.asarray(frames)


def write_gltf(
    model: BlendshapeModel,
    path,
    weights=None,
    animation=None,
    *,
    scale: float | None = None,
    node_matrix=None,
    quantize: bool = False,
    sparse: bool = False,
    meshopt: bool = False,
    extra_meshes: Sequence[tuple[str, np.ndarray, np.ndarray]] = (),
) -> Path:
    """Write ``model`` as a glTF 2.0 face: a mesh with its shapes as morph targets.

    Parameters
    ----------
    path : path
        ``.glb`` (one binary file) or ``.gltf`` (JSON plus ``<stem>.bin`` beside it); each
        file is written atomically.
    weights : vector or mapping, optional
        Default weights (``mesh.weights``), e.g. a posed slider vector.
    animation : (times, weights) or {"times", "weights"}, optional
        A weight animation: times in seconds (strictly increasing) and one weight vector
        per time; written as an animation channel with path ``"weights"`` (LINEAR).
    scale : float, optional
        Metres per model unit; default from ``model.units`` (:data:`UNIT_SCALE`).
    node_matrix : (4, 4) array, optional
        The mesh node's transform; the vertices are stored in its local frame so that the
        world positions (what :func:`~repro.blendshapes.faces.gltf.read_gltf` returns) are the model's, in metres.
    quantize : bool
        Store positions and target deltas as normalised 16-bit integers
        (``KHR_mesh_quantization``), dequantised by the node's transform.
    sparse : bool
        Store each target as a sparse accessor over its non-zero deltas.
    meshopt : bool
        Compress every buffer view with ``EXT_meshopt_compression`` (``meshopt`` encoder).
    extra_meshes : sequence of (name, vertices (k, 3) metres, triangles (t, 3))
        Further meshes without targets (eyes, teeth), each on its own node, listed
        before the face's mesh.

    Names go to ``mesh.extras.targetNames``; the model's sliders and regions to
    ``mesh.extras.repro``, so :func:`~repro.blendshapes.faces.gltf.read_gltf` gives the same model back.
    """
    # every argument checked at the entry (issue 23, section 6), before anything is built
    path, scale, T, extra_meshes = _check_arguments(model, path, scale, node_matrix, extra_meshes)
    quantize = as_bool(quantize, "quantize", error=ModelError)
    sparse = as_bool(sparse, "sparse", error=ModelError)
    meshopt = as_bool(meshopt, "meshopt", error=ModelError)
    g = _Builder()
    pg = g.g
    local, deltas = _local_frame(model, scale, T)
    extensions = []
    if quantize:
        T, pos_acc, targets = _quantized_geometry(g, local, deltas, T, sparse)
        extensions.append("KHR_mesh_quantization")
    else:
        pos_acc, targets = _float_geometry(g, local, deltas, sparse)
    prim = _face_primitive(g, model, pos_acc, targets)
    mesh_weights = model.check_weights(weights).tolist() if weights is not None else []
    meshes, nodes = _extra_mesh_nodes(g, extra_meshes)  # first, as exporters often list eyes before the head
    head = len(nodes)
    meshes.append(pg.Mesh(name=model.name, primitives=[prim], weights=mesh_weights, extras=_mesh_extras(model)))
    nodes.append(pg.Node(mesh=head, name=model.name, matrix=None if np.allclose(T, np.eye(4), atol=0) else T.T.ravel().tolist()))
    animations = [] if animation is None else [_weight_animation(g, model, animation, head)]
    buffers = [pg.Buffer(byteLength=len(g.blob))]
    if meshopt:
        extensions.append("EXT_meshopt_compression")
        buffers = _meshopt_compress(g)
    else:
        for bv in g.views:
            bv.extras = {}
    doc = pg.GLTF2(
        asset=pg.Asset(generator="repro", version="2.0"),
        scene=0, scenes=[pg.Scene(nodes=list(range(len(nodes))))], nodes=nodes, meshes=meshes,
        accessors=g.accessors, bufferViews=g.views, buffers=buffers, animations=animations,
        extensionsUsed=extensions, extensionsRequired=list(extensions),
    )
    _save(doc, bytes(g.blob), path)
    return path


def _check_arguments(model, path, scale, node_matrix, extra_meshes) -> tuple[Path, float, np.ndarray, list]:
    """The model, the path (``.glb``/``.gltf``), metres per unit, the node's 4x4 transform and the extra meshes, checked."""
    if not isinstance(model, BlendshapeModel):
        raise ModelError(f"write_gltf writes a BlendshapeModel, got {describe(model)}")
    if not isinstance(path, (str, os.PathLike)):
        raise ModelError(f"path must be a .glb or .gltf path, got {describe(path)}")
    path = Path(path)
    if path.suffix.lower() not in (".glb", ".gltf"):
        raise ModelError(f"{path}: a glTF file ends in .glb or .gltf")
    if scale is None:
        if model.units not in UNIT_SCALE:
            raise ModelError(f"model units {model.units!r} unknown; pass scale= (metres per unit); known: {sorted(UNIT_SCALE)}")
        scale = UNIT_SCALE[model.units]
    scale = as_real(scale, "scale (metres per model unit)", lo=0, lo_open=True, error=ModelError)
    T = np.eye(4) if node_matrix is None else as_real_array(node_matrix, "node_matrix", shape=(4, 4), error=ModelError)
    if abs(np.linalg.det(T[:3, :3])) < 1e-12:
        raise ModelError("node_matrix must be a finite invertible 4x4 transform")
    if isinstance(extra_meshes, (str, bytes)) or not isinstance(extra_meshes, Sequence):
        raise ModelError(f"extra_meshes must be a sequence of (name, vertices, triangles), got {describe(extra_meshes)}")
    checked = []
    for j, item in enumerate(extra_meshes):
        if not isinstance(item, (tuple, list)) or len(item) != 3 or not isinstance(item[0], str):
            raise ModelError(f"extra_meshes[{j}] must be (name, vertices (k, 3), triangles (t, 3)), got {describe(item)}")
        verts = as_real_array(item[1], f"extra_meshes[{j}] vertices", shape=(None, 3), error=ModelError)
        tris = as_real_array(item[2], f"extra_meshes[{j}] triangles", integer=True, shape=(None, 3), error=ModelError)
        if len(verts) == 0 or len(tris) == 0 or tris.min() < 0 or tris.max() >= len(verts):
            raise ModelError(f"extra_meshes[{j}] needs vertices and triangles indexing them (0..{len(verts) - 1})")
        checked.append((item[0], verts, tris))
    return path, scale, T, checked


def _local_frame(model: BlendshapeModel, scale: float, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The neutral (n, 3) and the deltas (n, 3, m) in metres, in the frame of the node's transform ``T``."""
    Tinv = np.linalg.inv(T)
    n, m = model.n_vertices, model.n_shapes
    world = model.f0 * scale
    local = world @ Tinv[:3, :3].T + Tinv[:3, 3]
    deltas = np.einsum("ij,vjk->vik", Tinv[:3, :3], model.D.reshape(n, 3, m) * scale)
    return local, deltas


def _quantized_geometry(g: _Builder, local, deltas, T, sparse: bool) -> tuple[np.ndarray, int, list[int]]:
    """``KHR_mesh_quantization``: the node's transform times the dequantisation, the position accessor, the targets'."""
    n, _, m = deltas.shape
    lo_, hi_ = local.min(axis=0), local.max(axis=0)
    centre, half = 0.5 * (lo_ + hi_), max(0.5 * float((hi_ - lo_).max()), 1e-12)
    peak = float(np.abs(deltas).max()) if m else 0.0
    if peak > half:
        raise ModelError(f"a delta ({peak:.3g}) exceeds the quantisation range ({half:.3g}); write without quantize")
    Q = np.eye(4)
    Q[:3, :3] *= half
    Q[:3, 3] = centre
    qpos = np.round((local - centre) / half * 32767).astype("<i2")
    qdel = np.round(deltas / half * 32767).astype("<i2")
    padded = np.zeros((n, 4), dtype="<i2")
    padded[:, :3] = qpos
    v = g.view(padded.tobytes(), stride=8, target=34962, count=n)
    pos_acc = g.accessor(v, 5122, n, "VEC3", normalized=True, lo=qpos.min(axis=0).tolist(), hi=qpos.max(axis=0).tolist())
    if sparse:
        targets = [_sparse_target(g, qdel[:, :, k], 5122, "<i2", True) for k in range(m)]
    elif m:  # all targets in one buffer view (fewer JSON objects), one accessor each
        padded = np.zeros((m, n, 4), dtype="<i2")
        padded[:, :, :3] = qdel.transpose(2, 0, 1)
        v = g.view(padded.tobytes(), stride=8, target=34962, count=m * n)
        targets = [g.accessor(v, 5122, n, "VEC3", normalized=True, offset=8 * n * k,
                              lo=qdel[:, :, k].min(axis=0).tolist(), hi=qdel[:, :, k].max(axis=0).tolist())
                   for k in range(m)]
    else:
        targets = []
    return T @ Q, pos_acc, targets


def _float_geometry(g: _Builder, local, deltas, sparse: bool) -> tuple[int, list[int]]:
    """Float32 positions and targets: the position accessor and the targets'."""
    n, _, m = deltas.shape
    pos_acc = g.accessor(g.view(_f32(local), stride=12, target=34962, count=n), 5126, n, "VEC3",
                         lo=local.min(axis=0).astype(np.float32).tolist(), hi=local.max(axis=0).astype(np.float32).tolist())
    d32 = deltas.astype(np.float32)
    if sparse:
        targets = [_sparse_target(g, d32[:, :, k], 5126, "<f4", False) for k in range(m)]
    elif m:  # all targets in one buffer view (fewer JSON objects), one accessor each
        v = g.view(np.ascontiguousarray(d32.transpose(2, 0, 1)).tobytes(), stride=12, target=34962, count=m * n)
        targets = [g.accessor(v, 5126, n, "VEC3", offset=12 * n * k,
                              lo=d32[:, :, k].min(axis=0).tolist(), hi=d32[:, :, k].max(axis=0).tolist())
                   for k in range(m)]
    else:
        targets = []
    return pos_acc, targets


def _face_primitive(g: _Builder, model: BlendshapeModel, pos_acc: int, targets: list[int]):
    """The face's triangles primitive: its positions, indices and morph targets."""
    pg = g.g
    faces = np.ascontiguousarray(model.faces, dtype="<u4")
    prim_kw = {}
    if len(faces):
        iv = g.view(faces.tobytes(), target=34963, count=faces.size, mode="TRIANGLES")
        prim_kw["indices"] = g.accessor(iv, 5125, faces.size, "SCALAR")
    elif model.n_vertices % 3:
        raise ModelError(f"a model without triangles needs a multiple of 3 vertices to be written, has {model.n_vertices}")
    return pg.Primitive(attributes=pg.Attributes(POSITION=pos_acc), mode=4, targets=[{"POSITION": t} for t in targets], **prim_kw)


def _mesh_extras(model: BlendshapeModel) -> dict:
    """The shape names (``targetNames``) and the model's sliders and regions (``repro``), for :func:`read_gltf`."""
    return {
        "targetNames": list(model.names),
        "repro": {
            "sliders": {k: dict(v) for k, v in model.sliders.items()},
            "regions": {k: v.tolist() for k, v in model.regions.items()},
        },
    }


def _extra_mesh_nodes(g: _Builder, extra_meshes: list) -> tuple[list, list]:
    """A mesh and a node for each (name, vertices, triangles) without targets."""
    pg = g.g
    meshes, nodes = [], []
    for name, verts, tris in extra_meshes:
        verts = np.asarray(verts, dtype=np.float32)
        tris = np.ascontiguousarray(tris, dtype="<u4")
        pa = g.accessor(g.view(verts.tobytes(), stride=12, target=34962, count=len(verts)), 5126, len(verts), "VEC3",
                        lo=verts.min(axis=0).tolist(), hi=verts.max(axis=0).tolist())
        ia = g.accessor(g.view(tris.tobytes(), target=34963, count=tris.size, mode="TRIANGLES"), 5125, tris.size, "SCALAR")
        meshes.append(pg.Mesh(name=name, primitives=[pg.Primitive(attributes=pg.Attributes(POSITION=pa), indices=ia, mode=4)]))
        nodes.append(pg.Node(mesh=len(meshes) - 1, name=name))
    return meshes, nodes


def _weight_animation(g: _Builder, model: BlendshapeModel, animation, node: int):
    """The weight animation of ``node``: one LINEAR sampler over the times, one weight vector per time."""
    pg = g.g
    times, frames = _animation_arrays(model, animation)
    ta = g.accessor(g.view(_f32(times), count=times.size), 5126, times.size, "SCALAR",
                    lo=[float(times.min())], hi=[float(times.max())])
    wa = g.accessor(g.view(_f32(frames.ravel()), count=frames.size), 5126, frames.size, "SCALAR")
    return pg.Animation(
        name="weights",
        samplers=[pg.AnimationSampler(input=ta, output=wa, interpolation="LINEAR")],
        channels=[pg.AnimationChannel(sampler=0, target=pg.AnimationChannelTarget(node=node, path="weights"))],
    )


def _sparse_target(g: _Builder, d: np.ndarray, ctype: int, dt: str, normalized: bool) -> int:
    nz = np.flatnonzero(np.any(d != 0, axis=1)).astype("<u4")
    n = len(d)
    if nz.size == 0:
        return g.accessor(None, ctype, n, "VEC3", normalized=normalized, lo=[0, 0, 0], hi=[0, 0, 0])
    vals = np.ascontiguousarray(d[nz], dtype=dt)
    iv = g.view(nz.tobytes(), count=nz.size)
    if vals.itemsize * 3 % 4:  # 16-bit VEC3 values: meshopt rows need 4-byte multiples; store raw
        vv = g.view(vals.tobytes(), count=0)
    else:
        vv = g.view(vals.tobytes(), count=nz.size)
    sp = g.g.Sparse(count=int(nz.size), indices=g.g.AccessorSparseIndices(bufferView=iv, byteOffset=0, componentType=5125),
                    values=g.g.AccessorSparseValues(bufferView=vv, byteOffset=0))
    full = np.zeros_like(d)
    full[nz] = d[nz]
    return g.accessor(None, ctype, n, "VEC3", normalized=normalized, lo=full.min(axis=0).tolist(), hi=full.max(axis=0).tolist(), sparse=sp)


def _meshopt_compress(g: _Builder) -> list:
    """Re-lay ``g``'s views as EXT_meshopt_compression views over a fallback buffer."""
    import meshopt

    pg = g.g
    src = bytes(g.blob)
    out = bytearray()
    fallback = 0
    for bv in g.views:
        info = bv.extras.pop("_meshopt")
        bv.extras = {}
        data = src[bv.byteOffset : bv.byteOffset + bv.byteLength]
        count, stride, mode = info["count"], info["stride"], info["mode"]
        fallback += -fallback % 4
        if count and stride % 4 == 0 and count * stride == len(data):
            arr = np.frombuffer(data, dtype=np.uint8).reshape(count, stride) if mode == "ATTRIBUTES" else np.frombuffer(data, dtype="<u4")
            comp = meshopt.encode_gltf_buffer(arr, mode)
            out += b"\0" * (-len(out) % 4)
            bv.extensions = {"EXT_meshopt_compression": {
                "buffer": 0, "byteOffset": len(out), "byteLength": len(comp), "byteStride": stride,
                "count": count, "mode": mode}}
            out += comp
            bv.buffer, bv.byteOffset = 1, fallback
        else:  # not compressible as rows: stored plain in buffer 0
            out += b"\0" * (-len(out) % 4)
            bv.buffer, bv.byteOffset = 0, len(out)
            out += data
        fallback += bv.byteLength
    g.blob = out
    return [pg.Buffer(byteLength=len(out)),
            pg.Buffer(byteLength=max(fallback, 1), extensions={"EXT_meshopt_compression": {"fallback": True}})]


def _save(doc, blob: bytes, path: Path) -> None:
    """Write the document as .glb (header, JSON and BIN chunks) or .gltf + .bin, atomically."""
    if path.suffix.lower() == ".gltf":
        bin_path = path.with_suffix(".bin")
        doc.buffers[0].uri = bin_path.name
        with atomic_path(bin_path) as tmp:
            tmp.write_bytes(blob)
        text = doc.gltf_to_json()
        with atomic_path(path) as tmp:
            tmp.write_text(text)
        return
    js = doc.gltf_to_json(separators=(",", ":"), indent=None).encode("utf-8")
    js += b" " * (-len(js) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(js) + (8 + len(blob) if blob else 0)
    parts = [GLB_MAGIC, struct.pack("<II", 2, total), struct.pack("<II", len(js), CHUNK_JSON), js]
    if blob:
        parts += [struct.pack("<II", len(blob), CHUNK_BIN), blob]
    with atomic_path(path) as tmp:
        tmp.write_bytes(b"".join(parts))
