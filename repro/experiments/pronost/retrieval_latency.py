"""Pronost et al., Sections 3.2.2-3.3 and 4: retrieval latency and quality versus database size and k.

The paper's search ("Search" thread, Section 4) takes "almost 0.28 s" on a Pentium 4 for
a database of about 75 motions, while the system must react to the supervisor "in less
than 1/30 s" (Section 3.4.2).  Both are drawn as reference lines, not as pass/fail
thresholds (another machine, another implementation, 2008).

What the numbers are
--------------------
``table`` is :func:`repro.bench.bench_retrieval` (the contract of
``figures/retrieval_latency.csv``): for each base database (the synthetic one always,
the CMU one when dataset ``cmu-bvh`` is present) and each augmentation factor (1x and 10x
with ``quick``; 1x, 10x, 100x, 1,000x otherwise), the same random queries
(:func:`repro.motion.search.retrieval.make_queries`) are answered by three methods of
:class:`repro.motion.search.retrieval.MotionRetriever`, in one process:

* ``pruned`` -- the paper's algorithm (:meth:`~MotionRetriever.search`): Eq. 1, nearest
  cluster centroid to ``q_r``, box test on ``c_r``, minimum of ``d = w_q d_qr + w_c d_cr``
  over what is left (with the documented fallbacks when nothing is left);
* ``exhaustive`` -- the same ``d`` over every startable pose of the semantics (the exact
  optimum of ``d``; :meth:`~MotionRetriever.search_exhaustive`);
* ``kdtree`` -- a k-d tree over a pose + hit-point feature, 32 neighbours rescored with
  ``d`` (:meth:`~MotionRetriever.search_kdtree`).

``p50_ms`` / ``p99_ms`` are percentiles over the queries of the *search proper* given a
prepared query (each query run 3 times, its fastest time kept).  The query preparation
-- retargeting the current pose ``q`` to the database actor(s) to get ``q_r``
(:meth:`MotionRetriever.prepare`, Section 3.4.1) -- is the same for every method and is
reported separately as ``prepare_p50_ms`` (drawn as a grey line): a full query costs
``prepare_p50_ms + p50_ms``.  ``precompute_s`` is building the retriever (k-means and
indices, once per database, Section 3.2.2), not part of a query.  ``k`` is the number of
clusters (:func:`repro.motion.search.kmeans.default_k`, which grows as the square root of
the number of poses).

Quality: ``differs_from_exhaustive`` is the fraction of queries whose selected (clip,
start frame) is not the exhaustive optimum; ``mean_excess_d`` is the mean over *all*
queries of the relative excess ``(d - d_opt) / d_opt``; ``mean_excess_when_differs`` (added
here) is the same mean over the queries that differ only (``mean_excess_d /
differs_from_exhaustive``): "how much worse, when it is worse".  The pruned candidates are
a subset of the exhaustive ones, so the excess is never negative.

The 10x to 1,000x databases are made by :func:`repro.motion.database.augment.augment` (mirrored,
rescaled, time-warped, noisy *variants* of the base clips), not new captures: they are
strongly correlated with their sources, which flatters both the clustering and the
box pruning compared with as many real motions.  The 1,000x one (about 4.6 M poses for the
synthetic base, the order of the largest public mocap collections) stores its pose clouds in
float32 (:data:`repro.bench.index_build.FLOAT32_FROM`).  The latency panels print the log-log
slope of the p50 over all sizes (:func:`repro.bench.retrieval.retrieval_summary`).

``extra_tables["k_sweep"]``: on each base database, :class:`MotionRetriever` with
``k`` in 4, 8, 16, 32, 64 (full: 2 ... 128) and the default ``k``: the pruned search's p50
/ p99 latency, the exhaustive p50 measured in the same call, the differs fraction, the
excess of ``d``, how often each fallback was taken, and the mean number of poses scored.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from repro.bench.retrieval import bench_retrieval, retrieval_summary
from repro.experiments.progress import bar
from repro.experiments.pronost.databases import database_names
from repro.experiments.registry import Result, experiment
from repro.motion.runtime.paper import PAPER_SEARCH_S, REACTION_BUDGET_S

#: Cluster counts of the k sweep.
K_VALUES_QUICK = (4, 8, 16, 32, 64)
K_VALUES_FULL = (2, 4, 8, 16, 32, 64, 128)

METHOD_STYLE = {"pruned": ("C0", "pruned (paper: cluster + box)"), "exhaustive": ("C3", "exhaustive scan"),
                "kdtree": ("C2", "k-d tree + rescoring"),
                "exact": ("C4", "exact (branch and bound over clusters, clip runs, boxes)")}


def k_sweep(databases=None, k_values=K_VALUES_QUICK, *, n_queries: int = 100, seed: int = 0,
            progress: bool = False) -> pd.DataFrame:
    """The pruned search on each base database for several numbers of clusters ``k``.

    For every ``k`` (and the default one), :func:`repro.bench.retrieval.time_search` times
    the pruned and the exhaustive search on the same ``n_queries`` queries; then the
    pruned search is run once more per query (untimed) to count the poses it scored and
    the fallbacks it took.
    """
    from repro.motion.search.kmeans import default_k
    from repro.motion.database.sources import default_database
    from repro.bench.retrieval import time_search
    from repro.motion.search.retrieval import MotionRetriever, make_queries

    rows = []
    for name in databases or database_names():
        db = default_database(name)
        kd = default_k(db.n_poses)
        queries = make_queries(db, n_queries, seed)
        prepared = None
        for k in bar(sorted(set(k_values) | {kd}), desc=f"retrieval_latency: k sweep, {name}", unit="k",
                     progress=progress):
            t0 = time.perf_counter()
            r = MotionRetriever(db, k=k, seed=seed)
            pre = time.perf_counter() - t0
            if prepared is None:  # q_r does not depend on the clusters: prepare once per database
                prepared = [(c, r.prepare(pose, ch), sem) for c, pose, ch, sem in queries]
            t = time_search(db, n_queries=n_queries, seed=seed, retriever=r, methods=("pruned", "exhaustive"))
            res = [r.search(c, q, None, sem) for c, q, sem in prepared]
            ag = t["agreement"]["pruned"]
            fb = t["pruned_fallbacks"]
            rows.append(dict(
                database=name, n_clips=db.n_clips, n_poses=db.n_poses, k=r.k, k_asked=k, is_default_k=k == kd,
                mean_cluster_size=db.n_poses / r.k, p50_ms=t["latency"]["pruned"]["p50_ms"],
                p99_ms=t["latency"]["pruned"]["p99_ms"], exhaustive_p50_ms=t["latency"]["exhaustive"]["p50_ms"],
                differs_from_exhaustive=ag["differs"], same_clip=ag["same_clip"], mean_excess_d=ag["mean_excess"],
                mean_excess_when_differs=ag["mean_excess"] / ag["differs"] if ag["differs"] > 0 else 0.0,
                max_excess_d=ag["max_excess"],
                fallback_none=fb.get("none", 0) / n_queries,
                fallback_neighbour_clusters=fb.get("neighbour_clusters", 0) / n_queries,
                fallback_no_box=fb.get("no_box", 0) / n_queries,
                mean_poses_scored=float(np.mean([x.n_candidates for x in res])),
                median_poses_scored=float(np.median([x.n_candidates for x in res])),
                mean_poses_exhaustive=float(np.mean([r.sem_rows[sem].size for _, _, sem in prepared])),
                precompute_s=pre, n_queries=n_queries,
            ))
    return pd.DataFrame(rows)


@experiment("retrieval_latency", "Retrieval latency versus database size (1x-1,000x) and number of clusters k; "
            "quality against the exhaustive optimum", paper="pronost2008")
def retrieval_latency(quick: bool = False, progress: bool = False) -> Result:
    from repro.experiments.shared import augmented_database

    table = bench_retrieval(quick=quick, progress=progress, database=augmented_database)
    differs = table.differs_from_exhaustive
    table["mean_excess_when_differs"] = (table.mean_excess_d / differs.where(differs > 0)).fillna(0.0)
    ks = k_sweep(sorted(set(table.database), key=list(table.database).index),
                 K_VALUES_QUICK if quick else K_VALUES_FULL, n_queries=100 if quick else 200, progress=progress)
    return Result(table=table, draw=lambda: draw(table, ks), extra_tables={"k_sweep": ks})


#: The base databases a full run draws (the CMU one only when its takes are staged).
BASE_DATABASES = {"synthetic": None, "cmu": "dataset 'cmu-bvh' not present (repro data fetch cmu-bvh)"}
#: Font sizes of the figure (points at the saved size; at least 8, issue 26 item 5).
FONT, SMALL_FONT = 10, 8.5


def _latency_panel(ax, g: pd.DataFrame, name: str) -> None:
    for method, sub in g.groupby("method", sort=False):
        sub = sub.sort_values("n_poses")
        color, _ = METHOD_STYLE.get(method, (None, method))
        ax.plot(sub.n_poses, sub.p50_ms, "o-", color=color)
        ax.plot(sub.n_poses, sub.p99_ms, "s--", color=color, alpha=0.6, ms=4)
    prep = g.groupby("n_poses").prepare_p50_ms.first()
    ax.plot(prep.index, prep.values, ":", color="0.45")
    for y, ls, lw, text in ((PAPER_SEARCH_S * 1e3, "-", 1.2, "paper: 0.28 s (Pentium 4, ~75 motions)"),
                            (REACTION_BUDGET_S * 1e3, "--", 1.0, "reaction budget 1/30 s")):
        ax.axhline(y, color="k", ls=ls, lw=lw)
        ax.annotate(text, (0.01, y), xycoords=("axes fraction", "data"), va="bottom", fontsize=SMALL_FONT)
    ax.set_xscale("log")
    ax.set_yscale("log")
    # every curve inside: from a sixth of the lowest p50 (room for the size labels) to 3x the highest p99
    lo = min(g.p50_ms.min(), g.prepare_p50_ms.min()) / 6
    hi = max(g.p99_ms.max(), g.prepare_p50_ms.max(), PAPER_SEARCH_S * 1e3) * 3
    ax.set_ylim(lo, hi)
    for (f, n, c, k), _ in g.groupby(["factor", "n_poses", "n_clips", "k"]):
        ax.annotate(f"{f}x: {c:,} clips\n{n:,} poses, k={k}", (n, lo), xytext=(0, 3), textcoords="offset points",
                    ha="center", va="bottom", fontsize=SMALL_FONT, color="0.3")
    xs = np.sort(g.n_poses.unique())
    ax.set_xlim(xs[0] / 2, xs[-1] * 2)
    _no_minor_labels(ax)
    ax.set_xlabel("poses in the database (log)")
    ax.set_ylabel("search latency per query (ms, log)")
    ax.set_title(f"{name} database: latency vs size", fontsize=FONT)
    s = retrieval_summary(g)[name]
    caption = (f"pruned search p50 at 1x: {s['base_p50_ms']:.3f} ms (+ {g.prepare_p50_ms.iloc[0]:.2f} ms preparation); "
               f"log-log slope of its p50: {s['loglog_slope_pruned']:.2f}\n"
               f"at {s['largest_factor']}x: pruned {s['speedup_vs_exhaustive_at_largest']:.1f}x faster than "
               "exhaustive (p50)"
               + (f"; exact {s['exact_speedup_vs_exhaustive_at_largest']:.1f}x faster, {s['exact_n_differs']} "
                  f"differences, slope {s['loglog_slope_exact']:.2f}" if "exact_n_differs" in s else ""))
    # the numbers as a caption under the axes, not over the curves
    ax.annotate(caption, (0.5, 0), xycoords="axes fraction", xytext=(0, -42), textcoords="offset points",
                ha="center", va="top", fontsize=SMALL_FONT)
    ax.grid(alpha=0.3, which="both")


def _latency_key(methods) -> list:
    """Legend handles of the latency panels: colour = method, line = percentile."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=METHOD_STYLE[m][0], lw=2, label=METHOD_STYLE[m][1]) for m in methods
               if m in METHOD_STYLE]
    return handles + [Line2D([], [], color="k", marker="o", ls="-", label="p50 (median)"),
                      Line2D([], [], color="k", marker="s", ms=4, ls="--", alpha=0.6, label="p99"),
                      Line2D([], [], color="0.45", ls=":", label="query preparation q -> q_r (shared), p50")]


