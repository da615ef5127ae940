"""The paper's scenarios on the embedded face: the qualitative claims of Figs. 1-5 and Section 3."""

import numpy as np
import pytest

from repro.blendshapes import load_model
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
    for method in (sc.vertices, sc.selection, sc.weights, sc.lockable_shapes):  # AttributeError before
        with pytest.raises(ModelError, match="expected a BlendshapeModel"):
            method("procedural")
    for alphas in (np.array(1.0), [None, 1.0], [[1.0], [1.0, 2.0]], np.ones((2, 2))):  # TypeError before
        with pytest.raises(ModelError, match="alphas"):
            S.alpha_sweep(face, "furrow_then_mouth", alphas)
    rows = S.alpha_sweep(face, "furrow_then_mouth", (a for a in (1.0, 10.0)))  # a generator still works
    assert [r["alpha"] for r in rows] == [1.0, 10.0]
