"""Lewis et al. 2005, Figs. 1-2: blendshape interference.

Fig. 2: "b) The effect of moving the fourth slider, Furrow, to a value of 0.4.
c) Further slider moves, mostly affecting the mouth, but the middle of the brow
has continued to move downward as well, below the desired position."  Fig. 1:
the eyelid moves when the brows are raised.  Measured: how far the further
moves drag the vertices the first move positioned (:func:`repro.blendshapes.scenarios.interference`).

``extra_tables["whole_face"]``: Section 3's "identical in power": per model, the largest
difference between a face posed in the delta form and the same face from the whole-face form
(weights ``(1 - sum w, w1, w2, ...)``, five seeded random poses), and of the deltas after a
round trip delta -> whole-face -> delta (claim L10).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.blendshapes import scenarios as S
from repro.experiments.lewis import common
from repro.experiments.registry import Result, experiment

SCENARIOS = ("furrow_then_mouth", "eyelid_then_brow")


@experiment("fig2_interference", "Figs. 1-2: further slider moves drag a region an earlier move positioned", paper="lewis2005")
def fig2_interference(quick: bool = False) -> Result:
    models, skipped = common.applicable(common.models(), SCENARIOS)
    rows = []
    for model in models:
        for key in SCENARIOS:
            r = S.interference(model, key)
            r.pop("drift")
            rows.append(r)
    table = pd.DataFrame(rows)
    whole_face = pd.DataFrame([whole_face_round_trip(model) for model in models])
    return Result(table=table, draw=lambda: draw(models), extra_tables={"whole_face": whole_face, **common.skipped_tables(skipped)})


def whole_face_round_trip(model, *, n_poses: int = 5, seed: int = 0) -> dict:
    """Largest error (model units) of the whole-face form against the delta form, for ``model``."""
    rng = np.random.default_rng(seed)
    B = model.to_whole_face()
    pose = 0.0
    for _ in range(n_poses):
        w = rng.uniform(-0.5, 1.0, model.n_shapes)
        pose = max(pose, float(np.abs(B @ model.whole_face_weights(w) - model.pose(w).ravel()).max()))
    back = type(model).from_whole_face(B, model.faces, model.names)
    deltas = float(np.abs(back.D - model.D).max())
    return {"model": model.name, "n_poses": n_poses, "max_pose_error": pose, "max_delta_round_trip_error": deltas,
            "max_round_trip_error": max(pose, deltas)}


def draw(models):
    from repro.ui.render import face_images, panel_figure

    images, titles, values = [], [], []
    for model in models:
        for key in SCENARIOS:
            sc = S.scenario(key)
            w_base, w_target = sc.weights(model)
            d_base, d_target = model.D @ w_base, model.D @ w_target
            first, drift = common.motion(d_base), common.motion(d_target, d_base)
            values += [first, drift]
            images += face_images(
                model, [common.zeros(model), d_base, d_target], [0 * first, first, drift],
                selected=sc.vertices(model), clim=(0.0, 0.5),
            )
            base = ", ".join(f"{k} {v}" for k, v in sc.base.items())
            titles += [f"{model.name}: neutral", f"{sc.figure} first move: {base}",
                       f"further moves; colour = drift since\n(selected drift {drift[sc.vertices(model)].mean():.3g})"]
    return panel_figure(images, titles, clim=(0.0, 0.5), label=common.MOTION_LABEL, ncols=3,
                        suptitle="Interference: cyan = vertices the first move positioned")


def summary(result) -> str:
    """Markdown: per face and session, how far the further moves drag what the first move positioned."""
    from repro.experiments.summaries import bullets, num, pct

    lines = []
    for r in result.table.itertuples():
        way = "down" if r.drift_selected_dy < 0 else "up"
        lines.append(f"*{r.model}, {r.figure}* (`{r.scenario}`): the first move moved the selected vertices "
                     f"{num(r.first_move_selected)} {r.units}; the further moves drag them {num(r.drift_selected_mean)} "
                     f"{r.units} (mean; vertical part {num(r.drift_selected_dy)}, i.e. {way}), "
                     f"{pct(r.drift_relative, 3)} of the first move")
    return bullets(lines)
