"""User glTF faces in the Lewis figures (``common.use_faces``, ``repro run --face``)."""

import json

import pytest

from repro.blendshapes import BlendshapeModel, load_model, write_gltf
from repro.errors import ModelError
from repro.experiments.lewis import common
from repro.experiments.registry import call_experiment, get, run_many

ARKIT = {
    "BrowInnerUp": "browInnerUp", "BrowUpLeft": "browOuterUp_L", "BrowUpRight": "browOuterUp_R",
    "BrowDownLeft": "browDown_L", "BrowDownRight": "browDown_R", "BlinkLeft": "eyeBlink_L", "BlinkRight": "eyeBlink_R",
    "EyeWideLeft": "eyeWide_L", "EyeWideRight": "eyeWide_R", "EyeSquintLeft": "eyeSquint_L", "EyeSquintRight": "eyeSquint_R",
    "SneerLeft": "noseSneer_L", "SneerRight": "noseSneer_R", "CheekPuff": "cheekPuff", "JawOpen": "jawOpen",
    "MouthPucker": "mouthPucker", "MouthFunnel": "mouthFunnel", "MouthStretchLeft": "mouthStretch_L",
    "MouthStretchRight": "mouthStretch_R", "SmirkLeft": "mouthSmile_L", "SmirkRight": "mouthSmile_R",
    "MouthFrownLeft": "mouthFrown_L", "MouthFrownRight": "mouthFrown_R",
}


@pytest.fixture(scope="module")
def face_path(tmp_path_factory):
    proc = load_model("procedural")
    keep = [i for i, n in enumerate(proc.names) if n in ARKIT]
    face = BlendshapeModel(proc.f0, proc.D[:, keep], [ARKIT[proc.names[i]] for i in keep], proc.faces, units=proc.units)
    path = tmp_path_factory.mktemp("face") / "my_face.gltf"
    write_gltf(face, path)
    doc = json.loads(path.read_text())
    doc["meshes"][0].get("extras", {}).pop("repro", None)  # as another exporter writes it: ARKit names only
    path.write_text(json.dumps(doc))
    return path


def test_models_include_the_face_only_inside_use_faces(face_path):
    n = len(common.models())
    with common.use_faces([face_path]) as loaded:
        assert len(common.models()) == n + 1
        assert common.models()[-1].name == loaded[0].name
        assert common.face_inputs()[0]["file"] == "my_face.gltf"
    assert len(common.models()) == n and common.face_inputs() == []


@pytest.mark.parametrize("name", ["fig2_interference", "fig3_attenuation", "fig4_axis_selection", "fig5_alpha",
                                  "alpha_sweep", "rejected_alternatives", "bounded_attenuation", "direct_manipulation"])
def test_every_lewis_figure_has_rows_for_the_face(face_path, name):
    exp = get(name)
    with common.use_faces([face_path]) as loaded:
        table = call_experiment(exp, quick=True).table
    assert (table["model"] == loaded[0].name).any()


def test_bad_face_is_one_error_before_any_figure(tmp_path):
    bad = tmp_path / "page.glb"
    bad.write_text("<html>not a face</html>")
    for path in (bad, tmp_path / "missing.glb", tmp_path / "face.obj"):
        with pytest.raises(ModelError):
            run_many(["fig3_attenuation"], tmp_path / "out", quick=True, faces=[path])
    assert not (tmp_path / "out" / "fig3_attenuation.csv").exists()


def test_cli_face_flag_and_cache(face_path, tmp_path):
    from repro.cli import main

    out = str(tmp_path / "figs")
    assert main(["run", "fig3_attenuation", "--quick", "--out", out]) == 0
    key = json.loads((tmp_path / "figs" / "manifest.json").read_text())["fig3_attenuation"]["inputs"]
    assert "faces" not in key
    assert main(["run", "fig3_attenuation", "--quick", "--out", out, "--face", str(face_path)]) == 0
    entry = json.loads((tmp_path / "figs" / "manifest.json").read_text())["fig3_attenuation"]
    assert entry["inputs"]["faces"][0]["file"] == "my_face.gltf"
    assert "my_face.gltf" in (tmp_path / "figs" / "fig3_attenuation.csv").read_text()
    assert main(["run", "fig3_attenuation", "--quick", "--out", out, "--face", str(tmp_path / "nope.glb")]) == 1
