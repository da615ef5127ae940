"""The claims of Pronost et al. ~2008 (kung-fu motion retrieval and adaptation), one function each.

The paper's published numbers come from :mod:`repro.motion.runtime.paper`; this ledger's thresholds
are named once, here.  Each claim reads the tables of the figure it names
(:mod:`repro.experiments.pronost`).
"""

from __future__ import annotations

import numpy as np

from repro.claims.ledger import Claim, per_database, registrar
from repro.motion.runtime.paper import (
    PAPER_ADAPT_PER_FRAME_S,
    PAPER_LOAD_CONVERT_S,
    PAPER_ORDER_TO_SEARCH_S,
    PAPER_SEARCH_S,
    REACTION_BUDGET_S,
)

__all__ = ["LEDGER"]

PAPER = "pronost2008"
NB3, NB4, NB5 = ("notebooks/03_retrieval_latency.ipynb", "notebooks/04_retargeting_morphologies.ipynb",
                 "notebooks/05_kungfu_fighter.ipynb")

# ----------------------------------------------------------------- thresholds of this ledger
#: K1: with the full database, adaptation divides the reach error by at least this
ERROR_REDUCTION = 3
#: K3: the pruned search returns a worse clip than the exhaustive optimum in less than this fraction of queries
DIFFERS_FRACTION = 0.1
#: K5: planted feet slide less than this after retargeting (metres; the joint-angle copy more) ...
FOOT_SLIDE_M = 0.005
#: ... and toes stay above this height (metres)
TOE_FLOOR_M = -0.02
#: K5, the played strikes (retarget + adapt, feet planted on the floor; adapted_motions' feet table), on
#: every clip: toes no lower than this during contacts (metres, 5 mm below the floor) ...
PLAYED_TOE_FLOOR_M = -0.005
#: ... and a planted (support) foot slides less than this (metres)
PLAYED_FOOT_SLIDE_M = 0.01
#: K6: the target is reached at contact in at least this fraction of orders (PARTLY_REACHED: partially)
REACHED_FRACTION = 0.95
PARTLY_REACHED = 0.5
#: K7: a trend of search time against database size needs at least this many sizes (two points fit any
#: line: a quick run's 1x and 10x give a slope, not evidence of one)
K7_MIN_SIZES = 3


def _budget() -> str:
    """The reaction budget as the paper writes it, one over a frame rate (``REACTION_BUDGET_S``)."""
    return f"1/{1 / REACTION_BUDGET_S:.0f} s"


LEDGER: list[Claim] = []
claim = registrar(LEDGER, PAPER, per=per_database)


@claim("K1", "'an average-size database (75 motions compared to hundreds ...)' suffices thanks to adaptation (Abstract, Sections 1, 2)",
       figure="database_vs_adaptation", notebook=NB4, table="table",
       criterion=f"with the full database adaptation divides the reach error by >= {ERROR_REDUCTION}",
       expected={"embedded": "reproduced", "real": "reproduced"})
def k1(t, name):
    full = t[t.db_size == t.db_size.max()]
    small = t[t.db_size == t.db_size.min()]
    gain = float(full.before_mean_m.mean() / full.after_mean_m.mean())
    vals = {"clips": int(t.db_size.max()), "mean_error_before_m": float(full.before_mean_m.mean()),
            "mean_error_after_m": float(full.after_mean_m.mean()), "error_reduction": gain,
            "smallest_db": int(t.db_size.min()),
            "smallest_db_reachable_area_kept": float(small.reached_fraction_of_full_db_area.mean()),
            # the price of adaptation (repro.motion.adaptation.cost), full and smallest database
            "rotation_change_mean_deg": float(full.rotation_change_mean_deg_mean.mean()),
            "smallest_db_rotation_change_mean_deg": float(small.rotation_change_mean_deg_mean.mean()),
            "joint_limit_violations_per_strike": float(full.joint_limit_violations_per_strike.mean()),
            "smallest_db_joint_limit_violations_per_strike": float(small.joint_limit_violations_per_strike.mean())}
    if gain >= ERROR_REDUCTION:
        return ("reproduced", vals, f"with {vals['clips']} clips adaptation divides the reach error by {gain:.1f}; "
                f"a {vals['smallest_db']}-clip database keeps {vals['smallest_db_reachable_area_kept']:.0%} of the reachable area, "
                f"at a price: mean joint-rotation change {vals['rotation_change_mean_deg']:.1f} deg with {vals['clips']} clips, "
                f"{vals['smallest_db_rotation_change_mean_deg']:.1f} deg with {vals['smallest_db']}")
    return ("not reproduced", vals, "adaptation does not substantially lower the reach error")


