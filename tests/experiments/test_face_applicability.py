"""A user's face in the Lewis figures (issue 25, item 7): a ``.vrm`` is a face ``repro run --face`` takes,
and a figure whose session does not apply to a face leaves that face out with the reason in its
``skipped`` table (``<name>-skipped.csv``) instead of failing the run."""

import json
import struct

import pandas as pd
import pytest

from repro.blendshapes import BlendshapeModel, load_model, write_gltf
from repro.blendshapes import scenarios as S
from repro.cli import main
from repro.errors import ModelError
from repro.experiments.lewis import common
from repro.experiments.registry import call_experiment, get
from tests.experiments.test_user_faces import ARKIT  # the embedded face's sliders as an exporter names them

LEWIS = ["fig2_interference", "fig3_attenuation", "fig4_axis_selection", "fig5_alpha", "alpha_sweep",
         "rejected_alternatives", "bounded_attenuation", "direct_manipulation"]


def _face(folder, name, drop=()):
    """The embedded face written as another exporter would (ARKit target names only), without ``drop``."""
    proc = load_model("procedural")
    keep = [i for i, n in enumerate(proc.names) if n in ARKIT and ARKIT[n] not in drop]
    face = BlendshapeModel(proc.f0, proc.D[:, keep], [ARKIT[proc.names[i]] for i in keep], proc.faces, units=proc.units)
    path = folder / name
    write_gltf(face, path)
    if path.suffix == ".gltf":
        doc = json.loads(path.read_text())
        doc["meshes"][0].get("extras", {}).pop("repro", None)
        path.write_text(json.dumps(doc))
    else:  # a GLB: the same edit in its JSON chunk, the BIN chunk kept
        glb = path.read_bytes()
        jlen = struct.unpack_from("<I", glb, 12)[0]
        doc = json.loads(glb[20 : 20 + jlen])
        doc["meshes"][0].get("extras", {}).pop("repro", None)
        j = json.dumps(doc).encode()
        j += b" " * (-len(j) % 4)
        body = struct.pack("<II", len(j), 0x4E4F534A) + j + glb[20 + jlen :]
        path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return path


@pytest.fixture(scope="module")
def smileless(tmp_path_factory):
    """A face without mouthSmile_L/R: no SmirkLeft/Right, so Fig. 4's session and the furrow session
    (whose moves include them) do not apply to it; Fig. 1's and Fig. 5's do."""
    return _face(tmp_path_factory.mktemp("smileless"), "smileless.gltf", drop=("mouthSmile_L", "mouthSmile_R"))


def test_the_sessions_that_do_not_apply_are_the_expected_ones(smileless):
    model = load_model(smileless)
    out = {k for k in S.SCENARIOS if S.scenario(k).not_applicable(model) is not None}
    assert out == {"smirk_corners_y", "furrow_then_mouth"}


@pytest.mark.parametrize("name", [n for n in LEWIS if n != "fig5_alpha"])
def test_a_figure_leaves_out_a_face_its_session_does_not_fit(smileless, name):
    with common.use_faces([smileless]) as (model,):
        result = call_experiment(get(name), quick=True)
    skipped = result.extra_tables["skipped"]
    assert list(skipped.columns) == common.SKIPPED_COLUMNS
    assert set(skipped.model) == {model.name}
    for r in skipped.itertuples():  # the scenarios' own words
        assert r.reason == S.scenario(r.scenario).not_applicable(model)
        assert r.reason
    ran = set(result.table.scenario[result.table.model == model.name]) if "scenario" in result.table else set()
    # figures over every session keep the face's sessions that apply; a figure of one or two sessions
    # leaves the face out as soon as one of them does not fit
    if name in ("alpha_sweep", "rejected_alternatives", "bounded_attenuation", "direct_manipulation"):
        assert ran == {"eyelid_then_brow", "wince_sneer_under_eye"}
    else:
        assert not (result.table.model == model.name).any()


def test_fig5_keeps_the_face_its_session_fits(smileless):
    with common.use_faces([smileless]) as (model,):
        result = call_experiment(get("fig5_alpha"), quick=True)
    assert "skipped" not in result.extra_tables
    assert (result.table.model == model.name).sum() == 3  # alpha 25, default, 3000


def test_the_built_in_faces_have_no_skipped_table():
    for name in ("fig4_axis_selection", "alpha_sweep"):
        assert "skipped" not in call_experiment(get(name), quick=True).extra_tables


def test_applicable_splits_faces_and_says_why(smileless):
    proc, face = load_model("procedural"), load_model(smileless)
    kept, skipped = common.applicable([(proc, 1), (face, 2)], ["eyelid_then_brow", "smirk_corners_y"])
    assert [k for _, k in kept] == [1]
    assert skipped.to_dict("records") == [{"model": face.name, "scenario": "smirk_corners_y",
                                           "reason": S.scenario("smirk_corners_y").not_applicable(face)}]
    runs, skipped = common.applicable_sessions([proc, face], ["eyelid_then_brow", "smirk_corners_y"])
    assert [(m.name, k) for m, k in runs] == [(proc.name, "eyelid_then_brow"), (proc.name, "smirk_corners_y"),
                                              (face.name, "eyelid_then_brow")]
    assert list(skipped.scenario) == ["smirk_corners_y"]
    assert common.skipped_tables(skipped[:0]) == {}


def test_repro_run_writes_the_skipped_reason(smileless, tmp_path):
    out = tmp_path / "figs"
    assert main(["run", "fig4_axis_selection", "--quick", "--out", str(out), "--face", str(smileless)]) == 0
    skipped = pd.read_csv(out / "fig4_axis_selection-skipped.csv")
    assert list(skipped.scenario) == ["smirk_corners_y"]
    assert skipped.reason[0] == S.scenario("smirk_corners_y").not_applicable(load_model(smileless))
    assert "smileless" not in (out / "fig4_axis_selection.csv").read_text()


def test_a_vrm_face_runs_through_repro_run(tmp_path):
    glb = _face(tmp_path, "avatar.glb")
    vrm = tmp_path / "avatar.vrm"
    vrm.write_bytes(glb.read_bytes())  # a VRM is a GLB (its expressions, if any, are sliders too)
    with common.use_faces([vrm]) as (model,):
        assert common.face_inputs()[0]["file"] == "avatar.vrm"
    assert model.n_vertices == load_model("procedural").n_vertices
    out = tmp_path / "figs"
    assert main(["run", "fig4_axis_selection", "--quick", "--out", str(out), "--face", str(vrm)]) == 0
    table = pd.read_csv(out / "fig4_axis_selection.csv")
    assert (table.model == model.name).any()
    assert not (out / "fig4_axis_selection-skipped.csv").exists()


def test_other_suffixes_are_still_refused(tmp_path):
    obj = tmp_path / "face.obj"
    obj.write_text("v 0 0 0\n")
    with pytest.raises(ModelError, match=r"\.vrm"):
        with common.use_faces([obj]):
            pass
    assert main(["run", "fig4_axis_selection", "--quick", "--out", str(tmp_path / "o"), "--face", str(obj)]) == 1
