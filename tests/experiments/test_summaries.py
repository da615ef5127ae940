"""Numbers in prose come from the code: every figure's ``summary(result)``, and the README's claims lines."""

import re

import pandas as pd
import pytest

from repro import data
from repro.experiments import registry, summaries
from tests.conftest import REPO


def test_every_figure_module_has_a_summary():
    import importlib

    for exp in registry().values():
        module = importlib.import_module(exp.module)
        assert callable(getattr(module, "summary", None)), f"{exp.module} has no summary(result)"


@pytest.mark.parametrize("x, text", [(0.0057172, "0.00572"), (1007.0, "1,007"), (335, "335"), (0.9488, "0.949"),
                                     (0.12534, "0.125"), (1567.1667, "1,567"), (0, "0"), (-0.1253, "-0.125"),
                                     (2.5e-6, "2.50e-06"), (12.34, "12.3"), (3.3e-16, "0"), (-2e-11, "0")])
def test_num_formats_significant_figures(x, text):
    assert summaries.num(x) == text


def test_pct():
    assert summaries.pct(0.0322) == "3.2 %" and summaries.pct(1.6572) == "166 %" and summaries.pct(0.363, 3) == "36.3 %"


def _rows(embedded, real, timing=False, id_="L1", figure="fig2_interference"):
    return {"id": id_, "figure": figure, "timing": timing, "embedded_verdict": embedded, "real_verdict": real}


def test_readme_block_counts_the_stable_claims_and_names_the_timing_ones():
    rows = [_rows("reproduced", "partially"), _rows("partially", "not applicable", id_="L2"),
            _rows("reproduced", "reproduced", timing=True, id_="K4", figure="latency_breakdown")]
    block = summaries.readme_claims_block(rows)
    assert block.splitlines()[0] == ("    2 claims — embedded data: 1 reproduced, 1 partially; "
                                     "real data: 1 partially, 1 not applicable")
    assert "plus 1 timing claims (K4 (`latency_breakdown`))" in block


def _readme_block() -> str:
    text = (REPO / "README.md").read_text()
    m = re.search(re.escape(summaries.README_START) + r"\n(.*?)\n" + re.escape(summaries.README_END), text, re.DOTALL)
    assert m, "README.md has no generated claims-summary block"
    return m.group(1)


@pytest.mark.slow
@pytest.mark.data("ict")
@pytest.mark.data("cmu-bvh")
def test_readme_claims_block_is_the_generated_one(quick_figures):
    from repro import claims

    rows = claims.evaluate(quick=True, results=quick_figures)  # the session's quick figures
    block = summaries.readme_claims_block(rows)
    assert block.splitlines()[0].strip() == claims.summary_line([r for r in rows if not r["timing"]])
    assert _readme_block() == block, f"README.md's claims block should read:\n{block}"


# ------------------------------------------------------------------ the figures' summaries, on the quick runs
LEWIS = ["fig2_interference", "fig3_attenuation", "fig4_axis_selection", "fig5_alpha", "alpha_sweep",
         "rejected_alternatives"]


@pytest.fixture(scope="module")
def lewis_results(quick_figures):
    return {n: quick_figures(n) for n in LEWIS}  # the session's quick figures


def _numbers(text):
    return re.findall(r"-?\d[\d,]*\.?\d*(?:e[-+]\d+)?", text)


@pytest.mark.parametrize("name", LEWIS)
def test_lewis_summaries_cite_the_tables_numbers(lewis_results, name):
    r = lewis_results[name]
    md = summaries.summary(name, r)
    assert isinstance(md, str) and md.strip() and _numbers(md)
    for model in r.table.model.unique():
        assert f"*{model}" in md or f"{model}," in md or f"*{model}*" in md, (model, md)


def test_fig3_summary_quotes_the_table(lewis_results):
    r = lewis_results["fig3_attenuation"]
    md = summaries.summary("fig3_attenuation", r)
    row = r.table.iloc[0]
    assert summaries.num(row.attenuated_unselected_fidelity) in md
    assert summaries.pct(row.reduction) in md and f"alpha = {row.alpha:.6g}" in md


def test_a_summary_follows_its_table(lewis_results):
    """Change a number in the table: the summary changes with it (nothing is typed in)."""
    import dataclasses

    r = lewis_results["fig2_interference"]
    t = r.table.copy()
    t.loc[0, "drift_selected_mean"] = 0.4321
    md = summaries.summary("fig2_interference", dataclasses.replace(r, table=t))
    assert "0.432" in md and "0.432" not in summaries.summary("fig2_interference", r)


def test_summaries_say_which_models_are_absent():
    from repro.experiments.lewis import fig4_axis_selection

    t = pd.DataFrame({"model": ["procedural"] * 2, "scenario": ["s"] * 2, "vertex": [1, 2], "method": ["none", "attenuated"],
                      "alpha": [float("nan"), 3023.0], "dx": [-0.55, -0.56], "dy": [0.6, 0.003], "dz": [0.0, 0.0],
                      "selected_axes": ["y", "y"]})
    from repro.experiments.registry import Result

    md = fig4_axis_selection.summary(Result(t))
    assert "procedural" in md and "ict" not in md
    assert data.DATA_CHOICES  # the notebooks' parameter values exist


def _session(reached):
    import pandas as pd

    n = len(reached)
    return pd.DataFrame(dict(order=["kick"] * n, reached=reached, unadapted_cm=[10.0] * n, hit_error_cm=[0.0, 7.5][:n],
                             head_y=[1.6, 1.9][:n], head_moved_cm=[0.0] * n, touched=[False] * n))


@pytest.mark.parametrize("reached", [[True, True], [False, False], [True, False], []])
def test_fighter_session_never_shows_a_blank_number(reached):
    """Notebook 05 printed "the kicks not reached miss by  cm, at head heights  m" when every kick was reached."""
    import re

    from repro.experiments.summaries import fighter_session

    text = fighter_session(_session(reached), actors=[1.7], fighter_size=1.8, contact_s=[0.5] * len(reached))
    assert not re.search(r"  (cm|m)\b|by  |at  |nan", text), text
    assert ("kicks not reached miss by" in text) == (False in reached)
    if reached == [True, False]:
        assert "miss by 7.5 cm, at head heights 1.90 m" in text
    assert ("reached kicks' heads were at 1.60" in text) == (reached[:1] == [True])
