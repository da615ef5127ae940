"""Lewis et al. 2005, Section 3: the two approaches the paper rejects, measured against attenuation.

Zeroing the selected rows of D freezes the selection exactly but "allows facial
poses that depart from the designed subspace": the frozen vertex is torn from
its neighbours (``roughness_at_selection``: the largest uniform-Laplacian
magnitude of the motion since the selection, over the selected vertices and
their neighbours).  Orthogonal locking of the shapes that made the base pose
"does not sufficiently constrain the movement of particular vertices"
(selected motion).  Attenuation at the default alpha for comparison.
"""

from __future__ import annotations

import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment


@experiment("rejected_alternatives", "Section 3: zeroed rows of D and orthogonal locking vs attenuation (motion, fidelity, smoothness)", paper="lewis2005")
def rejected_alternatives(quick: bool = False) -> Result:
    runs, skipped = common.applicable_sessions(common.attenuators(), S.SCENARIOS)
    table = pd.DataFrame([r for (m, att), key in runs for r in S.compare_methods(m, key, attenuator=att)])
    pairs = list({id(p): p for p, _ in runs}.values())  # the faces with a session to run
    return Result(table=table, draw=lambda: draw(pairs, table), extra_tables=common.skipped_tables(skipped))


def draw(pairs, table):
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    from repro.blendshapes.alternatives import edit_zeroed
    from repro.blendshapes.metrics import laplacian_magnitude
    from repro.ui.render import face_images

    methods = ["none", "attenuation", "zeroed_rows", "orthogonal_lock"]
    metrics = [("selected_motion", "selected motion since selection"), ("unselected_fidelity", "unselected fidelity"),
               ("roughness_at_selection", "roughness at the selection (max |L (d - d_base)|)")]
    fig = plt.figure(figsize=(14, 4.2 * len(pairs) + 3.4), layout="constrained")
    sub = fig.subfigures(2, 1, height_ratios=[4.2 * len(pairs), 3.4])
    axes = sub[0].subplots(len(pairs), 3, squeeze=False)
    for row, (model, _) in zip(axes, pairs):
        t = table[table.model == model.name]
        keys = list(dict.fromkeys(t.scenario))
        for ax, (col, label) in zip(row, metrics):
            for j, method in enumerate(methods):
                cells = [t[(t.scenario == k) & (t.method == method)].iloc[0] for k in keys]
                xs = np.arange(len(keys)) + 0.2 * (j - 1.5)
                bars = ax.bar(xs, [c[col] for c in cells], 0.2, label=method)
                _mark_missing_bars(ax, xs, cells, col, bars.patches[0].get_facecolor())
            _mark_tiny_groups(ax, t, keys, col)
            ax.set_xticks(range(len(keys)), [k.replace("_", "\n") for k in keys], fontsize=8)
            ax.tick_params(axis="y", labelsize=8)
            ax.set_title(f"{model.name}: {label}", fontsize=10)
    # one legend for every panel, above them, at a size that reads at 100 % (the figure is 14 in wide)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    sub[0].legend(handles, [m.replace("_", " ") for m in labels], loc="outside upper center", ncols=len(methods),
                  fontsize=11, frameon=False)
    na = table[~table.applicable]
    if len(na):
        sessions = ", ".join(dict.fromkeys(na.scenario))
        sub[0].supxlabel(f"n/a: orthogonal locking locks the shapes of the base pose; {sessions} start from the "
                         f"neutral face, so there is nothing to lock.\n0: exactly zero (zeroed rows hold the "
                         f"selection by construction)", fontsize=9)
    # where zeroing tears: Laplacian magnitude of the motion, procedural face, Fig. 5 session
    model, att = pairs[0]
    sc = S.scenario("wince_sneer_under_eye")
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    ds = [att.displacement(w_target), att.displacement(att.edit(w_base, w_target, sel)),
          edit_zeroed(model.D, w_base, w_target, sel)]
    d_base = att.displacement(w_base)
    lap = [laplacian_magnitude(model, d - d_base) for d in ds]
    hi = max(float(x.max()) for x in lap)
    imgs = face_images(model, ds, lap, selected=sc.vertices(model), clim=(0, hi), cmap="viridis")
    bottom = sub[1].subplots(1, 3)
    for ax, img, title, l in zip(bottom, imgs, ["no attenuation", "attenuation", "zeroed rows"], lap):
        ax.imshow(img)
        ax.axis("off")
        ax.set_title(f"{model.name} {sc.figure}, {title}: max |L d| = {l.max():.3g}", fontsize=10)
    bar = sub[1].colorbar(ScalarMappable(Normalize(0, hi), "viridis"), ax=bottom, shrink=0.8, aspect=15)
    bar.set_label(f"|L (d - d_base)| ({model.units})", fontsize=9)
    bar.ax.tick_params(labelsize=8)
    sub[1].suptitle("Laplacian magnitude of the displacement (bright = surface torn)", fontsize=10)
    return fig


def _mark_tiny_groups(ax, t, keys, col) -> None:
    """Write the largest value over a session's bars where all of them are too small to see (under 1 %
    of the axis): e.g. the ICT face's furrow session, whose moves barely reach the selection."""
    top = ax.get_ylim()[1]
    for i, k in enumerate(keys):
        hi = t[t.scenario == k][col].max()
        if 0 < hi < 0.01 * top:
            ax.text(i, 0.06 * top, f"all \u2264 {hi:.2g}", ha="center", va="bottom", fontsize=8)


def _mark_missing_bars(ax, xs, cells, col, colour) -> None:
    """Say on the axes why a bar is not there: "n/a" where the method does not apply to the session
    (its row is NaN), "0" where the value is exactly zero."""
    for x, cell in zip(xs, cells):
        if not cell["applicable"]:
            ax.text(x, 0, " n/a", rotation=90, ha="center", va="bottom", fontsize=8, color=colour)
        elif cell[col] == 0:
            ax.text(x, 0, "0", ha="center", va="bottom", fontsize=8, color=colour)


def summary(result) -> str:
    """Markdown: per face and session, the tear of zeroed rows and what orthogonal locking leaves moving."""
    from repro.experiments.summaries import bullets, num, units

    t = result.table[result.table.applicable]
    piv = t.pivot(index=["model", "scenario"], columns="method", values="roughness_at_selection")
    sm = t.pivot(index=["model", "scenario"], columns="method", values="selected_motion")
    lines = []
    for (model, scenario), r in piv.iterrows():
        u = units(model)
        line = (f"*{model}*, `{scenario}`: roughness at the selection {num(r['zeroed_rows'])} {u} with zeroed rows, "
                f"{num(r['attenuation'])} with attenuation ({num(r['zeroed_rows'] / r['attenuation'], 2)} times)")
        s = sm.loc[(model, scenario)]
        if "orthogonal_lock" in s and s.notna()["orthogonal_lock"]:
            line += (f"; orthogonal locking leaves the selection moving {num(s['orthogonal_lock'])} {u} against "
                     f"{num(s['none'])} without correction ({num(s['orthogonal_lock'] / s['none'], 2)} times)")
        lines.append(line)
    return bullets(lines)