@claim("K2", "Eq. 1, c_r = c size_a / size_c: 'a constraint placed at 1-meter ... does not have the same influence if the latter is 2m or 1.5m tall' (Section 3.3)",
       figure="retargeting_morphologies", notebook=NB4, table="eq1",
       criterion="the retrieved clip reaches the target better with Eq. 1 at every character height",
       expected={"embedded": "reproduced", "real": "reproduced"})
def k2(g, name):
    by = g.groupby(["height_m", "eq1"]).reach_error_m.mean().unstack()
    better = bool((by[True] < by[False]).all())
    vals = {f"reach_error_{h:g}m_with_eq1": float(by.loc[h, True]) for h in by.index}
    vals.update({f"reach_error_{h:g}m_without": float(by.loc[h, False]) for h in by.index})
    if better:
        return ("reproduced", vals, "with c_r = c size_a / size_c the retrieved clip reaches the target better at every character height")
    return ("partially", vals, "Eq. 1 helps at some heights only")


@claim("K3", "Clusters + bounding-box pruning make the search fast enough for real time (Sections 3.2.2, 3.3)",
       figure="retrieval_latency", notebook=NB3, table="table",
       criterion=f"pruned faster than the exhaustive scan and returning its optimum in > {1 - DIFFERS_FRACTION:.0%} of queries",
       expected={"embedded": "partially", "real": "partially"})
def k3(g, name):
    largest = g.factor.max()
    at = g[g.factor == largest].set_index("method")
    speedup = float(at.loc["exhaustive", "p50_ms"] / at.loc["pruned", "p50_ms"])
    differs = float(g[g.method == "pruned"].differs_from_exhaustive.max())
    vals = {"largest_factor": int(largest), "speedup_vs_exhaustive": speedup,
            "worst_fraction_differing_from_exhaustive": differs,
            "base_fraction_differing": float(g[(g.method == "pruned") & (g.factor == g.factor.min())].differs_from_exhaustive.iloc[0])}
    exact = ""
    if "exact" in set(g.method):  # the three rows: the paper's pruning, the exact search, the exhaustive scan
        vals["exact_speedup_vs_exhaustive"] = float(at.loc["exhaustive", "p50_ms"] / at.loc["exact", "p50_ms"])
        vals["exact_worst_fraction_differing"] = float(g[g.method == "exact"].differs_from_exhaustive.max())
        exact = (f"; the exact branch-and-bound search over the same clusters and boxes returns the optimum in "
                 f"{1 - vals['exact_worst_fraction_differing']:.0%} of queries")
    if differs < DIFFERS_FRACTION and speedup > 1:
        return ("reproduced", vals, f"faster than the exhaustive scan and returns its optimum in > {1 - DIFFERS_FRACTION:.0%} of queries{exact}")
    # the speed-up is a timing (see the values); the verdict and its reason rest on the choice alone
    return ("partially", vals, f"faster than the exhaustive scan at x{largest} (see speedup_vs_exhaustive), but the pruned "
            f"search returns a worse clip than the exhaustive optimum in up to {differs:.0%} of queries{exact}")


