"""Scaling the database: deterministic *synthetic* variants of its clips, for latency versus size.

The paper's database holds about 75 motions; the retrieval's latency is measured on
databases 10 and 100 times larger made by :func:`augment` (mirror, actor rescaling,
time warp, feature noise).  These are not new captures (see :func:`augment`).
"""

from __future__ import annotations

import numpy as np

from repro.errors import MotionError
from repro.motion.database import Clip, MotionDatabase, clip_record
from repro.motion.ops import mirror_joint_map, variant_motion

__all__ = ["augment"]


def augment(db: MotionDatabase, factor: int, seed: int = 0, *, scale_range=(0.85, 1.15), warp_range=(0.85, 1.15),
            noise: float = 0.005, mirror_probability: float = 0.5) -> MotionDatabase:
    """A ``factor`` times larger database of *synthetic* variants, for latency-vs-size.

    "Scaling the database": the paper's database holds about 75 motions; to measure how
    the search time grows with the size of the database, every clip gets ``factor - 1``
    variants (the originals are kept, first), each with parameters drawn from
    ``numpy.random.default_rng(seed)`` in a fixed order (so the result is deterministic):

    * mirrored left/right with probability ``mirror_probability``
      (:func:`mirror_motion`; a punch with the right fist becomes one with the left);
    * the actor rescaled uniformly by a factor in ``scale_range`` (a new, taller or
      smaller actor: every length and ``size_a`` multiplied);
    * time-warped: the number of frames multiplied by a factor in ``warp_range``
      (resampled uniformly, the hit frame moved accordingly);
    * Gaussian noise of ``noise`` metres (std) added to the pose clouds and the hit
      trajectory (as capture noise; the stored motion is not noisy).

    These are not new captures: the variants are strongly correlated with their source,
    which makes the retrieval's job *easier* than on as many real motions would be.  A
    mirrored variant keeps its source's base actor (exact for the left/right symmetric
    synthetic actor; for a captured skeleton such as CMU's the mirrored one has the other
    side's bone lengths, a difference of millimetres that the retrieval ignores).

    Returns
    -------
    MotionDatabase
        ``factor * n_clips`` clips; the variants store no motion of their own
        (:meth:`MotionDatabase.motion` rebuilds it from the source clip).
    """
    factor = int(factor)
    if factor < 1:
        raise MotionError(f"factor must be >= 1, got {factor}")
    rng = np.random.default_rng(seed)
    C = db.n_clips
    recs = []
    src_ids = []
    for v in range(1, factor):
        for i in range(C):
            mir = bool(rng.random() < mirror_probability)
            s = float(rng.uniform(*scale_range))
            w = float(rng.uniform(*warp_range))
            n = max(2, int(round((db.n_frames[i] - 1) * w)) + 1)
            base = db.motion(i)
            m = variant_motion(base, n, s, mir)
            hf = int(round(db.hit_frame[i] * (n - 1) / (db.n_frames[i] - 1)))
            role = str(db.hit_roles[i])
            side = str(db.sides[i])
            joint = str(db.hit_joints[i])
            if mir:
                role = role.replace("left", "@").replace("right", "left").replace("@", "right")
                side = {"left": "right", "right": "left"}.get(side, side)
                pi = mirror_joint_map(base.joint_names, base.parents)
                joint = base.joint_names[pi[base.joint_index(joint)]]
            c = Clip(name=f"{db.names[i]}~v{v:03d}", motion=m, semantics=str(db.semantics[i]), hit_role=role,
                     hit_joint=joint, hit_where=str(db.hit_wheres[i]), hit_frame=min(hf, n - 1),
                     kind=str(db.kinds[i]), side=side, source=str(db.sources[i]),
                     source_time=float(db.source_time[i]), level=str(db.levels[i]))
            sk = db.actor_skeleton(i)
            sk = sk.with_offsets(sk.offsets * s, sk.end_site_offsets * s)
            r = clip_record(c, sk, int(db.actor[i]), float(db.scale[i]) * s, db.pose_roles, db.window, db.step,
                            noise=noise, rng=rng)
            r.update(mirror=mir ^ bool(db.mirror[i]), warp=w * float(db.warp[i]))
            recs.append(r)
            src_ids.append(int(db.source_clip[i]) if int(db.source_clip[i]) != i else i)
    if not recs:
        return db
    meta = {**db.meta, "augmented": {"factor": factor, "seed": seed, "scale_range": list(scale_range),
                                     "warp_range": list(warp_range), "noise_m": noise,
                                     "mirror_probability": mirror_probability,
                                     "note": "synthetic variants of the original clips, for latency-vs-size only"}}
    return db.with_variants(recs, src_ids, meta)
