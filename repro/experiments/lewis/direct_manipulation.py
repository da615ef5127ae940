"""Direct manipulation (Lewis and Anjyo 2010) against the slider edit that reaches the same pose.

For every model (the embedded face; ICT when present) and every scenario of
Lewis et al. 2005: the slider edit moves the sliders from ``w_base`` to
``w_target``.  The direct-manipulation edit instead drags the ``N_DRAGGED``
vertices that edit moves most (outside the scenario's selection) to where the
slider edit puts them, from ``w_base``
(:class:`repro.blendshapes.manipulation.DirectManipulator`): without a pin,
with the scenario's selection pinned (the 2005 pin), and pinned within the
slider range [0, 1].  The table gives, per edit: how many sliders move, how far
the dragged vertices end from their targets, how far the pinned (selected)
region moves, and how far the whole face ends from the slider pose.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.blendshapes import scenarios as S
from repro.blendshapes.manipulation import DirectManipulator
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

N_DRAGGED = 2
#: a slider counts as moved when its weight changes by more than this
MOVED = 1e-3
METHODS = ("sliders", "dm", "dm_pinned", "dm_pinned_bounded")


def edit_rows(model, dm: DirectManipulator, key: str) -> list[dict]:
    """The slider edit of scenario ``key`` and the three direct-manipulation edits reaching for it."""
    sc = S.scenario(key)
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    d_base = model.displacement(w_base)
    edit = np.linalg.norm(model.displacement(w_target) - d_base, axis=1)
    edit[np.unique(sel // 3)] = -1.0  # drag outside the selection
    dragged = np.sort(np.argsort(-edit, kind="stable")[:N_DRAGGED])
    targets = dm.positions(w_target, dragged)
    weights = {
        "sliders": w_target,
        "dm": dm.solve(w_base, dragged, targets),
        "dm_pinned": dm.solve(w_base, dragged, targets, pinned=sel),
        "dm_pinned_bounded": dm.solve(w_base, dragged, targets, pinned=sel, lo=0.0, hi=1.0),
    }
    pinned_vertices = np.unique(sel // 3)
    reach = float(np.linalg.norm(targets - dm.positions(w_base, dragged), axis=1).max())
    d_slider = model.displacement(w_target)
    rows = []
    for method in METHODS:
        w = weights[method]
        d = model.displacement(w)
        motion = (d - d_base).reshape(-1)[sel]  # the pinned coordinates only (Fig. 4 pins y alone)
        per_vertex = np.sqrt(np.bincount(np.searchsorted(pinned_vertices, sel // 3), motion**2,
                                         minlength=pinned_vertices.size))
        dw = w - w_base
        rows.append({
            "model": model.name, "scenario": key, "figure": sc.figure, "method": method,
            "dragged_vertices": " ".join(map(str, dragged)), "drag_distance": reach,
            "n_sliders_moved": int(np.count_nonzero(np.abs(dw) > MOVED)),
            "n_sliders_moved_over_0.05": int(np.count_nonzero(np.abs(dw) > 0.05)),
            "weight_change_norm": float(np.linalg.norm(dw)),
            "min_weight": float(w.min()), "max_weight": float(w.max()),
            "dragged_error": float(np.linalg.norm(dm.positions(w, dragged) - targets, axis=1).max()),
            "pinned_motion_max": float(per_vertex.max()), "pinned_motion_mean": float(per_vertex.mean()),
            "distance_from_slider_pose_mean": float(np.linalg.norm(d - d_slider, axis=1).mean()),
            "distance_from_slider_pose_max": float(np.linalg.norm(d - d_slider, axis=1).max()),
        })
    return rows


@experiment("direct_manipulation", "Lewis and Anjyo 2010: dragging vertices (with and without the 2005 pin) vs the slider edit",
            paper="lewis2005")
def direct_manipulation(quick: bool = False) -> Result:
    runs, skipped = common.applicable_sessions([(m, DirectManipulator(att)) for m, att in common.attenuators()],
                                               S.SCENARIOS)
    table = pd.DataFrame([r for (m, dm), key in runs for r in edit_rows(m, dm, key)])
    return Result(table=table, draw=lambda: draw(table), extra_tables=common.skipped_tables(skipped))


def draw(table: pd.DataFrame):
    import matplotlib.pyplot as plt

    models = list(dict.fromkeys(table.model))
    cols = [("n_sliders_moved", "sliders moved (|dw| > 1e-3)", False),
            ("pinned_motion_max", "largest motion in the pinned region", True),
            ("dragged_error", "dragged vertices: distance from target", True)]
    fig, axes = plt.subplots(len(models), len(cols), figsize=(15, 3.6 * len(models)), squeeze=False, layout="constrained")
    for row, model in zip(axes, models):
        t = table[table.model == model]
        keys = list(dict.fromkeys(t.scenario))
        x = np.arange(len(keys))
        width = 0.8 / len(METHODS)
        for ax, (col, label, log) in zip(row, cols):
            for i, method in enumerate(METHODS):
                v = t[t.method == method].set_index("scenario").loc[keys, col].to_numpy(dtype=float)
                ax.bar(x + (i - 1.5) * width, np.maximum(v, 1e-12) if log else v, width, label=method)
            ax.set_xticks(x, [k.replace("_", "\n", 1) for k in keys], fontsize=8)
            if log:
                ax.set_yscale("log")
            ax.set_title(f"{model}: {label}", fontsize=9)
            ax.grid(alpha=0.3, axis="y")
    handles, labels = axes[0, 0].get_legend_handles_labels()  # one legend above the panels: none covers a bar
    fig.legend(handles, labels, loc="outside upper center", ncols=len(METHODS), fontsize=8)
    return fig


def summary(result) -> str:
    """Markdown: per face and scenario, the sliders each edit moves and how far the pinned region moves."""
    from repro.experiments.summaries import bullets, num

    t = result.table
    lines = []
    for (model, scenario), g in t.groupby(["model", "scenario"], sort=False):
        g = g.set_index("method")
        parts = [f"{m}: {int(g.loc[m, 'n_sliders_moved_over_0.05'])} sliders moved by more than 0.05, pinned region "
                 f"moved {num(g.loc[m, 'pinned_motion_max'], 2)} (max), weights {num(g.loc[m, 'min_weight'], 2)} to "
                 f"{num(g.loc[m, 'max_weight'], 2)}" for m in g.index]
        lines.append(f"*{model}*, `{scenario}`: " + "; ".join(parts))
    return bullets(lines)
