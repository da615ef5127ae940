"""Benchmarks that print ratios against a baseline measured in the same process.

These machines are noisy, so no absolute time is asserted anywhere: each
benchmark times a baseline and the method side by side, interleaved, and
reports medians and their ratio.

``repro bench attenuation`` (Lewis et al. 2005, Section 5: "fast enough to be
performed at interactive speeds"):

(a) a new selection plus solve: Eq. (3) as the paper describes it (slice S and
    Sbar from D, form P and Q, solve) versus :class:`Attenuator` (Gram matrix
    precomputed; Q from the k selected rows; m x m Cholesky).  Goal >= 100x.
(b) a slider move with a cached selection (``M @ w1`` then the posed mesh
    ``D @ w2``) versus one bare ``D @ w``.  Goal <= 2x.
"""

from __future__ import annotations

import platform
import sys
import time

import numpy as np

from repro.motion.paper import (
    PAPER_ADAPT_PER_FRAME_S,
    PAPER_LOAD_CONVERT_S,
    PAPER_SEARCH_S,
)

__all__ = ["bench_attenuation", "bench_attenuation_scaling", "machine"]


def machine() -> str:
    """A one-line description of this machine, for benchmark output."""
    import os

    return f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores, {platform.python_implementation()} {platform.python_version()}, numpy {np.__version__}".replace("  ", " ")


def _median_time(fn, args_list) -> float:
    """Median seconds per call of ``fn(*args)`` over ``args_list`` (after one untimed warm-up call)."""
    fn(*args_list[0])
    times = []
    for args in args_list:
        t0 = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _models(quick: bool):
    from repro import data
    from repro.blendshapes import load_model

    yield load_model("procedural")
    if data.missing_reason("ict") is None:
        yield load_model("ict", face_only=False)
    else:  # no data: a procedural face of the real model's size
        yield load_model("procedural", n_vertices=26_712)


def bench_attenuation(*, quick: bool = False, seed: int = 0, progress: bool = False):
    """Measure (a) and (b) above on the 2,016-vertex face and a ~26k-vertex one; a DataFrame."""
    import pandas as pd
    from tqdm import tqdm  # plain bar on stderr, never a notebook widget

    from repro.blendshapes import Attenuator, attenuate, select_vertices

    rng = np.random.default_rng(seed)
    reps_direct = 3 if quick else 7
    reps_fast = 50 if quick else 300
    rows = []
    models = list(_models(quick))
    bar = tqdm(total=2 * len(models), desc="bench attenuation", delay=1.0, disable=not progress, file=sys.stderr)
    for model in models:
        D = np.ascontiguousarray(model.D)
        n, m = model.n_vertices, model.n_shapes
        att = Attenuator(model, cache_size=4)
        w1 = rng.uniform(0, 0.7, size=m)
        sels = [select_vertices(rng.choice(n, 6, replace=False)) for _ in range(reps_direct + reps_fast)]
        # (a) new selection + solve; every Attenuator call sees a selection it has not cached
        direct = _median_time(lambda s: attenuate(D, w1, s), [(s,) for s in sels[:reps_direct]])
        fast = _median_time(lambda s: att.attenuate(w1, s), [(s,) for s in sels[reps_direct:]])
        rows.append(dict(model=model.name, n_vertices=n, n_shapes=m, measurement="new selection + solve",
                         baseline="direct Eq. 3 (slice S, Sbar; form P, Q; solve)", baseline_us=direct * 1e6,
                         method="Attenuator (Gram precomputed)", method_us=fast * 1e6,
                         ratio=direct / fast, ratio_meaning="baseline / method (speed-up)", goal=">= 100"))
        bar.update()
        # (b) slider move with the selection cached, versus a bare matvec; interleaved
        sel = sels[0]
        att.matrix(sel)
        ws = [(rng.uniform(0, 0.7, size=m),) for _ in range(reps_fast)]
        bare, moved = [], []
        for (w,) in ws:
            t0 = time.perf_counter()
            D @ w
            t1 = time.perf_counter()
            D @ att.attenuate(w, sel)
            t2 = time.perf_counter()
            bare.append(t1 - t0)
            moved.append(t2 - t1)
        b, mv = float(np.median(bare)), float(np.median(moved))
        rows.append(dict(model=model.name, n_vertices=n, n_shapes=m, measurement="slider move (cached selection)",
                         baseline="bare D @ w", baseline_us=b * 1e6,
                         method="M @ w1 then D @ w2", method_us=mv * 1e6,
                         ratio=mv / b, ratio_meaning="method / baseline (slow-down)", goal="<= 2"))
        bar.update()
    bar.close()
    table = pd.DataFrame(rows)
    table["meets_goal"] = [
        (r.ratio >= 100) if r.goal.startswith(">=") else (r.ratio <= 2) for r in table.itertuples()
    ]
    table["machine"] = machine()
    return table


