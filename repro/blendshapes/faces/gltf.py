"""glTF 2.0 blendshape faces in: the morph targets of a mesh primitive as a delta model.

A glTF face is a mesh primitive whose ``POSITION`` is the neutral ``f0`` and
whose morph ``targets`` hold the deltas ``d_k`` (glTF stores targets as
displacements, exactly the delta form of Lewis et al. 2005, Section 3), named
in ``mesh.extras.targetNames``.  :func:`read_gltf` turns such a file (``.gltf``
with its buffers, ``.glb``, or a VRM avatar's ``.vrm``) into a :class:`BlendshapeModel` in metres;
:func:`~repro.blendshapes.faces.gltf_write.write_gltf` writes one back, optionally
with default weights and a weight animation, so a slider session opens in
Blender or a browser viewer.  The file is read through
:class:`~repro.blendshapes.faces.gltf_document.GltfDocument` (the container, buffers and
accessors, and the library that parses them).

What is read
------------
* The face, found without being told (``mesh=None`` or ``"auto"``, the default):
  the meshes with morph targets grouped by their set of target names, the group
  with the most morph motion read as one face, its meshes merged (an avatar's
  head, eyes and teeth that share ARKit names: one ``jawOpen`` moves head and
  teeth); a face whose deltas are all zero is refused
  (:mod:`~repro.blendshapes.faces.gltf_meshes`).  ``mesh=`` (a name or an index;
  a mesh named ``"auto"`` by its index) reads that one mesh.  Primitives of a mesh
  with its largest number of targets are merged (exporters split a mesh by
  material), unless ``primitive=`` picks one (of the face's first mesh when the
  face is found).  The choice is recorded in the model's ``name``,
  ``"<file>:<mesh>/<primitives>"`` (meshes joined by ``+``), and said in words, with
  the other meshes, in its ``notes``.
* The mesh's world placement (node ``matrix`` or TRS, through the scene
  graph) is applied to the neutral; the deltas get its linear part.
* Targets' ``NORMAL`` and ``TANGENT`` are ignored.
* Names: ``mesh.extras.targetNames``, else the primitive's, else
  ``target_0, target_1, ...``.  A target that is the neutral pose itself
  (``neutral``, ``face_shapes.ai_neutral``: :func:`~repro.blendshapes.faces.arkit.neutral_targets`)
  is no expression: it stays a shape of its own (every target can be set by its
  name), used by no named slider or region, and a note gives how far it moves.
* Sliders and regions: a file written by :func:`~repro.blendshapes.faces.gltf_write.write_gltf` carries the
  model's own (``mesh.extras.repro``); any other face gets the paper's
  sliders through ARKit-style names (also namespaced FACS names such as
  ``face_shapes.ai_browDown_L``) and regions found from where the named
  shapes move (:func:`~repro.blendshapes.faces.arkit.arkit_rig`).  A VRM avatar's
  expressions (``extensions.VRM`` 0.x or ``VRMC_vrm`` 1.0) are sliders too
  (:func:`~repro.blendshapes.faces.vrm.vrm_expressions`; what of them cannot be used
  is skipped and said in the model's ``notes``).

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

import struct
from pathlib import Path

import numpy as np

from repro.blendshapes.faces.arkit import arkit_rig, neutral_targets
from repro.blendshapes.faces.gltf_document import GltfDocument
from repro.blendshapes.faces.gltf_meshes import MeshPart, choose_face, merge
from repro.blendshapes.faces.vrm import vrm_expressions
from repro.blendshapes.model import BlendshapeModel
from repro.checks import MEMORY_BUDGET, as_int, describe
from repro.errors import ModelError
from repro.io import MAX_READ_BYTES, read_bytes

__all__ = ["read_gltf", "MODEL_BYTES_RATIO", "MODEL_BYTES_FLOOR"]

_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES", 5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}
#: What one file may make the loader allocate (summed over every primitive, morph target and
#: accessor it materialises, as float64, before anything is allocated): at most this many times
#: the bytes of the file and the buffers it uses (a float32 target takes 2x as float64, a quantised
#: one 4-8x, a sparse one more) ...
MODEL_BYTES_RATIO = 64
#: ... or this many bytes (64 MiB), whichever is more; never more than :data:`repro.checks.MEMORY_BUDGET`.
MODEL_BYTES_FLOOR = 64 << 20


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


def _world_of_mesh(r: GltfDocument, mesh_index: int) -> tuple[np.ndarray, str]:
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


def _target_names(r: GltfDocument, mesh, prim, m: int) -> list[str]:
    for owner in (mesh, prim):
        names = (owner.extras or {}).get("targetNames") if isinstance(owner.extras, dict) else None
        if names is not None:
            if not isinstance(names, list) or len(names) != m or not all(isinstance(s, str) for s in names):
                raise r.err(f"extras.targetNames of mesh {mesh.name!r} must be {m} strings, one per target, got {names!r:.120}")
            return names
    return [f"target_{k}" for k in range(m)]


def _plan(r: GltfDocument, parts: list[tuple[int, list[int]]]) -> None:
    """Check what reading the primitives ``prims`` of each mesh ``mi`` in ``parts`` will allocate.

    Sums, before anything is allocated, every array the loader materialises for this file:
    the neutral and the dense float64 deltas of every primitive (and the model's own copies;
    one more copy when several meshes are merged into one face), the faces, and the largest
    accessor being decoded; refuses the file above
    ``min(MEMORY_BUDGET, max(MODEL_BYTES_RATIO x bytes of the file and its buffers, MODEL_BYTES_FLOOR))``.
    Primitives sharing one accessor (a 7 KB file whose 20 primitives all point at one
    zero-filled 87k-vertex accessor, x 32 targets) count once per use: each use is a copy.
    """
    uses: dict[int, int] = {}
    n_total = faces_total = dense = n_prims = m = 0
    for mi, prims in parts:
        mesh = r.doc.meshes[mi]
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
            dense += n * 3 * m * 8
            n_prims += 1
    for a in sorted(uses):
        r.buffers_of(a)
    transient = 0
    for a in uses:
        acc, _, dtype, _, ncomp, count = r.meta(a, "size")
        copies = 2 if acc.sparse is not None else 1
        transient = max(transient, count * ncomp * (copies * dtype.itemsize + 8))
    # deltas and neutral (ours, the merged face's, the model's copies), their finiteness masks, faces twice, one accessor
    copies = 2 if len(parts) == 1 else 3
    need = copies * dense + dense // 8 + (copies * n_total * 3 + 2 * faces_total) * 8 + transient
    cap = min(MEMORY_BUDGET, max(MODEL_BYTES_RATIO * r.read_total, MODEL_BYTES_FLOOR))
    if need > cap:
        shared, times = max(uses.items(), key=lambda kv: (kv[1], -kv[0]))
        why = f"; accessor {shared} is used {times} times" if times > 1 else ""
        where = f"meshes[{parts[0][0]}]" if len(parts) == 1 else f"meshes {[mi for mi, _ in parts]}"
        sizes = f"{n_total} vertices x {m} targets" if len(parts) == 1 else f"{n_total} vertices, {dense // 24} vertex-targets"
        raise r.err(
            f"asks for {_size(need)} of vertex data across {n_prims} primitive(s) of {where} "
            f"({sizes} in all, as float64{why}); the cap for this file is {_size(cap)} "
            f"({MODEL_BYTES_RATIO}x the {_size(r.read_total)} of the file and its buffers, at least {_size(MODEL_BYTES_FLOOR)}, "
            f"at most the memory budget {_size(MEMORY_BUDGET)}); refusing"
        )


def _size(n: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n >= 1 << shift:
            return f"{n / (1 << shift):.3g} {unit}"
    return f"{n} bytes"


def _read_primitive(r: GltfDocument, mi: int, pj: int, f0_out: np.ndarray, d_out: np.ndarray) -> tuple[int, np.ndarray]:
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


def _n_targets(mesh) -> int:
    return max((len(p.targets or []) for p in mesh.primitives or []), default=0)


def _choose(r: GltfDocument, mesh, primitive) -> list[tuple[int, list[int]]]:
    """The meshes to read, each with its primitives: the one asked for, or (``mesh=None``) every mesh with targets."""
    meshes = r.doc.meshes or []
    if not meshes:
        raise r.err("has no meshes")
    if mesh is None:
        candidates = [i for i, m in enumerate(meshes) if any(p.targets for p in m.primitives or [])]
        if not candidates:
            raise r.err(
                f"has no morph targets (blendshapes): none of its {len(meshes)} meshes "
                f"{[m.name for m in meshes]} has a primitive with targets"
            )
        return [(mi, _primitives(r, mi, None)) for mi in candidates]
    if isinstance(mesh, str):
        hits = [i for i, m in enumerate(meshes) if m.name == mesh]
        if not hits:
            raise r.err(f"has no mesh named {mesh!r}; meshes: {[m.name for m in meshes]}")
        mi = hits[0]
    else:
        mi = r.integer(mesh, "mesh=")
        r.item("meshes", mi)
    return [(mi, _primitives(r, mi, primitive))]


def _primitives(r: GltfDocument, mi: int, primitive) -> list[int]:
    """Mesh ``mi``'s primitives to read: ``primitive``, or all those with the mesh's largest number of targets."""
    prims = r.doc.meshes[mi].primitives or []
    name = r.doc.meshes[mi].name
    if not prims:
        raise r.err(f"meshes[{mi}] ({name!r}) has no primitives")
    m = _n_targets(r.doc.meshes[mi])
    if m == 0:
        raise r.err(f"meshes[{mi}] ({name!r}) has no morph targets (blendshapes)")
    if primitive is not None:
        pj = r.integer(primitive, "primitive=")
        if pj >= len(prims):
            raise r.err(f"meshes[{mi}] has {len(prims)} primitives, no primitive {pj}")
        if not prims[pj].targets:
            raise r.err(f"meshes[{mi}] primitive {pj} has no morph targets (blendshapes)")
        return [pj]
    return [j for j, p in enumerate(prims) if len(p.targets or []) == m]


def _read_mesh(r: GltfDocument, mi: int, prims: list[int]) -> MeshPart:
    """Mesh ``mi``'s primitives ``prims`` read into one neutral and delta array, in world placement."""
    gmesh = r.doc.meshes[mi]
    m = len(gmesh.primitives[prims[0]].targets)
    n_total = sum(r.meta(gmesh.primitives[j].attributes.POSITION, "size")[5] for j in prims)
    # one neutral and one delta array for all primitives, filled in place (no per-primitive copies)
    f0 = np.empty((n_total, 3))
    D3 = np.zeros((n_total, 3, m))
    faces_parts, o = [], 0
    for j in prims:
        n, fc = _read_primitive(r, mi, j, f0[o:], D3[o:])
        faces_parts.append(fc + o)
        o += n
    names = _target_names(r, gmesh, gmesh.primitives[prims[0]], m)
    M, _ = _world_of_mesh(r, mi)
    L = M[:3, :3]
    f0 = f0 @ L.T + M[:3, 3]
    if not np.array_equal(L, np.eye(3)):
        step = max(1, (1 << 22) // max(1, 3 * m))  # in place, a block of vertices at a time
        for s in range(0, n_total, step):
            D3[s : s + step] = np.einsum("ij,vjk->vik", L, D3[s : s + step])
    named = names != [f"target_{k}" for k in range(m)]
    return MeshPart(mi, gmesh.name or f"mesh{mi}", prims, f0, D3, np.concatenate(faces_parts), names, named)


def read_gltf(
    path, *, mesh: str | int | None = None, primitive: int | None = None, max_bytes: int = MAX_READ_BYTES
) -> BlendshapeModel:
    """A glTF 2.0 face (``.gltf``, ``.glb`` or ``.vrm``) as a delta blendshape model in metres.

    Parameters
    ----------
    path : path
        The file; a ``.gltf``'s external buffers are read beside it.
    mesh : str or int, optional
        The mesh to read (name or index); default (None or ``"auto"``) the face found in the
        file: the meshes sharing one set of target names with the most morph motion, as one face.
    primitive : int, optional
        One primitive of that mesh (of the face's first mesh by default); default all its
        primitives with its largest number of targets, merged.
    max_bytes : int, default :data:`repro.io.MAX_READ_BYTES`
        Cap on the bytes read: the file and the buffers it uses, together.  What the file may
        make the loader allocate is bounded separately (:data:`MODEL_BYTES_RATIO`), and so are
        its counts (the ``MAX_*`` of :mod:`~repro.blendshapes.faces.gltf_document`).

    Returns
    -------
    BlendshapeModel
        ``units="m"``, ``name="<file>:<mesh>/<primitives>"`` (which meshes and primitives were
        read, ``+`` between meshes), ``notes`` saying why and what else the file holds; neutral
        and deltas in world placement (the node's transform; deltas get its linear part); names
        from ``extras.targetNames``.  Sliders and regions: the model's own when the file was
        written by :func:`~repro.blendshapes.faces.gltf_write.write_gltf`, else
        :func:`~repro.blendshapes.faces.arkit.arkit_rig`; and a VRM file's expressions.

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
    if mesh == "auto":
        mesh = None
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
    r = GltfDocument(p, raw, max_bytes)
    auto = mesh is None
    chosen = _choose(r, mesh, None if auto else primitive)
    _plan(r, chosen)  # what this will allocate, checked first
    parts = [_read_mesh(r, mi, prims) for mi, prims in chosen]
    read = {mi for mi, _ in chosen}
    others = [m.name or f"mesh{i}" for i, m in enumerate(r.doc.meshes) if i not in read and not _n_targets(m)]
    try:
        group, notes = choose_face(parts, without_targets=others, auto=auto)
    except ModelError as exc:
        raise r.err(str(exc)) from None
    if auto and primitive is not None:  # one primitive of the face's first mesh
        group = [_read_mesh(r, group[0].mi, _primitives(r, group[0].mi, primitive))]
        notes[0] += f"; primitive {primitive} only"
    f0, D3, faces, names = merge(group)
    del parts
    D = D3.reshape(-1, D3.shape[2])
    label = f"{p.name}:{'+'.join(g.where for g in group)}"
    gmesh = r.doc.meshes[group[0].mi]
    extra = (gmesh.extras or {}).get("repro") if isinstance(gmesh.extras, dict) and len(group) == 1 else None
    try:
        vrm = vrm_expressions(r.doc.extensions, {g.mi: g.names for g in group},
                              [getattr(n, "mesh", None) for n in r.doc.nodes or []], names)
    except ModelError as exc:
        raise r.err(str(exc)) from None
    notes += _neutral_notes(D3, names) + vrm.notes
    try:
        if isinstance(extra, dict):
            sliders = dict(extra.get("sliders") or {})
            regions = {k: np.asarray(v, dtype=np.int64) for k, v in (extra.get("regions") or {}).items()}
        else:
            sliders, regions = arkit_rig(f0, D, names, aliases=vrm.aliases)
        for key, combo in vrm.sliders.items():
            if key in sliders:
                notes.append(f"VRM expression {key!r} has the name of another slider: its slider is {key + '_expression'!r}")
                key += "_expression"
            sliders[key] = combo
        return BlendshapeModel(f0=f0, D=D, names=names, faces=faces, name=label, units="m", sliders=sliders,
                               regions=regions, notes=notes)
    except (ModelError, TypeError, ValueError, AttributeError) as exc:
        raise r.err(f"mesh {gmesh.name!r} does not make a blendshape model: {exc}") from None


def _neutral_notes(D3: np.ndarray, names: list[str]) -> list[str]:
    """A note for each target that is the neutral pose itself (:func:`~repro.blendshapes.faces.arkit.neutral_targets`)."""
    notes = []
    for k in neutral_targets(names):
        move = np.linalg.norm(D3[:, :, k], axis=1)
        notes.append(f"target {names[k]!r} is the neutral pose, not an expression: kept as a shape of its own, in no "
                     f"named slider or region (it moves {np.count_nonzero(move)} vertices, at most {move.max():.3g} m)")
    return notes
