"""Wall-clock timing of the Section 3.4.2 solvers, for reports (:func:`time_adaptation`)."""

from __future__ import annotations

import time

import numpy as np

from repro.checks import as_int
from repro.errors import MotionError
from repro.motion.adaptation.ccd_solver import ccd
from repro.motion.adaptation.limb import reach_limb
from repro.motion.adaptation.rig import check_frames, rig_of, vec3
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.core.motion import Motion

__all__ = ["time_adaptation"]


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
