"""``repro bench retrieval``: Pronost et al., Sections 3.3 and 4 -- the search latency versus
database size, for the paper's pruned search, the exact search (branch and bound over the same
clusters and boxes), the exhaustive scan and a kd-tree.

The paper's search took 0.28 s (:data:`repro.motion.runtime.paper.PAPER_SEARCH_S`): a reference
printed as a ratio to ours, never pass/fail.  The goals below are this reproduction's.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

import numpy as np

from repro.bench import machine
from repro.bench.index_build import FLOAT32_FROM
from repro.checks import as_int
from repro.errors import RetrievalError
from repro.motion.database.clips import MotionDatabase
from repro.motion.runtime.paper import PAPER_SEARCH_S
from repro.motion.search.retrieval import MAX_QUERIES, METHODS, MotionRetriever, make_queries

__all__ = [
    "GOAL_BASE_P50_MS",
    "GOAL_EXACT_P99_MS",
    "GOAL_LOGLOG_SLOPE",
    "GOAL_SPEEDUP_AT_100X",
    "bench_retrieval",
    "check_bench_arguments",
    "format_retrieval",
    "retrieval_summary",
    "time_search",
]

#: the pruned search's median at the base size (a prepared query), milliseconds
GOAL_BASE_P50_MS: float = 1.0
#: pruned versus exhaustive at the 100x database
GOAL_SPEEDUP_AT_100X: float = 20.0
#: the exact search's 99th percentile at 100x (one frame at 30 Hz)
GOAL_EXACT_P99_MS: float = 1000.0 / 30.0
#: growth of the pruned search's median with the number of poses (log-log slope)
GOAL_LOGLOG_SLOPE: float = 0.5
#: from FLOAT32_FROM (1,000x, 4.6 M poses) at most this many queries, each timed once: the
#: exhaustive scan there takes ~0.2 s a query (measured: 198 ms p50 on synthetic), so 200
#: queries x 3 repeats per method would add ~10 min to `repro all` for one row
LARGE_N_QUERIES: int = 100


#: queries per (database, size) when not asked for (``n_queries=None``)
DEFAULT_N_QUERIES: int = 200
#: the sizes (augmentation factors) drawn in the figure
FACTORS: tuple[int, ...] = (1, 10, 100, 1000)
#: peak memory of a benchmarked size over its augmented database alone
#: (:func:`repro.experiments.shared.estimated_bytes`): the database, its retriever's index and the
#: timed searches; measured 2.35 at 20x synthetic (``bench_index_build``: 0.126 GB peak, 0.054 GB
#: estimated), so a factor is checked against the budget at 2.5 times its database
INDEX_OVERHEAD: float = 2.5
#: the largest factor even considered (its memory is then checked against the budget: this one is
#: far past any, 10**6 GiB of the synthetic database; a factor of 400 digits overflowed the estimate)
MAX_FACTOR: int = 10**9
#: the base databases :func:`bench_retrieval` knows
DATABASES: tuple[str, ...] = ("synthetic", "cmu")
#: most repeats of each timed search in :func:`time_search` (the figures use 3)
MAX_REPEATS: int = 1000


def check_bench_arguments(databases, factors, n_queries, *, bases=None):
    """``(databases, factors, n_queries)`` of :func:`bench_retrieval` checked (None kept: the defaults).

    Before anything is built, what each given factor will allocate (the base database's
    arrays ``factor`` times, :func:`repro.experiments.shared.estimated_bytes`, with the index:
    :data:`INDEX_OVERHEAD`) is checked
    against :data:`repro.checks.MEMORY_BUDGET` (``--factors 1000000000`` asked numpy for
    67-99 GiB, issue 23 section 3).  ``bases``: a dict filled with the base databases loaded
    for that estimate (``name -> database``), for the caller to reuse.

    Raises
    ------
    repro.errors.RetrievalError
        An unknown database, a factor that is not an int in 1..:data:`MAX_FACTOR` or asks for more
        memory than the budget, ``n_queries`` not an int in 1..:data:`repro.motion.search.retrieval.MAX_QUERIES`.
    """
    from repro.checks import check_alloc

    if databases is not None:
        databases = _names(databases, "databases", DATABASES)
    if factors is not None:
        if isinstance(factors, (str, bytes)):
            raise RetrievalError(f"factors must be a sequence of ints >= 1, got {factors!r}")
        try:
            factors = tuple(factors)
        except TypeError:
            raise RetrievalError(f"factors must be a sequence of ints >= 1, got {factors!r}") from None
        if not factors:
            raise RetrievalError("factors must name at least one size (an int >= 1)")
        factors = tuple(as_int(f, "factor", 1, MAX_FACTOR, error=RetrievalError) for f in factors)
    if n_queries is not None:
        n_queries = as_int(n_queries, "n_queries", 1, MAX_QUERIES, error=RetrievalError)
    if factors is not None and max(factors) > 1:
        from repro.experiments.shared import estimated_bytes
        from repro.motion.database.sources import default_database

        bases = {} if bases is None else bases
        for name in databases if databases is not None else _default_databases():
            base = bases.get(name)
            if base is None:
                base = bases[name] = default_database(name)
            f = max(factors)  # the largest asks the most
            check_alloc(int(estimated_bytes(base, f) * INDEX_OVERHEAD), f"factor {f} (the {name} database of "
                        f"{base.n_clips} clips, {f} times, and its search index)", error=RetrievalError)
    return databases, factors, n_queries


def time_search(db: MotionDatabase, n_queries: int = 200, seed: int = 0, *, retriever: MotionRetriever | None = None,
                methods: Sequence[str] = ("pruned", "exact", "exhaustive", "kdtree"), repeats: int = 3, noise: float = 0.05,
                **retriever_kw) -> dict:
    """Latency of the three searches on random queries (no assertion; for the figures).

    Times, per query, the search proper given the prepared query (Eq. 1, cluster
    selection, pruning, scoring, alignment) for each method, and separately
    :meth:`MotionRetriever.prepare` (retargeting the current pose to the actor), which is
    the same for every method.  Every method sees the same queries (:func:`make_queries`
    with ``noise``), after a warm-up on the first 20.  Each query (and its preparation) is run
    ``repeats`` times and its fastest time kept (the machine is shared: this removes most of the
    scheduler noise, not the cache effects).

    Returns
    -------
    dict
        ``n_clips``, ``n_poses``, ``k``, ``precompute_s`` (building the retriever),
        ``prepare_ms`` (p50, p99), per method ``{method: {"p50_ms", "p99_ms",
        "mean_ms"}}`` under ``"latency"``, and ``"agreement"``: for ``pruned`` and
        ``kdtree``, the fraction of queries whose selection (clip, start frame) differs
        from the exhaustive optimum and the mean / max relative excess of ``d``; plus the
        fallback counts of the pruned search.  ``"exact"`` (the branch and bound,
        :meth:`MotionRetriever.search_exact`) should differ in 0 queries (``n_differs``).

    Raises
    ------
    repro.errors.RetrievalError
        ``n_queries`` not an int in 1..:data:`repro.motion.search.retrieval.MAX_QUERIES`, ``repeats`` not an int >= 1, an unknown or no method, a
        ``retriever`` of another database, and the errors of :func:`make_queries`.
    """
    if not isinstance(db, MotionDatabase):
        raise RetrievalError(f"expected a MotionDatabase, got {type(db).__name__}")
    n_queries = as_int(n_queries, "n_queries", 1, MAX_QUERIES, error=RetrievalError)
    repeats = as_int(repeats, "repeats", 1, MAX_REPEATS, error=RetrievalError)
    methods = tuple(_names(methods, "methods", METHODS))
    if retriever is not None and (not isinstance(retriever, MotionRetriever) or retriever.db is not db):
        raise RetrievalError("retriever must be a MotionRetriever built on this database")
    t0 = time.perf_counter()
    r = retriever if retriever is not None else MotionRetriever(db, **retriever_kw)
    precompute = time.perf_counter() - t0
    queries = make_queries(db, n_queries, seed, noise=noise)
    prep_t, prepared = _time_preparation(r, queries, repeats)
    fns = {"pruned": r.search, "exact": r.search_exact, "exhaustive": r.search_exhaustive, "kdtree": r.search_kdtree}
    lat, results = {}, {}
    for mth in methods:
        lat[mth], results[mth] = _time_method(fns[mth], prepared, repeats)
    fb = {}
    for res in results.get("pruned", []):
        fb[res.fallback] = fb.get(res.fallback, 0) + 1
    pt = np.array(prep_t) * 1e3
    return {"n_clips": db.n_clips, "n_poses": db.n_poses, "k": r.k, "n_queries": n_queries, "seed": seed,
            "repeats": repeats, "noise_m": noise, "precompute_s": precompute if retriever is None else None,
            "prepare_ms": {"p50_ms": float(np.percentile(pt, 50)), "p99_ms": float(np.percentile(pt, 99))},
            "latency": lat, "agreement": _agreement(results), "pruned_fallbacks": fb}


def _names(values, what: str, allowed: tuple[str, ...]) -> list[str]:
    """``values`` (one name or a sequence of them) as a non-empty list of names in ``allowed``."""
    values = [values] if isinstance(values, str) else values
    try:
        values = list(values)
    except TypeError:
        raise RetrievalError(f"{what} must be a non-empty list of {list(allowed)}, got {values!r}") from None
    if not values or any(not isinstance(v, str) or v not in allowed for v in values):
        raise RetrievalError(f"{what} must be a non-empty list of {list(allowed)}, got {values!r}")
    return values


def _time_preparation(r: MotionRetriever, queries: list, repeats: int) -> tuple[list, list]:
    """Each query's :meth:`MotionRetriever.prepare`, timed: (fastest seconds, (c, prepared query, semantics))."""
    prep_t, prepared = [], []
    for c, pose, ch, sem in queries:
        best_t = np.inf
        for _ in range(repeats):  # fastest of ``repeats``, as the searches (nothing is cached per pose)
            t = time.perf_counter()
            qq = r.prepare(pose, ch)
            best_t = min(best_t, time.perf_counter() - t)
        prep_t.append(best_t)
        prepared.append((c, qq, sem))
    return prep_t, prepared


