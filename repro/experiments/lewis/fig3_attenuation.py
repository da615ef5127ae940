"""Lewis et al. 2005, Fig. 3: attenuating the motion of selected vertices.

"a) The user selects two vertices whose motion is to be attenuated ... b) The
results of the same slider moves ... with coordinate movement attenuation.
c) Repeated from Fig. 2c for comparison."  Numbers from
:func:`repro.blendshapes.scenarios.evaluate` at the default alpha.
"""

from __future__ import annotations

import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

SCENARIOS = ("furrow_then_mouth", "eyelid_then_brow")


@experiment("fig3_attenuation", "Fig. 3: the same moves with the drifting vertices selected, with and without attenuation", paper="lewis2005")
def fig3_attenuation(quick: bool = False) -> Result:
    pairs, skipped = common.applicable(common.attenuators(), SCENARIOS)
    table = pd.DataFrame([S.evaluate(m, key, attenuator=att) for m, att in pairs for key in SCENARIOS])
    return Result(table=table, draw=lambda: draw(pairs), extra_tables=common.skipped_tables(skipped))


def draw(pairs):
    from repro.ui.render import face_images, panel_figure

    images, titles = [], []
    for model, att in pairs:
        for key in SCENARIOS:
            sc = S.scenario(key)
            sel = sc.selection(model)
            w_base, w_target = sc.weights(model)
            d_base = att.displacement(w_base)
            d_att = att.displacement(att.edit(w_base, w_target, sel))
            d_none = att.displacement(w_target)
            m_att, m_none = common.motion(d_att, d_base), common.motion(d_none, d_base)
            images += face_images(model, [d_base, d_att, d_none], [0 * m_att, m_att, m_none],
                                  selected=sc.vertices(model), clim=(0.0, 0.5))
            v = sc.vertices(model)
            titles += [f"{model.name} {sc.figure}a: selection ({len(v)} vertices)",
                       f"b) attenuated (alpha {att.default_alpha(sel):.4g})\nselected motion {m_att[v].mean():.3g}",
                       f"c) no attenuation\nselected motion {m_none[v].mean():.3g}"]
    return panel_figure(images, titles, clim=(0.0, 0.5), label="motion since the selection", ncols=3,
                        suptitle="Selected motion attenuation (colour: motion since the selection was made)")


def summary(result) -> str:
    """Markdown: per face and session, the selection, alpha, the selected motion left and the unselected fidelity."""
    from repro.experiments.summaries import bullets, num, pct, units

    lines = []
    for r in result.table.itertuples():
        u = units(r.model)
        lines.append(f"*{r.model}, {r.figure}* (`{r.scenario}`): {r.n_selected_vertices} selected vertices = "
                     f"{r.n_selected_coordinates} coordinates, alpha = {r.alpha:.6g}; the selected motion is "
                     f"{num(r.attenuated_selected_motion)} instead of {num(r.none_selected_motion)} {u} "
                     f"({pct(r.reduction)} of it left); unselected fidelity {num(r.attenuated_unselected_fidelity)}")
    return bullets(lines)