@claim("K4", f"Latencies {PAPER_ORDER_TO_SEARCH_S * 1e3:.0f} ms, {PAPER_SEARCH_S:.2f} s, {PAPER_LOAD_CONVERT_S * 1e3:.0f} ms, "
       f"{PAPER_ADAPT_PER_FRAME_S * 1e6:.0f} µs; react in less than {_budget()} (Sections 3.4.2, 4)",
       figure="latency_breakdown", notebook=NB5, table="table",
       criterion=f"order to first adapted frame within {_budget()} (p50), stages as ratios to the paper's",
       expected={"embedded": "reproduced", "real": "reproduced"}, timing=True)
def k4(g, name):
    g = g.set_index("stage")
    first = float(g.loc["order -> first adapted frame", "ours_p50_ms"])
    vals = {f"{stage}_p50_ms": float(g.loc[stage, "ours_p50_ms"]) for stage in g.index}
    vals["machine"] = str(g.machine.iloc[0]) if "machine" in g else ""
    if first < REACTION_BUDGET_S * 1e3:
        return ("reproduced", vals, f"order to first adapted frame {first:.1f} ms (p50) is within {_budget()}; the paper's "
                f"{PAPER_SEARCH_S:.2f} s search is {PAPER_SEARCH_S * 1e3 / vals['search_p50_ms']:.0f}x ours")
    return ("partially", vals, f"order to first adapted frame {first:.1f} ms (p50) exceeds {_budget()} on this machine")


@claim("K5", "Retargeting through the morphology-independent representation, 'correcting the feet artifacts' (Sections 3.4, 3.4.1)",
       figure="retargeting_morphologies", notebook=NB4, reads=("adapted_motions",),
       criterion=f"the decoder alone: planted feet slide < {FOOT_SLIDE_M * 1e3:g} mm (joint-angle copy more) and toes stay "
       f"above {TOE_FLOOR_M * 1e2:g} cm across morphologies; the played strikes (retarget + adapt) on every clip: toes "
       f"no lower than {-PLAYED_TOE_FLOOR_M * 1e3:g} mm below the floor during contacts, support-foot slide "
       f"< {PLAYED_FOOT_SLIDE_M * 1e2:g} cm",
       expected={"embedded": "reproduced", "real": "reproduced"})
def k5(get):
    feet = get("adapted_motions").extra_tables["feet"]

    def judge(g, name):
        naive, ours = g[g.method == "naive"], g[g.method == "mi_feet"]
        vals = {"foot_slide_mean_naive_m": float(naive.foot_slide_mean_m.mean()),
                "foot_slide_mean_ours_m": float(ours.foot_slide_mean_m.mean()),
                "min_toe_height_naive_m": float(naive.min_toe_height_m.min()),
                "min_toe_height_ours_m": float(ours.min_toe_height_m.min())}
        no_slide = vals["foot_slide_mean_ours_m"] < FOOT_SLIDE_M < vals["foot_slide_mean_naive_m"]
        on_floor = vals["min_toe_height_ours_m"] > TOE_FLOOR_M
        decoder = (f"the decoder alone: planted feet do not slide (joint-angle copy: {vals['foot_slide_mean_naive_m']:.3f} m)"
                   if no_slide else "the decoder alone: feet slide after retargeting")
        decoder += ("" if on_floor else
                    f", toes dip {-vals['min_toe_height_ours_m'] * 100:.1f} cm below the floor around kick touch-downs")
        played = feet[feet.database == name]
        if not len(played):
            return ("partially" if no_slide else "not reproduced", vals, decoder + "; the played strikes are not measured")
        vals.update({"played_clips": len(played),
                     "played_min_toe_height_m": float(played.min_toe_height_m.min()),
                     "played_max_foot_slide_m": float(played.max_foot_slide_m.max())})
        toe_ok = vals["played_min_toe_height_m"] >= PLAYED_TOE_FLOOR_M
        slide_ok = vals["played_max_foot_slide_m"] < PLAYED_FOOT_SLIDE_M
        strikes = (f"the played strikes ({vals['played_clips']} clips): lowest toe "
                   f"{vals['played_min_toe_height_m'] * 1e3:.1f} mm, support foot slides at most "
                   f"{vals['played_max_foot_slide_m'] * 1e3:.1f} mm")
        if no_slide and toe_ok and slide_ok:
            return ("reproduced", vals, (f"{decoder}; {strikes}: within {-PLAYED_TOE_FLOOR_M * 1e3:g} mm of the floor "
                                         f"and {PLAYED_FOOT_SLIDE_M * 1e2:g} cm of slide on every clip"))
        if no_slide or (toe_ok and slide_ok):
            return ("partially", vals, f"{decoder}; {strikes}"
                    + ("" if toe_ok and slide_ok else f" (limits: {-PLAYED_TOE_FLOOR_M * 1e3:g} mm, "
                                                      f"{PLAYED_FOOT_SLIDE_M * 1e2:g} cm)"))
        return ("not reproduced", vals, f"{decoder}; {strikes}")

    return per_database(judge, get("retargeting_morphologies").table)


