"""The overview notebook 00 opens with (issue 26, item 1): the stored ledger, current, drawn as a coloured table."""

from __future__ import annotations

import re

import pytest

from repro import claims
from repro.claims import overview
from repro.errors import DataError


def _row(id_="K7", embedded="reproduced", real="not judged", timing=True):
    return {"id": id_, "paper": "pronost2008", "figure": "retrieval_latency", "notebook": "n", "timing": timing,
            "statement": "Search time grows with the size of the database (Section 2: 'the larger <the> number')",
            "embedded_verdict": embedded, "real_verdict": real,
            "embedded_why": "search time grows with the database (log-log slope 0.41; exhaustive 0.93) " * 3,
            "real_why": "not judged in quick mode: needs the full sweep (2 database sizes; a verdict needs at least 3)"}


def test_the_table_shows_each_claim_in_one_line_its_badges_and_the_whole_why():
    page = overview.ledger_html([_row(), _row("L1", "partially", "not reproduced", timing=False)], caption="a & b")
    assert page.startswith("<p>a &amp; b</p>")
    assert page.count("<tr>") == 3  # the head and two claims
    assert "Search time grows with the size of the database" in page and "Section 2" not in page.split("title=")[0]
    assert "title=\"Search time grows with the size of the database (Section 2: &#x27;the larger &lt;the&gt; number" in page
    assert _row()["embedded_why"].strip() in page and "..." not in page  # nothing cut
    for verdict in ("reproduced", "not judged", "partially", "not reproduced"):
        bg = overview.BADGE_COLOURS[verdict][0]
        assert re.search(rf"background:{bg};[^>]*>{verdict}</span>", page), verdict
    assert page.count("<em>(timing)</em>") == 1
    assert "text-align:left" in page and "white-space:normal" in page


def test_one_line_drops_the_quotation_and_section():
    assert overview.one_line("A (Section 1: 'b')") == "A"
    assert overview.one_line("no parenthesis") == "no parenthesis"
    assert overview.one_line("'a (75 motions ...)' suffices (Abstract, Sections 1, 2)") == "'a (75 motions ...)' suffices"
    assert overview.one_line("unbalanced)") == "unbalanced)"


def test_every_verdict_has_a_badge_colour():
    assert set(overview.BADGE_COLOURS) == set(claims.VERDICTS)


def test_the_stored_ledger_reads_back_and_a_bad_file_is_a_data_error(tmp_path):
    rows = [_row(), _row("L1", timing=False)]
    p = tmp_path / "stored.csv"
    p.write_text(overview.stored_csv(rows))
    back = overview.stored_rows(p)
    assert [r["id"] for r in back] == ["K7", "L1"] and [r["timing"] for r in back] == [True, False]
    assert back[0]["real_why"] == rows[0]["real_why"]
    (tmp_path / "bad.csv").write_text("id,verdict\nL1,yes\n")
    with pytest.raises(DataError, match="not a stored claims ledger"):
        overview.stored_rows(tmp_path / "bad.csv")
    with pytest.raises(DataError):
        overview.stored_rows(tmp_path / "missing.csv")


@pytest.mark.slow
@pytest.mark.data("ict")
@pytest.mark.data("cmu-bvh")
def test_the_stored_ledger_is_the_measured_one(quick_figures):
    """repro/claims/stored.csv holds today's verdicts and whys (timing claims: their ids and statements; their
    numbers are the storing machine's).  When a change moves them: ``repro claims --store``, and review."""
    rows = claims.evaluate(quick=True, results=quick_figures)
    stored = overview.stored_rows()
    assert [r["id"] for r in stored] == [r["id"] for r in rows]
    for s, r in zip(stored, rows):
        assert (s["statement"], s["timing"]) == (r["statement"], r["timing"]), r["id"]
        if not r["timing"]:
            for col in ("embedded_verdict", "real_verdict", "embedded_why", "real_why"):
                assert s[col] == r[col], f"{r['id']} {col}: stored {s[col]!r}, measured {r[col]!r} (repro claims --store)"
