"""glTF 2.0 blendshape faces read (repro.blendshapes.faces.gltf, through the container of
repro.blendshapes.faces.gltf_document): the fixture files (pygltflib container, quantised, meshopt,
sparse, node transforms, several meshes), and bad files as ModelErrors naming the file.

Bounds (issue 23, sections 2, 3, 4 and 6 for glTF): a buffer is read only from a regular file
inside the model's folder and only its ``byteLength``; the JSON's counts are bounded before
pygltflib builds the document; what one file may make the loader allocate is summed over its
primitives, targets and accessors and checked first; and ``read_gltf`` / ``load_model`` refuse
arguments of the wrong type with a ModelError."""

from __future__ import annotations

import json
import os
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from repro.blendshapes import load_model
from repro.blendshapes.faces import gltf, gltf_document
from repro.blendshapes.faces.gltf import read_gltf
from repro.blendshapes.faces.gltf_document import GltfDocument
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.errors import ModelError
from tests.blendshapes.faces.conftest import DATA, F32, canonical_faces


def _doc(path):
    return GltfDocument(path, path.read_bytes(), 1 << 30).doc


# ---------------------------------------------------------------- fixtures
@pytest.mark.parametrize(
    "name, tol",
    [("face.glb", F32), ("face.gltf", F32), ("face_quantized.glb", 1e-6), ("face_meshopt.glb", 1e-6),
     ("face_meshes.glb", F32), ("face_node.glb", 1e-7), ("face_sparse.glb", F32)],
)
def test_fixture_files_hold_the_fixture_face(expected, name, tol):
    back = load_model(DATA / name)
    assert back.names == expected.names and back.units == "m"
    assert back.name.startswith(f"{name}:fixture-face/")
    np.testing.assert_allclose(back.f0, expected.f0, rtol=0, atol=tol)
    np.testing.assert_allclose(back.D, expected.D, rtol=0, atol=tol)
    np.testing.assert_array_equal(canonical_faces(back.faces), canonical_faces(expected.faces))


def test_fixtures_use_the_storage_they_are_named_for():
    q = _doc(DATA / "face_quantized.glb")
    assert "KHR_mesh_quantization" in q.extensionsRequired
    prim = q.meshes[0].primitives[0]
    pos = q.accessors[prim.attributes.POSITION]
    assert pos.componentType == 5122 and pos.normalized
    assert all(q.accessors[t["POSITION"]].componentType == 5122 for t in prim.targets)
    mo = _doc(DATA / "face_meshopt.glb")
    assert "EXT_meshopt_compression" in mo.extensionsRequired
    assert sum("EXT_meshopt_compression" in (bv.extensions or {}) for bv in mo.bufferViews) >= 3
    assert (DATA / "face_meshopt.glb").stat().st_size < 0.6 * (DATA / "face.glb").stat().st_size
    sp = _doc(DATA / "face_sparse.glb")
    targets = [sp.accessors[t["POSITION"]] for t in sp.meshes[0].primitives[0].targets]
    assert all(a.sparse is not None and a.bufferView is None for a in targets)
    assert min(a.sparse.count for a in targets) < targets[0].count
    nd = _doc(DATA / "face_node.glb")
    assert nd.nodes[0].matrix is not None and nd.nodes[0].matrix[0] == pytest.approx(0.01)
    gl = json.loads((DATA / "face.gltf").read_text())
    assert gl["buffers"][0]["uri"] == "face.bin"


def test_node_transform_is_applied_to_neutral_and_deltas(fixtures, expected):
    """Stored in centimetres under scale 0.01 + translation: world metres come back."""
    r = GltfDocument(DATA / "face_node.glb", (DATA / "face_node.glb").read_bytes(), 1 << 30)
    prim = r.doc.meshes[0].primitives[0]
    local = r.accessor(prim.attributes.POSITION, "p")
    local_d = r.accessor(prim.targets[0]["POSITION"], "d")
    np.testing.assert_allclose(local, (expected.f0 - fixtures.NODE_MATRIX[:3, 3]) / 0.01, atol=1e-4)
    np.testing.assert_allclose(local_d, expected.D[:, 0].reshape(-1, 3) / 0.01, atol=1e-4)


