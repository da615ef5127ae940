"""Lewis et al. 2005, Fig. 5: the same slider moves at several alpha.

"a) Six vertices (18 coordinates) are selected below the eye. b) ... Wince,
SneerLeft, and SneerRight are all set to 0.7 ... c) ... with attenuation ...
alpha = 335. d) The user adjusts alpha to 25. Now the mouth moves exactly as in
Fig. 5b, but so do the selected vertices. e) alpha = 3000. The algorithm favors
keeping the selected vertices stationary, but at the cost of not moving
unselected vertices either."  335 = (2016 - 6) / 6 on the paper's model; the
embedded face has 2,016 vertices so its default is 335 too.  On the ICT face
area (9,409 vertices) the default is larger.
"""

from __future__ import annotations

import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

KEY = "wince_sneer_under_eye"
ALPHAS = (25.0, None, 3000.0)  # None: the default


@experiment("fig5_alpha", "Fig. 5: six vertices under the eye held at alpha = 25, default (335), 3000, and none", paper="lewis2005")
def fig5_alpha(quick: bool = False) -> Result:
    pairs, skipped = common.applicable(common.attenuators(), [KEY])
    rows = []
    for model, att in pairs:
        for a in ALPHAS:
            r = S.evaluate(model, KEY, a, attenuator=att)
            r["alpha_setting"] = "default" if a is None else f"{a:g}"
            rows.append(r)
    table = pd.DataFrame(rows)
    return Result(table=table, draw=lambda: draw(pairs, table), extra_tables=common.skipped_tables(skipped))


def draw(pairs, table):
    """Per face, two rows: the faces posed (b, then alpha increasing), coloured by their motion; under
    each attenuated face the motion attenuation removed, ``|d_att - d_none|`` per vertex, on one scale
    for every face: the selection held, and how much of the rest goes with it."""
    from repro.ui.render import ColourScale, face_images, panel_grid

    sc = S.scenario(KEY)
    images, titles, scales, removed = [], [], [], []
    for model, att in pairs:
        sel = sc.selection(model)
        w_base, w_target = sc.weights(model)
        settings = sorted(((att.default_alpha(sel) if a is None else a, label, a)
                           for label, a in [("c) default", None), ("d)", 25.0), ("e)", 3000.0)]),
                          key=lambda s: s[0])  # panels in increasing alpha, after the unattenuated face
        d_none = att.displacement(w_target)
        poses = [("b) no attenuation", d_none)]
        for a_val, label, a in settings:
            poses.append((f"{label} alpha {a_val:.4g}", att.displacement(att.edit(w_base, w_target, sel, a))))
        v = sc.vertices(model)
        ds = [d for _, d in poses]
        ms = [common.motion(d) for d in ds]
        images += face_images(model, ds, ms, selected=v, clim=(0.0, 1.0))
        titles += [f"{model.name} {t}\nselected motion {m[v].mean():.3g}" for (t, _), m in zip(poses, ms)]
        scales += [("motion", model.name)] * len(poses)
        t = table[table.model == model.name].set_index("alpha_setting")
        removed.append((model, v, [common.motion(d, d_none) for d in ds[1:]],
                        [(label, t.loc["default" if a is None else f"{a:g}"]) for _, label, a in settings]))
    hi = max((float(r.max()) for *_, rs, _ in removed for r in rs), default=0.0) or 1.0
    for model, v, rs, rows in removed:
        images.append(None)
        titles.append(f"{model.name}, in blue:\nthe motion attenuation\nremoves from b),\n|pose - b)| per vertex")
        scales.append(None)
        # no cyan markers here: the selection is the darkest blue
        images += face_images(model, [common.zeros(model)] * len(rs), rs, clim=(0.0, hi), cmap="Blues")
        titles += [f"{label}: removed {1 - r.reduction:.0%} of the\nselection's motion, "
                   f"{1 - r.attenuated_unselected_fidelity:.0%} of the rest's" for (label, r) in rows]
        scales += [("removed", model.name)] * len(rs)
    # rows: each face's posed row, then its removed row (the faces first, for reading across)
    n = len(ALPHAS) + 1  # slots per row
    order = [i for k in range(len(pairs)) for i in [*range(n * k, n * k + n),
                                                    *range(n * (len(pairs) + k), n * (len(pairs) + k) + n)]]
    motion = ColourScale((0.0, 1.0), label=common.MOTION_LABEL)
    gone = ColourScale((0.0, hi), cmap="Blues", label="motion removed")
    return panel_grid([images[i] for i in order], [titles[i] for i in order], [scales[i] for i in order],
                      {k: (motion if k[0] == "motion" else gone) for k in scales if k is not None}, ncols=n,
                      suptitle="Fig. 5: alpha trades selected stillness against unselected freedom (cyan: selected)")


def summary(result) -> str:
    """Markdown: per face, the default alpha, and the selected motion left and the fidelity at each alpha."""
    from repro.experiments.summaries import bullets, num, pct

    t = result.table
    lines = []
    for model in t.model.unique():
        g = t[t.model == model].sort_values("alpha")
        d = g[g.alpha_setting == "default"].iloc[0]
        alphas = ", ".join(f"{a:.6g}" for a in g.alpha)
        lines.append(f"*{model}*: {d.n_selected_vertices} vertices ({d.n_selected_coordinates} coordinates) selected, "
                     f"default alpha = {d.alpha:.6g}; at alpha = {alphas} the selection keeps "
                     f"{', '.join(pct(x) for x in g.reduction)} of its motion and the unselected fidelity is "
                     f"{', '.join(num(x, 2) for x in g.attenuated_unselected_fidelity)}")
    return bullets(lines)
