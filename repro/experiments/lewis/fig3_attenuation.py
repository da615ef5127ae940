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
    """Per face and session: a) the selection, b) attenuated, c) not, coloured by the motion since the
    selection; d) the motion attenuation removed, ``|d_att - d_none|`` per vertex, on a scale of its own
    per row (the sessions remove 1e-4 to 0.6): the selection held, and how far around it the rest is
    held with it."""
    from repro.ui.render import ColourScale, face_images, panel_grid

    images, titles, removed = [], [], []
    for model, att in pairs:
        for key in SCENARIOS:
            sc = S.scenario(key)
            sel = sc.selection(model)
            w_base, w_target = sc.weights(model)
            d_base = att.displacement(w_base)
            d_att = att.displacement(att.edit(w_base, w_target, sel))
            d_none = att.displacement(w_target)
            m_att, m_none = common.motion(d_att, d_base), common.motion(d_none, d_base)
            v = sc.vertices(model)
            images += face_images(model, [d_base, d_att, d_none], [0 * m_att, m_att, m_none],
                                  selected=v, clim=(0.0, 0.5))
            titles += [f"{model.name} {sc.figure}a: selection ({len(v)} vertices)",
                       f"b) attenuated (alpha {att.default_alpha(sel):.4g})\nselected motion {m_att[v].mean():.3g}",
                       f"c) no attenuation\nselected motion {m_none[v].mean():.3g}"]
            gone = common.motion(d_att, d_none)
            removed.append((model, d_base, gone))
            images.append(None)  # drawn below, on its own scale
            titles.append(f"d) removed: selected {gone[v].mean():.3g}\n(|b - c| per vertex)")
    slots = [i for i, img in enumerate(images) if img is None]
    colour_scales = {"motion": ColourScale((0.0, 0.5), label="motion since the selection", location="bottom")}
    scales = ["motion"] * len(images)
    for k, (i, (model, d_base, gone)) in enumerate(zip(slots, removed)):
        hi = float(gone.max()) or 1.0  # each row on its own scale: the sessions remove 1e-4 to 0.6
        images[i] = face_images(model, [d_base], [gone], clim=(0.0, hi), cmap="Blues")[0]
        scales[i] = k
        colour_scales[k] = ColourScale((0.0, hi), cmap="Blues", label="removed")
    return panel_grid(images, titles, scales, colour_scales, ncols=4,
                      suptitle="Selected motion attenuation (colour: motion since the selection was made; "
                               "blue: what attenuation removed)")


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
