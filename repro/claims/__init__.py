"""The claims ledger: every claim of both papers, its measured counterpart, and a verdict.

Each claim (:class:`~repro.claims.ledger.Claim`) quotes the paper, names the registered
figure and the notebook that measure it, states the criterion, and judges that figure's
tables, separately on the embedded data (procedural face, synthetic database) and on the
real data (ICT face, CMU mocap) when present:

- ``reproduced``: the criterion holds;
- ``partially``: part of the claim holds (the ``why`` says which part);
- ``not reproduced``: the numbers contradict it;
- ``not applicable``: the data needed is absent, or the claim is about
  something this reproduction cannot have (e.g. the paper's own model).
- ``not judged``: the run measured less than the claim's verdict needs (its
  ``evidence``: e.g. a trend over two database sizes in quick mode).

``expected`` records the verdicts the ledger was last reviewed with; the test suite fails
when a measured verdict changes (a regression in reproduction) -- except for timing claims,
whose values are printed as ratios to the paper's figure with the machine named, and never
fail a run.

- :mod:`repro.claims.ledger`: the claim type, the evaluation, the rendering;
- :mod:`repro.claims.lewis`, :mod:`repro.claims.pronost`: the two ledgers, one decorated
  function per claim, thresholds named at the top of each.

``repro claims`` prints the table and writes ``figures/claims.md`` and ``figures/claims.csv``.
"""

from __future__ import annotations

from repro.claims import ledger, lewis, pronost
from repro.claims.ledger import VERDICTS, Claim, ledger_table, summary_line, to_markdown

__all__ = ["LEDGER", "VERDICTS", "Claim", "evaluate", "ledger_table", "summary_line", "to_markdown"]

#: both ledgers, Lewis et al. first, each in the order of its ids
LEDGER: list[Claim] = sorted(lewis.LEDGER + pronost.LEDGER, key=lambda c: (c.paper != lewis.PAPER, int(c.id[1:])))


def evaluate(*, quick: bool = True, claims=None, progress: bool = False, results=None) -> list[dict]:
    """Run the figures the claims need (once each) and judge every claim; one row per claim.

    ``results``: figures already computed (``name -> Result`` mapping or callable, in the
    same ``quick`` mode), used instead of running them.  ``progress``: progress bars (plain
    tqdm, on stderr) for the figures that have them; off by default, so that a call from
    code or a notebook prints nothing (a notebook cell's output must not depend on how fast
    the machine is).
    """
    from repro.experiments import get as get_experiment
    from repro.experiments.registry import call_experiment

    cache: dict = {}
    given = results.__getitem__ if hasattr(results, "__getitem__") else results

    def get(name):
        if name not in cache:
            cache[name] = (given(name) if given is not None
                           else call_experiment(get_experiment(name), quick=quick, progress=progress))
        return cache[name]

    return ledger.evaluate(claims or LEDGER, get, quick=quick)
