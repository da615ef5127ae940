"""glTF faces stay inside their bounds (issue 23, sections 2, 3, 4 and 6 for glTF): a buffer
is read only from a regular file inside the model's folder and only its ``byteLength``; the
JSON's counts are bounded before pygltflib builds the document; what one file may make the
loader allocate is summed over its primitives, targets and accessors and checked first; and
``read_gltf`` / ``load_model`` refuse arguments of the wrong type with a ModelError."""

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
from repro.blendshapes.faces.arkit import arkit_rig
from repro.blendshapes.faces.gltf import read_gltf
from repro.errors import ModelError
from tests.conftest import REPO

DATA = REPO / "tests" / "data" / "gltf"


@pytest.fixture(scope="module")
def reference():
    return read_gltf(DATA / "face.gltf")


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


# ------------------------------------------------------------------ section 2: paths
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


# ------------------------------------------------------------------ section 3: sizes
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


# ------------------------------------------------------------------ section 6: arguments
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


# ------------------------------------------------------------------ section 3/4: the command line
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


# ------------------------------------------------------------------ the other public entries of these modules
@pytest.mark.parametrize("args, match", [
    (("x", np.zeros((3, 1)), ["a"]), r"f0 must be an array of real numbers"),
    ((np.zeros((1, 3)), np.zeros((4, 1)), ["a"]), r"D must have shape \(3n, m\) or \(n, 3, m\)"),
    ((np.zeros((1, 3)), np.zeros((3, 2)), ["a"]), r"names must be 2 strings"),
    ((np.zeros((1, 3)), np.zeros((3, 1)), "a"), r"names must be 1 strings"),
    ((np.zeros((1, 3)), np.full((3, 1), np.nan), ["a"]), r"D has 3 NaN/inf"),
])
def test_arkit_rig_refuses_bad_arguments(args, match):
    with pytest.raises(ModelError, match=match):
        arkit_rig(*args)


@pytest.mark.parametrize("kw, match", [
    ({"path": None}, r"path must be a \.glb or \.gltf path"),
    ({"scale": "x"}, r"scale \(metres per model unit\) must be a real number"),
    ({"scale": -1.0}, r"scale .* must be in \(0, inf\)"),
    ({"node_matrix": "eye"}, r"node_matrix must be an array of real numbers"),
    ({"node_matrix": np.eye(3)}, r"node_matrix must have shape \(4, 4\)"),
    ({"quantize": "yes"}, r"quantize must be True or False"),
    ({"sparse": 1}, r"sparse must be True or False"),
    ({"extra_meshes": [("eye", "v", [[0, 1, 2]])]}, r"extra_meshes\[0\] vertices must be an array"),
    ({"extra_meshes": [("eye", np.zeros((3, 3)), [[0, 1, 5]])]}, r"extra_meshes\[0\] needs vertices and triangles"),
    ({"extra_meshes": 5}, r"extra_meshes must be a sequence"),
])
def test_write_gltf_refuses_bad_arguments_before_writing(tmp_path, reference, kw, match):
    from repro.blendshapes.faces.gltf_write import write_gltf

    path = kw.pop("path", tmp_path / "out.glb")
    with pytest.raises(ModelError, match=match):
        write_gltf(reference, path, **kw)
    assert not (tmp_path / "out.glb").exists()
    with pytest.raises(ModelError, match="writes a BlendshapeModel"):
        write_gltf("model", tmp_path / "out.glb")
