"""``repro bench adaptation``: Pronost et al., Sections 3.4 and 4 -- retargeting and adaptation
per frame, and BVH load + convert, against one forward-kinematics pass in the same process.

The paper's 40 ms and 88 us (:mod:`repro.motion.runtime.paper`) are printed beside ours, with the
machine named, never as pass/fail.  :func:`time_adaptation` times the Section 3.4.2 solvers
(the limb step, batched and frame by frame, and CCD).
"""

from __future__ import annotations

import time

import numpy as np

from repro.bench import machine, median_time
from repro.checks import as_int
from repro.errors import MotionError
from repro.motion.adaptation import ccd, reach_limb
from repro.motion.adaptation.rig import check_frames, rig_of, vec3
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.runtime.paper import PAPER_ADAPT_PER_FRAME_S, PAPER_LOAD_CONVERT_S

__all__ = ["GOAL_BATCH_PER_FRAME_US", "bench_adaptation", "format_adaptation", "time_adaptation"]

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
    from repro.bench.retarget import time_retarget
    from repro.motion.retargeting.morphology import encode
    from repro.motion.body.skeleton import scale_skeleton, skeleton_of

    from repro.checks import as_bool
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


def time_adaptation(motion: Motion, effector: str, *, frames=None, offset=(0.0, 0.0, 0.1), repeats: int = 7) -> dict:
    """Best-of-``repeats`` wall time per frame of the solvers (seconds), for reports.

    The paper: "If only the limb is involved, this method only requires 88 us" per frame.
    Measures, on ``frames`` (default: every frame) with goals = original hit point +
    ``offset``:

    * ``limb_batch_per_frame``: :func:`reach_limb` on all frames at once, divided by the
      number of frames;
    * ``limb_single_frame``: :func:`reach_limb` on one frame (median over the frames of a
      sample of 200), the frame-by-frame use of the paper;
    * ``ccd_batch_per_frame``: :func:`ccd` (from the limb result, then the limb again)
      on all frames at once, per frame, with goals moved 3 times as far, and the mean
      number of sweeps ``ccd_mean_iterations``.

    The tests never assert on time.
    """
    rig = rig_of(motion)
    ch = rig.chain(effector)
    repeats = as_int(repeats, "repeats", 1, 1000, error=MotionError)
    idx = np.arange(motion.n_frames) if frames is None else check_frames(frames, motion.n_frames)[0]
    gq, gp = rig.globals
    p = gp[idx, ch.hit] + qrot(gq[idx, ch.hit], ch.hit_offset)
    off = vec3("offset", offset)
    goal = p + off
    best_b = best_c = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        reach_limb(motion, idx, effector, goal)
        best_b = min(best_b, time.perf_counter() - t)
    pos = np.linspace(0, len(idx) - 1, min(200, len(idx))).astype(int)
    single = []
    for f, g in zip(idx[pos], goal[pos]):
        reach_limb(motion, int(f), effector, g)  # warm
        t = time.perf_counter()
        reach_limb(motion, int(f), effector, g)
        single.append(time.perf_counter() - t)
    goal_far = p + 3.0 * off
    its = None
    for _ in range(max(1, min(repeats, 3))):
        lr = reach_limb(motion, idx, effector, goal_far)
        t = time.perf_counter()
        sol = ccd(motion, idx, effector, goal_far, rotations=lr.rotations)
        best_c = min(best_c, time.perf_counter() - t)
        its = sol.iterations
    n = len(idx)
    return {
        "frames": float(n),
        "limb_batch_per_frame": best_b / n,
        "limb_single_frame": float(np.median(single)),
        "ccd_batch_per_frame": best_c / n,
        "ccd_mean_iterations": float(np.mean(its)),
        "ccd_frames_iterating": float(np.sum(its > 0)),
    }
