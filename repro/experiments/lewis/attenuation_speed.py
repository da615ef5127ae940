"""Measurement: interactive speed of attenuation (Lewis et al. 2005, Section 5).

"The computations required are simple and fast enough to be performed at
interactive speeds."  Numbers from :func:`repro.bench.bench_attenuation`.
"""

from __future__ import annotations

from repro.experiments.registry import Result, experiment


@experiment(
    "attenuation_speed",
    "Section 5 speed: new selection (direct vs cached Attenuator), slider move vs bare D@w, vs vertices and shapes",
    paper="lewis2005",
)
def attenuation_speed(quick: bool = False, progress: bool = False) -> Result:
    from repro.bench.attenuation import bench_attenuation, bench_attenuation_scaling

    table = bench_attenuation(quick=quick, progress=progress)
    scaling = bench_attenuation_scaling(quick=quick, progress=progress)
    return Result(table=table, draw=lambda: draw(table, scaling), extra_tables={"scaling": scaling})


def draw(table, scaling):
    """Top: median time per call, baseline beside method.  Bottom: cost versus vertices and shapes."""
    import matplotlib.pyplot as plt

    fig, all_axes = plt.subplots(2, 2, figsize=(11, 7.6), layout="constrained")
    axes = all_axes[0]
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
        ax.legend(fontsize=8, loc="lower right")
    for ax, (sweep, xcol, xlabel) in zip(all_axes[1], [("vertices", "n_vertices", "vertices (procedural faces)"),
                                                        ("shapes", "n_shapes", "shapes (columns of the largest model)")]):
        s = scaling[scaling.sweep == sweep]
        for col, label in [("selection_direct_us", "new selection: direct Eq. 3"),
                           ("selection_attenuator_us", "new selection: Attenuator"),
                           ("slider_move_us", "slider move: M w1, D w2"), ("bare_matvec_us", "bare D @ w")]:
            ax.plot(s[xcol], s[col], "o-", label=label)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("median time (µs)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Attenuation speed — {table['machine'].iloc[0]}", fontsize=8)
    return fig


def summary(result) -> str:
    """Markdown: each speed measurement as a ratio, and whether it meets its goal (timings: machine-dependent)."""
    from repro.experiments.summaries import bullets, num

    lines = [f"*{r.model}*, {r.measurement}: {num(r.method_us)} µs against {num(r.baseline_us)} µs for {r.baseline} "
             f"({num(r.ratio, 3)}: {r.ratio_meaning}); goal {r.goal}: {'met' if r.meets_goal else 'not met'}"
             for r in result.table.itertuples()]
    return bullets(lines + [f"machine: {result.table.machine.iloc[0]}"])
