"""Lewis et al. 2005, Section 5 "The scaling factor alpha": a continuous sweep.

For alpha from 1e-3 to 1e6: the selected coordinates' motion (as a fraction of
their unattenuated motion) and the unselected coordinates' fidelity, for every
scenario on every model, with Section 5's default alpha marked, and the
trade-off curve they trace.

The limits, in the paper's own words: Eq. (3) gives w2 -> w1 as alpha -> 0
and S w2 -> 0 as alpha -> infinity, and Fig. 5's caption agrees (alpha = 25:
"the mouth moves exactly as in Fig. 5b, but so do the selected vertices";
alpha = 3000: "... not moving unselected vertices either").  The body text at
the end of Section 5 says the opposite ("At very high values, the results are
almost indistinguishable from the attenuated pose. At very low values, none of
the vertices, selected or unselected, move very much").  The ``limits`` table
states which reading the numbers support.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment


#: alphas far beyond the plotted range, where Section 5's limits should be reached
LIMIT_ALPHAS = (1e-6, 1e12)


def limits_table(limits: pd.DataFrame) -> pd.DataFrame:
    """Per model and scenario: the two extreme alphas, and which reading of Section 5 they support."""
    rows = []
    for (model, key), g in limits.groupby(["model", "scenario"], sort=False):
        lo, hi = g.loc[g.alpha.idxmin()], g.loc[g.alpha.idxmax()]
        eq3 = lo.w_change_vs_w1 < 1e-2 and lo.unselected_fidelity > 0.99 and hi.selected_motion_fraction < 1e-2
        rows.append({
            "model": model, "scenario": key,
            "alpha_low": lo.alpha, "low_w_change_vs_w1": lo.w_change_vs_w1,
            "low_selected_motion_fraction": lo.selected_motion_fraction, "low_unselected_fidelity": lo.unselected_fidelity,
            "alpha_high": hi.alpha, "high_selected_motion_fraction": hi.selected_motion_fraction,
            "high_unselected_fidelity": hi.unselected_fidelity,
            "supports": "Eq. 3 and the Fig. 5 caption (low alpha: everything moves as asked; high alpha: selection still)"
            if eq3 else "neither reading cleanly",
            "body_text_low_alpha_claim_holds": bool(lo.selected_motion_fraction < 0.1 and lo.unselected_fidelity < 0.1),
        })
    return pd.DataFrame(rows)


@experiment("alpha_sweep", "Section 5: selected motion and unselected fidelity for alpha 1e-3..1e6; limits; trade-off", paper="lewis2005")
def alpha_sweep(quick: bool = False) -> Result:
    alphas = np.logspace(-3, 6, 19 if quick else 73)
    runs, skipped = common.applicable_sessions(common.attenuators(), S.SCENARIOS)
    sweep = pd.DataFrame([r for (m, att), key in runs for r in S.alpha_sweep(m, key, alphas, attenuator=att)])
    ends = pd.DataFrame([r for (m, att), key in runs for r in S.alpha_sweep(m, key, LIMIT_ALPHAS, attenuator=att)])
    return Result(table=sweep, draw=lambda: draw(sweep),
                  extra_tables={"limits": limits_table(ends), **common.skipped_tables(skipped)})


def draw(sweep: pd.DataFrame):
    import matplotlib.pyplot as plt

    models = list(dict.fromkeys(sweep.model))
    fig, axes = plt.subplots(3, len(models), figsize=(5.2 * len(models), 10), squeeze=False, layout="constrained")
    for col, model in zip(axes.T, models):
        for key, g in sweep[sweep.model == model].groupby("scenario", sort=False):
            d = g.default_alpha.iloc[0]
            i = (g.alpha - d).abs().idxmin()
            line, = col[0].plot(g.alpha, g.selected_motion_fraction, label=key)
            col[0].plot(d, np.interp(np.log(d), np.log(g.alpha), g.selected_motion_fraction), "o", color=line.get_color())
            col[1].plot(g.alpha, g.unselected_fidelity, color=line.get_color())
            col[1].plot(d, np.interp(np.log(d), np.log(g.alpha), g.unselected_fidelity), "o", color=line.get_color())
            col[2].plot(g.selected_motion_fraction, 1 - g.unselected_fidelity, color=line.get_color())
            col[2].plot(g.selected_motion_fraction[i], 1 - g.unselected_fidelity[i], "o", color=line.get_color())
        for ax in col[:2]:
            ax.set_xscale("log")
            ax.set_xlabel("alpha")
            ax.grid(alpha=0.3)
        col[0].set_ylabel("selected motion / unattenuated")
        col[0].set_title(f"{model} (dots: Section 5's default alpha)", fontsize=9)
        col[0].legend(fontsize=8)
        col[1].set_ylabel("unselected fidelity (1 = as the sliders intend)")
        col[2].set_xlabel("selected motion / unattenuated")
        col[2].set_ylabel("unselected relative error")
        col[2].set_title("trade-off, parametrised by alpha", fontsize=9)
        col[2].grid(alpha=0.3)
    return fig


def summary(result) -> str:
    """Markdown: the sweep's extent, and both limits over every session (the numbers of notebook 02's Section 3)."""
    from repro.experiments.summaries import bullets, num

    t, lim = result.table, result.extra_tables["limits"]
    hard = lim[lim.high_unselected_fidelity < 0.9]
    lines = [
        f"the sweep: {t.alpha.nunique()} values of alpha from {t.alpha.min():g} to {t.alpha.max():g}, "
        f"{t.scenario.nunique()} sessions on {t.model.nunique()} face(s)",
        f"alpha = {lim.alpha_low.iloc[0]:g}: ||w2 - w1|| / ||w1|| at most {num(lim.low_w_change_vs_w1.max(), 2)}; "
        f"selected motion fraction {num(lim.low_selected_motion_fraction.min(), 4)} to "
        f"{num(lim.low_selected_motion_fraction.max(), 4)}, unselected fidelity {num(lim.low_unselected_fidelity.min(), 4)} "
        f"to {num(lim.low_unselected_fidelity.max(), 4)}",
        f"alpha = {lim.alpha_high.iloc[0]:g}: selected motion fraction at most {num(lim.high_selected_motion_fraction.max(), 2)}; "
        f"unselected fidelity {num(lim.high_unselected_fidelity.min(), 2)} to {num(lim.high_unselected_fidelity.max(), 2)}"
        + (f" ({num(hard.high_unselected_fidelity.min(), 2)} to {num(hard.high_unselected_fidelity.max(), 2)} without "
           f"the sessions that keep more than 0.9)" if 0 < len(hard) < len(lim) else ""),
        f"the body text's low-alpha claim holds in {int(lim.body_text_low_alpha_claim_holds.sum())} of {len(lim)} "
        f"sessions; the numbers support: {', '.join(sorted(set(lim.supports)))}",
    ]
    for r in lim[lim.scenario == "wince_sneer_under_eye"].itertuples():
        g = t[(t.model == r.model) & (t.scenario == r.scenario)]
        at_default = g.iloc[(g.alpha - g.default_alpha).abs().argmin()]
        lines.append(f"*{r.model}*, Fig. 5 session: unselected fidelity {num(at_default.unselected_fidelity, 2)} at "
                     f"alpha = {at_default.alpha:.4g} (the sweep's value nearest the default, "
                     f"{at_default.default_alpha:.6g}), {num(r.high_unselected_fidelity, 2)} at "
                     f"alpha = {r.alpha_high:g}")
    return bullets(lines)