def _time_method(fn, prepared: list, repeats: int) -> tuple[dict, list]:
    """One search method on every prepared query after a warm-up: its latency (ms) and its results."""
    for c, qq, sem in prepared[: min(20, len(prepared))]:  # warm-up (and the lazy kd-tree build)
        fn(c, qq, None, sem)
    ts, res = [], []
    for c, qq, sem in prepared:
        best = np.inf
        for _ in range(repeats):
            t = time.perf_counter()
            out = fn(c, qq, None, sem)
            best = min(best, time.perf_counter() - t)
        res.append(out)
        ts.append(best)
    ts = np.array(ts) * 1e3
    return {"p50_ms": float(np.percentile(ts, 50)), "p99_ms": float(np.percentile(ts, 99)),
            "mean_ms": float(ts.mean())}, res


def _agreement(results: dict) -> dict:
    """Per method, how its selections differ from the exhaustive optimum's (empty without it)."""
    agreement = {}
    if "exhaustive" in results:
        ex = results["exhaustive"]
        for mth in results:
            if mth == "exhaustive":
                continue
            diff = [(a.clip, a.start_frame) != (b.clip, b.start_frame) for a, b in zip(results[mth], ex)]
            excess = np.array([(a.d - b.d) / max(b.d, 1e-12) for a, b in zip(results[mth], ex)])
            agreement[mth] = {"differs": float(np.mean(diff)), "n_differs": int(np.sum(diff)),
                              "mean_excess": float(excess.mean()),
                              "max_excess": float(excess.max()), "same_clip": float(np.mean(
                                  [a.clip == b.clip for a, b in zip(results[mth], ex)]))}
    return agreement


