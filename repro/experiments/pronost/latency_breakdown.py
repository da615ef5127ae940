"""Pronost et al., Section 4: the latency of an order, stage by stage, next to the paper's.

"The latency between the supervisor keystroke and the beginning of the search is
approximately 3ms. In the *Search* thread, the time from the beginning of the search
algorithm and the return of the selected motion is almost 0.28s. [...] This file must be
loaded and converted into the morphological independent representation to retarget it
to the virtual character. This total process spends about 40ms [...] motion retargetting
and adaptation is very fast (only spends 88us)", on a Pentium 4 3.6 GHz; and (Section
3.4.2) "when the supervisor provides an order, the system should react in less than
1/30s".

Here :class:`repro.motion.runtime.fighter.KungFuFighter` carries out orders (kicks and punches,
drawn at random) at the head of a simulated user (:func:`repro.motion.runtime.fighter.simulated_user`,
random instants of a 60 s walk), having first stepped to striking distance of it
(:meth:`~repro.motion.runtime.fighter.KungFuFighter.follow`), on the synthetic database and, when
the staged CMU takes are present, on the CMU one.  Every stage is measured with
``time.perf_counter`` inside :func:`repro.motion.runtime.strike.strike` (the one pipeline), after
two warm-up orders; the table gives the median, 90th and 99th percentile over the orders.
``extra_tables["per_level"]``: per reach level (limb only / with CCD / with CCD and a root
shift) the retarget + adapt time per frame and order -> first adapted frame, p50 and p99,
beside the paper's 88 µs per frame.

Stages (ours -> the paper's):

* ``order -> search start``: the query: target in the root frame, Eq. 1, the current
  pose retargeted to the actor (``q_r``) -> 3 ms;
* ``search``: the pruned retrieval of Section 3.3 -> 0.28 s;
* ``clip load + convert``: the clip from the in-memory database, cut, retargeted to the
  character (morphology-independent encode + decode) -> 40 ms (the paper read a BVH file
  from disk);
* ``retarget + adapt per frame``: (retargeting + placement, blend and constraint solver)
  / frames of the clip -> 88 µs;
* ``adaptation (whole clip)``: placement, blend, solver for all frames (the paper gives
  no total);
* ``order -> first adapted frame``: the stages up to frame ``t0 + 1`` final (the reach
  level decided on the contact frame, that frame solved; for a kick whose foot lifts
  after ``t0 + 1``, that frame is final before the level is decided, since no level moves
  it; the rest of the clip is solved after it, :func:`repro.motion.runtime.strike.strike`) -> the
  paper's stages add up to 323 ms plus the adaptation; the budget is 1/30 s = 33.3 ms;
* ``order -> reach level decided``: the stricter number, up to the level chosen on the
  contact frame (the paper gives none).

``within_budget``: the stage's 90th percentile is under 1/30 s (for the per-frame row:
30 frames of it).  Not a pass/fail against the paper: another machine, 17 years apart.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.bench import machine
from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment
from repro.motion.runtime.paper import (
    PAPER_ADAPT_PER_FRAME_S,
    PAPER_LOAD_CONVERT_S,
    PAPER_MACHINE,
    PAPER_ORDER_TO_SEARCH_S,
    PAPER_SEARCH_S,
    REACTION_BUDGET_S,
)

#: (stage, key of Strike.timings, paper seconds or None, note)
STAGES = (
    ("order -> search start", "prepare", PAPER_ORDER_TO_SEARCH_S, "keystroke to search start"),
    ("search", "search", PAPER_SEARCH_S, "search thread"),
    ("clip load + convert", "load_convert", PAPER_LOAD_CONVERT_S, "paper: BVH file read from disk"),
    ("retarget + adapt per frame", "retarget_adapt_per_frame", PAPER_ADAPT_PER_FRAME_S, "per frame"),
    ("adaptation (whole clip)", "adapt", None, "paper: no total given"),
    ("order -> first adapted frame", "first_frame", PAPER_ORDER_TO_SEARCH_S + PAPER_SEARCH_S + PAPER_LOAD_CONVERT_S,
     "paper: sum of its three stages, adaptation not included"),
    ("order -> reach level decided", "level", None, "the level chosen on the contact frame"),
)
STAGE_NAMES = tuple(s[0] for s in STAGES)


def run_orders(database="synthetic", n_orders: int = 40, seed: int = 0, warmup: int = 2, *,
               progress: bool = False) -> pd.DataFrame:
    """Orders at a simulated user's head: one row per order (strike numbers and stage timings, ms)."""
    from repro.motion.runtime.fighter import KungFuFighter, simulated_user

    fighter = KungFuFighter(database, seed=seed)
    user = simulated_user(seed, duration=60.0, fps=30.0)
    rng = np.random.default_rng(seed)
    rows = []
    name = database if isinstance(database, str) else "custom"
    for i in bar(range(warmup + n_orders), desc=f"latency_breakdown: {name} orders", unit="order", progress=progress):
        head = user[int(rng.integers(len(user)))]
        kind = str(rng.choice(["punch", "kick"]))
        fighter.follow(head, 0.0, snap=True)
        s = fighter.order(kind, head)
        if i >= warmup:
            rows.append({"order": i - warmup, **s.summary()})
    out = pd.DataFrame(rows)
    out.insert(0, "database", database if isinstance(database, str) else "custom")
    return out


