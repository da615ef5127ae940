"""ARKit-style shape names onto the paper's sliders and selection regions (repro.blendshapes.faces.arkit),
on faces written as another exporter would (without this package's own sliders and regions)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from repro.blendshapes import BlendshapeModel, load_model, scenarios
from repro.blendshapes.faces.arkit import arkit_rig, canonical_names, neutral_targets
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.blendshapes.faces.ict import ICT_SLIDERS
from repro.errors import ModelError


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


# ---------------------------------------------------------------- arguments
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


# ---------------------------------------------------------------- other tools' spellings of the names
@pytest.mark.parametrize("names, want", [
    # assimp through FBX: a namespace, then a group prefix that several names share
    (["face_shapes.ai_browDown_L", "face_shapes.ai_browDown_R", "face_shapes.ca_jawOpen", "face_shapes.ca_x"],
     ["browDown_L", "browDown_R", "jawOpen", "x"]),
    # Maya namespaces and DAG paths; side suffixes of other tools; ARKit's names in any case
    (["head:eyeBlink.L", "rig|eyeBlink_left", "EyeBlinkRight", "JAWOPEN", "browDownLeft"],
     ["eyeBlink_L", "eyeBlink_L", "eyeBlink_R", "jawOpen", "browDown_L"]),
    # mouthLeft is a shape of its own in ARKit, spelled as the _L form consistently
    (["mouthLeft", "mouth_left", "jawRight"], ["mouth_L", "mouth_L", "jaw_R"]),
    # a prefix only one name carries is part of that name; in-between shapes keep their number
    (["ab_jawOpen", "eyeLowerClose_25_L", "eyeLowerClose_L"], ["ab_jawOpen", "eyeLowerClose_25_L", "eyeLowerClose_L"]),
    # names that mean nothing in ARKit are left as they are
    (["viseme_aa", "mouthOpen", "tongue"], ["viseme_aa", "mouthOpen", "tongue"]),
])
def test_canonical_names_follow_the_conventions_of_other_tools(names, want):
    assert canonical_names(names) == want


def test_neutral_targets_are_found_under_their_conventions():
    assert neutral_targets(["face_shapes.ai_neutral", "face_shapes.ai_jawOpen", "Basis", "neutralize"]) == [0, 2]


def test_a_namespaced_facs_face_gets_the_papers_sliders_and_regions(face, tmp_path):
    """The ARKit face written as assimp writes an FBX blend-shape node: every name prefixed."""
    m = _third_party(face, tmp_path, lambda s: f"face_shapes.ai_{s}")
    plain = _third_party(face, tmp_path, lambda s: s)
    assert set(m.sliders) == set(plain.sliders)
    assert m.sliders["Furrow"] == {"face_shapes.ai_browDown_L": 1.0, "face_shapes.ai_browDown_R": 1.0}
    assert set(m.regions) == set(plain.regions)
    for key, verts in plain.regions.items():
        np.testing.assert_array_equal(m.regions[key], verts, err_msg=key)
