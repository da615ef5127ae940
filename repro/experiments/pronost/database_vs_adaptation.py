"""Pronost et al. (about 2008): database size versus adaptation -- the paper's central argument.

"In order to avoid using a huge database that can deal with any kind of situation, we
propose to associate this searching process to an adaptation module. Hence, even if the
selected motion is not perfectly suited with the situation, it can be adapted in order to
reach accurately the target" (abstract); "we use an average-size database because our
motion adaptation allows reaching a wider set of constraints without requiring specific
motion captures" (Section 2).

The experiment: a 1.8 m fighter (the synthetic actor scaled uniformly) stands in its
fighting stance (frame 0 of ``actor2_punch_left_high`` retargeted to it) and is ordered
to punch and to kick targets on a grid in front of it, in its root reference frame:
lateral ``x`` from -0.3 H to 0.3 H, height ``y`` from 0.2 H to 1.0 H, at depth
``z = 0.5 H`` (H = 1.8 m).  For each target the motion is retrieved (Section 3.3,
:class:`~repro.motion.search.retrieval.MotionRetriever`, Eq. 1) from the full synthetic database
(72 clips) or from random subsets of it (stratified: a quarter punches, at least one
punch and one kick; several seeds), retargeted to the fighter
(:func:`~repro.motion.retargeting.morphology.retarget` with ``fix_feet=True``), placed where the
system plays it (aligned on the current pose, :meth:`RetrievalResult.place`), and adapted
(Section 3.4.2, :func:`~repro.motion.adaptation.adapt` from the start frame ``t0`` to the
hit frame ``tc``).

Columns: ``before`` -- distance from the hit point at the clip's hit frame to the target
(what playing the retrieved clip unchanged would give); ``closest`` -- the closest the hit
point's trajectory comes to the target after the start frame (what the retrieval's
``d_cr`` measures, in the clip's own frame); ``after`` -- the residual after adaptation
(0 when reached); ``reached`` -- within the solver's tolerance (1e-4 of the limb length);
``reached_fraction_of_full_db_area`` -- among the targets that the *full* database
reaches after adaptation (the reachable area of this fighter, for that semantics), the
fraction a smaller database reaches too.

Every strike goes through the one pipeline, :func:`repro.motion.runtime.strike.strike` (retrieve,
retarget, place, blend with the stance, solve at the levels limb / spine / root).  The
price paid for "after = 0" is measured per strike against the retargeted, placed and
blended clip (:func:`repro.motion.adaptation.cost.adaptation_cost`) and averaged per
database size: ``rotation_change_mean_deg_mean`` (mean joint-rotation change),
``rotation_change_max_deg_mean`` / ``rotation_change_worst_deg``, the added joint
acceleration (``added_acceleration_max_mps2_mean``, ``acceleration_ratio_mean``),
``joint_limit_violations_per_strike``, ``bone_length_error_m_mean`` and the root shift;
``limb_fraction`` / ``spine_fraction`` / ``root_fraction``: the targets reached with the limb
alone, with CCD over the spine / pelvis, with a root shift.

The main table has one row per semantics x database size x seed;
``extra_tables["grid"]`` one row per target as well; ``extra_tables["reach"]`` the
whole-body reach study: the full database, targets on the centre column at depths
:data:`REACH_DEPTHS` x H, per semantics and depth the reached fraction and the fraction
that needed each level (:func:`repro.motion.runtime.strike.reach_by_distance`).  ``quick=True``: a 5 x 5 grid,
sizes 72 / 18 / 4, two seeds (the full run: 9 x 9, sizes 72 / 36 / 18 / 9 / 4 / 2,
five seeds).

The same sweep runs on the CMU karate takes when they are staged (every table has a first
column ``database``; the CMU actor scaled to 1.8 m, in the guard of the first lunge punch:
:func:`repro.experiments.pronost.databases.fighter_in_stance`), so that claim K1 is judged on
real motion too; quick mode there: the full database and the 4-clip one, one seed.  The heat
maps show the synthetic database; the curves every database.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.experiments.progress import bar
from repro.experiments.registry import Result, experiment

#: Fighter stature (m); its stance: :func:`repro.experiments.pronost.databases.fighter_in_stance`.
HEIGHT = 1.8
#: Target grid, in units of the fighter's height (root frame: x lateral, y up, z forward).
X_RANGE, Y_RANGE, DEPTH = (-0.3, 0.3), (0.2, 1.0), 0.5
SIZES, SEEDS, GRID = (72, 36, 18, 9, 4, 2), 5, (9, 9)
SIZES_QUICK, SEEDS_QUICK, GRID_QUICK = (72, 18, 4), 2, (5, 5)
#: Quick mode on real data (the CMU takes): the full database and the small one, one seed.
SIZES_REAL_QUICK = (72, 4)
#: The "small database" of the heat maps.
SMALL = 4
#: Whole-body reach study (full database, centre column x = 0): target depths, in units of H.
REACH_DEPTHS, REACH_DEPTHS_QUICK = (0.4, 0.5, 0.6, 0.7, 0.8), (0.5, 0.7)
#: Columns of the cost of adaptation (repro.motion.adaptation.cost.adaptation_cost), aggregated by mean.
COST_COLUMNS = ("rotation_change_mean_deg", "rotation_change_max_deg", "added_acceleration_max_mps2",
                "acceleration_ratio", "bone_length_error_m", "joint_limit_violations", "root_shift_max_m")


def subset(db, n: int, seed: int) -> np.ndarray:
    """Clip indices of a random database of ``n`` clips (all clips when ``n`` >= their number).

    Stratified by semantics like the full database (a quarter punches), with at least one
    punch and one kick; ``numpy.random.default_rng([n, seed])``.
    """
    if n >= db.n_clips:
        return np.arange(db.n_clips)
    punch = np.flatnonzero(db.semantics == "punch")
    kick = np.flatnonzero(db.semantics == "kick")
    n_p = min(max(1, round(n * punch.size / db.n_clips)), n - 1)
    rng = np.random.default_rng([n, seed])
    return np.sort(np.concatenate([rng.choice(punch, n_p, replace=False), rng.choice(kick, n - n_p, replace=False)]))


def grid(H: float, quick: bool) -> tuple[np.ndarray, np.ndarray, float]:
    nx, ny = GRID_QUICK if quick else GRID
    return np.linspace(*X_RANGE, nx) * H, np.linspace(*Y_RANGE, ny) * H, DEPTH * H


def _row(s, ch) -> dict:
    a = s.adaptation
    return {
        "clip": s.retrieval.name, "start_frame": s.retrieval.start_frame, "hit_frame": s.retrieval.hit_frame,
        "fallback": s.retrieval.fallback, "before_m": s.unadapted_error, "closest_m": s.closest_error,
        "after_m": s.hit_error, "reached": s.reached, "level": s.level,
        "frames_ccd": int(np.sum(a.solver == "ccd")), "foot_slide_m": s.foot_slide, **s.cost,
    }


class _Strikes:
    """``_row(strike(retriever, ...))`` for one fighter and stance, each distinct strike played once.

    The databases of the sweep are subsets of one database, so a smaller one often retrieves
    the clip a larger one did.  What a strike does after its search depends only on the
    target, the semantics, the query's root frame and what the search returned (the clip,
    its start frame, the alignment and Eq. 1's sizes), never on the other clips: those,
    compared bit for bit, are the key, and a strike seen before is not played again (half
    of the 4,212 strikes of the full run).  ``fallback`` is the search's own, per database.
    """

    def __init__(self, ch, stance):
        self.ch, self.stance, self.rows = ch, stance, {}

    def __call__(self, retriever, q, c: np.ndarray, sem: str) -> dict:
        from repro.motion.runtime.paper import PAPER
        from repro.motion.runtime.strike import strike

        res = retriever.search(c, q, semantics=sem, method=PAPER.method)  # the search strike() makes
        key = (sem, c.tobytes(), float(q.heading), np.asarray(q.origin).tobytes(), res.name, res.start_frame,
               res.hit_frame, res.lead_frames, float(res.heading), float(res.rotation_y),
               np.asarray(res.translation).tobytes(), np.asarray(res.origin).tobytes(), float(res.size_a),
               float(res.size_c))
        row = self.rows.get(key)
        if row is None:
            s = strike(retriever, self.ch, self.stance, c, sem, frame="root", query=q, options=PAPER)
            if (s.retrieval.name, s.retrieval.start_frame) != (res.name, res.start_frame):  # pragma: no cover
                raise AssertionError(f"strike() retrieved {s.retrieval.name} where search() gave {res.name}")
            row = self.rows[key] = _row(s, self.ch)
        return {**row, "fallback": res.fallback}


def _runs(db, quick: bool, real: bool) -> list[tuple[int, int]]:
    """(database size, seed) of the sweep on ``db`` (:data:`SIZES` x :data:`SEEDS`; quick on real data:
    :data:`SIZES_REAL_QUICK`, one seed)."""
    sizes = (SIZES_REAL_QUICK if real else SIZES_QUICK) if quick else SIZES
    seeds = (1 if real else SEEDS_QUICK) if quick else SEEDS
    return [(n, seed) for n in sizes for seed in range(1 if n >= db.n_clips else seeds)]


def _compute(quick: bool, progress: bool = False):
    from repro.experiments.pronost.databases import databases

    dbs = databases()
    plans = {name: _runs(db, quick, real=name != "synthetic") for name, db in dbs.items()}
    nx, ny = GRID_QUICK if quick else GRID
    depths = REACH_DEPTHS_QUICK if quick else REACH_DEPTHS
    n_strikes = sum(2 * ny * (len(runs) * nx + sum(n >= dbs[name].n_clips for n, _ in runs) * len(depths))
                    for name, runs in plans.items())
    parts = []
    with bar(total=n_strikes, desc="database_vs_adaptation: strikes", unit="strike", progress=progress) as b:
        for name, db in dbs.items():
            parts.append(_sweep(name, db, plans[name], quick, b))
    return tuple(pd.concat(p, ignore_index=True) for p in zip(*parts))


def _sweep(name: str, db, runs, quick: bool, b):
    """The tables of one database (each with a first column ``database``): per run, per target, the reach study."""
    from repro.experiments.pronost.databases import fighter_in_stance
    from repro.motion.search.retrieval import MotionRetriever
    from repro.motion.runtime.strike import reach_by_distance

    ch, stance = fighter_in_stance(db, HEIGHT)
    xs, ys, z = grid(ch.size, quick)
    depths = REACH_DEPTHS_QUICK if quick else REACH_DEPTHS
    play = _Strikes(ch, stance)
    rows, reach = [], []
    for n, seed in runs:
        idx = subset(db, n, seed)
        retriever = MotionRetriever(db.select(idx), seed=0)
        q = retriever.prepare(stance, ch)
        for sem in ("punch", "kick"):
            for x in xs:  # one bar step per column of the target grid
                for y in ys:
                    c = np.array([x, y, z])
                    rows.append({"semantics": sem, "db_size": int(idx.size), "seed": seed,
                                 "x_m": float(x), "y_m": float(y), "z_m": float(z), **play(retriever, q, c, sem)})
                b.update(len(ys))
            if n >= db.n_clips:  # whole-body reach: deeper targets, the full database
                for depth in depths:
                    for y in ys:
                        c = np.array([0.0, y, depth * ch.size])
                        reach.append({"semantics": sem, "depth_h": depth, "y_m": float(y),
                                      "distance_m": float(np.linalg.norm(c - [0.0, ch.hip_height, 0.0])),
                                      **play(retriever, q, c, sem)})
                    b.update(len(ys))
    g = pd.DataFrame(rows)
    # the reachable area: targets the full database's clips reach after adaptation
    full = g[g.db_size == g.db_size.max()].set_index(["semantics", "x_m", "y_m"]).reached
    g["reachable_with_full_db"] = [bool(full.loc[k]) for k in zip(g.semantics, g.x_m, g.y_m)]
    g["reached_in_reachable"] = np.where(g.reachable_with_full_db, g.reached.astype(float), np.nan)
    for lv in ("limb", "spine", "root"):
        g[f"level_{lv}"] = (g.level == lv) & g.reached
    table = g.groupby(["semantics", "db_size", "seed"], sort=False).agg(
        n_targets=("x_m", "size"),
        before_mean_m=("before_m", "mean"), before_median_m=("before_m", "median"), before_max_m=("before_m", "max"),
        closest_mean_m=("closest_m", "mean"),
        after_mean_m=("after_m", "mean"), after_median_m=("after_m", "median"), after_max_m=("after_m", "max"),
        reached_fraction=("reached", "mean"),
        reached_fraction_of_full_db_area=("reached_in_reachable", "mean"),
        distinct_clips=("clip", "nunique"),
        limb_fraction=("level_limb", "mean"), spine_fraction=("level_spine", "mean"),
        root_fraction=("level_root", "mean"),
        **{f"{k}_mean" if k != "joint_limit_violations" else "joint_limit_violations_per_strike": (k, "mean")
           for k in COST_COLUMNS},
        rotation_change_worst_deg=("rotation_change_max_deg", "max"),
    ).reset_index()
    rd = pd.DataFrame(reach)
    reach_table = pd.DataFrame([
        {"semantics": sem, "depth_h": d, **row}
        for (sem, d), part in rd.groupby(["semantics", "depth_h"], sort=False)
        for row in reach_by_distance(part.distance_m, part.reached, part.level, bins=1)])
    for t in (table, g, reach_table):
        t.insert(0, "database", name)
    return table, g, reach_table


def draw(table: pd.DataFrame, g: pd.DataFrame):
    import matplotlib.pyplot as plt

    # the heat maps: the first database (the synthetic one); the curves: every database, one line style each
    main = str(g.database.iloc[0])
    names = list(dict.fromkeys(table.database))
    styles = dict(zip(names, ("-", "--", ":", "-.")))
    all_sizes = sorted(set(table.db_size))
    g = g[g.database == main]
    sizes = sorted(set(g.db_size))
    full, small = max(sizes), (SMALL if SMALL in sizes else min(sizes))
    vmax = float(np.ceil(g.before_m.quantile(0.95) * 10) / 10)
    fig = plt.figure(figsize=(21, 8.5))
    gs = fig.add_gridspec(2, 7, width_ratios=[1, 1, 1, 1, 0.07, 0.3, 1.5], wspace=0.3, hspace=0.38, left=0.05,
                          right=0.85)  # the right margin holds the curves' key
    labels = {"before": "before adaptation (hit frame)", "closest": "closest approach of the trajectory",
              "after": "after adaptation"}
    colors = {"before": "tab:red", "closest": "tab:orange", "after": "tab:green"}
    for row, sem in enumerate(("punch", "kick")):
        for col, (n, what) in enumerate(((full, "before"), (full, "after"), (small, "before"), (small, "after"))):
            ax = fig.add_subplot(gs[row, col])
            d = g[(g.semantics == sem) & (g.db_size == n)]
            pv = d.groupby(["y_m", "x_m"])[f"{what}_m"].mean().unstack()
            xs, ys = pv.columns.to_numpy(), pv.index.to_numpy()
            dx, dy = (xs[1] - xs[0]) / 2, (ys[1] - ys[0]) / 2
            im = ax.imshow(pv.to_numpy(), origin="lower", cmap="magma_r", vmin=0, vmax=vmax,
                           extent=(xs[0] - dx, xs[-1] + dx, ys[0] - dy, ys[-1] + dy), aspect="auto")
            n_seeds = d.seed.nunique()
            ax.set_title(f"{sem}: {n} clips{'' if n_seeds == 1 else f' (mean of {n_seeds} seeds)'}\n"
                         f"{what} adaptation: mean {pv.to_numpy().mean():.3f} m", fontsize=9)
            ax.set_xlabel("target x, lateral (m)", fontsize=8)
            if col == 0:
                ax.set_ylabel("target height y (m)", fontsize=8)
        cax = fig.add_subplot(gs[row, 4])
        fig.colorbar(im, cax=cax, label="hit error (m)")
        ax = fig.add_subplot(gs[row, 6])
        for name in names:
            t = table[(table.semantics == sem) & (table.database == name)]
            for what, color in colors.items():
                s = t.groupby("db_size")[f"{what}_mean_m"]
                mean, lo, hi = s.mean(), s.min(), s.max()
                ax.errorbar(mean.index, mean.values, yerr=[mean.values - lo.values, hi.values - mean.values], marker="o",
                            color=color, ls=styles[name], capsize=3)
        ax.set_xscale("log", base=2)
        ax.set_ylim(bottom=0)
        ax.set_xticks(all_sizes, [str(s) for s in all_sizes])
        ax.set_xlabel("database size (clips)")
        ax.set_ylabel("mean hit error over the grid (m)")
        ax.set_title(f"{sem}: error vs database size (bars: range over seeds)", fontsize=9)
        ax.grid(alpha=0.3)
        if row == 0:  # one key for both curve panels, beside them (never over the curves)
            from matplotlib.lines import Line2D

            handles = [Line2D([], [], color=c, marker="o", label=labels[w]) for w, c in colors.items()]
            if len(names) > 1:
                handles += [Line2D([], [], color="k", ls=styles[n], label=f"{n} database") for n in names]
            ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.03, 1), frameon=False,
                      title="both curve panels", title_fontsize=8)
    more = "" if len(names) == 1 else f"; heat maps: the {main} database, curves: " + ", ".join(
        f"{n} ({'solid' if styles[n] == '-' else 'dashed' if styles[n] == '--' else 'dotted'})" for n in names)
    fig.suptitle(f"Database size versus adaptation: a {HEIGHT:g} m fighter, targets at depth {DEPTH:g} H "
                 f"in its root frame (Pronost et al., Sections 3.3-3.4.2){more}")
    return fig


@experiment(
    "database_vs_adaptation",
    "Database size versus adaptation: hit error before and after the constraints solver as the database "
    "shrinks, over a grid of targets (the paper's central argument)",
    paper="pronost2008",
    data=("cmu-bvh",),  # the synthetic database, and the CMU takes when staged
)
def database_vs_adaptation(quick: bool = False, progress: bool = False) -> Result:
    table, g, reach = _compute(bool(quick), bool(progress))
    return Result(table=table, draw=lambda: draw(table, g), extra_tables={"grid": g, "reach": reach})


def summary(result) -> str:
    """Markdown: per database, strike and size, the hit error before and after adaptation and the area reached."""
    from repro.experiments.summaries import bullets

    t, grid = result.table, result.extra_tables.get("grid")
    lines = []
    for name in dict.fromkeys(t.database):
        lines += _summary_lines(name, t[t.database == name], None if grid is None else grid[grid.database == name])
    return bullets(lines)


def _summary_lines(name: str, t, grid) -> list[str]:
    from repro.experiments.summaries import num, pct

    lines = []
    for (sem, size), g in t.groupby(["semantics", "db_size"], sort=False):
        def span(col, f=num, g=g):
            lo, hi = f(g[col].min()), f(g[col].max())
            return lo if lo == hi else f"{lo}-{hi}"

        lines.append(f"*{name}, {sem}*, {int(size)} clips ({len(g)} seed{'s' if len(g) > 1 else ''}): hit error "
                     f"{span('before_mean_m')} m before adaptation (closest approach {span('closest_mean_m')} m), "
                     f"{span('after_mean_m')} m after; {span('reached_fraction', pct)} of the grid reached, "
                     f"{span('reached_fraction_of_full_db_area', pct)} of the full database's area")
    for sem, g in t.groupby("semantics", sort=False):
        by = g.groupby("db_size").mean(numeric_only=True).sort_index()
        lines.append(f"*{name}, {sem}*, the price of adaptation: mean joint-rotation change "
                     + ", ".join(f"{num(v, 2)} deg with {int(n)} clips" for n, v in by.rotation_change_mean_deg_mean.items())
                     + "; joint-limit violations per strike "
                     + ", ".join(f"{num(v, 2)} with {int(n)}" for n, v in by.joint_limit_violations_per_strike.items()))
    ratio = t.after_mean_m / t.before_mean_m
    lines.append(f"*{name}*: after / before adaptation {num(ratio.min(), 2)} to {num(ratio.max(), 2)} over every size "
                 "and seed")
    if grid is not None and len(grid):
        full = grid[grid.db_size == grid.db_size.max()]
        for sem, g in full.groupby("semantics", sort=False):
            lines.append(f"*{name}, {sem}*, full database: targets on the right (x > 0) missed by "
                         f"{num(g[g.x_m > 0].before_m.mean(), 2)} m before adaptation, on the left (x < 0) by "
                         f"{num(g[g.x_m < 0].before_m.mean(), 2)} m; closest approach on the left "
                         f"{num(g[g.x_m < 0].closest_m.mean(), 2)} m")
    return lines