def breakdown(orders: pd.DataFrame) -> pd.DataFrame:
    """The stage table of one database's orders (see the module docstring)."""
    rows = []
    budget_ms = REACTION_BUDGET_S * 1e3
    for stage, key, paper_s, note in STAGES:
        v = orders[f"{key}_ms"].to_numpy()
        p50, p90, p99 = (float(np.percentile(v, p)) for p in (50, 90, 99))
        paper_ms = np.nan if paper_s is None else paper_s * 1e3
        scale = 30.0 if key.endswith("per_frame") else 1.0
        rows.append(dict(stage=stage, ours_p50_ms=p50, ours_p90_ms=p90, ours_p99_ms=p99, paper_ms=paper_ms,
                         ratio_paper_over_ours=paper_ms / p50 if p50 > 0 else np.nan,
                         within_budget=bool(scale * p90 <= budget_ms), budget_ms=budget_ms,
                         database=str(orders["database"].iloc[0]), n_orders=len(orders),
                         reached_fraction=float(orders["reached"].mean()), note=note))
    return pd.DataFrame(rows)


#: Reach levels of the per-level table: the paper's "if only the limb is involved, this method only requires 88 us".
LEVEL_GROUPS = (("limb only", ("limb",)), ("with CCD (spine)", ("spine",)), ("with CCD + root shift", ("root",)))


def per_level(orders: pd.DataFrame) -> pd.DataFrame:
    """Per reach level (:attr:`repro.motion.runtime.strike.Strike.level`): retarget + adapt per frame and order -> first frame.

    p50 and p99 (ms) over the orders of that level, beside the paper's 88 µs per frame
    (which it gives for the limb alone).
    """
    rows = []
    for label, levels in LEVEL_GROUPS:
        o = orders[orders["level"].isin(levels)]
        row = {"database": str(orders["database"].iloc[0]), "level": label, "n_orders": len(o),
               "paper_per_frame_ms": PAPER_ADAPT_PER_FRAME_S * 1e3}
        for key, name in (("retarget_adapt_per_frame", "per_frame"), ("first_frame", "first_frame")):
            v = o[f"{key}_ms"].to_numpy()
            for p in (50, 99):
                row[f"{name}_p{p}_ms"] = float(np.percentile(v, p)) if v.size else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


@experiment("latency_breakdown", "Latency breakdown versus the paper (Section 4)", paper="pronost2008")
def latency_breakdown(quick: bool = False, databases=None, n_orders: int | None = None, seed: int = 0,
                      progress: bool = False) -> Result:
    from repro import data

    if databases is None:
        databases = ["synthetic"] + (["cmu"] if data.missing_reason("cmu-bvh") is None else [])
    n = n_orders if n_orders is not None else (12 if quick else 40)
    orders = [run_orders(name, n, seed, progress=progress) for name in databases]
    table = pd.concat([breakdown(o) for o in orders], ignore_index=True)
    table["machine"] = machine()
    levels = pd.concat([per_level(o) for o in orders], ignore_index=True)
    return Result(table=table, draw=lambda: draw(table),
                  extra_tables={"orders": pd.concat(orders, ignore_index=True), "per_level": levels})


