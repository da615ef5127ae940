"""Real faces from other tools (issue 25, items 7 and 8 and the FACS names), read from the staged
``faces/formats/realfaces/`` (see its PROVENANCE.md; skipped when it is absent): a Ready Player Me
avatar whose head, eyes and teeth carry the same 69 targets, and a FACS face written by assimp
whose 82 target names carry a ``face_shapes.ai_`` prefix.  (The VRM 0.x avatar's expressions are
in test_vrm.py.)  On all three, the VRM too: the face found without being told, a target set
whose deltas are all zero refused, and Eq. 3 run without a NaN: each paper session that applies
gives its numbers, each that does not says why."""

from __future__ import annotations

import json
import re
import struct
import warnings

import numpy as np
import pytest

from repro import data
from repro.blendshapes import Attenuator, load_model
from repro.blendshapes import scenarios as S
from repro.blendshapes.attenuation import select_vertices
from repro.blendshapes.faces.gltf import read_gltf
from repro.blendshapes.metrics import selected_motion, unselected_fidelity
from repro.errors import ModelError


def _real(name):
    path = data.data_dir() / "faces/formats/realfaces" / name
    if not path.exists():
        pytest.skip("the real faces are not staged")
    return path


@pytest.fixture(scope="module")
def rpm():
    return _real("rpm_arkit_visemes_69_glasses.glb")


def test_ready_player_me_head_eyes_and_teeth_are_one_face(rpm):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a clear choice: said in the notes, no warning
        m = load_model(rpm)
    assert m.name == "rpm_arkit_visemes_69_glasses.glb:Wolf3D_Head/0+Wolf3D_Teeth/0+EyeLeft/0+EyeRight/0"
    assert (m.n_vertices, m.n_shapes) == (2162 + 84 + 120 + 120, 69)
    assert len(m.sliders) == 11 and len(m.regions) == 8
    head = read_gltf(rpm, mesh="Wolf3D_Head")
    assert (head.n_vertices, head.n_shapes, len(head.sliders), len(head.regions)) == (2162, 69, 11, 8)
    # the head's vertices come first, unchanged, and keep their regions
    np.testing.assert_array_equal(m.f0[:2162], head.f0)
    np.testing.assert_array_equal(m.D[: 3 * 2162], head.D)
    for key, verts in head.regions.items():
        np.testing.assert_array_equal(m.regions[key], verts, err_msg=key)
    # jawOpen moves the teeth, eyeLookUpLeft the left eyeball: one weight, the whole face
    jaw = np.linalg.norm(m.displacement({"jawOpen": 1.0}), axis=1)
    assert jaw[2162:2246].max() > 0.005
    look = np.linalg.norm(m.displacement({"eyeLookUpLeft": 1.0}), axis=1)
    assert look[2246:2366].max() > 0.001
    notes = "\n".join(m.notes)
    assert "meshes Wolf3D_Head, Wolf3D_Teeth, EyeLeft, EyeRight read as one face" in notes
    assert "share 69 target names" in notes and "Wolf3D_Glasses" in notes


def test_an_eye_of_the_avatar_is_still_read_when_asked_for(rpm):
    eye = load_model(rpm, mesh="EyeLeft")
    assert (eye.name, eye.n_vertices, eye.n_shapes) == ("rpm_arkit_visemes_69_glasses.glb:EyeLeft/0", 120, 69)


