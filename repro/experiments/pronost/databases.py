"""The motion databases the Pronost figures run on, and the fighter standing in each (one home for the figures).

The synthetic database always; CMU's karate takes when they are staged
(:func:`repro.data.missing_reason` of ``cmu-bvh``), so that the claims ledger judges the
figures on real motion as well as on the embedded set.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SYNTHETIC_STANCE_CLIP", "database_names", "databases", "fighter_in_stance", "stance_clip"]

#: The synthetic clip whose first frame is the fighters' stance (a guard, fists up).
SYNTHETIC_STANCE_CLIP = "actor2_punch_left_high"


def database_names() -> list[str]:
    """``["synthetic"]``, and ``"cmu"`` when the CMU takes are staged."""
    from repro import data

    return ["synthetic"] + (["cmu"] if data.missing_reason("cmu-bvh") is None else [])


def databases() -> dict:
    """``{name: MotionDatabase}`` of :func:`database_names` (each built once per process)."""
    from repro.motion.database.sources import default_database

    return {name: default_database(name) for name in database_names()}


def stance_clip(db) -> int:
    """The clip whose first frame is the stance: :data:`SYNTHETIC_STANCE_CLIP` in the synthetic
    database; elsewhere the first lunge punch (the guard the fighter of
    :class:`~repro.motion.runtime.fighter.KungFuFighter` holds), else the first punch."""
    names = [str(n) for n in db.names]
    if SYNTHETIC_STANCE_CLIP in names:
        return names.index(SYNTHETIC_STANCE_CLIP)
    for pick in (np.asarray(db.kinds) == "lunge_punch", np.asarray(db.semantics) == "punch"):
        if pick.any():
            return int(np.flatnonzero(pick)[0])
    return 0


def fighter_in_stance(db, height: float):
    """``(character, stance)``: the database's first actor scaled to ``height`` metres, and the
    one-frame motion of it in the stance (:func:`stance_clip`'s first frame, retargeted)."""
    from repro.motion.body.skeleton import scale_skeleton
    from repro.motion.retargeting.morphology import retarget
    from repro.motion.runtime.strike import one_frame

    ch = scale_skeleton(db.actors[0], height=height)
    return ch, one_frame(retarget(db.motion(stance_clip(db)), ch), 0)
