"""Measurement: interactive speed of attenuation (Lewis et al. 2005, Section 5).

"The computations required are simple and fast enough to be performed at
interactive speeds."  Numbers from :func:`repro.bench.bench_attenuation`.
"""

from __future__ import annotations

from repro.experiments.registry import Result, experiment


@experiment(
    "attenuation_speed",
    "Eq. 3 cost: new selection (direct vs Gram-cached Attenuator) and slider move vs bare D@w",
    paper="lewis2005",
)
def attenuation_speed(quick: bool = False) -> Result:
    from repro.bench import bench_attenuation

    table = bench_attenuation(quick=quick)
    return Result(table=table, draw=lambda: draw(table))


def draw(table):
    """Bars of median time per call, baseline beside method, ratio annotated."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    for ax, (what, sub) in zip(axes, table.groupby("measurement", sort=False)):
        labels = [f"{r.model}\n{r.n_vertices:,} v, {r.n_shapes} shapes" for r in sub.itertuples()]
        x = range(len(sub))
        ax.bar([i - 0.2 for i in x], sub["baseline_us"], 0.4, label=sub["baseline"].iloc[0])
        ax.bar([i + 0.2 for i in x], sub["method_us"], 0.4, label=sub["method"].iloc[0])
        for i, r in zip(x, sub.itertuples()):
            ax.annotate(f"ratio {r.ratio:,.1f}", (i, max(r.baseline_us, r.method_us)), ha="center", va="bottom")
        ax.set_xticks(list(x), labels)
        ax.set_yscale("log")
        ax.set_ylabel("median time per call (µs)")
        ax.set_title(what)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(f"Attenuation speed — {table['machine'].iloc[0]}", fontsize=8)
    return fig