def format_attenuation(table) -> str:
    """Human-readable lines for :func:`bench_attenuation`'s table."""
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        verdict = "meets" if r.meets_goal else "MISSES"
        lines.append(
            f"{r.model} ({r.n_vertices:,} vertices, {r.n_shapes} shapes), {r.measurement}: "
            f"{r.baseline} {r.baseline_us:,.1f} us vs {r.method} {r.method_us:,.1f} us -> "
            f"ratio {r.ratio:,.2f} ({r.ratio_meaning}; goal {r.goal}: {verdict})"
        )
    return "\n".join(lines)


def _time_case(D, n_vertices, rng, reps_direct, reps_fast):
    """(direct new-selection, cached new-selection, cached slider move, bare D @ w) median seconds."""
    from repro.blendshapes import Attenuator, attenuate, select_vertices

    m = D.shape[1]
    att = Attenuator(D, cache_size=4)
    w1 = rng.uniform(0, 0.7, size=m)
    sels = [select_vertices(rng.choice(n_vertices, 6, replace=False)) for _ in range(reps_direct + reps_fast)]
    direct = _median_time(lambda s: attenuate(D, w1, s), [(s,) for s in sels[:reps_direct]])
    fast = _median_time(lambda s: att.attenuate(w1, s), [(s,) for s in sels[reps_direct:]])
    att.matrix(sels[0])
    D @ w1  # warm-up
    bare, moved = [], []
    for _ in range(reps_fast):
        w = rng.uniform(0, 0.7, size=m)
        t0 = time.perf_counter()
        D @ w
        t1 = time.perf_counter()
        D @ att.attenuate(w, sels[0])
        t2 = time.perf_counter()
        bare.append(t1 - t0)
        moved.append(t2 - t1)
    return direct, fast, float(np.median(moved)), float(np.median(bare))


def bench_attenuation_scaling(*, quick: bool = False, seed: int = 0, progress: bool = False):
    """Cost of a selection change and of a slider move versus model size and number of shapes.

    Vertices: procedural faces of increasing size (all their shapes).  Shapes:
    the first k columns of the largest available model (the ICT face with all
    26,719 vertices when its data is present, else a 26,712-vertex procedural
    face).  Every row times the direct formula and the cached Attenuator in
    the same process.
    """
    import pandas as pd
    from tqdm import tqdm  # plain bar on stderr, never a notebook widget

    from repro import data
    from repro.blendshapes import load_model

    rng = np.random.default_rng(seed)
    sizes = (2016, 10_000, 26_712) if quick else (2016, 5_000, 10_000, 26_712, 50_000)
    big = load_model("ict", face_only=False) if data.missing_reason("ict") is None else load_model("procedural", n_vertices=26_712)
    shape_counts = sorted({k for k in ((8, 16, 32) if quick else (4, 8, 16, 32, 48)) if k < big.n_shapes} | {big.n_shapes})
    cases = [("vertices", load_model("procedural", n_vertices=n)) for n in sizes]
    reps_direct, reps_fast = (3, 30) if quick else (5, 200)
    rows = []
    for sweep, model in tqdm(cases, desc="scaling: vertices", delay=1.0, disable=not progress, file=sys.stderr):
        rows.append((sweep, model.name, model.n_vertices, model.D))
    for k in shape_counts:
        rows.append(("shapes", big.name, big.n_vertices, np.ascontiguousarray(big.D[:, :k])))
    out = []
    for sweep, name, n, D in tqdm(rows, desc="bench attenuation scaling", delay=1.0, disable=not progress, file=sys.stderr):
        direct, fast, move, bare = _time_case(np.ascontiguousarray(D), n, rng, reps_direct, reps_fast)
        out.append(dict(sweep=sweep, model=name, n_vertices=n, n_shapes=D.shape[1],
                        selection_direct_us=direct * 1e6, selection_attenuator_us=fast * 1e6,
                        slider_move_us=move * 1e6, bare_matvec_us=bare * 1e6,
                        selection_speedup=direct / fast, slider_move_over_matvec=move / bare))
    table = pd.DataFrame(out)
    table["machine"] = machine()
    return table


