"""The retrieval's query path on a character of the actor's joint tree with another rest pose.

``QueryPreparer`` retargets the current pose with a cached ``RetargetPlan``; the plan re-expresses
the poses on the actor's rest directions (its rest step, issue 25), so ``prepare`` gives the pose
cloud of ``retarget`` then Section 3.3's normalisation, to 1e-9, without ``non_fighting_poses(rest_like=db)``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from repro.motion.body.pose_frames import pose_points
from repro.motion.body.skeleton import scale_skeleton
from repro.motion.retargeting.morphology import retarget
from repro.motion.search.retrieval import MotionRetriever


def _turned(actor, **kw):
    """``actor`` scaled (``kw``) with the left forearm turned by 90 degrees and the right shin by 20 at rest
    (same tree)."""
    ch = scale_skeleton(actor, **kw)
    off = np.array(ch.offsets)
    j = ch.index("LeftForeArm")
    off[j] = np.array([off[j][1], -off[j][0], off[j][2]])
    k = ch.index("RightLeg")
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
    off[k] = np.array([off[k][0], c * off[k][1] - s * off[k][2], s * off[k][1] + c * off[k][2]])
    return dataclasses.replace(ch, offsets=off)


def test_prepare_other_rest_pose_equals_retarget(synthetic_db):
    db = synthetic_db
    r = MotionRetriever(db, seed=0)
    actor = db.actors[0]
    idx = [actor.index(n) for n in db.pose_roles]
    rng = np.random.default_rng(11)
    for kw in (dict(scale=1.1), dict(leg_scale=1.2, arm_scale=0.9)):
        ch = _turned(actor, **kw)
        for _ in range(3):
            m = db.motion(int(rng.integers(db.n_clips)))
            f = int(rng.integers(m.n_frames))
            t = np.where(m.position_mask[None], m.local_translations(), ch.offsets[None])[f:]
            pose = ch.motion_with(m.rotations[f:], t, frame_time=m.frame_time)
            q = r.prepare(pose, ch)
            last = dataclasses.replace(pose, rotations=pose.rotations[-1:], positions=pose.positions[-1:])
            g = retarget(last, actor).global_positions()
            want = pose_points(g, idx, actor.index("pelvis"), actor.index("left_hip"), actor.index("right_hip"),
                               window=db.window, step=db.step)[-1] / actor.size
            assert np.abs(q.q_n[0] - want).max() <= 1e-9