def _default_databases() -> list:
    """The base databases benched when none is named: synthetic, and cmu when its data is present."""
    from repro import data

    return ["synthetic"] + (["cmu"] if data.missing_reason("cmu-bvh") is None else [])


def bench_retrieval(*, quick: bool = False, databases=None, factors=None, n_queries: int | None = None,
                    seed: int = 0, progress: bool = False, database=None):
    """Latency of the paper's pruned search, the exact search, the exhaustive scan and the kd-tree, vs size.

    For each base database (the synthetic one always, the CMU one when its data is
    present) and each augmentation factor (1x, 10x, 100x, 1,000x; 1x and 10x with ``quick``;
    from :data:`~repro.bench.index_build.FLOAT32_FROM` = 1,000x the pose clouds are float32, whose
    rounding, 6e-8 relative, is far below the noise of the variants, and, unless ``n_queries``
    is given, at most :data:`LARGE_N_QUERIES` queries are timed once each),
    :func:`time_search` times all four methods on the same
    ``n_queries`` random queries (default :data:`DEFAULT_N_QUERIES`, 100 with ``quick``; a
    given number is honoured at every size), in one process.  One row per (database, factor,
    method) with the columns ``n_clips, n_poses, method, p50_ms, p99_ms`` (the
    contract of ``figures/retrieval_latency.csv``) plus how often the method's choice
    differs from the exhaustive optimum (fraction and count: 0 for the exact search),
    the mean excess of its distance, the query-preparation cost (Eq. 1 and retargeting
    q to the actor, shared by all) and the index build time (``precompute_s``).

    ``database(name, factor, seed)``: where the databases come from (default: built here,
    ``augment(default_database(name), factor, seed=seed)``; the figure passes
    :func:`repro.experiments.shared.augmented_database`, which keeps them on disk; from
    ``FLOAT32_FROM`` they are always built here, float32).
    """
    import pandas as pd
    from tqdm import tqdm  # plain bar on stderr, never a notebook widget

    from repro.motion.database.augment import augment
    from repro.motion.database.sources import default_database

    from repro.checks import as_bool, describe

    quick = as_bool(quick, "quick", error=RetrievalError)
    progress = as_bool(progress, "progress", error=RetrievalError)
    seed = as_int(seed, "seed", 0, None, error=RetrievalError)
    if database is not None and not callable(database):
        raise RetrievalError(f"database must be a function (name, factor, seed) -> database or None, got "
                             f"{describe(database)}")
    bases = {}  # the base databases the memory check loaded, reused below
    databases, factors, asked = check_bench_arguments(databases, factors, n_queries, bases=bases)
    if databases is None:
        databases = _default_databases()
    if factors is None:
        factors = FACTORS[:2] if quick else FACTORS
    rows = []
    work = [(name, f) for name in databases for f in factors]
    for name, factor in tqdm(work, desc="bench retrieval", delay=1.0, disable=not progress, file=sys.stderr):
        if database is not None and factor < FLOAT32_FROM:  # 1,000x: float32, built here (too big to cache as npz)
            db = database(name, factor, seed)
        else:
            base = bases.pop(name, None)  # a base the memory check loaded is used once, as before
            base = default_database(name) if base is None else base
            db = base if factor == 1 else augment(base, factor, seed=seed,
                                                  pose_dtype=np.float32 if factor >= FLOAT32_FROM else None)
        large = factor >= FLOAT32_FROM
        if asked is not None:
            nq = asked
        else:
            nq = min(DEFAULT_N_QUERIES, 100) if quick else DEFAULT_N_QUERIES
            nq = min(nq, LARGE_N_QUERIES) if large else nq
        t = time_search(db, n_queries=nq, seed=seed, repeats=1 if large else 3)
        for method, lat in t["latency"].items():
            agree = t["agreement"].get(method, {"differs": 0.0, "n_differs": 0, "mean_excess": 0.0})
            rows.append(dict(database=name, factor=factor, n_clips=t["n_clips"], n_poses=t["n_poses"],
                             method=method, p50_ms=lat["p50_ms"], p99_ms=lat["p99_ms"], k=t["k"],
                             n_queries=t["n_queries"], differs_from_exhaustive=agree["differs"],
                             n_differs=int(agree.get("n_differs", 0)), mean_excess_d=agree["mean_excess"],
                             prepare_p50_ms=t["prepare_ms"]["p50_ms"], precompute_s=t["precompute_s"]))
    table = pd.DataFrame(rows)
    table["machine"] = machine()
    return table


