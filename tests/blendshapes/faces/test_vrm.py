"""VRM avatars (issue 25 item 8): a ``.vrm`` is read as the GLB it is, and its expressions (VRM 0.x
``blendShapeGroups``, VRM 1.0 ``expressions``) become named sliders built from their morph-target
binds (repro.blendshapes.faces.vrm).  VRM 1.0 on a synthetic file (the fixture face written with
write_gltf plus a ``VRMC_vrm`` extension); VRM 0.x on the same and on the real Godette avatar."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from repro import data
from repro.blendshapes import load_model
from repro.blendshapes.faces.arkit import ARKIT_SLIDERS
from repro.blendshapes.faces.gltf import read_gltf
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.blendshapes.faces.vrm import vrm_expressions
from repro.blendshapes.scenarios import PAPER_SLIDERS, default_sliders
from repro.errors import ModelError

NAMES = ("browDown_L", "browDown_R", "mouthSmile_L", "mouthSmile_R", "jawOpen")  # the fixture face's targets


def _with_extension(glb: bytes, edit) -> bytes:
    """A GLB with ``edit(doc)`` applied to its JSON chunk (the BIN chunk kept)."""
    jlen = struct.unpack_from("<I", glb, 12)[0]
    doc = json.loads(glb[20 : 20 + jlen])
    edit(doc)
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    rest = glb[20 + jlen :]
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + rest
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _vrm(expected, tmp_path, extension: str, value, name="avatar.vrm", target_names=None):
    """The fixture face as a ``.vrm``: no repro extras, the VRM extension ``extension`` = ``value``
    (and the targets renamed ``target_names``)."""
    glb = tmp_path / "face.glb"
    write_gltf(expected, glb)

    def edit(doc):
        del doc["meshes"][0]["extras"]["repro"]
        if target_names is not None:
            doc["meshes"][0]["extras"]["targetNames"] = list(target_names)
        doc["extensions"] = {extension: value}
        doc["extensionsUsed"] = [extension]

    path = tmp_path / name
    path.write_bytes(_with_extension(glb.read_bytes(), edit))
    return path


def _binds1(*pairs):
    return {"morphTargetBinds": [{"node": 0, "index": NAMES.index(s), "weight": w} for s, w in pairs]}


VRM1 = {
    "specVersion": "1.0",
    "expressions": {
        "preset": {
            "happy": _binds1(("mouthSmile_L", 1.0), ("mouthSmile_R", 1.0)),
            "aa": _binds1(("jawOpen", 0.8)),
            "blinkLeft": _binds1(("browDown_L", 1.0)),
            "blinkRight": _binds1(("browDown_R", 1.0)),
            "neutral": {},
            "angry": {"morphTargetBinds": [{"node": 7, "index": 0, "weight": 1.0}]},  # no such node
        },
        "custom": {
            "smirk": _binds1(("mouthSmile_L", 0.5), ("mouthSmile_L", 0.25)),  # binds to one target add up
            "jawOpen": _binds1(("jawOpen", 1.0)),  # a shape at weight 1: no slider of its own
            "mouthSmile_R": _binds1(("mouthSmile_R", 0.5)),  # a shape's name: renamed
            "wide": {"morphTargetBinds": [{"node": 0, "index": 99, "weight": 1.0}, {"node": 0, "index": 4, "weight": 2.0},
                                          {"node": 0, "index": 4, "weight": float("nan")}, {"node": 0, "index": 3, "weight": "1"},
                                          {"node": 0, "index": 2, "weight": 0.5}]},
        },
    },
}


def test_vrm_1_expressions_become_sliders(expected, tmp_path):
    m = load_model(_vrm(expected, tmp_path, "VRMC_vrm", VRM1))
    assert m.name == "avatar.vrm:fixture-face/0" and m.names == expected.names
    np.testing.assert_allclose(m.D, expected.D, atol=1e-6)
    s = m.sliders
    assert s["happy"] == {"mouthSmile_L": 1.0, "mouthSmile_R": 1.0}
    assert s["aa"] == {"jawOpen": 0.8} and s["smirk"] == {"mouthSmile_L": 0.75}
    assert s["mouthSmile_R_expression"] == {"mouthSmile_R": 0.5} and "jawOpen" not in s
    assert s["wide"] == {"mouthSmile_L": 0.5}
    assert "neutral" not in s and "angry" not in s
    # the blinks stand for ARKit's eyeBlink_L/R: the paper's Blink slider and the eye regions
    assert s["Blink"] == {"browDown_L": 1.0, "browDown_R": 1.0}
    assert {"left_eye", "right_eye"} <= set(m.regions)
    np.testing.assert_array_equal(m.weights(happy=0.5), m.weights(mouthSmile_L=0.5, mouthSmile_R=0.5))
    notes = "\n".join(m.notes)
    for said in ("'neutral' has no usable morph-target bind", "'angry': 1 bind(s) skipped: node 7 is not a node of the file",
                 "'jawOpen' is the shape 'jawOpen' at weight 1", "its slider is 'mouthSmile_R_expression'",
                 "'wide': 4 bind(s) skipped: target index 99 of mesh 0 (it has 5 targets) (and 3 more)"):
        assert said in notes
    assert read_gltf(m_path := tmp_path / "avatar.vrm").sliders == s and load_model(str(m_path)).sliders == s


def test_vrm_0_groups_weigh_0_to_100_and_name_customs_by_name(expected, tmp_path):
    groups = [
        {"name": "Joy", "presetName": "joy", "binds": [{"mesh": 0, "index": 2, "weight": 100}, {"mesh": 0, "index": 3, "weight": 50}]},
        {"name": "Blink_L", "presetName": "blink_l", "binds": [{"mesh": 0, "index": 0, "weight": 100}], "isBinary": True},
        {"name": "Pout", "presetName": "unknown", "binds": [{"mesh": 0, "index": 4, "weight": 25}]},
        {"name": "Body", "presetName": "fun", "binds": [{"mesh": 3, "index": 0, "weight": 100}]},  # not the face
        {"name": "Over", "presetName": "sorrow", "binds": [{"mesh": 0, "index": 0, "weight": 150}]},
        {"name": "Zero", "presetName": "lookup", "binds": [{"mesh": 0, "index": 0, "weight": 0}]},
        "not an object", {"binds": []},
        {"name": "Joy", "presetName": "joy", "binds": [{"mesh": 0, "index": 4, "weight": 100}]},
    ]
    m = load_model(_vrm(expected, tmp_path, "VRM", {"blendShapeMaster": {"blendShapeGroups": groups}}))
    s = m.sliders
    assert s["joy"] == {"mouthSmile_L": 1.0, "mouthSmile_R": 0.5} and s["blink_l"] == {"browDown_L": 1.0}
    assert s["Pout"] == {"jawOpen": 0.25}
    assert not {"fun", "sorrow", "lookup", "Blink"} & set(s)  # Blink needs both eyes
    assert "left_eye" in m.regions and "right_eye" not in m.regions
    notes = "\n".join(m.notes)
    for said in ("'fun': 1 bind(s) skipped: mesh 3 is not part of the face read", "weight 150 of target 0 is not a number in 0..100",
                 "'lookup' binds its targets at weight 0 only", "blendShapeGroups[6] is not an object",
                 "blendShapeGroups[7] has no presetName or name", "'joy' appears twice"):
        assert said in notes


@pytest.mark.parametrize("value", [
    "a string", None, 3, [], {"blendShapeMaster": 3}, {"blendShapeMaster": {"blendShapeGroups": {"a": 1}}},
    {"blendShapeMaster": {"blendShapeGroups": [{"presetName": 5, "name": None}, {"name": "x", "binds": "no"},
                                                {"name": "y", "binds": [None, 3, {"mesh": True, "index": 0, "weight": 1}]},
                                                {"name": "z", "binds": [{"mesh": 0, "index": -1, "weight": 1}]},
                                                {"name": "w", "binds": {"mesh": 0, "index": 0, "weight": 100}}]}},
])
@pytest.mark.parametrize("extension", ["VRM", "VRMC_vrm"])
def test_odd_vrm_json_is_skipped_with_a_reason_never_a_bare_exception(expected, tmp_path, extension, value):
    if extension == "VRMC_vrm" and isinstance(value, dict) and "blendShapeMaster" in value:
        value = {"expressions": {"preset": value["blendShapeMaster"], "custom": [1]}}
    m = load_model(_vrm(expected, tmp_path, extension, value))
    assert m.names == expected.names
    assert set(m.sliders) - set(ARKIT_SLIDERS) <= {"w"}  # only the bind given as an object alone is usable
    assert m.notes


def test_vrm_binds_are_bounded(expected, tmp_path):
    many = {"blendShapeMaster": {"blendShapeGroups": [{"name": "x", "binds": [{"mesh": 0, "index": 0, "weight": 1}] * 20_001}]}}
    with pytest.raises(ModelError, match=r"avatar\.vrm: .*more than 20000 morph-target binds"):
        load_model(_vrm(expected, tmp_path, "VRM", many))


def test_a_file_with_both_versions_reads_the_1_0_expressions():
    out = vrm_expressions({"VRM": {}, "VRMC_vrm": VRM1}, {0: list(NAMES)}, [0], NAMES)
    assert out.version == "1.0" and "happy" in out.sliders and "both the VRM 0.x and 1.0" in out.notes[0]
    assert vrm_expressions({"KHR_x": {}}, {0: list(NAMES)}, [0], NAMES).version is None


# ------------------------------------------------ the sliders a VRM face offers (issue 25: not Blink alone)
OWN = ("lidL", "lidR", "grin", "pout", "drop")  # the fixture's targets under names that mean nothing in ARKit
ONLY_BLINKS = {
    "VRM": {"blendShapeMaster": {"blendShapeGroups": [
        {"name": "Blink_L", "presetName": "blink_l", "binds": [{"mesh": 0, "index": 0, "weight": 100}]},
        {"name": "Blink_R", "presetName": "blink_r", "binds": [{"mesh": 0, "index": 1, "weight": 100}]},
        {"name": "Neutral", "presetName": "neutral", "binds": []}]}},
    "VRMC_vrm": {"specVersion": "1.0", "expressions": {"preset": {
        "blinkLeft": {"morphTargetBinds": [{"node": 0, "index": 0, "weight": 1.0}]},
        "blinkRight": {"morphTargetBinds": [{"node": 0, "index": 1, "weight": 1.0}]}, "neutral": {}}}},
}


@pytest.mark.parametrize("extension", ["VRM", "VRMC_vrm"])
def test_a_vrm_whose_expressions_bind_only_the_blinks_offers_its_other_targets_too(expected, tmp_path, extension):
    """Only the blink presets bound: the paper's Blink alone would be all a user could move; the
    face's own expressions and the targets no expression binds follow (VRM 0.x groups and 1.0 presets)."""
    m = load_model(_vrm(expected, tmp_path, extension, ONLY_BLINKS[extension], target_names=OWN))
    left, right = ("blink_l", "blink_r") if extension == "VRM" else ("blinkLeft", "blinkRight")
    assert m.sliders == {"Blink": {"lidL": 1.0, "lidR": 1.0}, left: {"lidL": 1.0}, right: {"lidR": 1.0}}
    assert default_sliders(m) == ("Blink", left, right, "grin", "pout", "drop")