def _style_key(entries, names, lines) -> list:
    """Legend handles: ``entries`` (label, colour, marker) and, when several databases, one line style each."""
    from matplotlib.lines import Line2D

    out = [Line2D([], [], color=c, marker=m, ls="-", label=lab) for lab, c, m in entries]
    if len(names) > 1:
        out += [Line2D([], [], color="k", ls=lines.get(n, "-"), label=f"{n} database") for n in names]
    return out


def _below(ax, handles, ncol: int) -> None:
    """The panel's legend under its axes (never over the curves)."""
    ax.legend(handles=handles, fontsize=SMALL_FONT, ncol=ncol, loc="upper center", bbox_to_anchor=(0.5, -0.16),
              frameon=False)


def _no_minor_labels(ax) -> None:
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())


def draw(table: pd.DataFrame, ks: pd.DataFrame):
    """Top row: latency vs size, one panel per base database present.  Bottom row: quality vs size, quality and
    latency vs k.  A base database that is absent is said in the caption line (no empty panel)."""
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(table.database))
    span = 4 // len(names) if len(names) in (1, 2, 4) else 2
    top = [f"lat:{n}" for n in names for _ in range(span)][:4]
    mosaic = [top, ["q_differs", "q_excess", "k_quality", "k_latency"]]
    fig, ax = plt.subplot_mosaic(mosaic, figsize=(16, 12), layout="constrained", height_ratios=[1.25, 1])
    for n in names:
        _latency_panel(ax[f"lat:{n}"], table[table.database == n], n)
    lines = {"synthetic": "-", "cmu": "--"}
    quality = [m for m in dict.fromkeys(table.method) if m != "exhaustive"]
    for n in names:
        g = table[(table.database == n) & (table.method != "exhaustive")]
        for method, sub in g.groupby("method", sort=False):
            sub = sub.sort_values("n_poses")
            color, _ = METHOD_STYLE[method]
            ax["q_differs"].plot(sub.n_poses, 100 * sub.differs_from_exhaustive, "o" + lines.get(n, "-"), color=color)
            ax["q_excess"].plot(sub.n_poses, 100 * sub.mean_excess_when_differs, "o" + lines.get(n, "-"), color=color)
    q_key = _style_key([(m, METHOD_STYLE[m][0], "o") for m in quality], names, lines)
    for key, ylabel, title in [("q_differs", "queries whose choice differs (%)",
                                "choice differs from\nthe exhaustive optimum"),
                               ("q_excess", "mean excess of d when it differs (%)", "penalty when it differs:\n"
                                "(d - d_opt) / d_opt")]:
        a = ax[key]
        a.set_xscale("log")
        _no_minor_labels(a)
        a.set_xlabel("poses in the database (log)")
        a.set_ylabel(ylabel)
        a.set_title(f"vs size: {title}", fontsize=FONT)
        a.set_ylim(bottom=0)
        a.grid(alpha=0.3)
        _below(a, q_key, 2)
    for n in ks.database.unique():
        g = ks[ks.database == n].sort_values("k")
        ls = lines.get(n, "-")
        ax["k_quality"].plot(g.k, 100 * g.differs_from_exhaustive, "o" + ls, color="C0")
        ax["k_quality"].plot(g.k, 100 * g.mean_excess_when_differs, "^" + ls, color="C1")
        ax["k_quality"].plot(g.k, 100 * g.fallback_no_box, "x" + ls, color="0.5")
        ax["k_latency"].plot(g.k, g.p50_ms, "o" + ls, color="C0")
        ax["k_latency"].plot(g.k, g.exhaustive_p50_ms, "s" + ls, color="C3", ms=4)
        d = g[g.is_default_k]
        ax["k_quality"].plot(d.k, 100 * d.differs_from_exhaustive, "o", ms=11, mfc="none", color="k")
        ax["k_latency"].plot(d.k, d.p50_ms, "o", ms=11, mfc="none", color="k")
    knames = list(ks.database.unique())
    keys = {"k_quality": _style_key([("choice differs (%)", "C0", "o"), ("excess of d when it differs (%)", "C1", "^"),
                                     ("no box contains c_r (%)", "0.5", "x")], knames, lines),
            "k_latency": _style_key([("pruned p50", "C0", "o"), ("exhaustive p50", "C3", "s")], knames, lines)}
    for key, ylabel in [("k_quality", "% (of queries; excess: % of d_opt)"), ("k_latency", "search latency p50 (ms)")]:
        a = ax[key]
        a.set_xscale("log", base=2)
        a.set_xlabel("clusters k (log2; circled: default k)")
        a.set_ylabel(ylabel)
        a.set_title(f"base database{'s' if ks.database.nunique() > 1 else ''}: vs k\n"
                    + ("quality of the pruned choice" if key == "k_quality" else "search latency"), fontsize=FONT)
        a.grid(alpha=0.3)
        _below(a, keys[key], 1 if key == "k_quality" else 2)
    ax["k_quality"].set_ylim(0, 100 * max(ks.differs_from_exhaustive.max(), ks.mean_excess_when_differs.max(),
                                          ks.fallback_no_box.max()) * 1.1)
    ax["k_latency"].set_ylim(bottom=0)
    absent = [f"{n} database: {why}" for n, why in BASE_DATABASES.items() if why and n not in names]
    title = (f"Retrieval latency and quality (Pronost et al. Sections 3.3, 4) — {table['machine'].iloc[0]}"
             + "".join(f"\n{a}" for a in absent))
    # the title heads the key of the latency panels (a suptitle and an outside legend would overlap)
    fig.legend(handles=_latency_key(list(dict.fromkeys(table.method))), fontsize=SMALL_FONT, ncol=4,
               loc="outside upper center", frameon=False, title=title, title_fontsize=FONT + 1,
               alignment="center")
    return fig