def test_the_facs_face_with_namespaced_names_gets_the_papers_sliders_and_regions():
    m = load_model(_real("playcanvas_bitmoji_facs82.glb"))
    assert (m.name, m.n_vertices, m.n_shapes) == ("playcanvas_bitmoji_facs82.glb:C_head_GEO/0", 5105, 82)
    assert set(m.sliders) == {"Furrow", "SmirkLeft", "SmirkRight", "SneerLeft", "SneerRight", "JawOpen",
                              "MouthStretch", "Smile", "BrowUp", "Blink", "Wince"}
    # its lids are FACS-named: the upper lid closing is the blink, the lower lid raised the wince's squint
    assert m.sliders["Blink"] == {f"face_shapes.ai_eyeUpperClose_{s}": 1.0 for s in "LR"}
    assert m.sliders["Wince"] == {f"face_shapes.ai_eyeLowerClose_{s}": 1.0 for s in "LR"}
    assert m.sliders["JawOpen"] == {"face_shapes.ca_jawOpen": 1.0}
    assert m.sliders["BrowUp"] == {f"face_shapes.ai_brow{p}Up_{s}": 1.0 for p in ("Inner", "Outer") for s in "LR"}
    assert set(m.regions) == {"brow", "mouth", "nose", "brow_middle", "mouth_corners", "left_eye", "right_eye"}
    # every target stays reachable under its own name, the neutral one and the in-betweens too
    assert set(m.names) <= set(m.slider_names)
    assert m.weights({"face_shapes.ai_eyeLowerClose_25_L": 1.0}).sum() == 1.0
    neutral = [n for n in m.notes if "face_shapes.ai_neutral" in n]
    assert len(neutral) == 1 and "not an expression" in neutral[0] and "at most 3.19e-06 m" in neutral[0]
    assert "face_shapes.ai_neutral" not in {s for combo in m.sliders.values() for s in combo}


# ------------------------------------------------------------------ every real face, end to end
#: For each real face: the meshes read as the face (the model's name), the other meshes the notes
#: name, and the paper's sessions that apply to it (measured; the others say why they do not).
REAL_FACES = {
    "rpm_arkit_visemes_69_glasses.glb": (
        "Wolf3D_Head/0+Wolf3D_Teeth/0+EyeLeft/0+EyeRight/0",
        ["Wolf3D_Glasses", "Wolf3D_Headwear", "Wolf3D_Body", "Wolf3D_Outfit_Bottom", "Wolf3D_Outfit_Footwear",
         "Wolf3D_Outfit_Top"],
        {"eyelid_then_brow", "smirk_corners_y", "wince_sneer_under_eye"}),
    "godette_vrm0_cc_by.vrm": ("FaceMesh/0", ["BodyMesh"], set()),
    "playcanvas_bitmoji_facs82.glb": ("C_head_GEO/0", ["C_main_GEO"], {"smirk_corners_y", "eyelid_then_brow"}),
}
#: Why a session does not apply, for each face (a local mouth leaves the brow exactly still).
NOT_APPLICABLE = {
    ("rpm_arkit_visemes_69_glasses.glb", "furrow_then_mouth"): "there is no interference to attenuate",
    ("playcanvas_bitmoji_facs82.glb", "furrow_then_mouth"): "there is no interference to attenuate",
    ("playcanvas_bitmoji_facs82.glb", "wince_sneer_under_eye"): "needs region 'under_left_eye'",
    ("godette_vrm0_cc_by.vrm", "eyelid_then_brow"): r"needs the sliders \['BrowUp'\]",
    ("godette_vrm0_cc_by.vrm", "furrow_then_mouth"): "needs region 'brow_middle'",
    ("godette_vrm0_cc_by.vrm", "smirk_corners_y"): "needs region 'mouth_corners'",
    ("godette_vrm0_cc_by.vrm", "wince_sneer_under_eye"): "needs region 'under_left_eye'",
}


def _finite(row: dict) -> bool:
    return all(np.isfinite(v) for v in row.values() if isinstance(v, float))


@pytest.fixture(scope="module", params=sorted(REAL_FACES))
def real_face(request):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a clear choice: said in the notes, no warning
        return request.param, load_model(_real(request.param))