@claim("K6", "d(t) interpolated to d(tc) = X - M(tc), limb then CCD: the hit point reaches the target at contact (Section 3.4.2, Fig. 10)",
       figure="adapted_motions", notebook=NB4, table="table",
       criterion=f"the target is reached at tc in >= {REACHED_FRACTION:.0%} of orders",
       expected={"embedded": "reproduced", "real": "partially"})
def k6(t, name):
    frac = float(t.reached.mean())
    vals = {"orders": int(len(t)), "reached_fraction": frac, "worst_miss_m": float(t.after_m.max()),
            "mean_error_before_m": float(t.before_m.mean())}
    if frac >= REACHED_FRACTION:
        return ("reproduced", vals, "d(t) + limb IK / CCD, with the spine and a root shift when the limb cannot reach, "
                "reach the target at contact time in every order")
    if frac >= PARTLY_REACHED:
        miss = t[~t.reached.astype(bool)]
        return ("partially", vals, f"{int(len(miss))} of {len(t)} orders miss (worst by {vals['worst_miss_m'] * 100:.1f} cm): "
                "limb, spine and a root shift with the support foot pinned do not reach every target (no step is taken)")
    return ("not reproduced", vals, "most adapted orders miss the target")


@claim("K7", "Search time grows with the size of the database (Section 2: 'the larger the number of motions ... the higher the computation time')",
       figure="retrieval_latency", notebook=NB3, table="table",
       criterion="positive log-log slope of search time versus poses",
       expected={"embedded": "reproduced", "real": "reproduced"}, timing=True,
       evidence=(("sizes", K7_MIN_SIZES, "database sizes"),))
def k7(g, name):
    p = g[g.method == "pruned"].sort_values("n_poses")
    e = g[g.method == "exhaustive"].sort_values("n_poses")
    slope = float(np.polyfit(np.log(p.n_poses), np.log(p.p50_ms), 1)[0])
    slope_e = float(np.polyfit(np.log(e.n_poses), np.log(e.p50_ms), 1)[0])
    vals = {"loglog_slope_pruned": slope, "loglog_slope_exhaustive": slope_e, "sizes": len(p)}
    x = g[g.method == "exact"].sort_values("n_poses")
    exact = ""
    if len(x) > 1:  # the exact search's row (branch and bound over the same clusters and boxes)
        vals["loglog_slope_exact"] = float(np.polyfit(np.log(x.n_poses), np.log(x.p50_ms), 1)[0])
        exact = f", exact {vals['loglog_slope_exact']:.2f}"
    if slope > 0:
        return ("reproduced", vals, f"search time grows with the database (log-log slope {slope:.2f}; "
                f"exhaustive {slope_e:.2f}{exact})")
    return ("not reproduced", vals, "search time does not grow with the database")