def draw(table: pd.DataFrame):
    """Horizontal bars, log scale: our median (p90 whisker) per database, and the paper's value."""
    from matplotlib.figure import Figure

    dbs = list(dict.fromkeys(table["database"]))
    stages = list(STAGE_NAMES)
    fig = Figure(figsize=(10.5, 5.6), dpi=100)
    ax = fig.add_subplot()
    n_bars = len(dbs) + 1
    h = 0.8 / n_bars
    y = np.arange(len(stages))[::-1].astype(float)
    colours = ["tab:blue", "tab:green", "tab:purple"]
    for k, name in enumerate(dbs):
        t = table[table.database == name].set_index("stage").loc[stages]
        yy = y + 0.4 - h * (k + 0.5)
        ax.barh(yy, t.ours_p50_ms, height=h, color=colours[k % len(colours)], label=f"ours, {name} database (median)")
        ax.errorbar(t.ours_p90_ms, yy, xerr=[t.ours_p90_ms - t.ours_p50_ms, np.zeros(len(t))], fmt="none",
                    ecolor="k", elinewidth=0.8, capsize=2)
        for yi, v, v90 in zip(yy, t.ours_p50_ms, t.ours_p90_ms):
            ax.text(max(v, v90) * 1.12, yi, f"{v:.3g} ms", va="center", fontsize=8)
    t = table[table.database == dbs[0]].set_index("stage").loc[stages]
    yy = y + 0.4 - h * (len(dbs) + 0.5)
    ok = t.paper_ms.notna().to_numpy()
    ax.barh(yy[ok], t.paper_ms[ok], height=h, color="tab:orange", label=f"paper ({PAPER_MACHINE})")
    for yi, v in zip(yy[ok], t.paper_ms[ok]):
        ax.text(v * 1.08, yi, f"{v:.3g} ms", va="center", fontsize=8)
    budget = REACTION_BUDGET_S * 1e3
    ax.axvline(budget, color="tab:red", linestyle="--", linewidth=1.0)
    ax.text(budget * 1.05, y[0] + 0.42, "1/30 s budget", color="tab:red", fontsize=8, va="top")
    ax.set_xscale("log")
    ax.set_yticks(y, stages)
    ax.set_xlabel("milliseconds (log scale); whisker: 90th percentile")
    lo = float(np.nanmin(table[["ours_p50_ms", "paper_ms"]].to_numpy()))
    hi = float(np.nanmax(table[["ours_p90_ms", "paper_ms"]].to_numpy()))
    ax.set_xlim(lo / 3, hi * 6)
    n = int(table.n_orders.iloc[0])
    ax.set_title(f"Latency of an order, stage by stage ({n} orders per database, kicks and punches)\n"
                 f"ours on {table.machine.iloc[0]}", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.4, -0.11), ncol=n_bars, fontsize=8, frameon=False)
    fig.tight_layout()
    return fig


def summary(result) -> str:
    """Markdown: each stage's p50 beside the paper's figure (timings: machine-dependent)."""
    from repro.experiments.summaries import bullets, num

    t = result.table
    lines = []
    for r in t.itertuples():
        paper = "" if r.paper_ms != r.paper_ms else f"; paper {num(r.paper_ms)} ms ({num(r.ratio_paper_over_ours, 2)}x ours)"
        lines.append(f"*{r.database}*, {r.stage}: p50 {num(r.ours_p50_ms)} ms, p90 {num(r.ours_p90_ms)} ms{paper}")
    for name, g in t.groupby("database", sort=False):
        lines.append(f"*{name}*: {int(g.n_orders.iloc[0])} orders, {num(100 * g.reached_fraction.iloc[0], 3)} % reached")
    return bullets(lines + [f"machine: {t.machine.iloc[0]}"])