def test_rotated_node_applies_the_linear_part_to_deltas(expected, tmp_path):
    c, s = np.cos(0.7), np.sin(0.7)
    T = np.array([[c, 0, s, 0.3], [0, 2.0, 0, -0.1], [-s, 0, c, 1.0], [0, 0, 0, 1]])
    write_gltf(expected, tmp_path / "rot.glb", node_matrix=T)
    back = load_model(tmp_path / "rot.glb")
    np.testing.assert_allclose(back.f0, expected.f0, atol=F32)
    np.testing.assert_allclose(back.D, expected.D, atol=F32)
    assert not np.allclose(GltfDocument(tmp_path / "rot.glb", (tmp_path / "rot.glb").read_bytes(), 1 << 30).accessor(0, "p"), expected.f0, atol=1e-3)


def test_the_mesh_with_targets_is_chosen_and_named(expected):
    doc = _doc(DATA / "face_meshes.glb")
    assert [m.name for m in doc.meshes] == ["eye_L", "fixture-face"]
    back = load_model(DATA / "face_meshes.glb")
    assert back.name == "face_meshes.glb:fixture-face/0" and back.n_vertices == expected.n_vertices
    assert load_model(DATA / "face_meshes.glb", mesh=1).n_vertices == expected.n_vertices
    assert read_gltf(DATA / "face_meshes.glb", mesh="fixture-face", primitive=0).n_vertices == expected.n_vertices
    with pytest.raises(ModelError, match=r"face_meshes\.glb.*no morph targets"):
        load_model(DATA / "face_meshes.glb", mesh="eye_L")
    with pytest.raises(ModelError, match="no mesh named 'nose'"):
        load_model(DATA / "face_meshes.glb", mesh="nose")
    with pytest.raises(ModelError, match="no primitive 3"):
        load_model(DATA / "face_meshes.glb", mesh=1, primitive=3)


def test_primitives_of_one_mesh_with_targets_are_merged(expected, tmp_path):
    gpath = tmp_path / "two.gltf"
    write_gltf(expected, gpath)
    doc = json.loads(gpath.read_text())
    prim = doc["meshes"][0]["primitives"][0]
    # the same vertices again as a second primitive (an exporter's split by material)
    doc["meshes"][0]["primitives"].append(json.loads(json.dumps(prim)))
    gpath.write_text(json.dumps(doc))
    both = load_model(gpath)
    assert both.n_vertices == 2 * expected.n_vertices and both.name.endswith("/0,1")
    np.testing.assert_allclose(both.f0[expected.n_vertices:], expected.f0, atol=F32)
    assert both.faces.max() == 2 * expected.n_vertices - 1
    assert load_model(gpath, primitive=1).n_vertices == expected.n_vertices


def test_target_names_fall_back_to_primitive_extras_then_target_k(expected, tmp_path):
    gpath = tmp_path / "names.gltf"
    write_gltf(expected, gpath)
    doc = json.loads(gpath.read_text())
    names = doc["meshes"][0]["extras"].pop("targetNames")
    del doc["meshes"][0]["extras"]["repro"]
    doc["meshes"][0]["primitives"][0]["extras"] = {"targetNames": names}
    gpath.write_text(json.dumps(doc))
    assert load_model(gpath).names == expected.names
    del doc["meshes"][0]["primitives"][0]["extras"]
    gpath.write_text(json.dumps(doc))
    assert load_model(gpath).names == tuple(f"target_{k}" for k in range(expected.n_shapes))


def test_target_normals_and_tangents_are_ignored(expected, tmp_path):
    gpath = tmp_path / "n.gltf"
    write_gltf(expected, gpath)
    doc = json.loads(gpath.read_text())
    for t in doc["meshes"][0]["primitives"][0]["targets"]:
        t["NORMAL"] = t["TANGENT"] = 10_000  # would be out of range if read
    gpath.write_text(json.dumps(doc))
    np.testing.assert_allclose(load_model(gpath).D, expected.D, atol=F32)


