"""Bounded attenuation: how far Eq. (3) leaves the slider range, what clamping costs, what the bounded solve keeps.

Eq. (3) of Lewis et al. 2005 is unconstrained, so the attenuated weights can
leave the sliders' range [0, 1]; a rig clamps them, and the clamp moves the
selected vertices again.  For every model (the embedded face; ICT when present)
and scenario, over Section 5's alpha sweep, the table gives: the final weights'
range under Eq. (3) and how many shapes leave [0, 1]; the selected motion (as a
fraction of the unattenuated motion) and unselected fidelity of Eq. (3), of
Eq. (3) clamped to [0, 1], and of the bounded solve
(:func:`repro.blendshapes.bounded.bounded_edit`).  ``summary`` condenses it per
model and scenario; ``ict_case`` checks the issue's example (ICT, six vertices
under the left eye, ``eyeSquint_L/R`` and ``noseSneer_L/R`` at 0.7).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.blendshapes import metrics
from repro.blendshapes import scenarios as S
from repro.blendshapes.bounded import bounded_edit, clamped_edit
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

LO, HI = 0.0, 1.0
#: an Eq. (3) weight counts as out of range when it is more than this beyond [0, 1] (0.1 % of the
#: slider range; below it, rounding-level negatives of untouched shapes would count at every alpha)
EXCURSION_TOL = 1e-3
METHODS = ("eq3", "clamped", "bounded")


def session_rows(model, att, key, alphas) -> list[dict]:
    """One row per alpha (and one at Section 5's default alpha): Eq. (3), clamped and bounded weights."""
    sc = S.scenario(key)
    sel = sc.selection(model)
    default = att.default_alpha(sel)
    alphas = [*alphas, default]
    w_base, w_target = sc.weights(model)
    d_base, d_target = att.displacement(w_base), att.displacement(w_target)
    none = metrics.selected_motion(d_target, sel, d_base)
    rows = []
    for a in alphas:
        w = {"eq3": att.edit(w_base, w_target, sel, a),
             "clamped": clamped_edit(att, w_base, w_target, sel, a, LO, HI)}
        r = bounded_edit(att, w_base, w_target, sel, a, LO, HI, info=True)
        w["bounded"] = r.x
        w3 = w["eq3"]
        out = np.maximum(LO - w3, 0.0) + np.maximum(w3 - HI, 0.0)
        row = {"model": model.name, "scenario": key, "alpha": float(a), "default_alpha": default,
               "is_default_alpha": a is default,
               "eq3_min_weight": float(w3.min()), "eq3_max_weight": float(w3.max()),
               "eq3_n_out_of_range": int(np.count_nonzero(out > EXCURSION_TOL)), "eq3_max_excursion": float(out.max()),
               "eq3_worst_shape": _worst(model.names, out) if out.max() > EXCURSION_TOL else "",
               "bounded_steps": r.iterations, "bounded_n_at_bounds": r.n_at_bounds}
        for k in METHODS:
            d = att.displacement(w[k])
            row[f"{k}_selected_motion_fraction"] = metrics.selected_motion(d, sel, d_base) / none if none > 0 else float("nan")
            row[f"{k}_unselected_fidelity"] = metrics.unselected_fidelity(d, d_target, sel, d_base)
        row["bounded_weight_change_vs_clamped"] = float(np.abs(w["bounded"] - w["clamped"]).max())
        rows.append(row)
    return rows


def summary_table(sweep: pd.DataFrame) -> pd.DataFrame:
    """Per model and scenario: how often (share of the swept alphas with a weight more than
    :data:`EXCURSION_TOL` outside [0, 1]) and how far Eq. (3) leaves the range; the three methods at
    Section 5's default alpha; the largest selected motion the clamp adds over the sweep, and how much
    of it the bounded solve takes back."""
    rows = []
    for (model, key), both in sweep.groupby(["model", "scenario"], sort=False):
        at = both[both.is_default_alpha].iloc[0]
        g = both[~both.is_default_alpha]
        rows.append({
            "model": model, "scenario": key, "n_alphas": len(g),
            "share_of_alphas_out_of_range": float((g.eq3_n_out_of_range > 0).mean()),
            "max_excursion": float(g.eq3_max_excursion.max()),
            "default_alpha": at.alpha,
            **{f"at_default_{c}": at[c] for c in ("eq3_n_out_of_range", "eq3_max_excursion", "eq3_worst_shape",
                                                  *(f"{k}_selected_motion_fraction" for k in METHODS),
                                                  *(f"{k}_unselected_fidelity" for k in METHODS))},
            "max_clamp_cost": float((g.clamped_selected_motion_fraction - g.eq3_selected_motion_fraction).max()),
            "max_bounded_saving_vs_clamp": float((g.clamped_selected_motion_fraction - g.bounded_selected_motion_fraction).max()),
        })
    return pd.DataFrame(rows)


def ict_case(model, att) -> pd.DataFrame:
    """The issue's example at Section 5's default alpha: ``eyeSquint_L`` and the range of every weight."""
    sc = S.scenario("wince_sneer_under_eye")
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    rows = []
    for method, w in [("eq3", att.edit(w_base, w_target, sel)), ("clamped", clamped_edit(att, w_base, w_target, sel)),
                      ("bounded", bounded_edit(att, w_base, w_target, sel))]:
        rows.append({"model": model.name, "method": method, "alpha": att.default_alpha(sel),
                     "sliders_moved": ", ".join(f"{model.names[i]} {w_target[i]:g}" for i in np.flatnonzero(w_target)),
                     "selected_vertices": " ".join(map(str, sc.vertices(model))),
                     "eyeSquint_L": float(w[model.shape_index("eyeSquint_L")]), "issue_eyeSquint_L": -0.22,
                     "min_weight": float(w.min()), "min_shape": model.names[int(np.argmin(w))],
                     "max_weight": float(w.max()), "max_shape": model.names[int(np.argmax(w))]})
    return pd.DataFrame(rows)


@experiment("bounded_attenuation", "Eq. 3 leaves the slider range; clamping it costs selected motion; the bounded solve keeps it",
            paper="lewis2005")
def bounded_attenuation(quick: bool = False) -> Result:
    alphas = np.logspace(-3, 6, 10 if quick else 37)
    runs, skipped = common.applicable_sessions(common.attenuators(), S.SCENARIOS)
    pairs = list({id(p): p for p, _ in runs}.values())  # the faces with a session to run
    sweep = pd.DataFrame([r for (m, att), key in runs for r in session_rows(m, att, key, alphas)])
    extra = {"summary": summary_table(sweep), **common.skipped_tables(skipped)}
    ict = [(m, att) for m, att in pairs if m.name == "ict"]
    if ict:
        extra["ict_case"] = ict_case(*ict[0])
    return Result(table=sweep, draw=lambda: draw(sweep), extra_tables=extra)


def draw(sweep: pd.DataFrame):
    import matplotlib.pyplot as plt

    models = list(dict.fromkeys(sweep.model))
    fig, axes = plt.subplots(3, len(models), figsize=(5.2 * len(models), 10), squeeze=False, layout="constrained")
    styles = {"eq3": "-", "clamped": "--", "bounded": ":"}
    for col, model in zip(axes.T, models):
        for key, g in sweep[(sweep.model == model) & ~sweep.is_default_alpha].groupby("scenario", sort=False):
            line, = col[0].plot(g.alpha, g.eq3_max_excursion, label=key)
            c = line.get_color()
            for k, ls in styles.items():
                col[1].plot(g.alpha, g[f"{k}_selected_motion_fraction"], ls, color=c,
                            label=f"{key}: {k}" if key == sweep.scenario.iloc[0] else None)
                col[2].plot(g.alpha, g[f"{k}_unselected_fidelity"], ls, color=c)
        col[0].set_ylabel("Eq. 3: largest excursion outside [0, 1]")
        col[0].set_title(f"{model}", fontsize=9)
        col[0].legend(fontsize=8)
        col[1].set_ylabel("selected motion / unattenuated")
        col[1].set_title("solid: Eq. 3   dashed: Eq. 3 clamped   dotted: bounded", fontsize=8)
        col[2].set_ylabel("unselected fidelity")
        for ax in col:
            ax.set_xscale("log")
            ax.set_xlabel("alpha")
            ax.grid(alpha=0.3)
    return fig


def summary(result) -> str:
    """Markdown: per face and scenario, how often and how far Eq. 3 leaves [0, 1], and what clamping and the bounded solve keep."""
    from repro.experiments.summaries import bullets, num, pct

    s = result.extra_tables["summary"]
    lines = []
    for _, r in s.iterrows():
        lines.append(f"*{r.model}*, `{r.scenario}`: Eq. 3 leaves [0, 1] at {pct(r.share_of_alphas_out_of_range)} of the "
                     f"{int(r.n_alphas)} alphas (by up to {num(r.max_excursion, 2)}); at the default alpha "
                     f"({r.default_alpha:.6g}) the selection keeps {pct(r.at_default_eq3_selected_motion_fraction)} of its "
                     f"motion with Eq. 3, {pct(r.at_default_clamped_selected_motion_fraction)} once clamped, "
                     f"{pct(r.at_default_bounded_selected_motion_fraction)} with the bounded solve")
    ict = result.extra_tables.get("ict_case")
    if ict is not None and len(ict):
        e = ict[ict.method == "eq3"].iloc[0]
        lines.append(f"the issue's ICT case ({e.sliders_moved}; vertices {e.selected_vertices}; alpha {e.alpha:.6g}): "
                     f"Eq. 3 puts `eyeSquint_L` at {num(e.eyeSquint_L, 2)} (the issue says {num(e.issue_eyeSquint_L, 2)}), "
                     f"its weights span {num(e.min_weight, 3)} (`{e.min_shape}`) to {num(e.max_weight, 3)} (`{e.max_shape}`)")
    return bullets(lines)


def _worst(names, out: np.ndarray) -> str:
    """The shape of the largest excursion; of shapes tied within rounding, the first.  The left and right
    shapes of a symmetric face tie: measured on the procedural face, their excursions differ by up to
    2e-9 relative at alpha = 1e6 (ill-conditioned), and which is larger changes with the machine's BLAS."""
    top = float(out.max())
    return names[int(np.flatnonzero(out >= top - (1e-6 * top + 1e-12))[0])]