def retrieval_summary(table) -> dict:
    """The issue's goals, computed from :func:`bench_retrieval`'s table, per database."""
    out = {}
    for name, g in table.groupby("database", sort=False):
        p = g[g.method == "pruned"].sort_values("n_poses")
        e = g[g.method == "exhaustive"].sort_values("n_poses")
        slope = float(np.polyfit(np.log(p.n_poses), np.log(p.p50_ms), 1)[0]) if len(p) > 1 else float("nan")
        out[name] = {
            "base_p50_ms": float(p.p50_ms.iloc[0]),
            "base_full_query_p50_ms": float(p.p50_ms.iloc[0] + p.prepare_p50_ms.iloc[0]),
            "largest_factor": int(p.factor.iloc[-1]),
            "speedup_vs_exhaustive_at_largest": float(e.p50_ms.iloc[-1] / p.p50_ms.iloc[-1]),
            "loglog_slope_pruned": slope,
            "paper_search_over_ours": PAPER_SEARCH_S * 1e3 / float(p.p50_ms.iloc[0]),
        }
        x = g[g.method == "exact"].sort_values("n_poses")
        if len(x) and len(e):
            out[name].update({
                "exact_n_differs": int(x.n_differs.sum()),
                "exact_speedup_vs_exhaustive_at_largest": float(e.p50_ms.iloc[-1] / x.p50_ms.iloc[-1]),
                "exact_p99_ms_at_largest": float(x.p99_ms.iloc[-1]),
                "loglog_slope_exact": float(np.polyfit(np.log(x.n_poses), np.log(x.p50_ms), 1)[0])
                if len(x) > 1 else float("nan"),
            })
    return out