# ---------------------------------------------------------------- bad files
def _gltf(expected, tmp_path, mutate=None, **kw):
    gpath = tmp_path / "bad.gltf"
    write_gltf(expected, gpath, **kw)
    if mutate:
        doc = json.loads(gpath.read_text())
        mutate(doc, tmp_path)
        gpath.write_text(json.dumps(doc))
    return gpath


def _no_targets(doc, _):
    del doc["meshes"][0]["primitives"][0]["targets"]


def _short_target(doc, _):
    doc["accessors"][doc["meshes"][0]["primitives"][0]["targets"][1]["POSITION"]]["count"] -= 5


def _strip(doc, _):
    doc["meshes"][0]["primitives"][0]["mode"] = 5


def _draco(doc, _):
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]


def _missing_bin(doc, tmp):
    (tmp / "bad.bin").unlink()


def _out_of_bounds(doc, _):
    doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["byteOffset"] = 400


def _view_out_of_buffer(doc, _):
    doc["bufferViews"][-1]["byteLength"] += 64


def _huge_count(doc, _):
    for a in doc["accessors"]:
        a["count"] = 10**12


def _nan(doc, tmp):
    acc = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    off = doc["bufferViews"][acc["bufferView"]].get("byteOffset", 0)
    raw = bytearray((tmp / "bad.bin").read_bytes())
    raw[off + 4 : off + 8] = struct.pack("<f", float("nan"))
    (tmp / "bad.bin").write_bytes(bytes(raw))


def _names_wrong_length(doc, _):
    doc["meshes"][0]["extras"]["targetNames"] = ["a"]


def _not_json_schema(doc, _):
    doc["meshes"] = 5


def _many_targets(doc, _):
    prim = doc["meshes"][0]["primitives"][0]
    prim["targets"] = [prim["targets"][0]] * 60_000  # one small accessor, 60,000 times
    doc["meshes"][0]["extras"] = {}


def _remote_buffer(doc, _):
    doc["buffers"][0]["uri"] = "https://example.invalid/face.bin"


def _absolute_buffer(doc, _):
    doc["buffers"][0]["uri"] = "/etc/hostname"


@pytest.mark.parametrize(
    "mutate, match",
    [
        (_no_targets, "no morph targets"),
        (_short_target, "target 1 has 99 vertices, the primitive has 104"),
        (_strip, r"mode 5 \(TRIANGLE_STRIP\); only triangles"),
        (_draco, "unsupported extension.*KHR_draco_mesh_compression"),
        (_missing_bin, r"missing buffer 0 \('bad.bin'\).*no such file"),
        (_out_of_bounds, "out of bounds"),
        (_view_out_of_buffer, r"bufferViews\[\d+\] \(bytes \d+\.\.\d+\) is out of bounds of buffers\[0\]"),
        (_huge_count, "refusing"),
        (_nan, "NaN"),
        (_names_wrong_length, "targetNames"),
        (_not_json_schema, "malformed glTF"),
        (_many_targets, "60000 targets.*refusing"),
        (_remote_buffer, "not a file name relative to the model"),
        (_absolute_buffer, "not a file name relative to the model"),
    ],
    ids=lambda x: getattr(x, "__name__", "")[1:],
)
def test_bad_gltf_files_raise_model_errors_naming_the_file(expected, tmp_path, mutate, match):
    gpath = _gltf(expected, tmp_path, mutate)
    with pytest.raises(ModelError, match=match) as info:
        load_model(gpath)
    assert str(gpath) in str(info.value)


def test_html_page_saved_as_glb_or_gltf(tmp_path):
    page = b"<!DOCTYPE html>\n<html><head><title>Sign in</title></head><body>...</body></html>\n"
    for name in ("face.glb", "face.gltf"):
        (tmp_path / name).write_bytes(page)
        with pytest.raises(ModelError, match="HTML") as info:
            load_model(tmp_path / name)
        assert str(tmp_path / name) in str(info.value)