def summary(result) -> str:
    """Markdown: quality of the pruned and k-d tree searches against the exhaustive optimum (deterministic),
    by database size and k; the latencies are in the table (machine-dependent)."""
    from repro.experiments.summaries import bullets, pct

    t, ks = result.table, result.extra_tables["k_sweep"]
    lines = []
    for (name, factor), g in t[t.method != "exhaustive"].groupby(["database", "factor"], sort=False):
        g = g.set_index("method")
        parts = [f"`{m}` differs from the optimum in {pct(r.differs_from_exhaustive)} of the queries"
                 + (f" (d {pct(r.mean_excess_when_differs)} higher when it does)" if r.differs_from_exhaustive > 0 else "")
                 for m, r in g.iterrows()]
        first = g.iloc[0]
        lines.append(f"*{name}* at {factor:g}x ({int(first.n_clips):,} clips, {int(first.n_poses):,} poses, "
                     f"k = {int(first.k)}): " + "; ".join(parts))
    for name, g in ks.groupby("database", sort=False):
        parts = [f"{pct(r.differs_from_exhaustive)} at k = {int(r.k)}{' (default)' if r.is_default_k else ''}"
                 for r in g.itertuples()]
        default = g[g.is_default_k]
        no_box = (f"; {pct(default.fallback_no_box.iloc[0])} of the queries find no box at the default k"
                  if "fallback_no_box" in g and len(default) else "")
        lines.append(f"*{name}*, the k sweep: the pruned choice differs in " + ", ".join(parts) + no_box)
    return bullets(lines)
