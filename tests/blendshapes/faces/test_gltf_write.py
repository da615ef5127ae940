"""glTF faces written (repro.blendshapes.faces.gltf_write) and read back: float, quantised, sparse and
meshopt storage, .glb and .gltf, weights and a weight animation; bad arguments refused before writing."""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest

from repro.blendshapes import BlendshapeModel, load_model
from repro.blendshapes.faces.gltf_document import GltfDocument
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.errors import ModelError
from tests.blendshapes.faces.conftest import F32, canonical_faces


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
        np.testing.assert_array_equal(canonical_faces(back.faces), canonical_faces(face.faces))
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


def test_pygltflib_reads_what_we_write(expected, tmp_path):
    """An independent reader (pygltflib's own GLB loader) accepts our container."""
    write_gltf(expected, tmp_path / "f.glb")
    g = pygltflib.GLTF2.load(str(tmp_path / "f.glb"))
    assert g.meshes[0].extras["targetNames"] == list(expected.names)
    assert len(g.binary_blob()) >= expected.n_vertices * 12


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