@pytest.mark.parametrize("keep", [0.999, 0.6, 0.1, 16 / 11900, 6 / 11900])
def test_truncated_glb(tmp_path, keep):
    raw = (DATA / "face.glb").read_bytes()
    path = tmp_path / "cut.glb"
    path.write_bytes(raw[: max(1, int(len(raw) * keep))])
    with pytest.raises(ModelError, match="truncated|not a binary glTF|empty") as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_corrupt_meshopt_stream(tmp_path):
    raw = bytearray((DATA / "face_meshopt.glb").read_bytes())
    json_len = struct.unpack_from("<I", raw, 12)[0]
    bin_start = 20 + json_len + 8
    raw[bin_start + 40 : bin_start + 400] = bytes(range(256)) + bytes(104)
    path = tmp_path / "corrupt.glb"
    path.write_bytes(bytes(raw))
    with pytest.raises(ModelError, match="meshopt could not decode|out of bounds|NaN|indices") as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_missing_file_and_not_gltf(tmp_path):
    with pytest.raises(ModelError, match="no such file"):
        load_model(tmp_path / "nothing.glb")
    (tmp_path / "x.gltf").write_text('{"no": "asset"}')
    with pytest.raises(ModelError, match="no 'asset'"):
        load_model(tmp_path / "x.gltf")
    (tmp_path / "y.gltf").write_text("not json at all")
    with pytest.raises(ModelError, match="not valid glTF JSON"):
        load_model(tmp_path / "y.gltf")


def test_a_face_packed_by_gltfpack_loads(expected):
    """Third-party writer: gltfpack 1.3 -cc (its own quantisation, TRS node under a parent node,
    vertex reordering, meshopt-compressed 16-bit triangle indices) of face.glb."""
    path = DATA / "face_gltfpack.glb"
    doc = _doc(path)
    assert doc.asset.generator.startswith("gltfpack")
    assert {"KHR_mesh_quantization", "EXT_meshopt_compression"} <= set(doc.extensionsRequired)
    assert "repro" not in doc.meshes[0].extras  # a third party keeps only targetNames
    back = load_model(path)
    assert back.names == expected.names and back.n_vertices == expected.n_vertices
    from scipy.spatial import cKDTree

    dist, idx = cKDTree(expected.f0).query(back.f0)
    assert np.unique(idx).size == expected.n_vertices and dist.max() < 1e-5  # gltfpack's 14-bit grid
    np.testing.assert_allclose(back.D.reshape(-1, 3, 5), expected.D.reshape(-1, 3, 5)[idx], atol=1e-5)
    np.testing.assert_array_equal(canonical_faces(idx[back.faces]), canonical_faces(expected.faces))
    # sliders and regions come from the ARKit names, at the same places as the original's
    assert back.sliders == expected.sliders
    for key in ("brow_middle", "mouth_corners"):
        np.testing.assert_array_equal(idx[back.regions[key]], expected.regions[key], err_msg=key)


