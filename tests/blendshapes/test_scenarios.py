"""The paper's scenarios on the embedded face: the qualitative claims of Figs. 1-5 and Section 3."""

import re

import numpy as np
import pytest

from repro.blendshapes import BlendshapeModel, load_model
from repro.blendshapes import scenarios as S
from repro.errors import ModelError


@pytest.fixture(scope="module")
def face():
    return load_model("procedural")


@pytest.mark.parametrize("key", ["eyelid_then_brow", "furrow_then_mouth"])
def test_interference_exists_without_attenuation(face, key):
    r = S.interference(face, key)
    assert r["first_move_selected"] > 0.1
    assert r["drift_relative"] > 0.1  # the further moves drag what the first move positioned
    assert r["drift"].shape == (face.n_vertices,)


def test_furrow_drift_is_downward(face):
    """Fig. 2c: 'the middle of the brow has continued to move downward'."""
    assert S.interference(face, "furrow_then_mouth")["drift_selected_dy"] < -0.05


@pytest.mark.parametrize("key", ["furrow_then_mouth", "smirk_corners_y", "wince_sneer_under_eye"])
def test_default_alpha_holds_selection_within_10_percent(face, key):
    r = S.evaluate(face, key)
    assert r["reduction"] <= 0.10
    assert r["attenuated_unselected_fidelity"] > 0.3  # the rest still moves
    assert r["alpha"] == r["default_alpha"]


def test_fig5_default_alpha_is_335(face):
    assert S.evaluate(face, "wince_sneer_under_eye")["alpha"] == pytest.approx(335.0)


def test_per_axis_selection_keeps_y_while_x_moves(face):
    """Fig. 4: the corners keep their vertical position but move along x."""
    rows = {(r["vertex"], r["method"]): r for r in S.axis_table(face, "smirk_corners_y")}
    for v in face.regions["mouth_corners"]:
        none, att = rows[(int(v), "none")], rows[(int(v), "attenuated")]
        assert abs(none["dy"]) > 0.3 and abs(att["dy"]) < 0.05 * abs(none["dy"])
        assert abs(att["dx"]) > 0.5 * abs(none["dx"]) > 0.1


def test_alpha_sweep_monotone_and_limits(face):
    alphas = np.logspace(-3, 6, 19)
    rows = S.alpha_sweep(face, "wince_sneer_under_eye", alphas)
    frac = [r["selected_motion_fraction"] for r in rows]
    assert all(b <= a + 1e-12 for a, b in zip(frac, frac[1:]))
    assert rows[0]["w_change_vs_w1"] < 1e-3  # alpha -> 0: w2 -> w1
    assert rows[0]["unselected_fidelity"] > 0.999
    assert frac[-1] < 1e-3  # alpha -> infinity: S w2 -> 0
    # the caption of Fig. 5e, not the body text: at high alpha the unselected vertices move less too
    assert rows[-1]["unselected_fidelity"] < rows[0]["unselected_fidelity"] - 0.2


def test_zeroing_rows_degrades_smoothness_more_than_attenuation(face):
    for key in ["furrow_then_mouth", "wince_sneer_under_eye"]:
        rows = {r["method"]: r for r in S.compare_methods(face, key)}
        assert rows["zeroed_rows"]["selected_motion"] == 0.0
        assert rows["zeroed_rows"]["roughness_at_selection"] > 1.5 * rows["attenuation"]["roughness_at_selection"]


def test_orthogonal_lock_only_where_a_base_pose_exists(face):
    fig3 = {r["method"]: r for r in S.compare_methods(face, "furrow_then_mouth")}
    assert fig3["orthogonal_lock"]["applicable"]
    # Section 3: locking the Furrow shape does not keep the brow vertices still
    assert fig3["orthogonal_lock"]["selected_motion"] > 5 * fig3["attenuation"]["selected_motion"]
    fig5 = {r["method"]: r for r in S.compare_methods(face, "wince_sneer_under_eye")}
    assert not fig5["orthogonal_lock"]["applicable"] and np.isnan(fig5["orthogonal_lock"]["selected_motion"])


def test_unknown_scenario_and_missing_region(face):
    with pytest.raises(ModelError, match="unknown scenario"):
        S.evaluate(face, "nope")
    sub = face.restrict(np.arange(100))
    with pytest.raises(ModelError, match="needs region"):
        S.evaluate(sub, "furrow_then_mouth")


@pytest.mark.data("ict")
def test_real_model_numbers_are_computed_and_attenuation_helps():
    """On the ICT model: report, do not tune. Attenuation still reduces the selected motion everywhere."""
    ict = load_model("ict")
    for key in S.SCENARIOS:
        r = S.evaluate(ict, key)
        assert r["reduction"] < 1.0
        assert np.isfinite(r["attenuated_unselected_fidelity"])


def test_scenario_arguments_are_checked(face):
    """Found by tests/fuzz/test_fuzz_arguments_blendshapes.py (issue 23 section 6)."""
    for moves in ({1: 0.5}, {"JawOpen": np.nan}, {"JawOpen": "x"}):  # NaN came back as NaN weights
        with pytest.raises(ModelError, match="Scenario.moves|slider name"):
            S.Scenario("k", "f", "d", region="brow_middle", moves=moves)
    with pytest.raises(ModelError, match="Scenario.base"):
        S.Scenario("k", "f", "d", region="brow_middle", moves={}, base={"Furrow": np.inf})
    sc = S.scenario("eyelid_then_brow")
    for method in (sc.vertices, sc.selection, sc.weights, sc.lockable_shapes, sc.not_applicable, sc.check,
                   S.default_sliders):  # AttributeError before
        with pytest.raises(ModelError, match="expected a BlendshapeModel"):
            method("procedural")
    for alphas in (np.array(1.0), [None, 1.0], [[1.0], [1.0, 2.0]], np.ones((2, 2))):  # TypeError before
        with pytest.raises(ModelError, match="alphas"):
            S.alpha_sweep(face, "furrow_then_mouth", alphas)
    rows = S.alpha_sweep(face, "furrow_then_mouth", (a for a in (1.0, 10.0)))  # a generator still works
    assert [r["alpha"] for r in rows] == [1.0, 10.0]