@pytest.mark.parametrize("extension", ["VRM", "VRMC_vrm"])
def test_a_vrm_face_that_plays_the_paper_offers_the_papers_sliders(expected, tmp_path, extension):
    m = load_model(_vrm(expected, tmp_path, extension, ONLY_BLINKS[extension]))  # the fixture's ARKit names
    assert default_sliders(m) == tuple(s for s in PAPER_SLIDERS if s in m.slider_names)
    assert "Blink" in default_sliders(m) and "SmirkLeft" in default_sliders(m)


# ---------------------------------------------------------------- the real VRM 0.x avatar
def test_godette_vrm_0_avatar_has_its_17_expressions_as_sliders():
    path = data.data_dir() / "faces/formats/realfaces/godette_vrm0_cc_by.vrm"
    if not path.exists():
        pytest.skip("the real faces are not staged")
    m = load_model(path)
    assert m.name == "godette_vrm0_cc_by.vrm:FaceMesh/0" and (m.n_vertices, m.n_shapes) == (630, 15)
    assert m.names[3:5] == ("blink_left", "blink_right")  # named in the primitive's extras
    presets = ["a", "i", "u", "e", "o", "blink", "joy", "angry", "sorrow", "fun",
               "lookup", "lookdown", "lookleft", "lookright", "blink_l", "blink_r"]
    assert set(m.sliders) == set(presets) | {"Blink"}  # neutral binds nothing
    assert m.sliders["angry"] == {"angled_eyebrows": 1.0, "ah": 0.25, "blink_left": 0.25, "blink_right": 0.25}
    assert m.sliders["Blink"] == {"blink_left": 1.0, "blink_right": 1.0}
    assert set(m.regions) == {"left_eye", "right_eye"}
    assert any("'neutral' has no usable morph-target bind" in n for n in m.notes)
    assert read_gltf(path).sliders == m.sliders


def test_godette_offers_its_expressions_and_the_targets_they_leave_out():
    """Issue 25: the face app opened Godette with the paper's Blink as its only slider."""
    path = data.data_dir() / "faces/formats/realfaces/godette_vrm0_cc_by.vrm"
    if not path.exists():
        pytest.skip("the real faces are not staged")
    m = load_model(path)
    offered = default_sliders(m)
    assert offered == ("Blink", "a", "i", "u", "e", "o", "blink", "joy", "angry", "sorrow", "fun", "lookup", "lookdown",
                       "lookleft", "lookright", "blink_l", "blink_r", "HideHairBalls", "HdieEarRings")
    moved = {s for o in offered for s in (m.sliders[o] if o in m.sliders else {o: 1.0})}
    assert moved == set(m.names)  # every target can be moved from the sliders offered