def _paths(node, prefix=()):
    """Every key path of a JSON document."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


def test_mangled_documents_give_a_model_or_a_model_error(tmp_path):
    """Any field replaced by a value of another type or range: never a bare exception."""
    import shutil

    shutil.copy(DATA / "face.bin", tmp_path / "face.bin")
    doc = json.loads((DATA / "face.gltf").read_text())
    paths = [p for p in _paths(doc) if "repro" not in p and "targetNames" not in p[-2:]]
    rng = np.random.default_rng(11)
    junk = [None, -1, 0, 3, 10**12, 2.5, "x", [], {}, [1, 2], {"a": 1}, True, float("nan")]
    outcomes = {"ok": 0, "error": 0}
    for _ in range(120):
        mangled = json.loads(json.dumps(doc))
        where = paths[rng.integers(len(paths))]
        node = mangled
        for key in where[:-1]:
            node = node[key]
        node[where[-1]] = junk[rng.integers(len(junk))]
        (tmp_path / "face.gltf").write_text(json.dumps(mangled))
        try:
            load_model(tmp_path / "face.gltf")
            outcomes["ok"] += 1
        except ModelError as exc:
            assert "face.gltf" in str(exc)
            outcomes["error"] += 1
    assert outcomes["error"] > 20


def test_flipped_bytes_in_a_glb_give_a_model_or_a_model_error(tmp_path):
    raw = (DATA / "face_meshopt.glb").read_bytes()
    rng = np.random.default_rng(12)
    for _ in range(60):
        b = bytearray(raw)
        for i in rng.integers(0, len(b), size=4):
            b[i] = rng.integers(256)
        (tmp_path / "f.glb").write_bytes(bytes(b))
        try:
            load_model(tmp_path / "f.glb")
        except ModelError as exc:
            assert "f.glb" in str(exc)


def test_load_model_takes_paths_and_still_knows_its_names(tmp_path):
    from pathlib import Path

    assert load_model(DATA / "face.glb").n_vertices == load_model(str(DATA / "face.glb")).n_vertices
    assert isinstance(DATA / "face.glb", Path)
    assert load_model("procedural").name == "procedural"
    with pytest.raises(ModelError, match="unknown model 'bingo'"):
        load_model("bingo")


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
@pytest.mark.parametrize("kind", ["list", "dict"])
def test_deeply_nested_json_is_a_model_error(tmp_path, suffix, kind):
    # fuzz finding: a 2,000-deep JSON value in the document raised a bare RecursionError
    import shutil

    deep = "[" * 2000 + "1" + "]" * 2000 if kind == "list" else '{"a":' * 2000 + "1" + "}" * 2000
    doc = json.loads((DATA / "face.gltf").read_text())
    text = json.dumps(doc).replace('"asset": {', f'"extras": {deep}, "asset": {{', 1)
    assert deep in text
    if suffix == ".gltf":
        shutil.copy(DATA / "face.bin", tmp_path / "face.bin")
        path = tmp_path / "deep.gltf"
        path.write_text(text)
    else:  # the same document as the JSON chunk of a GLB (no BIN chunk: the buffer stays external)
        shutil.copy(DATA / "face.bin", tmp_path / "face.bin")
        js = text.encode() + b" " * (-len(text) % 4)
        body = struct.pack("<II", len(js), 0x4E4F534A) + js
        path = tmp_path / "deep.glb"
        path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    with pytest.raises(ModelError, match=r"deep\.gl(tf|b): malformed glTF \(JSON nested too deeply\)"):
        load_model(path)


def _face(folder: Path, uri: str | None = "face.bin", edit=None) -> Path:
    """The fixture ``face.gltf`` copied into ``folder`` with its buffer ``uri`` replaced (and ``edit(doc)``)."""
    folder.mkdir(parents=True, exist_ok=True)
    doc = json.loads((DATA / "face.gltf").read_text())
    shutil.copy(DATA / "face.bin", folder / "face.bin")
    if uri is not None:
        doc["buffers"][0]["uri"] = uri
    if edit:
        edit(doc)
    path = folder / "face.gltf"
    path.write_text(json.dumps(doc))
    return path


def _to_root(folder: Path) -> str:
    """``../`` enough times to climb from ``folder`` to ``/``."""
    return "../" * (len(Path(os.path.realpath(folder)).parts) - 1)


def _glb(js: dict, bin_: bytes | None = None) -> bytes:
    j = json.dumps(js).encode()
    j += b" " * (-len(j) % 4)
    out = struct.pack("<II", len(j), 0x4E4F534A) + j
    if bin_ is not None:
        b = bin_ + b"\0" * (-len(bin_) % 4)
        out += struct.pack("<II", len(b), 0x004E4942) + b
    return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


def bomb(n_prims: int, n: int = 87_000, m: int = 32) -> bytes:
    """A few KB of GLB whose ``n_prims`` primitives share one zero-filled ``n``-vertex accessor for all ``m`` targets."""
    prim = {"attributes": {"POSITION": 0}, "targets": [{"POSITION": 0}] * m}
    return _glb({"asset": {"version": "2.0"}, "accessors": [{"componentType": 5126, "type": "VEC3", "count": n}],
                 "meshes": [{"name": "bomb", "primitives": [prim] * n_prims}]})


# ---------------------------------------------------------------- bounds (issue 23, section 2): paths
def test_a_buffer_outside_the_folder_is_refused_even_when_it_holds_a_valid_face(tmp_path):
    shutil.copy(DATA / "face.bin", tmp_path / "outside.bin")  # a complete face would be built from it
    path = _face(tmp_path / "a" / "b", "../../outside.bin")
    with pytest.raises(ModelError, match=r"buffers\[0\] uri '\.\./\.\./outside\.bin' leads outside its folder"):
        read_gltf(path)


@pytest.mark.parametrize("uri", [
    "{root}etc/passwd",
    "{root_pct}etc/passwd",  # %2e%2e: percent-decoded before the check
    "{root}proc/self/environ",
    "{root}dev/zero",  # would stream forever (2 GiB before the old size cap)
    "%2E%2E/%2e%2e/outside.bin",
    "sub/../../../outside.bin",
])
def test_buffer_uris_that_climb_out_are_refused_before_reading(tmp_path, uri):
    shutil.copy(DATA / "face.bin", tmp_path / "outside.bin")
    folder = tmp_path / "a" / "b"
    folder.mkdir(parents=True)
    root = _to_root(folder)
    uri = uri.format(root=root, root_pct=root.replace("..", "%2e%2e"))
    path = _face(folder, uri)
    with pytest.raises(ModelError, match="leads outside its folder") as info:
        read_gltf(path)
    assert str(path) in str(info.value)


def test_a_buffer_symlinked_out_of_the_folder_is_refused(tmp_path):
    shutil.copy(DATA / "face.bin", tmp_path / "outside.bin")
    for target in ("/etc/passwd", str(tmp_path / "outside.bin")):
        folder = tmp_path / Path(target).name.replace(".", "_")
        path = _face(folder)
        (folder / "face.bin").unlink()
        (folder / "face.bin").symlink_to(target)
        with pytest.raises(ModelError, match="leads outside its folder"):
            read_gltf(path)


def test_a_symlink_that_stays_inside_the_folder_is_read(tmp_path, reference):
    path = _face(tmp_path, "link.bin")
    (tmp_path / "link.bin").symlink_to("face.bin")
    np.testing.assert_array_equal(read_gltf(path).D, reference.D)


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_buffer_that_is_not_a_regular_file_is_refused_without_waiting(tmp_path, kind):
    path = _face(tmp_path)
    (tmp_path / "face.bin").unlink()
    if kind == "fifo":
        os.mkfifo(tmp_path / "face.bin")  # nobody writes: a plain open() would wait forever
    else:
        (tmp_path / "face.bin").mkdir()
    with pytest.raises(ModelError, match="buffer 0 .*(FIFO|folder).*only regular files are read|is a folder"):
        read_gltf(path)


def test_the_gltf_file_itself_as_a_fifo_is_refused(tmp_path):
    os.mkfifo(tmp_path / "pipe.glb")
    with pytest.raises(ModelError, match="FIFO"):
        load_model(tmp_path / "pipe.glb")


def test_byte_length_bounds_what_is_read(tmp_path, reference):
    path = _face(tmp_path)
    with open(tmp_path / "face.bin", "ab") as fh:  # a larger file: only byteLength bytes are read
        fh.write(b"\xff" * 100_000)
    model = read_gltf(path)
    np.testing.assert_array_equal(model.D, reference.D)
    (tmp_path / "face.bin").write_bytes((DATA / "face.bin").read_bytes()[:-4])
    with pytest.raises(ModelError, match=r"buffers\[0\] file 'face\.bin' is 9500 bytes, shorter than its byteLength 9504"):
        read_gltf(path)


def test_max_bytes_bounds_the_file_and_its_buffers_together(tmp_path):
    path = _face(tmp_path)
    size = path.stat().st_size
    read_gltf(path, max_bytes=size + 9504)
    with pytest.raises(ModelError, match=r"byteLength 9504 would bring what is read to more than max_bytes"):
        read_gltf(path, max_bytes=size + 9503)


def test_a_huge_declared_byte_length_is_refused_before_reading(tmp_path):
    path = _face(tmp_path, edit=lambda d: d["buffers"][0].update(byteLength=1 << 40))
    with pytest.raises(ModelError, match="more than max_bytes"):
        read_gltf(path)


# ---------------------------------------------------------------- bounds (section 3): sizes
@pytest.mark.parametrize("n_prims", [1, 10, 20])
def test_primitives_sharing_a_zero_filled_accessor_are_refused_before_allocating(tmp_path, n_prims):
    path = tmp_path / "bomb.glb"
    path.write_bytes(bomb(n_prims))
    assert path.stat().st_size < 14_000
    with pytest.raises(ModelError, match=rf"asks for .* of vertex data across {n_prims} primitive\(s\).*"
                                         r"accessor 0 is used \d+ times.*the cap for this file is 64 MiB") as info:
        load_model(path)
    assert "bomb.glb" in str(info.value)


def test_the_allocation_cap_grows_with_the_data_a_file_holds(tmp_path, monkeypatch):
    # the same shapes with real (float32) data are a legitimate face: 64x its bytes is plenty
    n, m = 3000, 8
    pos = np.random.default_rng(0).normal(size=(n, 3)).astype("<f4")
    deltas = np.random.default_rng(1).normal(size=(m, n, 3)).astype("<f4")
    blob = pos.tobytes() + deltas.tobytes()
    accessors = [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": n}]
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes}]
    for k in range(m):
        views.append({"buffer": 0, "byteOffset": pos.nbytes * (k + 1), "byteLength": pos.nbytes})
        accessors.append({"bufferView": k + 1, "componentType": 5126, "type": "VEC3", "count": n})
    prim = {"attributes": {"POSITION": 0}, "targets": [{"POSITION": k + 1} for k in range(m)]}
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(blob)}], "bufferViews": views,
           "accessors": accessors, "meshes": [{"primitives": [prim]}]}
    (tmp_path / "ok.glb").write_bytes(_glb(doc, blob))
    model = load_model(tmp_path / "ok.glb")
    assert model.D.shape == (3 * n, m)
    monkeypatch.setattr(gltf, "MODEL_BYTES_FLOOR", 1 << 10)
    monkeypatch.setattr(gltf, "MODEL_BYTES_RATIO", 1)  # the stated cap, not the machine, decides
    with pytest.raises(ModelError, match=r"the cap for this file is .*1x the"):
        load_model(tmp_path / "ok.glb")


def _nodes(count):
    return lambda d: d.update(nodes=[{"name": f"n{i}"} for i in range(count)])


@pytest.mark.parametrize("edit, match", [
    (_nodes(100_000), r"has 100000 nodes, more than the 4096 .*MAX_NODES"),
    (lambda d: d.update(meshes=d["meshes"] * 2000), r"has 2000 meshes, more than the 1024 .*MAX_MESHES"),
    (lambda d: d["meshes"][0].update(primitives=d["meshes"][0]["primitives"] * 5000),
     r"has 5000 mesh primitives, more than the 4096 .*MAX_PRIMITIVES"),
    (lambda d: d.update(materials=[{}] * 20_000), r"has 20\d\d\d glTF objects .*MAX_OBJECTS"),
])
def test_counts_are_bounded_before_the_document_is_built(tmp_path, edit, match):
    path = _face(tmp_path, edit=edit)
    with pytest.raises(ModelError, match=match):
        read_gltf(path)


@pytest.mark.parametrize("edit", [
    lambda d: d["accessors"][0].update(max=[0.0] * 150_000),
    lambda d: d["nodes"][0].update(children=[0] * 150_000),
    lambda d: d.update(scenes=[{"nodes": [0] * 150_000}]),
    lambda d: d["meshes"][0].update(weights=[0.0] * 150_000),
    lambda d: d["meshes"][0]["primitives"][0]["attributes"].update({f"A{i}": 0 for i in range(150_000)}),
], ids=["accessor_max", "children", "scene_nodes", "weights", "attributes"])
def test_long_lists_inside_objects_are_bounded_before_the_document_is_built(tmp_path, edit):
    # pygltflib converts each value (~20 us): 200,000 numbers in one accessor's "max" took 4 s
    with pytest.raises(ModelError, match=r"more than 100000 JSON values .*MAX_VALUES"):
        read_gltf(_face(tmp_path, edit=edit))


def test_extras_and_extensions_are_not_counted(tmp_path, reference):
    path = _face(tmp_path, edit=lambda d: d.update(extras={"big": [0] * 150_000}))
    np.testing.assert_array_equal(read_gltf(path).D, reference.D)


def test_the_count_limits_are_generous_for_real_avatars(tmp_path, reference):
    def avatar(d):  # a rig of 600 bones above the face, 40 more meshes (no targets), 300 materials
        d["nodes"] = [{"name": f"bone{i}", "children": [i + 1]} for i in range(600)] + [dict(d["nodes"][0])]
        d["scenes"] = [{"nodes": [0]}]
        d["scene"] = 0
        d["meshes"] += [{"name": f"m{i}", "primitives": [{"attributes": {"POSITION": 0}}]} for i in range(40)]
        d["materials"] = [{"name": f"mat{i}"} for i in range(300)]

    model = read_gltf(_face(tmp_path, edit=avatar))
    np.testing.assert_allclose(model.D, reference.D)


# ---------------------------------------------------------------- bounds (section 6): arguments
@pytest.mark.parametrize("kw, match", [
    ({"foo": 1}, r"takes only mesh=, primitive= and max_bytes=, got \['foo'\]"),
    ({"max_bytes": "10"}, r"max_bytes must be an integer, got '10'"),
    ({"max_bytes": 0}, r"max_bytes must be an integer in 1\.\."),
    ({"max_bytes": 1e9}, r"max_bytes must be an integer"),
    ({"mesh": 1.5}, r"mesh= .* must be an integer"),
    ({"mesh": True}, r"mesh= .* must be an integer, got the bool"),
    ({"mesh": [0]}, r"mesh= .* must be an integer"),
    ({"mesh": -1}, r"mesh= .* must be an integer in 0\.\."),
    ({"primitive": "0"}, r"primitive= must be an integer"),
    ({"primitive": -1}, r"primitive= must be an integer in 0\.\."),
    ({"primitive": None, "mesh": None}, None),
])
def test_load_model_and_read_gltf_refuse_bad_arguments(kw, match):
    if match is None:
        assert load_model(DATA / "face.glb", **kw).n_vertices > 0
        return
    with pytest.raises(ModelError, match=match):
        load_model(DATA / "face.glb", **kw)
    if "foo" not in kw:
        with pytest.raises(ModelError, match=match):
            read_gltf(DATA / "face.glb", **kw)


def test_read_gltf_refuses_a_stream_clearly():
    with open(DATA / "face.glb", "rb") as fh, pytest.raises(ModelError, match="reads a path .*got <_io.BufferedReader"):
        read_gltf(fh)
    for bad in (None, 3, b"face.glb"):
        with pytest.raises(ModelError, match="reads a path"):
            read_gltf(bad)


def test_load_model_ict_refuses_unknown_keywords_before_looking_for_data():
    with pytest.raises(ModelError, match=r"load_model\('ict'\) takes only face_only=, shapes= and cache=, got \['foo'\]"):
        load_model("ict", foo=1)


# ---------------------------------------------------------------- bounds (sections 3, 4): the command line
@pytest.mark.parametrize("kind", ["bomb", "fifo"])
def test_repro_run_with_a_bad_face_prints_one_line_and_fails(tmp_path, capsys, kind):
    from repro.cli import main

    face = tmp_path / ("bomb.glb" if kind == "bomb" else "pipe.glb")
    if kind == "bomb":
        face.write_bytes(bomb(20))
    else:
        os.mkfifo(face)
    rc = main(["run", "fig4_axis_selection", "--quick", "--face", str(face), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 1
    lines = [line for line in err.splitlines() if line.startswith("repro:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert ("vertex data" if kind == "bomb" else "FIFO") in lines[0]


def test_meshopt_decoding_is_bounded_per_file_not_per_view(monkeypatch):
    # face_meshopt.glb decodes views of 832, 4160 and 2016 bytes; its size bound is 64 KiB x the ratio
    monkeypatch.setattr(gltf_document, "_MESHOPT_MAX_RATIO", 0.1)  # 6.5 KB: each view fits, the three together do not
    with pytest.raises(ModelError, match=r"7008 for the file's meshopt views so far; refusing"):
        read_gltf(DATA / "face_meshopt.glb")