# ------------------------------------------------- sessions that do not apply to a face: said, never NaN
def _local_face():
    """Four vertices far apart; shape ``a`` moves vertices 0 and 1, ``b`` 0 and 2, ``c`` only 3, ``d`` only 0."""
    D = np.zeros((12, 4))
    D[[0, 3], 0] = 1.0
    D[[1, 7], 1] = 0.5
    D[10, 2] = 0.25
    D[2, 3] = 2.0
    return BlendshapeModel(np.arange(12.0).reshape(4, 3), D, ["a", "b", "c", "d"], [[0, 1, 2], [1, 2, 3]],
                           name="local", sliders={"ab": {"a": 1.0, "b": 1.0}}, regions={"r": [0]})


def _session(**kw):
    return S.Scenario("k", "Fig. x", "a session on the local face", **{"region": "r", **kw})


def _every_function(model, sc):
    return [lambda: S.evaluate(model, sc), lambda: S.compare_methods(model, sc), lambda: S.axis_table(model, sc),
            lambda: S.alpha_sweep(model, sc, [1.0, 10.0]), lambda: S.interference(model, sc)]


@pytest.mark.parametrize("kw, why", [
    (dict(base={"a": 0.5}, moves={"c": 0.5}), "leave the selected xyz coordinates of 'r' exactly still: there is no interference"),
    (dict(base={"c": 0.5}, moves={"b": 0.5}), r"first move \(c 0.5\) leaves the selected vertices of 'r' where they were"),
    (dict(base={"a": 0.5}, moves={"d": 0.3}), "move only the selected coordinates"),
    (dict(base={"b": 0.5}, moves={"a": 0.5}, axes="y"), "leave the selected y coordinates"),  # a moves vertex 0 along x
    (dict(base={"a": 0.5}, moves={"Furrow": 0.5}), r"needs the sliders \['Furrow'\]"),
    (dict(region="brow_middle", base={"a": 0.5}, moves={"b": 0.5}), "needs region 'brow_middle'"),
])
def test_a_session_that_cannot_run_on_a_face_says_why_in_every_function(kw, why):
    face, sc = _local_face(), _session(**kw)
    assert re.search(why, sc.not_applicable(face))
    for call in _every_function(face, sc):
        with pytest.raises(ModelError, match=f"scenario 'k' \\(Fig. x\\) does not apply to model 'local': .*{why}"):
            call()


def test_a_session_that_can_run_gives_numbers_and_no_nan():
    face, sc = _local_face(), _session(base={"a": 0.5}, moves={"b": 0.5})
    assert sc.not_applicable(face) is None
    sc.check(face)
    r = S.evaluate(face, sc)
    assert all(np.isfinite(v) for v in r.values() if isinstance(v, float))
    assert 0 < r["reduction"] < 1
    rows = S.alpha_sweep(face, sc, [1e-3, 1.0, 1e3])
    assert all(np.isfinite(v) for row in rows for v in row.values() if isinstance(v, float))
    assert np.isfinite(S.interference(face, sc)["drift_relative"])


@pytest.mark.parametrize("key", ["smirk_corners_y", "wince_sneer_under_eye"])
def test_interference_needs_a_first_move(face, key):
    """Figs. 1-2 compare the drag with what a first move positioned: the sessions without one have no such ratio."""
    with pytest.raises(ModelError, match=f"scenario '{key}' .* has no first move"):
        S.interference(face, key)
    assert S.scenario(key).not_applicable(face) is None  # the session itself runs (Figs. 4-5)


def test_every_session_applies_to_the_embedded_face(face):
    assert {k: sc.not_applicable(face) for k, sc in S.SCENARIOS.items()} == dict.fromkeys(S.SCENARIOS)


# ------------------------------------------------------------------ the sliders a face offers
def test_the_paper_sliders_are_those_its_sessions_move():
    moved = {s for sc in S.SCENARIOS.values() for s in (*sc.base, *sc.moves)}
    assert set(S.PAPER_SLIDERS) == moved and len(S.PAPER_SLIDERS) == len(moved)


def test_a_face_that_plays_the_paper_offers_the_papers_sliders(face):
    assert S.default_sliders(face) == S.PAPER_SLIDERS


def test_a_face_that_plays_no_session_offers_its_own_sliders_then_the_shapes_they_leave_out():
    face = _local_face()  # no paper slider, no session: its named slider, then c and d (ab reaches a and b)
    assert S.default_sliders(face) == ("ab", "c", "d")
    bare = BlendshapeModel(face.f0, face.D, face.names, face.faces)
    assert S.default_sliders(bare) == ("a", "b", "c", "d")
    blink = BlendshapeModel(face.f0, face.D, ["eyeBlink_L", "b", "c", "d"], face.faces,
                            sliders={"Blink": {"eyeBlink_L": 1.0}, "joy": {"b": 0.5, "c": 0.0}})
    assert S.default_sliders(blink) == ("Blink", "joy", "c", "d")  # joy binds c at weight 0: c is not reached
