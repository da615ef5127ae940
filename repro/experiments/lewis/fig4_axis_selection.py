"""Lewis et al. 2005, Fig. 4: selecting only the y coordinate of the mouth corners.

"a) The y-component of two vertices are selected. b) Sliders SmirkLeft and
SmirkRight are increased to 0.7 ... the selected vertices maintain their
vertical positions. c) The same slider moves with no attenuation."
Numbers: x/y/z displacement of the two corners (:func:`repro.blendshapes.scenarios.axis_table`).
"""

from __future__ import annotations

import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

KEY = "smirk_corners_y"


@experiment("fig4_axis_selection", "Fig. 4: y of the mouth corners selected; SmirkLeft/Right 0.7 move them in x only", paper="lewis2005")
def fig4_axis_selection(quick: bool = False) -> Result:
    pairs, skipped = common.applicable(common.attenuators(), [KEY])
    table = pd.DataFrame([r for m, att in pairs for r in S.axis_table(m, KEY, attenuator=att)])
    return Result(table=table, draw=lambda: draw(pairs, table), extra_tables=common.skipped_tables(skipped))


def draw(pairs, table):
    import matplotlib.pyplot as plt
    import numpy as np

    from repro.ui.render import face_images

    sc = S.scenario(KEY)
    fig, axes = plt.subplots(len(pairs), 4, figsize=(12, 3.2 * len(pairs)), squeeze=False, layout="constrained")
    for row, (model, att) in zip(axes, pairs):
        sel = sc.selection(model)
        w_base, w_target = sc.weights(model)
        d_att = att.displacement(att.edit(w_base, w_target, sel))
        d_none = att.displacement(w_target)
        imgs = face_images(model, [0 * d_att, d_att, d_none],
                           [np.zeros(model.n_vertices), common.motion(d_att), common.motion(d_none)],
                           selected=sc.vertices(model), clim=(0.0, 1.0))
        for ax, img, title in zip(row, imgs, ["a) y of 2 corners selected", "b) attenuated", "c) no attenuation"]):
            ax.imshow(img)
            ax.set_title(f"{model.name}: {title}", fontsize=8)
            ax.axis("off")
        sub = table[table.model == model.name]
        ax = row[3]
        labels, x = [], 0
        for r in sub.itertuples():
            ax.bar([x, x + 1, x + 2], [r.dx, r.dy, r.dz], color=["tab:blue", "tab:orange", "tab:green"],
                   alpha=1.0 if r.method == "attenuated" else 0.45)
            labels.append(f"v{r.vertex}\n{'att.' if r.method == 'attenuated' else 'none'}")
            x += 4
        ax.set_xticks([4 * i + 1 for i in range(len(labels))], labels, fontsize=8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"displacement ({model.units})")
        ax.set_title("dx (blue), dy (orange), dz (green);\nfaint: none, solid: attenuated (att.)", fontsize=8)
    fig.suptitle("Per-axis selection: only y of the mouth corners is attenuated", fontsize=9)
    return fig


def summary(result) -> str:
    """Markdown: per face, the mouth corners' |dy| and |dx| without and with y-only attenuation."""
    from repro.experiments.summaries import bullets, num, units

    t = result.table
    lines = []
    for model in t.model.unique():
        none = t[(t.model == model) & (t.method == "none")]
        att = t[(t.model == model) & (t.method == "attenuated")]
        lines.append(f"*{model}*: the corners' vertical motion |dy| goes from {num(none.dy.abs().mean())} to "
                     f"{num(att.dy.abs().mean())} {units(model)}; their sideways motion |dx| from "
                     f"{num(none.dx.abs().mean())} to {num(att.dx.abs().mean())} (alpha = {att.alpha.iloc[0]:.6g})")
    return bullets(lines)
