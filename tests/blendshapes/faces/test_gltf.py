"""glTF 2.0 blendshape faces: read (pygltflib container, quantised, meshopt, sparse, node
transforms, several meshes), write back (targets, weights, animation), ARKit names onto the
paper's sliders, and bad files as ModelErrors naming the file."""

from __future__ import annotations

import importlib.util
import json
import struct

import numpy as np
import pygltflib
import pytest

from repro.blendshapes import BlendshapeModel, load_model, scenarios
from repro.blendshapes.faces.arkit import arkit_rig
from repro.blendshapes.faces.gltf import read_gltf
from repro.blendshapes.faces.gltf_document import GltfDocument
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.blendshapes.faces.ict import ICT_SLIDERS
from repro.errors import ModelError
from tests.conftest import REPO

DATA = REPO / "tests" / "data" / "gltf"
F32 = 1e-6  # float32 rounding of coordinates of a few decimetres, in metres


def _script():
    spec = importlib.util.spec_from_file_location("make_gltf_fixtures", REPO / "scripts" / "make_gltf_fixtures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def fixtures():
    return _script()


@pytest.fixture(scope="module")
def expected(fixtures):
    return fixtures.fixture_model()


@pytest.fixture(scope="module")
def face():
    return load_model("procedural")


def _canonical_faces(faces):
    """Triangles up to a cyclic rotation (meshopt's index codec may rotate them, winding kept)."""
    f = np.asarray(faces)
    k = np.argmin(f, axis=1)
    rolled = np.stack([np.roll(row, -s) for row, s in zip(f, k)])
    return rolled[np.lexsort(rolled.T[::-1])]


def _doc(path):
    return GltfDocument(path, path.read_bytes(), 1 << 30).doc


# ---------------------------------------------------------------- round trip
@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize(
    "opts, tol",
    [({}, F32), ({"sparse": True}, F32), ({"quantize": True}, 2e-6), ({"meshopt": True}, F32),
     ({"quantize": True, "meshopt": True, "sparse": True}, 2e-6)],
    ids=["plain", "sparse", "quantized", "meshopt", "all"],
)
def test_procedural_face_round_trips_through_gltf(face, tmp_path, suffix, opts, tol):
    path = tmp_path / f"face{suffix}"
    assert write_gltf(face, path, **opts) == path
    back = load_model(path)
    assert back.units == "m" and back.names == face.names
    # procedural "model units" are centimetres: glTF stores metres
    np.testing.assert_allclose(back.f0, face.f0 * 0.01, rtol=0, atol=tol)
    np.testing.assert_allclose(back.D, face.D * 0.01, rtol=0, atol=tol)
    if opts.get("meshopt"):
        np.testing.assert_array_equal(_canonical_faces(back.faces), _canonical_faces(face.faces))
    else:
        np.testing.assert_array_equal(back.faces, face.faces)
    assert back.sliders == face.sliders
    assert set(back.regions) == set(face.regions)
    for k, v in face.regions.items():
        np.testing.assert_array_equal(back.regions[k], v)
    if suffix == ".gltf":
        assert (tmp_path / "face.bin").is_file()


def test_round_trip_of_a_metre_model_is_exact_to_float32(tmp_path):
    rng = np.random.default_rng(3)
    f0 = rng.normal(size=(30, 3)) * 0.1
    m = BlendshapeModel(f0, rng.normal(size=(90, 4)) * 0.01, ["a", "b", "c", "d"], np.arange(30).reshape(10, 3), units="m")
    write_gltf(m, tmp_path / "m.glb")
    back = load_model(tmp_path / "m.glb")
    np.testing.assert_array_equal(back.f0, f0.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(back.D, m.D.astype(np.float32).astype(np.float64))


def test_weights_and_weight_animation_are_written(face, tmp_path):
    w = face.weights(Furrow=0.4, JawOpen=0.2)
    times = [0.0, 0.5, 1.25]
    frames = [face.weights(), face.weights(Furrow=0.4), face.weights(Furrow=0.4, JawOpen=0.6)]
    path = tmp_path / "anim.glb"
    write_gltf(face, path, weights=w, animation=(times, frames))
    r = GltfDocument(path, path.read_bytes(), 1 << 30)
    mesh = r.doc.meshes[0]
    np.testing.assert_allclose(mesh.weights, w)
    assert mesh.extras["targetNames"] == list(face.names)
    (anim,) = r.doc.animations
    (channel,) = anim.channels
    assert channel.target.path == "weights" and r.doc.nodes[channel.target.node].mesh == 0
    sampler = anim.samplers[channel.sampler]
    np.testing.assert_allclose(r.accessor(sampler.input, "t").ravel(), times)
    np.testing.assert_allclose(r.accessor(sampler.output, "w").reshape(3, -1), np.array(frames), atol=1e-7)


def test_bad_weights_raise_and_leave_an_existing_file_untouched(face, tmp_path):
    path = tmp_path / "face.glb"
    write_gltf(face, path)
    before = path.read_bytes()
    with pytest.raises(ModelError, match="weights"):
        write_gltf(face, path, weights=np.full(face.n_shapes, np.nan))
    with pytest.raises(ModelError, match="strictly increasing"):
        write_gltf(face, path, animation=([1.0, 0.5], [face.weights(), face.weights()]))
    with pytest.raises(ModelError, match=r"\.glb or \.gltf"):
        write_gltf(face, tmp_path / "face.obj")
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["face.glb"]


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
    np.testing.assert_array_equal(_canonical_faces(back.faces), _canonical_faces(expected.faces))


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


# ---------------------------------------------------------------- ARKit names
ARKIT = {
    "BrowInnerUp": "browInnerUp", "BrowUpLeft": "browOuterUp_L", "BrowUpRight": "browOuterUp_R",
    "BrowDownLeft": "browDown_L", "BrowDownRight": "browDown_R", "BlinkLeft": "eyeBlink_L",
    "BlinkRight": "eyeBlink_R", "EyeSquintLeft": "eyeSquint_L", "EyeSquintRight": "eyeSquint_R",
    "SneerLeft": "noseSneer_L", "SneerRight": "noseSneer_R", "JawOpen": "jawOpen",
    "MouthStretchLeft": "mouthStretch_L", "MouthStretchRight": "mouthStretch_R",
    "SmirkLeft": "mouthSmile_L", "SmirkRight": "mouthSmile_R", "MouthFrownLeft": "mouthFrown_L",
    "MouthFrownRight": "mouthFrown_R",
}


def _third_party(face, tmp_path, rename, perm=None):
    """The procedural face under ARKit names, as another exporter would write it (no repro extras)."""
    keep = [i for i, n in enumerate(face.names) if n in ARKIT]
    n = face.n_vertices
    perm = np.arange(n) if perm is None else perm
    inv = np.argsort(perm)
    D = face.D[:, keep].reshape(n, 3, -1)[perm].reshape(3 * n, -1)
    m = BlendshapeModel(face.f0[perm], D, [rename(ARKIT[face.names[i]]) for i in keep], inv[face.faces], units=face.units)
    gpath = tmp_path / "arkit.gltf"
    write_gltf(m, gpath)
    doc = json.loads(gpath.read_text())
    del doc["meshes"][0]["extras"]["repro"]
    doc["asset"]["generator"] = "some exporter"
    gpath.write_text(json.dumps(doc))
    return load_model(gpath)


@pytest.mark.parametrize("style", ["arkit", "camel"])
def test_arkit_names_map_onto_the_papers_sliders_as_for_ict(face, tmp_path, style):
    rename = (lambda s: s) if style == "arkit" else (lambda s: s.replace("_L", "Left").replace("_R", "Right"))
    m = _third_party(face, tmp_path, rename)
    # every ICT slider whose shapes the face has is the same combination
    for slider, combo in ICT_SLIDERS.items():
        if all(rename(s) in m.names for s in combo):
            assert m.sliders[slider] == {rename(s): c for s, c in combo.items()}
    assert m.sliders["BrowUp"] == {rename(s): 1.0 for s in ("browInnerUp", "browOuterUp_L", "browOuterUp_R")}
    # the regions the scenarios select, found from where the shapes move, lie where the
    # procedural face's hand-placed presets are (within 1.1 units = 2.5 grid steps)
    for key in ("brow_middle", "mouth_corners", "under_left_eye"):
        got, want = m.f0[m.regions[key]] / 0.01, face.f0[face.regions[key]]
        assert len(got) == len(want)
        assert np.abs(got - want)[:, :2].max() < 1.1, key
    # every scenario runs and attenuates about as on the procedural face with its own names
    for key in scenarios.SCENARIOS:
        res, ref = scenarios.evaluate(m, key), scenarios.evaluate(face, key)
        assert res["n_selected_vertices"] == ref["n_selected_vertices"]
        assert res["reduction"] < 0.15, (key, res["reduction"])
        assert abs(res["attenuated_unselected_fidelity"] - ref["attenuated_unselected_fidelity"]) < 0.1, key


def test_arkit_regions_follow_the_shapes_not_the_vertex_ids(face, tmp_path):
    plain = _third_party(face, tmp_path, lambda s: s)
    perm = np.random.default_rng(7).permutation(face.n_vertices)
    shuffled = _third_party(face, tmp_path, lambda s: s, perm)
    for key, verts in plain.regions.items():
        np.testing.assert_array_equal(np.sort(perm[shuffled.regions[key]]), np.sort(verts), err_msg=key)


def test_arkit_rig_without_the_shapes_gives_no_regions():
    f0 = np.zeros((4, 3))
    sliders, regions = arkit_rig(f0, np.ones((12, 1)), ["cheekPuff"])
    assert sliders == {} and regions == {}


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


def test_pygltflib_reads_what_we_write(expected, tmp_path):
    """An independent reader (pygltflib's own GLB loader) accepts our container."""
    write_gltf(expected, tmp_path / "f.glb")
    g = pygltflib.GLTF2.load(str(tmp_path / "f.glb"))
    assert g.meshes[0].extras["targetNames"] == list(expected.names)
    assert len(g.binary_blob()) >= expected.n_vertices * 12


# ---------------------------------------------------------------- the real ICT face
@pytest.mark.slow
@pytest.mark.data("ict")
def test_ict_written_as_a_third_party_arkit_face_gets_icts_sliders_and_nearby_regions(tmp_path):
    """ICT's names are ARKit's: through glTF without repro's extras, the ARKit mapping gives
    ICT's own sliders, and regions found from the shapes' motion near ICT's landmark ones."""
    ict = load_model("ict")
    gpath = tmp_path / "ict.gltf"
    write_gltf(ict, gpath, quantize=True, meshopt=True)
    doc = json.loads(gpath.read_text())
    del doc["meshes"][0]["extras"]["repro"]
    gpath.write_text(json.dumps(doc))
    m = load_model(gpath)
    assert m.units == "m" and m.names == ict.names
    assert m.sliders == ict.sliders
    for key, tol_cm in (("mouth_corners", 0.2), ("under_left_eye", 0.8), ("brow_middle", 1.5)):
        got, want = m.f0[m.regions[key]] / 0.01, ict.f0[ict.regions[key]]
        assert len(got) == len(want)
        # each selected vertex lies near the landmark-based selection
        gap = np.linalg.norm(got[:, None] - want[None], axis=2).min(axis=1)
        assert gap.max() < tol_cm, (key, gap)
    for key in scenarios.SCENARIOS:
        res, ref = scenarios.evaluate(m, key), scenarios.evaluate(ict, key)
        assert res["n_selected_vertices"] == ref["n_selected_vertices"]
        assert res["reduction"] < max(1.5 * ref["reduction"], 0.1), key


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
    np.testing.assert_array_equal(_canonical_faces(idx[back.faces]), _canonical_faces(expected.faces))
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