def format_retrieval(table) -> str:
    """Human-readable lines for :func:`bench_retrieval`'s table and its summary."""
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        lines.append(f"{r.database} x{r.factor} ({r.n_clips} clips, {r.n_poses} poses) {r.method:10s} "
                     f"p50 {r.p50_ms:8.3f} ms  p99 {r.p99_ms:8.3f} ms  differs from exhaustive {r.differs_from_exhaustive:5.1%}"
                     f" ({getattr(r, 'n_differs', 0)} of {getattr(r, 'n_queries', '?')}), mean excess of d "
                     f"{r.mean_excess_d:6.1%}")
    for (name, factor), g in table.groupby(["database", "factor"], sort=False):  # the ratios, per size
        m = g.set_index("method")
        if {"exact", "exhaustive"} <= set(m.index):
            x, e = m.loc["exact"], m.loc["exhaustive"]
            lines.append(f"{name} x{factor}: exact vs exhaustive p50 {e.p50_ms / x.p50_ms:.1f}x faster, p99 "
                         f"{e.p99_ms / x.p99_ms:.1f}x faster ({x.p99_ms:.2f} ms; goal < {GOAL_EXACT_P99_MS:.1f} ms at "
                         f"100x), {int(x.n_differs)} of {int(x.n_queries)} differ (goal 0); query preparation p50 "
                         f"{x.prepare_p50_ms:.3f} ms (goal < 1 ms)")
    for name, s in retrieval_summary(table).items():
        lines.append(
            f"{name}: base p50 {s['base_p50_ms']:.3f} ms (goal < {GOAL_BASE_P50_MS:g} ms; with query preparation "
            f"{s['base_full_query_p50_ms']:.2f} ms; paper {PAPER_SEARCH_S * 1e3:.0f} ms = {s['paper_search_over_ours']:.0f}x ours); "
            f"pruned vs exhaustive at x{s['largest_factor']}: {s['speedup_vs_exhaustive_at_largest']:.1f}x faster "
            f"(goal >= {GOAL_SPEEDUP_AT_100X:g}x at 100x); log-log slope {s['loglog_slope_pruned']:.2f} (goal < {GOAL_LOGLOG_SLOPE:g})")
        if "exact_n_differs" in s:
            lines.append(
                f"{name}: exact vs exhaustive at x{s['largest_factor']}: {s['exact_speedup_vs_exhaustive_at_largest']:.1f}x "
                f"faster (goal >= {GOAL_SPEEDUP_AT_100X:g}x at 100x), p99 {s['exact_p99_ms_at_largest']:.2f} ms (goal < "
                f"{GOAL_EXACT_P99_MS:.1f} ms at 100x), {s['exact_n_differs']} differences (goal 0); log-log slope "
                f"{s['loglog_slope_exact']:.2f}")
    return "\n".join(lines)
