"""Queries and an independent evaluation of ``d`` shared by the search tests (not a test module)."""

from __future__ import annotations

import dataclasses

import numpy as np

from repro.motion.body.skeleton import Skeleton
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.distance import aligned_distance


def frame_of(m, f):
    return dataclasses.replace(m, rotations=m.rotations[f:f + 1], positions=m.positions[f:f + 1])


def queries(db, n, seed=0):
    """(target, pose, character, semantics): a pose of one clip, a target near another's hit."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        i = int(rng.integers(db.n_clips))
        m = db.motion(i)
        pose = frame_of(m, int(rng.integers(m.n_frames)))
        j = int(rng.integers(db.n_clips))
        c = db.hit_position[j] * (db.size_a[i] / db.size_a[j]) + rng.normal(0, 0.03, 3)
        out.append((c, pose, db.actor_skeleton(i), str(db.semantics[j])))
    return out


def brute_force(db, c, pose, character, semantics, w_q=1.0, w_c=1.0):
    """Independent evaluation of d over every startable pose of the semantics."""
    sk = db.actors[0]
    qr = retarget(pose, sk)
    g = qr.global_positions()
    from repro.motion.body.pose_frames import pose_points

    q = pose_points(g, [sk.index(r) for r in db.pose_roles], sk.index("pelvis"), sk.index("left_hip"),
                    sk.index("right_hip"))[-1] / sk.size
    size_c = Skeleton.from_motion(pose).size if character is None else character.size
    best = (np.inf, None)
    for i in range(db.n_clips):
        if db.semantics[i] != semantics:
            continue
        c_r = c * db.size_a[i] / size_c
        d_cr = np.min(np.linalg.norm(db.trajectory(i) - c_r, axis=1))
        for p in db.poses_of(i):
            if db.pose_frame[p] >= db.hit_frame[i]:
                continue
            d_qr = db.size_a[i] * aligned_distance(q, db.pose_points[p])
            d = w_q * d_qr + w_c * d_cr
            if d < best[0]:
                best = (d, p)
    return best
