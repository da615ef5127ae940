"""Pronost et al., Section 3.3 -- the retargeting's wall time per frame, for reports.

The paper: "motion retargetting and adaptation is very fast (only spends 88 us)" per frame;
:func:`time_retarget` times :func:`~repro.motion.retargeting.morphology.encode` and
:func:`~repro.motion.retargeting.morphology.decode`, never asserted on.
"""

from __future__ import annotations

import time

from repro.checks import as_int, describe
from repro.errors import MotionError
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.core.motion import Motion
from repro.motion.retargeting.morphology import decode, encode

__all__ = ["time_retarget"]


def time_retarget(motion: Motion, target, *, repeats: int = 5) -> dict[str, float]:
    """Best-of-``repeats`` wall time of ``encode`` and ``decode``, per frame (seconds)."""
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a Motion, got {describe(motion)}")
    if not isinstance(target, (Skeleton, Motion)):
        raise MotionError(f"target must be a Skeleton or a Motion, got {describe(target)}")
    repeats = as_int(repeats, "repeats", 1, 1000, error=MotionError)
    tgt = skeleton_of(target)
    enc, dec = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        mi = encode(motion)
        t1 = time.perf_counter()
        decode(mi, tgt)
        t2 = time.perf_counter()
        enc.append(t1 - t0)
        dec.append(t2 - t1)
    F = max(motion.n_frames, 1)
    return {
        "frames": float(motion.n_frames),
        "encode_per_frame": min(enc) / F,
        "decode_per_frame": min(dec) / F,
        "total_per_frame": (min(enc) + min(dec)) / F,
    }
