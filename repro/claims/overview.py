"""The ledger at a glance: the stored verdicts, and the coloured table notebook 00 opens with.

A reviewer opening ``notebooks/00_overview.ipynb`` sees what reproduces before anything is
computed: :func:`stored_rows` reads the ledger as measured and reviewed with this version
(:data:`STORED`, the quick figures with the real data present, the run the README's summary
line comes from; a test fails when it differs from a new measurement), and
:func:`ledger_html` draws it: one row per claim, the claim in one line (the paper's words and
section in a tooltip), the embedded and real verdicts as coloured badges, and the whole
"why" of each, wrapped, never cut.  The notebook then recomputes the ledger below it.
"""

from __future__ import annotations

import csv
import html
import io
from pathlib import Path

from repro.claims.ledger import DATASETS

__all__ = ["STORED", "COLUMNS", "BADGE_COLOURS", "stored_rows", "stored_csv", "one_line", "ledger_html"]

#: the stored ledger (package data)
STORED = Path(__file__).with_name("stored.csv")
#: its columns: what the overview shows (the measured values are in ``repro claims``' figures/claims.csv)
COLUMNS = ("id", "paper", "statement", "figure", "notebook", "timing",
           "embedded_verdict", "real_verdict", "embedded_why", "real_why")
#: (background, text) colour of each verdict's badge (one per :data:`~repro.claims.ledger.VERDICTS`: a test
#: checks it; a stored file's unknown verdict gets a plain badge)
BADGE_COLOURS = {
    "reproduced": ("#1a7f37", "#ffffff"),
    "partially": ("#bf8700", "#ffffff"),
    "not reproduced": ("#cf222e", "#ffffff"),
    "not applicable": ("#6e7781", "#ffffff"),
    "not judged": ("#ddf4ff", "#0a3069"),
}


def stored_csv(rows) -> str:
    """The text of :data:`STORED` for ledger ``rows`` (:func:`repro.claims.evaluate`'s)."""
    out = io.StringIO()
    w = csv.DictWriter(out, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({**r, "timing": "yes" if r["timing"] else "no"})
    return out.getvalue()


def stored_rows(path: Path | None = None) -> list[dict]:
    """The ledger as stored with this version (:data:`STORED`): one dict per claim, ``timing`` a bool."""
    from repro.errors import DataError
    from repro.io import read_bytes

    data, _ = read_bytes(path or STORED, error=DataError)
    try:
        rows = list(csv.DictReader(io.StringIO(data.decode("utf-8"))))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"{path or STORED}: not a stored claims ledger ({exc})") from None
    if not rows or tuple(rows[0]) != COLUMNS:
        raise DataError(f"{path or STORED}: not a stored claims ledger (expected the columns {', '.join(COLUMNS)})")
    for r in rows:
        r["timing"] = r["timing"] == "yes"
    return rows


def one_line(statement: str) -> str:
    """A claim's statement without the reference that closes it: ``"Search time grows ... (Section 2: '...')"``
    -> ``"Search time grows ..."``; a parenthesis inside the claim's own words stays."""
    if not statement.endswith(")"):
        return statement
    depth = 0
    for i in range(len(statement) - 1, -1, -1):  # the "(" matching the final ")"
        depth += {")": 1, "(": -1}.get(statement[i], 0)
        if depth == 0:
            return statement[:i].rstrip() or statement
    return statement


def _badge(verdict: str) -> str:
    bg, fg = BADGE_COLOURS.get(verdict, ("#ffffff", "#000000"))
    return (f'<span class="repro-verdict" style="background:{bg};color:{fg};padding:1px 7px;border-radius:9px;'
            f'white-space:nowrap;font-weight:600">{html.escape(verdict)}</span>')


def ledger_html(rows, *, caption: str = "") -> str:
    """The ledger as one HTML table: id, the claim in one line, the verdicts as badges, the whole "why".

    Timing claims are marked (their verdicts depend on the machine, and never fail a run).  Text is
    left-aligned and wraps; nothing is truncated.  ``caption``: a line above the table (escaped).
    """
    head = "".join(f"<th style='text-align:left'>{h}</th>" for h in
                   ("id", "claim", *(f"{ds} data" for ds in DATASETS), "why (embedded / real)"))
    body = []
    for r in rows:
        timing = " <em>(timing)</em>" if r["timing"] else ""
        why = "<br>".join(f"<b>{ds}:</b> {html.escape(str(r[f'{ds}_why']))}" for ds in DATASETS)
        body.append(
            "<tr>"
            f"<td style='text-align:left;vertical-align:top'><b>{html.escape(r['id'])}</b></td>"
            f"<td style='text-align:left;vertical-align:top' title=\"{html.escape(r['statement'])}\">"
            f"{html.escape(one_line(r['statement']))}{timing}</td>"
            + "".join(f"<td style='text-align:left;vertical-align:top'>{_badge(r[f'{ds}_verdict'])}</td>"
                      for ds in DATASETS)
            + f"<td style='text-align:left;vertical-align:top;white-space:normal'>{why}</td></tr>")
    cap = f"<p>{html.escape(caption)}</p>" if caption else ""
    return (f"{cap}<table class='repro-ledger' style='border-collapse:collapse;width:100%;table-layout:auto'>"
            f"<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>")
