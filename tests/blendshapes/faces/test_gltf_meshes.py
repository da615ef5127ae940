"""Which meshes of a glTF file make the face (repro.blendshapes.faces.gltf_meshes, issue 25 item 7):
the meshes sharing one set of target names with the most morph motion, read as one face;
all-zero targets refused; the choice said in the model's notes."""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pytest

from repro.blendshapes import load_model
from repro.blendshapes.faces.gltf import read_gltf
from repro.errors import ModelError, ReproWarning
from tests.blendshapes.faces.conftest import DATA, F32

SHIFT = np.array([0.0, -0.05, 0.01])  # where the "teeth" copy of the face is placed


def _avatar(tmp_path, *, teeth=True, eye="small", zero=True, face=True):
    """The fixture face plus other meshes on its accessors, as an avatar exporter writes them:
    ``teeth`` (the face again, shifted, its targets in reverse order under the same names),
    ``eye`` (two of the targets under other names, or all five: ``eye="same"``) and ``zero``
    (a target set whose deltas are all zero)."""
    doc = json.loads((DATA / "face.gltf").read_text())
    shutil.copy(DATA / "face.bin", tmp_path / "face.bin")
    face_mesh = doc["meshes"][0]
    del face_mesh["extras"]["repro"]
    names = face_mesh["extras"]["targetNames"]
    prim = face_mesh["primitives"][0]
    n = doc["accessors"][prim["attributes"]["POSITION"]]["count"]
    meshes, nodes = [], []

    def add(name, targets, target_names, translation=None):
        meshes.append({"name": name, "extras": {"targetNames": target_names},
                       "primitives": [dict(prim, targets=targets)]})
        nodes.append({"name": name, "mesh": len(meshes) - 1} | ({"translation": list(translation)} if translation is not None else {}))

    if eye:
        k = 5 if eye == "same" else 2
        add("eye", prim["targets"][:k], [f"eyeLook_{i}" for i in range(k)])
    if face:
        add("head", prim["targets"], names)
    if teeth:
        add("teeth", prim["targets"][::-1], names[::-1], SHIFT)
    if zero:
        doc["accessors"].append({"componentType": 5126, "type": "VEC3", "count": n})
        add("zero", [{"POSITION": len(doc["accessors"]) - 1}], ["z"])
    doc["meshes"], doc["nodes"], doc["scenes"] = meshes, nodes, [{"nodes": list(range(len(nodes)))}]
    path = tmp_path / "avatar.gltf"
    path.write_text(json.dumps(doc))
    return path


def test_the_meshes_sharing_the_face_target_names_are_read_as_one_face(expected, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a clear choice is said in notes, not warned about
        m = load_model(_avatar(tmp_path))
    n = expected.n_vertices
    assert m.name == "avatar.gltf:head/0+teeth/0" and m.n_vertices == 2 * n
    assert m.names == expected.names  # the first mesh's order; the teeth's reversed targets go by name
    np.testing.assert_allclose(m.f0[:n], expected.f0, atol=F32)
    np.testing.assert_allclose(m.f0[n:], expected.f0 + SHIFT, atol=F32)
    D = m.D.reshape(2, n, 3, -1)
    for half in D:
        np.testing.assert_allclose(half.reshape(3 * n, -1), expected.D, atol=F32)
    np.testing.assert_array_equal(m.faces[len(expected.faces):] - n, m.faces[: len(expected.faces)])
    # one jawOpen moves head and teeth
    moved = np.linalg.norm(m.displacement({"jawOpen": 1.0}), axis=1) > 0
    assert moved[:n].any() and moved[n:].any()
    assert m.sliders["JawOpen"] == {"jawOpen": 1.0} and "brow_middle" in m.regions
    notes = "\n".join(m.notes)
    assert "meshes head, teeth read as one face" in notes and "share 5 target names" in notes
    assert "other meshes with morph targets, not read: eye (2 targets" in notes and "zero (1 targets, motion 0 m)" in notes
    assert read_gltf(_avatar(tmp_path), mesh="auto").name == m.name


def test_one_mesh_is_still_read_when_asked_for(expected, tmp_path):
    path = _avatar(tmp_path)
    head = load_model(path, mesh="head")
    assert head.name == "avatar.gltf:head/0" and head.n_vertices == expected.n_vertices
    assert head.notes[0].startswith(f"face: mesh head ({expected.n_vertices} vertices, 5 targets), asked for")
    np.testing.assert_allclose(load_model(path, mesh="teeth").f0, expected.f0 + SHIFT, atol=F32)
    assert load_model(path, mesh=0).names == tuple(f"eyeLook_{i}" for i in range(2))
    assert read_gltf(path, primitive=0).name == "avatar.gltf:head/0"  # the face's first mesh, that primitive


def test_a_target_set_whose_deltas_are_all_zero_is_refused_naming_it(tmp_path):
    path = _avatar(tmp_path, teeth=False, eye=None, face=False)
    with pytest.raises(ModelError, match=r"avatar\.gltf: the mesh \(zero\) has morph targets whose deltas are all zero "
                                         r"\(1 targets: 'z'\)"):
        load_model(path)
    with pytest.raises(ModelError, match="deltas are all zero"):
        load_model(_avatar(tmp_path), mesh="zero")


def test_a_close_choice_is_warned_about(tmp_path):
    with pytest.warns(ReproWarning, match=r"morph motion is close: eye .* over head .*pass mesh= to choose"):
        m = load_model(_avatar(tmp_path, teeth=False, eye="same", zero=False))
    assert m.name == "avatar.gltf:eye/0"  # a tie: the earlier mesh


def test_meshes_without_names_are_not_merged(expected, tmp_path):
    path = _avatar(tmp_path, eye=None, zero=False)
    doc = json.loads(path.read_text())
    for mesh in doc["meshes"]:
        del mesh["extras"]
    path.write_text(json.dumps(doc))
    with pytest.warns(ReproWarning):  # two unnamed sets of the same motion: which is the face is a guess
        m = load_model(path)
    assert m.name == "avatar.gltf:head/0" and m.n_vertices == expected.n_vertices
