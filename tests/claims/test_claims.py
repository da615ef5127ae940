"""The claims ledger: every claim is measured, and no verdict silently changes (timing claims excepted)."""

import pytest

from repro import claims, cli, data

DATASET = {"lewis2005": "ict", "pronost2008": "cmu-bvh"}


@pytest.fixture(scope="module")
def rows(quick_figures):
    return claims.evaluate(quick=True, results=quick_figures)  # the session's quick figures


def test_every_claim_has_a_statement_figure_notebook_and_values(rows):
    from repro.experiments import registry

    ids = [r["id"] for r in rows]
    assert len(ids) == len(set(ids))
    assert {f"L{i}" for i in range(1, 11)} | {f"K{i}" for i in range(1, 8)} == set(ids)
    for r in rows:
        assert r["figure"] in registry(), r["id"]
        assert r["notebook"].startswith("notebooks/") and r["statement"] and r["criterion"]
        assert r["embedded_values"], r["id"]


def test_verdicts_match_the_ledger(rows):
    """A changed verdict is a regression in reproduction (or a reviewed improvement: update `expected`)."""
    changed = []
    for r in rows:
        if r["timing"]:
            continue
        datasets = ["embedded"] + (["real"] if data.missing_reason(DATASET[r["paper"]]) is None else [])
        for ds in datasets:
            if r[f"{ds}_verdict"] != r[f"{ds}_expected"]:
                changed.append(f"{r['id']} ({ds}): ledger says {r[f'{ds}_expected']!r}, measured "
                               f"{r[f'{ds}_verdict']!r}: {r[f'{ds}_why']} ({r[f'{ds}_values']})")
    assert not changed, "\n".join(changed)


def test_repro_claims_writes_markdown_and_csv(tmp_path, capsys, monkeypatch, rows):
    monkeypatch.setattr(claims, "evaluate", lambda quick=True, progress=False: rows)
    assert cli.main(["claims", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert claims.summary_line(rows) in out
    md = (tmp_path / "claims.md").read_text()
    assert md.startswith("# Claims ledger") and all(f"| {r['id']} |" in md for r in rows)
    assert (tmp_path / "claims.csv").read_text().startswith("id,paper,")


def test_readme_shows_the_measured_summary_line(rows):
    from tests.conftest import REPO

    if any(data.missing_reason(d) for d in DATASET.values()):
        pytest.skip("the README's line is measured with the real datasets present")
    line = claims.summary_line([r for r in rows if not r["timing"]])
    assert line in (REPO / "README.md").read_text(), f"README.md should show: {line}"
