"""``repro bench attenuation``: Lewis et al. 2005, Section 5 ("fast enough to be performed at
interactive speeds").

(a) a new selection plus solve: Eq. (3) as the paper describes it (slice S and Sbar from
    D, form P and Q, solve) versus :class:`~repro.blendshapes.Attenuator` (Gram matrix
    precomputed; Q from the k selected rows; m x m Cholesky).  Goal >= 100x.
(b) a slider move with a cached selection (``M @ w1`` then the posed mesh ``D @ w2``)
    versus one bare ``D @ w``.  Goal <= 2x.

:func:`bench_attenuation_scaling`: the same costs versus model size and number of shapes.
:func:`bench_bounded`: a slider move through the bounded solve (Eq. 2 within the slider
range, :mod:`repro.blendshapes.bounded`) versus Eq. (3)'s.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from repro.bench import machine, median_time

__all__ = [
    "GOAL_SELECTION_SPEEDUP",
    "GOAL_SLIDER_SLOWDOWN",
    "bench_attenuation",
    "bench_attenuation_scaling",
    "bench_bounded",
    "format_attenuation",
    "MAX_REPEATS",
]

#: (a): a new selection through the cached Attenuator is at least this many times faster than Eq. 3 direct
GOAL_SELECTION_SPEEDUP: float = 100.0
#: (b): a slider move with the selection cached costs at most this many bare ``D @ w``
GOAL_SLIDER_SLOWDOWN: float = 2.0


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

    from repro.checks import as_bool, as_int
    from repro.errors import ArgumentError

    quick = as_bool(quick, "quick", error=ArgumentError)
    progress = as_bool(progress, "progress", error=ArgumentError)
    seed = as_int(seed, "seed", 0, None, error=ArgumentError)
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
        direct = median_time(lambda s: attenuate(D, w1, s), [(s,) for s in sels[:reps_direct]])
        fast = median_time(lambda s: att.attenuate(w1, s), [(s,) for s in sels[reps_direct:]])
        rows.append(dict(model=model.name, n_vertices=n, n_shapes=m, measurement="new selection + solve",
                         baseline="direct Eq. 3 (slice S, Sbar; form P, Q; solve)", baseline_us=direct * 1e6,
                         method="Attenuator (Gram precomputed)", method_us=fast * 1e6,
                         ratio=direct / fast, ratio_meaning="baseline / method (speed-up)", goal=f">= {GOAL_SELECTION_SPEEDUP:g}"))
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
                         ratio=mv / b, ratio_meaning="method / baseline (slow-down)", goal=f"<= {GOAL_SLIDER_SLOWDOWN:g}"))
        bar.update()
    bar.close()
    table = pd.DataFrame(rows)
    table["meets_goal"] = [
        (r.ratio >= GOAL_SELECTION_SPEEDUP) if r.goal.startswith(">=") else (r.ratio <= GOAL_SLIDER_SLOWDOWN)
        for r in table.itertuples()
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
    direct = median_time(lambda s: attenuate(D, w1, s), [(s,) for s in sels[:reps_direct]])
    fast = median_time(lambda s: att.attenuate(w1, s), [(s,) for s in sels[reps_direct:]])
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

    from repro.checks import as_bool, as_int
    from repro.errors import ArgumentError

    quick = as_bool(quick, "quick", error=ArgumentError)
    progress = as_bool(progress, "progress", error=ArgumentError)
    seed = as_int(seed, "seed", 0, None, error=ArgumentError)

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


#: Largest ``repeats`` of :func:`bench_bounded` (a few seconds on the ICT face).
MAX_REPEATS = 100_000


def bench_bounded(model=None, *, repeats: int = 200) -> dict:
    """Per-slider-move cost of the bounded solve against Eq. (3)'s mat-vec (same process, ratios).

    On ``model`` (default the ICT face when present, else the procedural one) with
    the Fig. 5 scenario (``wince_sneer_under_eye``), whose Eq. (3) result leaves
    [0, 1]: median microseconds per call of ``Attenuator.edit`` (baseline),
    :func:`~repro.blendshapes.bounded.bounded_edit`, and ``scipy.optimize.lsq_linear``
    on the same Gram form (:func:`~repro.blendshapes.bounded.solve_box_qp` with
    ``method="lsq_linear"``).  Prints nothing; returns the numbers (for a benchmark
    table, not a test).  ``repeats``: 1..:data:`MAX_REPEATS` calls timed per method.
    """
    from repro import data
    from repro.blendshapes import Attenuator, BlendshapeModel, load_model
    from repro.blendshapes import scenarios as S
    from repro.blendshapes.bounded import bounded_edit, check_bounds, solve_box_qp
    from repro.checks import as_int, describe
    from repro.errors import AttenuationError

    repeats = as_int(repeats, "repeats", lo=1, hi=MAX_REPEATS, error=AttenuationError)
    if model is not None and not isinstance(model, BlendshapeModel):
        raise AttenuationError(f"model must be a BlendshapeModel or None, got {describe(model)}")
    if model is None:
        model = load_model("ict" if data.missing_reason("ict") is None else "procedural")
    att = Attenuator(model)
    sc = S.scenario("wince_sneer_under_eye")
    sel = sc.selection(model)
    w_base, w_target = sc.weights(model)
    lo, hi = check_bounds(0.0, 1.0, att.m)
    A, P, _ = att.system(sel)
    g = P @ (w_target - w_base)

    def median_us(f, n):
        return 1e6 * median_time(f, [()] * n)

    base = median_us(lambda: att.edit(w_base, w_target, sel), repeats)
    bounded = median_us(lambda: bounded_edit(att, w_base, w_target, sel), repeats)
    ref = median_us(lambda: solve_box_qp(A, g, lo - w_base, hi - w_base, method="lsq_linear"), max(5, repeats // 20))
    r = bounded_edit(att, w_base, w_target, sel, info=True)
    return {"model": model.name, "n_vertices": model.n_vertices, "n_shapes": model.n_shapes,
            "eq3_edit_us": base, "bounded_edit_us": bounded, "lsq_linear_us": ref,
            "bounded_over_eq3": bounded / base, "lsq_linear_over_bounded": ref / bounded,
            "active_set_steps": r.iterations, "n_at_bounds": r.n_at_bounds, "under_1ms": bounded < 1000.0}