# ------------------------------------------------------------------ Pronost et al. ~2008
# The paper's Section 4 timings (reference lines, not pass/fail): repro.motion.paper.


def bench_retrieval(*, quick: bool = False, databases=None, factors=None, n_queries: int = 200,
                    seed: int = 0, progress: bool = False):
    """Latency of the paper's pruned search, the exhaustive scan and the kd-tree, vs database size.

    For each base database (the synthetic one always, the CMU one when its data is
    present) and each augmentation factor (1x, 10x, 100x; 1x and 10x with ``quick``),
    :func:`repro.motion.retrieval.time_search` times all three methods on the same
    ``n_queries`` random queries, in one process.  One row per (database, factor,
    method) with the columns ``n_clips, n_poses, method, p50_ms, p99_ms`` (the
    contract of ``figures/retrieval_latency.csv``) plus how often the method's choice
    differs from the exhaustive optimum, the mean excess of its distance, and the
    query-preparation cost (Eq. 1 and retargeting q to the actor, shared by all three).
    """
    import pandas as pd
    from tqdm import tqdm  # plain bar on stderr, never a notebook widget

    from repro import data
    from repro.motion.augment import augment
    from repro.motion.sources import default_database
    from repro.motion.retrieval import time_search

    if databases is None:
        databases = ["synthetic"] + (["cmu"] if data.missing_reason("cmu-bvh") is None else [])
    if factors is None:
        factors = (1, 10) if quick else (1, 10, 100)
    rows = []
    work = [(name, f) for name in databases for f in factors]
    for name, factor in tqdm(work, desc="bench retrieval", delay=1.0, disable=not progress, file=sys.stderr):
        base = default_database(name)
        db = base if factor == 1 else augment(base, factor, seed=seed)
        t = time_search(db, n_queries=n_queries if not quick else min(n_queries, 100), seed=seed)
        for method, lat in t["latency"].items():
            agree = t["agreement"].get(method, {"differs": 0.0, "mean_excess": 0.0})
            rows.append(dict(database=name, factor=factor, n_clips=t["n_clips"], n_poses=t["n_poses"],
                             method=method, p50_ms=lat["p50_ms"], p99_ms=lat["p99_ms"], k=t["k"],
                             differs_from_exhaustive=agree["differs"], mean_excess_d=agree["mean_excess"],
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
    return out


def format_retrieval(table) -> str:
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        lines.append(f"{r.database} x{r.factor} ({r.n_clips} clips, {r.n_poses} poses) {r.method:10s} "
                     f"p50 {r.p50_ms:8.3f} ms  p99 {r.p99_ms:8.3f} ms  differs from exhaustive {r.differs_from_exhaustive:5.1%}")
    for name, s in retrieval_summary(table).items():
        lines.append(
            f"{name}: base p50 {s['base_p50_ms']:.3f} ms (goal < 1 ms; with query preparation "
            f"{s['base_full_query_p50_ms']:.2f} ms; paper 280 ms = {s['paper_search_over_ours']:.0f}x ours); "
            f"pruned vs exhaustive at x{s['largest_factor']}: {s['speedup_vs_exhaustive_at_largest']:.1f}x faster "
            f"(goal >= 20x at 100x); log-log slope {s['loglog_slope_pruned']:.2f} (goal < 0.5)")
    return "\n".join(lines)


def bench_adaptation(*, quick: bool = False, progress: bool = False):
    """Per-frame cost of retargeting and adaptation, and BVH load + convert, against FK in-process.

    The in-process baseline is one forward-kinematics pass over the same frames
    (``Motion.global_positions``): every ratio printed is "this step costs N FK passes".
    The paper's figures (40 ms load + convert, 88 µs retarget + adapt per frame) are
    printed beside ours for reference, with the machine named, not as a pass/fail.
    """
    import pandas as pd

    from repro import data
    from repro.motion import read_bvh
    from repro.motion.adaptation import time_adaptation
    from repro.motion.morphology import encode, time_retarget
    from repro.motion.skeleton import scale_skeleton, skeleton_of

    rows = []
    clips = []
    if data.missing_reason("cmu-bvh") is None:
        from repro.motion import CMU_UNIT_M

        clips.append(("cmu 135_09 (lunge punch)", data.fetch("mocap/cmu/135_09.bvh"), "right_fist", CMU_UNIT_M))
        clips.append(("cmu 135_04 (front kick)", data.fetch("mocap/cmu/135_04.bvh"), "right_foot", CMU_UNIT_M))
    import tempfile

    from repro.motion.bvh import write_bvh
    from repro.motion.synthetic import synthetic_clip

    reps = 3 if quick else 7
    with tempfile.TemporaryDirectory() as tmp:
        m, _ = synthetic_clip("punch", "right", "middle", seed=0)
        path = f"{tmp}/punch.bvh"
        write_bvh(m, path)
        clips.append(("synthetic punch", path, "right_fist", 1.0))
        for label, path, effector, unit_m in clips:
            t0 = time.perf_counter()
            load = []
            for _ in range(reps):
                t = time.perf_counter()
                motion = read_bvh(path, unit_m=unit_m).to_metres()
                encode(motion)
                load.append(time.perf_counter() - t)
            F = motion.n_frames
            fk = _median_time(lambda: motion.global_positions(), [()] * reps)
            target = scale_skeleton(skeleton_of(motion), scale=1.15)
            rt = time_retarget(motion, target, repeats=reps)
            ad = time_adaptation(motion, effector, repeats=reps)
            per_frame_fk = fk / F
            rows.append(dict(
                clip=label, frames=F, load_convert_ms=min(load) * 1e3,
                fk_per_frame_us=per_frame_fk * 1e6,
                retarget_per_frame_us=rt["total_per_frame"] * 1e6,
                limb_adapt_batch_per_frame_us=ad["limb_batch_per_frame"] * 1e6,
                limb_adapt_single_frame_us=ad["limb_single_frame"] * 1e6,
                ccd_batch_per_frame_us=ad["ccd_batch_per_frame"] * 1e6,
                retarget_plus_adapt_per_frame_us=(rt["total_per_frame"] + ad["limb_batch_per_frame"]) * 1e6,
                retarget_plus_adapt_over_fk=(rt["total_per_frame"] + ad["limb_batch_per_frame"]) / per_frame_fk,
                paper_adapt_per_frame_us=PAPER_ADAPT_PER_FRAME_S * 1e6, paper_load_convert_ms=PAPER_LOAD_CONVERT_S * 1e3,
                bench_s=time.perf_counter() - t0,
            ))
    table = pd.DataFrame(rows)
    table["machine"] = machine()
    return table


def format_adaptation(table) -> str:
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        lines.append(
            f"{r.clip} ({r.frames} frames): load+convert {r.load_convert_ms:.1f} ms (paper {r.paper_load_convert_ms:.0f} ms); "
            f"retarget+adapt {r.retarget_plus_adapt_per_frame_us:.1f} us/frame as a batch = "
            f"{r.retarget_plus_adapt_over_fk:.1f}x one FK pass (paper {r.paper_adapt_per_frame_us:.0f} us; goal < 20 us batched); "
            f"limb reach on a single frame {r.limb_adapt_single_frame_us:.0f} us; CCD {r.ccd_batch_per_frame_us:.0f} us/frame")
    return "\n".join(lines)
