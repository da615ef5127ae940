"""Planted feet pinned while decoding (``fix_feet``; Section 3.4).

"Retargetting mainly consists of multiplying adimensional data of the skeleton by the new
dimensions of the character, and correcting the feet artifacts" (Pronost et al., Section
3.4): on the frames where the source's ankle was planted the target's ankle is pinned,
per contact phase (:func:`repro.motion.body.feet.foot_goals`), at the source's ankle
height scaled by the ratio of foot lengths, blended in and out around each phase; where
a goal is out of the leg's reach the root is lowered.  The legs are then solved by
:mod:`repro.motion.retargeting.decoding`'s two-bone IK like any limb.
"""

from __future__ import annotations

import numpy as np

from repro.motion.body.feet import UP_AXIS, foot_goals, foot_scale
from repro.motion.core.quaternion import quat_conjugate as qinv
from repro.motion.core.quaternion import quat_rotate as qrot
from repro.motion.retargeting.representation import LIMB_NAMES

__all__ = ["pin_planted_feet"]


def pin_planted_feet(decoder, want: np.ndarray, gq: np.ndarray, gp: np.ndarray, local_t: np.ndarray,
                     contacts: np.ndarray, ankle_heights: np.ndarray, frame_time: float,
                     blend_time: float) -> tuple[np.ndarray, float]:
    """The limb vectors ``want`` (F, 4, 3) with the legs' goals pinned, and the largest root drop.

    ``decoder``: the :class:`~repro.motion.retargeting.decoding.Decoder` of the target;
    ``gq``, ``gp``: the target's world transforms before the limbs are solved; ``local_t``:
    its local translations.  Where the root has a vertical position channel and a planted
    foot is out of the leg's reach, the root is lowered: ``local_t`` and ``gp`` in place.
    ``contacts`` (F, 2) and ``ankle_heights`` (F, 2, in foot lengths) are the source's
    (:attr:`~repro.motion.retargeting.representation.MorphologyIndependentMotion.contacts`).
    """
    prox, L = decoder.prox, decoder.L
    Rp = gq[:, decoder.par]
    S = gp[:, prox]
    lowered = 0.0
    legs = [LIMB_NAMES.index("left_leg"), LIMB_NAMES.index("right_leg")]
    A = S[:, legs] + qrot(Rp[:, legs], want[:, legs])
    n_blend = int(round(min(blend_time / frame_time, 2.0**53)))  # longer than any clip: no overflow
    goal, w = foot_goals(A, contacts, ankle_heights * foot_scale(decoder.skeleton), n_blend)
    goal = A + w[..., None] * (goal - A)
    if decoder.mask[0, UP_AXIS]:
        # lower the root where a planted foot is out of the leg's reach
        r = goal - S[:, legs]
        ry = r[..., UP_AXIS]
        rh2 = np.sum(r * r, axis=-1) - ry**2
        drop = np.maximum(0.0, -ry - np.sqrt(np.maximum(L[legs][None] ** 2 - rh2, 0.0)))
        drop = drop.max(axis=1)
        lowered = float(drop.max(initial=0.0))
        local_t[:, 0, UP_AXIS] -= drop
        gp[..., UP_AXIS] -= drop[:, None]
        S = gp[:, prox]
    want = want.copy()
    want[:, legs] = qrot(qinv(Rp[:, legs]), goal - S[:, legs])
    return want, lowered