def test_every_real_face_gives_its_head_without_being_told_and_names_the_other_meshes(real_face):
    name, m = real_face
    chosen, others, _ = REAL_FACES[name]
    assert m.name == f"{name}:{chosen}"
    meshes = [p.split("/")[0] for p in chosen.split("+")]
    assert m.notes[0].startswith(f"face: mesh{'es' if len(meshes) > 1 else ''} {', '.join(meshes)}")
    assert "chosen as the target set with the most morph motion" in m.notes[0]
    assert f"meshes without morph targets, not read: {', '.join(others)}" in m.notes
    assert np.abs(m.D).max(axis=0).astype(bool).sum() >= m.n_shapes - 1  # RPM's viseme_sil is the one still target


def test_every_paper_session_on_a_real_face_gives_numbers_or_says_why_not(real_face):
    name, m = real_face
    runs = REAL_FACES[name][2]
    att = Attenuator(m)
    for key, sc in S.SCENARIOS.items():
        why = sc.not_applicable(m)
        if key not in runs:
            assert why is not None and re.search(NOT_APPLICABLE[name, key], why), (key, why)
            for call in (S.evaluate, S.compare_methods, S.axis_table):
                with pytest.raises(ModelError, match=re.escape(why)):
                    call(m, key, attenuator=att)
            continue
        assert why is None, (key, why)
        r = S.evaluate(m, key, attenuator=att)
        assert _finite(r) and r["reduction"] < 1.0 and r["attenuated_unselected_fidelity"] > 0, (key, r)
        rows = S.compare_methods(m, key, attenuator=att)
        assert all(_finite(row) for row in rows if row["applicable"])
        sweep = S.alpha_sweep(m, key, [1e-2, 1.0, 1e2, 1e4], attenuator=att)
        assert all(_finite(row) for row in sweep)
        assert all(b["selected_motion"] <= a["selected_motion"] + 1e-15 for a, b in zip(sweep, sweep[1:]))
        if sc.base:
            assert _finite({k: v for k, v in S.interference(m, key).items() if k != "drift"})


def test_eq3_holds_each_region_of_every_real_face_while_its_offered_sliders_move(real_face):
    """Eq. 3 on every face, with or without the paper's sessions: each region selected in turn while
    every slider the face offers (default_sliders) moves to 0.5, at Section 5's default alpha."""
    name, m = real_face
    att = Attenuator(m)
    w1 = m.weights(dict.fromkeys(S.default_sliders(m), 0.5))
    d1 = att.displacement(w1)
    held = 0
    for region, verts in m.regions.items():
        sel = select_vertices(verts, "xyz", m.n_vertices)
        before = selected_motion(d1, sel)
        if before == 0:
            continue
        d2 = att.displacement(att.attenuate(w1, sel))
        assert selected_motion(d2, sel) < 0.5 * before, region
        assert 0 < unselected_fidelity(d2, d1, sel) <= 1, region
        held += 1
    assert held >= 2  # the eyes at least


def test_a_real_avatar_whose_target_deltas_are_all_zero_is_refused(rpm, tmp_path):
    """The Ready Player Me avatar with every morph target's POSITION an accessor without a bufferView
    (all zeros by the glTF spec): no face to read, said with the meshes, not a silent still face."""
    glb = rpm.read_bytes()
    jlen = struct.unpack_from("<I", glb, 12)[0]
    doc = json.loads(glb[20 : 20 + jlen])
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            for target in prim.get("targets", []):
                n = doc["accessors"][prim["attributes"]["POSITION"]]["count"]
                doc["accessors"].append({"componentType": 5126, "count": n, "type": "VEC3"})
                target["POSITION"] = len(doc["accessors"]) - 1
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + glb[20 + jlen :]
    path = tmp_path / "still_avatar.glb"
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    with pytest.raises(ModelError, match=r"still_avatar\.glb: every one of the 4 meshes with targets \(.*Wolf3D_Head.*\) "
                                         r"has morph targets whose deltas are all zero \(69 targets"):
        load_model(path)
    with pytest.raises(ModelError, match="deltas are all zero"):
        load_model(path, mesh="Wolf3D_Head")
