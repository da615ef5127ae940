"""``repro bench index``: building the scaled databases and the retrieval's index (Pronost et al., Section
3.2.2, "a precomputation process"), time and peak memory, 10x to 1,000x.

For each factor, :func:`repro.motion.database.augment.augment` makes the database (float32 pose clouds from
1,000x, :data:`FLOAT32_FROM`) and :class:`repro.motion.search.retrieval.MotionRetriever` builds its
clusters and indices.  Peak memory is traced (:mod:`tracemalloc`, which numpy reports its arrays
to) per stage and for both; the process's ``ru_maxrss`` is printed beside it.  The baseline
measured in the same process is the per-variant path that :func:`augment` replaced: a sample of
variants rebuilt one by one (:meth:`MotionDatabase.clip` then
:meth:`MotionDatabase.from_clips`, i.e. :func:`~repro.motion.core.ops.variant_motion` and
:func:`~repro.motion.database.clips.clip_record` per variant), its time per variant times the number
of variants.  The goals are this reproduction's (issue 13): 100x in under 10 s, 1,000x in under
2 min within 4 GB.
"""

from __future__ import annotations

import resource
import sys
import time
import tracemalloc

import numpy as np

from repro.bench import machine

__all__ = ["FLOAT32_FROM", "GOAL_100X_S", "GOAL_1000X_GB", "GOAL_1000X_S", "bench_index_build", "format_index_build"]

#: factor from which the bench stores the pose clouds in float32 (halves the largest array)
FLOAT32_FROM: int = 1000
#: the retriever's build at 100x, seconds
GOAL_100X_S: float = 10.0
#: database and index at 1,000x, seconds and GB of peak memory
GOAL_1000X_S: float = 120.0
GOAL_1000X_GB: float = 4.0


def _per_variant_s(db, n: int, seed: int) -> float:
    """Seconds per variant of the per-variant path, on ``n`` variants drawn with ``seed``."""
    from repro.motion.database.clips import MotionDatabase

    variants = np.flatnonzero(db.source_clip != np.arange(db.n_clips))
    pick = np.random.default_rng(seed).choice(variants, min(n, variants.size), replace=False)
    t0 = time.perf_counter()
    for i in pick:
        MotionDatabase.from_clips([db.clip(int(i))], pose_roles=db.pose_roles, window=db.window, step=db.step)
    return (time.perf_counter() - t0) / pick.size


def bench_index_build(*, quick: bool = False, factors=None, database: str = "synthetic", seed: int = 0,
                      baseline_variants: int = 200, progress: bool = False):
    """Time and peak memory of :func:`augment` and of the retriever's build, per factor (one row each).

    Columns: ``factor, n_clips, n_poses, pose_dtype, k, augment_s, augment_cpu_s, index_s,
    index_cpu_s, total_s, augment_peak_gb, index_peak_gb`` (traced, the index's includes the
    database it is built on), ``maxrss_gb`` (the process so far), the baseline
    ``per_variant_augment_s`` (extrapolated to all variants) and ``augment_speedup``.
    Factors: 10 and 100 with ``quick``, else 100 and 1,000.
    """
    import pandas as pd
    from tqdm import tqdm

    from repro.motion.database.augment import augment
    from repro.motion.search.retrieval import MotionRetriever
    from repro.checks import as_bool, as_choice, as_int
    from repro.errors import RetrievalError
    from repro.motion.database.sources import default_database

    quick = as_bool(quick, "quick", error=RetrievalError)
    progress = as_bool(progress, "progress", error=RetrievalError)
    seed = as_int(seed, "seed", 0, None, error=RetrievalError)
    baseline_variants = as_int(baseline_variants, "baseline_variants", 1, 100_000, error=RetrievalError)
    database = as_choice(database, "database", ("synthetic", "cmu"), error=RetrievalError)
    if factors is not None:  # each an int >= 1
        if isinstance(factors, (str, bytes)) or not hasattr(factors, "__iter__"):
            raise RetrievalError(f"factors must be a sequence of ints >= 1, got {factors!r}")
        factors = tuple(as_int(f, "factor", 1, 10**9, error=RetrievalError) for f in factors)  # retrieval.MAX_FACTOR
        if not factors:
            raise RetrievalError("factors must name at least one size (an int >= 1)")
    if factors is None:
        factors = (10, 100) if quick else (100, 1000)
    base = default_database(database)
    from repro.checks import check_alloc
    from repro.experiments.shared import estimated_bytes

    f = max(factors)  # the largest asks the most: refused before any factor is built
    check_alloc(estimated_bytes(base, f), f"factor {f} (the {database} database of {base.n_clips} clips, {f} times)",
                error=RetrievalError)
    rows = []
    for factor in tqdm(list(factors), desc="bench index", delay=1.0, disable=not progress, file=sys.stderr):
        dtype = np.float32 if factor >= FLOAT32_FROM else None
        tracemalloc.start()
        t0, c0 = time.perf_counter(), time.process_time()
        db = augment(base, factor, seed=seed, pose_dtype=dtype)
        ta, ca = time.perf_counter() - t0, time.process_time() - c0
        peak_a = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        t0, c0 = time.perf_counter(), time.process_time()
        r = MotionRetriever(db, seed=seed)
        tb, cb = time.perf_counter() - t0, time.process_time() - c0
        peak_b = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        n_var = db.n_clips - base.n_clips
        per = _per_variant_s(db, baseline_variants if not quick else min(baseline_variants, 50), seed)
        rows.append({"database": database, "factor": factor, "n_clips": db.n_clips, "n_poses": db.n_poses,
                         "pose_dtype": str(db.pose_points.dtype), "k": r.k, "augment_s": ta, "augment_cpu_s": ca, "index_s": tb,
                         "index_cpu_s": cb, "total_s": ta + tb, "augment_peak_gb": peak_a / 1e9, "index_peak_gb": peak_b / 1e9,
                         "maxrss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9,
                         "per_variant_augment_s": per * n_var, "augment_speedup": per * n_var / ta})
        del r, db
    table = pd.DataFrame(rows)
    table["machine"] = machine()
    return table


def format_index_build(table) -> str:
    """Human-readable lines for :func:`bench_index_build`'s table, with the goals."""
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        lines.append(
            f"{r.database} x{r.factor} ({r.n_clips:,} clips, {r.n_poses:,} poses, {r.pose_dtype}, k={r.k}): augment "
            f"{r.augment_s:.1f} s (cpu {r.augment_cpu_s:.1f} s; per-variant path {r.per_variant_augment_s:.1f} s = "
            f"{r.augment_speedup:.1f}x slower), index {r.index_s:.1f} s (cpu {r.index_cpu_s:.1f} s), total "
            f"{r.total_s:.1f} s; peak traced {max(r.augment_peak_gb, r.index_peak_gb):.2f} GB (maxrss {r.maxrss_gb:.2f} GB)")
        if r.factor == 100:
            lines.append(f"  goal: index at 100x < {GOAL_100X_S:g} s: {'met' if r.index_s < GOAL_100X_S else 'NOT met'}")
        if r.factor == 1000:
            ok = r.total_s < GOAL_1000X_S and max(r.augment_peak_gb, r.index_peak_gb) < GOAL_1000X_GB
            lines.append(f"  goal: 1,000x < {GOAL_1000X_S:g} s within {GOAL_1000X_GB:g} GB: {'met' if ok else 'NOT met'}")
    return "\n".join(lines)
