"""Real faces from other tools (issue 25, items 7 and 8 and the FACS names), read from the staged
``faces/formats/realfaces/`` (see its PROVENANCE.md; skipped when it is absent): a Ready Player Me
avatar whose head, eyes and teeth carry the same 69 targets, and a FACS face written by assimp
whose 82 target names carry a ``face_shapes.ai_`` prefix.  (The VRM 0.x avatar is in test_vrm.py.)"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from repro import data
from repro.blendshapes import load_model
from repro.blendshapes.faces.gltf import read_gltf


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
                              "MouthStretch", "Smile", "BrowUp"}
    assert m.sliders["JawOpen"] == {"face_shapes.ca_jawOpen": 1.0}
    assert m.sliders["BrowUp"] == {f"face_shapes.ai_brow{p}Up_{s}": 1.0 for p in ("Inner", "Outer") for s in "LR"}
    assert set(m.regions) == {"brow", "mouth", "nose", "brow_middle", "mouth_corners"}
    # every target stays reachable under its own name, the neutral one and the in-betweens too
    assert set(m.names) <= set(m.slider_names)
    assert m.weights({"face_shapes.ai_eyeLowerClose_25_L": 1.0}).sum() == 1.0
    neutral = [n for n in m.notes if "face_shapes.ai_neutral" in n]
    assert len(neutral) == 1 and "not an expression" in neutral[0] and "at most 3.19e-06 m" in neutral[0]
    assert "face_shapes.ai_neutral" not in {s for combo in m.sliders.values() for s in combo}
