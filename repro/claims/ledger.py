"""The claim type, its evaluation against the figures' tables, and the rendering of the ledger.

A :class:`Claim` quotes the paper (with its section or figure), names the registered figure
and the notebook that measure it, states the criterion, and has a function that reads that
figure's tables (through ``get(name) -> Result``) and decides a verdict, separately on the
embedded data (procedural face, synthetic database) and on the real data (ICT face, CMU
mocap) when present: one of :data:`VERDICTS`.  A claim reads its own figure (and the other
figures it declares in ``reads``) and computes nothing else: :func:`evaluate` refuses a claim
that does not read its figure, or reads one it did not declare.

The ledgers themselves are :mod:`repro.claims.lewis` and :mod:`repro.claims.pronost`; a claim
is one decorated function there (:func:`registrar`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "VERDICTS",
    "Claim",
    "evaluate",
    "fmt",
    "ledger_table",
    "not_applicable",
    "per_database",
    "per_model",
    "registrar",
    "summary_line",
    "to_markdown",
]

VERDICTS = ("reproduced", "partially", "not reproduced", "not applicable", "not judged")
#: the two columns of every verdict: the embedded data, and the real data when present
DATASETS = ("embedded", "real")


@dataclass(frozen=True)
class Claim:
    id: str
    paper: str
    statement: str  #: quoted briefly, with section/figure
    figure: str  #: registered figure measuring it
    notebook: str
    criterion: str
    #: (get: name -> Result) -> {"embedded": (verdict, values, why), "real": (...)}
    measure: Callable[[Callable[[str], object]], dict]
    expected: dict = field(default_factory=dict)  #: {"embedded": verdict, "real": verdict}
    timing: bool = False
    reads: tuple = ()  #: other figures whose tables it reads besides ``figure``
    #: ``(values key, minimum, what it counts)``: the least evidence a verdict needs (see :func:`evaluate`)
    evidence: tuple = ()

    @property
    def figures(self) -> tuple:
        """Every figure the claim reads, its own first."""
        return (self.figure, *(r for r in self.reads if r != self.figure))


def registrar(ledger: list, paper: str, per: Callable | None = None):
    """A decorator factory adding one claim to ``ledger``: ``@claim("L1", statement, figure, ...)``.

    The decorated function is the claim's ``measure(get)``; or, given ``table`` (``"table"``, the
    figure's main table, or the name of one of its ``extra_tables``), the judge of that table:
    ``judge(rows, dataset)`` on each dataset's rows as ``per`` splits them (:func:`per_model`,
    :func:`per_database`), or with ``embedded_only`` (why the real data has no verdict)
    ``judge(table)`` on the embedded data alone.  Ids must be unique in ``ledger``.
    """

    def claim(id: str, statement: str, *, figure: str, notebook: str, criterion: str, expected: dict,
              timing: bool = False, reads: tuple = (), table: str | None = None, embedded_only: str | None = None,
              evidence: tuple = ()):
        def deco(func):
            if any(c.id == id for c in ledger):
                raise ValueError(f"claim {id!r} is in the {paper} ledger twice")
            measure = func if table is None else _judging(func, figure, table, per, embedded_only)
            ledger.append(Claim(id, paper, statement, figure, notebook, criterion, measure, dict(expected),
                                timing, tuple(reads), tuple(evidence)))
            return func

        return deco

    return claim


def _judging(judge, figure: str, table: str, per, embedded_only: str | None):
    """The ``measure`` of a claim that judges one table of its figure (:func:`registrar`)."""

    def measure(get):
        result = get(figure)
        rows = result.table if table == "table" else result.extra_tables[table]
        if embedded_only is not None:
            return {"embedded": judge(rows), "real": not_applicable(embedded_only)}
        return per(judge, rows)

    return measure


# ----------------------------------------------------------------- what the ledgers share
def not_applicable(why: str = "the real dataset is not present here"):
    return ("not applicable", {}, why)


def per_model(judge, table, embedded: str = "procedural", real: str = "ict") -> dict:
    """``judge(rows of the model, model)`` on the embedded face and on the real one when in ``table``."""
    out = {"embedded": judge(table[table.model == embedded], embedded)}
    sub = table[table.model == real]
    out["real"] = judge(sub, real) if len(sub) else not_applicable()
    return out


def per_database(judge, table) -> dict:
    """``judge(rows of the database, name)`` on the synthetic database and on CMU's when in ``table``."""
    out = {"embedded": judge(table[table.database == "synthetic"], "synthetic")}
    real = table[table.database == "cmu"]
    out["real"] = judge(real, "cmu") if len(real) else not_applicable("the CMU takes are not present here")
    return out


