"""Keyframe tracks and the small vector helpers the synthetic choreography is written with.

Every track eases with zero slope at the keys (quintic smootherstep; the strike segment
``5u^4 - 4u^5``), so positions and rotations are C1 with zero velocity at the keys.
Quaternion maths (scalar-last) is :mod:`repro.motion.core.quaternion`'s (its ``slerp`` blends
the foot rotations: it differs from the former private quaternion slerp by at most one
ulp, 2.2e-16, on 52 generated clips, and the written database is byte-identical).
``slerp_vec`` interpolates *directions* (no quaternion sign flip), which
:func:`repro.motion.core.quaternion.slerp` does not do.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from repro.errors import MotionError
from repro.motion.core.ops import ease

__all__ = [
    "UNIT_X",
    "UNIT_Y",
    "UNIT_Z",
    "ease_smooth",
    "ease_strike",
    "EASES",
    "track",
    "unit",
    "slerp_vec",
    "dir_track",
    "spherical",
    "rad",
]

UNIT_X, UNIT_Y, UNIT_Z = np.eye(3)


def ease_smooth(u):  # the library's smootherstep (repro.motion.core.ops.ease)
    return ease(u, "smootherstep")


def ease_strike(u):  # speed 20 u^3 (1 - u): peaks at u = 0.75, zero at both ends
    return u**4 * (5.0 - 4.0 * u)


EASES = {"smooth": ease_smooth, "strike": ease_strike}


def _piecewise(t: np.ndarray, kt: np.ndarray, kv: np.ndarray, segment) -> np.ndarray:
    """Keys ``kv`` at frames ``kt``; ``segment(i, u)`` between keys ``i`` and ``i + 1``.

    Constant before the first and after the last key, exact at the keys themselves.
    """
    out = np.empty((len(t),) + kv.shape[1:])
    out[t <= kt[0]] = kv[0]
    out[t >= kt[-1]] = kv[-1]
    for i in range(len(kt) - 1):
        m = (t > kt[i]) & (t < kt[i + 1])
        out[m] = segment(i, (t[m] - kt[i]) / (kt[i + 1] - kt[i]))
    for i in range(1, len(kt) - 1):  # interior keys: t == kt[i]
        out[t == kt[i]] = kv[i]
    return out


def track(t: np.ndarray, keys: Sequence[tuple[float, object]], eases: Sequence[str] | None = None) -> np.ndarray:
    """Evaluate a keyframe track at frames ``t``: ``v_i + (v_{i+1} - v_i) ease(u)`` per segment.

    Constant before the first and after the last key.  Every ease has zero slope at both
    ends, so the track is C1 with zero velocity at the keys.
    """
    kt = np.array([k[0] for k in keys], dtype=float)
    kv = np.array([np.asarray(k[1], dtype=float) for k in keys])
    if np.any(np.diff(kt) <= 0):
        raise MotionError(f"internal error: key frames not increasing: {kt}")
    eases = eases or ["smooth"] * (len(keys) - 1)

    def segment(i, u):
        s = EASES[eases[i]](u).reshape((-1,) + (1,) * (kv.ndim - 1))
        return kv[i] + (kv[i + 1] - kv[i]) * s

    return _piecewise(t, kt, kv, segment)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def slerp_vec(d0: np.ndarray, d1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit vectors (broadcast), along the shorter great circle."""
    c = np.clip(np.sum(d0 * d1, axis=-1, keepdims=True), -1.0, 1.0)
    om = np.arccos(c)
    so = np.sin(om)
    small = so < 1e-9
    so_safe = np.where(small, 1.0, so)
    s = np.asarray(s, dtype=float)[..., None] if np.ndim(s) == np.ndim(om) - 1 else np.asarray(s, float)
    a = np.where(small, 1.0 - s, np.sin((1.0 - s) * om) / so_safe)
    b = np.where(small, s, np.sin(s * om) / so_safe)
    return unit(a * d0 + b * d1)


def dir_track(t: np.ndarray, keys: Sequence[tuple[float, np.ndarray]], eases: Sequence[str]) -> np.ndarray:
    """Keyframed unit vectors, slerped per segment with the given eases."""
    kt = np.array([k[0] for k in keys], dtype=float)
    kv = unit(np.array([k[1] for k in keys], dtype=float))
    return _piecewise(t, kt, kv, lambda i, u: slerp_vec(kv[i][None], kv[i + 1][None], EASES[eases[i]](u)[:, None]))


def spherical(az, el) -> np.ndarray:
    """Unit vector with azimuth ``az`` (from +Z towards +X) and elevation ``el`` (radians)."""
    az, el = np.asarray(az, float), np.asarray(el, float)
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)


def rad(deg) -> float:
    return math.radians(float(deg))
