"""The `latency_breakdown` figure (Pronost et al., Section 4): stages, the paper's values, the drawing.

No timing is asserted: only that every stage was measured, that the paper's reference
values are the ones Section 4 gives, and that the table's derived columns follow from
its numbers.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from repro.experiments import get, registry
from repro.experiments.pronost.latency_breakdown import (
    STAGE_NAMES,
    breakdown,
    run_orders,
)

PAPER_MS = {
    "order -> search start": 3.0,
    "search": 280.0,
    "clip load + convert": 40.0,
    "retarget + adapt per frame": 0.088,
    "order -> first adapted frame": 323.0,
}
COLUMNS = {"stage", "ours_p50_ms", "ours_p90_ms", "paper_ms", "ratio_paper_over_ours", "within_budget", "database",
           "machine", "budget_ms", "n_orders"}


@pytest.fixture(scope="module")
def result():
    return get("latency_breakdown").func(quick=True, databases=["synthetic"], n_orders=6)


def test_registered_for_the_kung_fu_paper():
    exp = registry()["latency_breakdown"]
    assert exp.paper == "pronost2008"
    assert "Section 4" in exp.caption and "latency" in exp.caption.lower()


def test_table_has_the_papers_stages_and_reference_values(result):
    t = result.table
    assert COLUMNS <= set(t.columns)
    assert list(t.stage) == list(STAGE_NAMES)
    assert set(PAPER_MS) <= set(t.stage)
    for stage, ms in PAPER_MS.items():
        assert t.set_index("stage").loc[stage, "paper_ms"] == pytest.approx(ms)
    assert np.isnan(t.set_index("stage").loc["adaptation (whole clip)", "paper_ms"])
    assert (t.ours_p50_ms > 0).all() and (t.ours_p90_ms >= t.ours_p50_ms).all()
    ok = t.paper_ms.notna()
    np.testing.assert_allclose(t.ratio_paper_over_ours[ok], t.paper_ms[ok] / t.ours_p50_ms[ok])
    np.testing.assert_allclose(t.budget_ms, 1000 / 30)
    assert t.within_budget.dtype == bool
    assert (t.database == "synthetic").all() and (t.n_orders == 6).all()
    assert t.machine.str.len().min() > 5


def test_orders_table_and_breakdown_agree(result):
    orders = result.extra_tables["orders"]
    assert len(orders) == 6 and set(orders.kind) <= {"punch", "kick"}
    assert (orders["kind"] == orders["clip"].str.extract(r"_(punch|kick)_", expand=False)).all()
    t = result.table.set_index("stage")
    assert t.loc["search", "ours_p50_ms"] == pytest.approx(np.percentile(orders.search_ms, 50))
    assert t.loc["order -> first adapted frame", "ours_p90_ms"] == pytest.approx(np.percentile(orders.first_frame_ms, 90))


def test_breakdown_budget_logic_on_known_numbers():
    n = 10
    orders = pd.DataFrame({
        "database": ["x"] * n, "reached": [True] * n,
        "prepare_ms": np.full(n, 2.0), "search_ms": np.linspace(1, 10, n), "load_convert_ms": np.full(n, 50.0),
        "retarget_adapt_per_frame_ms": np.full(n, 2.0),  # x 30 frames = 60 ms: over the budget
        "adapt_ms": np.full(n, 5.0), "first_frame_ms": np.full(n, 20.0), "level_ms": np.full(n, 40.0),
    })
    t = breakdown(orders).set_index("stage")
    assert t.loc["search", "ours_p50_ms"] == pytest.approx(5.5)
    assert t.loc["search", "ours_p90_ms"] == pytest.approx(np.percentile(np.linspace(1, 10, n), 90))
    assert t.loc["order -> search start", "ratio_paper_over_ours"] == pytest.approx(1.5)
    assert t.within_budget.to_dict() == {
        "order -> search start": True, "search": True, "clip load + convert": False,
        "retarget + adapt per frame": False, "adaptation (whole clip)": True, "order -> first adapted frame": True,
        "order -> reach level decided": False}


def test_draw_is_a_log_scale_bar_chart_naming_the_machine(result):
    fig = result.draw()
    ax = fig.axes[0]
    assert ax.get_xscale() == "log"
    assert result.table.machine.iloc[0] in ax.get_title()
    labels = [tl.get_text() for tl in ax.get_yticklabels()]
    assert set(labels) == set(STAGE_NAMES)
    assert any("paper" in t.get_text() for t in ax.get_legend().get_texts())


def test_run_orders_is_deterministic_apart_from_timings():
    a = run_orders("synthetic", n_orders=3, seed=5)
    b = run_orders("synthetic", n_orders=3, seed=5)
    cols = ["kind", "clip", "start_frame", "d", "hit_error_m", "reached"]
    pd.testing.assert_frame_equal(a[cols], b[cols])


def test_p99_and_the_per_level_table(result):
    t = result.table
    assert (t.ours_p99_ms >= t.ours_p90_ms).all()
    orders = result.extra_tables["orders"]
    assert t.set_index("stage").loc["order -> first adapted frame", "ours_p99_ms"] == pytest.approx(
        np.percentile(orders.first_frame_ms, 99))
    lv = result.extra_tables["per_level"]
    assert list(lv.level) == ["limb only", "with CCD (spine)", "with CCD + root shift"]
    assert lv.n_orders.sum() == len(orders) and set(orders.level) <= {"limb", "spine", "root"}
    np.testing.assert_allclose(lv.paper_per_frame_ms, 0.088)
    for _, row in lv.iterrows():
        assert np.isnan(row.per_frame_p50_ms) == (row.n_orders == 0)
        if row.n_orders:
            assert row.per_frame_p99_ms >= row.per_frame_p50_ms > 0
