"""``d(t)``, the continuous constraint offset of Section 3.4.2 (:func:`offset_curve`)."""

from __future__ import annotations

import numpy as np

from repro.checks import as_choice, as_int, check_alloc
from repro.errors import MotionError
from repro.motion.adaptation.rig import vec3
from repro.motion.core.ops import EASINGS, ease

__all__ = ["EASINGS", "offset_curve"]

# ---------------------------------------------------------------------- d(t)
def offset_curve(
    t0: int, tc: int, d_tc, frames: int, kind: str = "smoothstep", release: int | None = None
) -> np.ndarray:
    """The continuous constraint offset ``d(t)`` of Section 3.4.2.

    ``d(t) = 0`` for ``t <= t0``, ``d(t) = s((t - t0) / (tc - t0)) d(tc)`` for
    ``t0 < t < tc`` with an easing ``s`` (``s(0) = 0``, ``s(1) = 1``, increasing), and
    ``d(tc)`` at ``tc``.  After ``tc``: held at ``d(tc)`` (``release=None``) or brought
    back to 0 over ``release`` frames with the mirrored easing (``d(tc + release) = 0``;
    the paper does not say what happens after the contact).  With ``t0 == tc`` the
    offset jumps to ``d(tc)`` at ``tc``.

    Parameters
    ----------
    t0, tc : int
        Current frame and contact frame, ``0 <= t0 <= tc < frames``.
    d_tc : (3,) array
        ``X - M(tc)``: the target minus the hit point's position at ``tc``.
    frames : int
        Number of frames F of the clip (> 0).
    kind : {"smoothstep", "linear", "smootherstep"}
        Easing: ``u``, ``3u^2 - 2u^3`` (C1: zero velocity at both ends) or
        ``6u^5 - 15u^4 + 10u^3`` (C2).  All are monotone on [0, 1].
    release : int or None
        Frames after ``tc`` over which ``d`` returns to 0 (``0``: immediately after
        ``tc``); ``None`` holds ``d(tc)`` to the end of the clip.

    Returns
    -------
    (F, 3) array

    Raises
    ------
    repro.errors.MotionError
        Non-integer or out-of-range frames, ``t0 > tc``, non-finite ``d_tc``, unknown
        ``kind``, negative ``release``.
    """
    F = as_int(frames, "frames", 1, 2**62, error=MotionError)
    # the weights, their eased copy and the (F, 3) result
    check_alloc(6 * 8 * F, f"offset_curve(frames={F})", error=MotionError)
    t0 = as_int(t0, "t0", 0, F - 1, error=MotionError)
    tc = as_int(tc, "tc", 0, F - 1, error=MotionError)
    if t0 > tc:
        raise MotionError(f"t0={t0} is after the contact frame tc={tc}; the offset must grow towards the contact")
    d_tc = vec3("d_tc", d_tc)
    kind = as_choice(kind, "kind", EASINGS, error=MotionError)
    if release is not None:
        release = as_int(release, "release", 0, 2**62, error=MotionError)
    t = np.arange(F, dtype=float)
    if tc > t0:
        w = ease(np.clip((t - t0) / (tc - t0), 0.0, 1.0), kind)
    else:
        w = (t >= tc).astype(float)
    w[tc] = 1.0
    if release is None:
        w[tc:] = 1.0
    elif release == 0:
        w[tc + 1:] = 0.0
    else:
        after = t > tc
        w[after] = 1.0 - ease(np.clip((t[after] - tc) / release, 0.0, 1.0), kind)
    return w[:, None] * d_tc[None, :]