def fmt(x) -> str:
    if isinstance(x, (float, np.floating)):
        return f"{x:.4g}"
    return str(x)


# ----------------------------------------------------------------- evaluation
def evaluate(claims, results: Callable[[str], object] | Mapping, *, quick: bool = False) -> list[dict]:
    """Judge every claim on the figures' results (``results(name)`` or ``results[name]``); one row each.

    A verdict needs the evidence its claim declares (``evidence``): where a measured count is below
    its minimum (a trend over two database sizes, as a quick run measures), the verdict is
    ``not judged`` and the ``why`` says what was missing; ``quick`` (the results are the quick
    figures) names the full sweep as what would judge it.
    """
    fetch = results.__getitem__ if isinstance(results, Mapping) else results
    rows = []
    for c in claims:
        allowed, read = set(c.figures), set()

        def get(name, c=c, allowed=allowed, read=read):
            if name not in allowed:
                raise ValueError(f"claim {c.id} reads figure {name!r}, which it does not declare "
                                 f"(its figure is {c.figure!r}; others go in reads=)")
            read.add(name)
            return fetch(name)

        m = c.measure(get)
        if c.figure not in read:
            raise ValueError(f"claim {c.id} does not read its figure {c.figure!r}: a claim judges that figure's tables")
        row = {"id": c.id, "paper": c.paper, "statement": c.statement, "figure": c.figure, "notebook": c.notebook,
               "criterion": c.criterion, "timing": c.timing}
        for ds in DATASETS:
            verdict, values, why = _enough(c, *m[ds], quick)
            if verdict not in VERDICTS:
                raise ValueError(f"claim {c.id}: unknown verdict {verdict!r}")
            row[f"{ds}_verdict"] = verdict
            row[f"{ds}_values"] = "; ".join(f"{k}={fmt(v)}" for k, v in values.items())
            row[f"{ds}_why"] = why
            row[f"{ds}_expected"] = c.expected.get(ds, "")
        rows.append(row)
    return rows


def _enough(claim: Claim, verdict: str, values: dict, why: str, quick: bool) -> tuple[str, dict, str]:
    """``(verdict, values, why)``, or ``not judged`` where ``values`` hold less than ``claim.evidence`` asks."""
    if verdict == "not applicable":
        return verdict, values, why
    for key, minimum, what in claim.evidence:
        if key in values and values[key] < minimum:
            mode = " in quick mode: needs the full sweep" if quick else ""
            return ("not judged", values,
                    f"not judged{mode} ({fmt(values[key])} {what}; a verdict needs at least {minimum})")
    return verdict, values, why


# ----------------------------------------------------------------- rendering
def ledger_table(rows):
    import pandas as pd

    return pd.DataFrame(rows)


def summary_line(rows) -> str:
    """e.g. ``10 claims: embedded 8 reproduced, 2 partially; real ...``."""
    parts = []
    for ds in DATASETS:
        counts = {v: sum(r[f"{ds}_verdict"] == v for r in rows) for v in VERDICTS}
        parts.append(f"{ds} data: " + ", ".join(f"{n} {v}" for v, n in counts.items() if n))
    return f"{len(rows)} claims — " + "; ".join(parts)


def to_markdown(rows) -> str:
    lines = ["# Claims ledger", "", summary_line(rows), "",
             "| id | claim | figure | embedded | real | why (embedded / real) |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['id']} | {r['statement']} | `{r['figure']}` | {r['embedded_verdict']} | {r['real_verdict']} | "
            f"{r['embedded_why']} ({r['embedded_values']}) / {r['real_why']} ({r['real_values']}) |")
    return "\n".join(lines) + "\n"
