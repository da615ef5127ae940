"""``repro bench adaptation``: Pronost et al., Sections 3.4 and 4 -- retargeting and adaptation
per frame, and BVH load + convert, against one forward-kinematics pass in the same process.

The paper's 40 ms and 88 us (:mod:`repro.motion.runtime.paper`) are printed beside ours, with the
machine named, never as pass/fail.
"""

from __future__ import annotations

import time

from repro.bench import machine, median_time
from repro.motion.runtime.paper import PAPER_ADAPT_PER_FRAME_S, PAPER_LOAD_CONVERT_S

__all__ = ["GOAL_BATCH_PER_FRAME_US", "bench_adaptation", "bench_order_latency", "format_adaptation"]

#: retarget + adapt per frame, as a batch, microseconds (this reproduction's goal)
GOAL_BATCH_PER_FRAME_US: float = 20.0


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
    from repro.motion.retargeting.morphology import encode, time_retarget
    from repro.motion.body.skeleton import scale_skeleton, skeleton_of

    from repro.checks import as_bool, as_int
    from repro.errors import ArgumentError

    quick = as_bool(quick, "quick", error=ArgumentError)
    progress = as_bool(progress, "progress", error=ArgumentError)

    rows = []
    clips = []
    if data.missing_reason("cmu-bvh") is None:
        from repro.motion import CMU_UNIT_M

        clips.append(("cmu 135_09 (lunge punch)", data.fetch("mocap/cmu/135_09.bvh"), "right_fist", CMU_UNIT_M))
        clips.append(("cmu 135_04 (front kick)", data.fetch("mocap/cmu/135_04.bvh"), "right_foot", CMU_UNIT_M))
    import tempfile

    from repro.motion.io.bvh import write_bvh
    from repro.motion.database.synthetic import synthetic_clip

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
            fk = median_time(lambda: motion.global_positions(), [()] * reps)
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
    """Human-readable lines for :func:`bench_adaptation`'s table."""
    lines = [f"machine: {table['machine'].iloc[0]}"]
    for r in table.itertuples():
        lines.append(
            f"{r.clip} ({r.frames} frames): load+convert {r.load_convert_ms:.1f} ms (paper {r.paper_load_convert_ms:.0f} ms); "
            f"retarget+adapt {r.retarget_plus_adapt_per_frame_us:.1f} us/frame as a batch = "
            f"{r.retarget_plus_adapt_over_fk:.1f}x one FK pass (paper {r.paper_adapt_per_frame_us:.0f} us; goal < {GOAL_BATCH_PER_FRAME_US:g} us batched); "
            f"limb reach on a single frame {r.limb_adapt_single_frame_us:.0f} us; CCD {r.ccd_batch_per_frame_us:.0f} us/frame")
    return "\n".join(lines)


#: most orders (or repeats) :func:`bench_order_latency` times: each is a strike solved twice
MAX_ORDERS: int = 10_000


def bench_order_latency(*, n_orders: int = 12, repeats: int = 3, database: str = "synthetic", seed: int = 0,
                        progress: bool = True) -> dict:
    """Order -> first adapted frame of the fighter (claim K4), the slow path against the fast one, in one process.

    The fighter's orders (alternating kick / punch at the simulated user's head, nothing
    committed) run through :func:`repro.motion.runtime.strike.strike` the slow way
    (``early_stop=False, stream=False``: every level and root-shift trial solved on the
    whole clip before the first frame) and the default way (trials stopped early, the
    level decided on the contact frame and the first frame solved before the rest),
    interleaved order by order so both see the same load; the two strikes are checked
    equal.  Returns and prints the p50 / p99 of ``timings["first_frame"]``, of
    ``timings["level"]`` (order -> reach level decided: after the first frame for a kick
    still planted at ``t0 + 1``) and of the whole call (ms) per path and the ratios
    slow / fast.  No pass/fail: the machine is named.
    """
    import numpy as np

    from repro.bench.retrieval import DATABASES
    from repro.checks import as_bool, as_choice, as_int
    from repro.errors import ArgumentError
    from repro.motion.runtime.fighter import KungFuFighter, check_target, simulated_user
    from repro.motion.runtime.strike import BLEND_S, strike

    n_orders = as_int(n_orders, "n_orders", 1, MAX_ORDERS, error=ArgumentError)
    repeats = as_int(repeats, "repeats", 1, MAX_ORDERS, error=ArgumentError)
    database = as_choice(database, "database", DATABASES, error=ArgumentError)
    seed = as_int(seed, "seed", 0, None, error=ArgumentError)
    progress = as_bool(progress, "progress", error=ArgumentError)

    f = KungFuFighter(database, seed=seed)
    user = simulated_user(seed=seed, duration=20.0, fps=30.0)
    pose = f.current_pose((f.db.window - 1) * f.db.step + 1)
    times = {"slow": ([], [], []), "fast": ([], [], [])}
    for _ in range(int(repeats)):
        for k in range(int(n_orders)):
            X = check_target(user[(k * 37) % len(user)])
            kind = "punch" if k % 2 else "kick"
            out = {}
            for path in (("slow", "fast") if k % 2 else ("fast", "slow")):
                t = time.perf_counter()
                s = strike(f.retriever, f.character, pose, X, kind, blend_s=BLEND_S, t_order=t, method=f.method,
                           scoring=f.scoring, early_stop=path == "fast", stream=path == "fast")
                times[path][1].append(time.perf_counter() - t)
                times[path][0].append(s.timings["first_frame"])
                times[path][2].append(s.timings["level"])
                out[path] = s
            if not np.array_equal(out["slow"].motion.rotations, out["fast"].motion.rotations) or \
                    out["slow"].summary(timings=False) != out["fast"].summary(timings=False):
                raise AssertionError(f"order {k}: the fast path changed the strike")
    res = {"machine": machine(), "orders": len(times["fast"][0])}
    for path, (first, whole, level) in times.items():
        for name, v in (("first_frame", first), ("level", level), ("order", whole)):
            res[f"{path}_{name}_p50_ms"] = 1e3 * float(np.percentile(v, 50))
            res[f"{path}_{name}_p99_ms"] = 1e3 * float(np.percentile(v, 99))
    for name in ("first_frame", "level", "order"):
        res[f"{name}_p50_ratio"] = res[f"slow_{name}_p50_ms"] / res[f"fast_{name}_p50_ms"]
    if progress:
        print(f"machine: {res['machine']}; {res['orders']} orders per path")
        for name in ("first_frame", "level", "order"):
            print(f"{name}: slow p50 {res[f'slow_{name}_p50_ms']:.1f} ms p99 {res[f'slow_{name}_p99_ms']:.1f} ms; "
                  f"fast p50 {res[f'fast_{name}_p50_ms']:.1f} ms p99 {res[f'fast_{name}_p99_ms']:.1f} ms; "
                  f"slow / fast {res[f'{name}_p50_ratio']:.2f}x")
    return res
