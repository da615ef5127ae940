"""The query of a retrieval (repro.motion.search.query): ``q_r``, the current pose retargeted to the actors.

What is asserted: a character that is a uniform scaling of the actor gets, without retargeting,
the ``q_r`` that retargeting gives; ``retarget_to_tree`` (what serving other joint trees relies on)
given a motion or target that is not a Motion is a :class:`MotionError` (was an ``AttributeError``).
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.retargeting.dispatch import retarget_to_tree
from repro.motion.search.retrieval import make_queries


@pytest.fixture(scope="module")
def small(synthetic_db):
    return synthetic_db.select(np.arange(3))


def test_prepare_fast_path_equals_retargeting(db, retriever):
    """A character that is a uniform scaling of the actor: q_r without retargeting is the retargeted one."""
    from repro.motion.body.pose_frames import pose_points
    from repro.motion.retargeting.morphology import retarget
    from repro.motion.body.skeleton import scale_skeleton

    a = db.actors[0]
    ch = scale_skeleton(a, height=1.3)
    for c, pose, _, sem in make_queries(db, 10, seed=11):
        p = retarget(pose, ch)
        q = retriever.prepare(p, ch)
        g = retarget(p, a).global_positions()
        ref = pose_points(g, [a.index(x) for x in db.pose_roles], a.index("pelvis"), a.index("left_hip"),
                          a.index("right_hip"))[-1] / a.size
        np.testing.assert_allclose(q.q_n[0], ref, atol=1e-12)
        assert q.size_c == pytest.approx(ch.size)


HOSTILE = ["x", None, float("nan"), 1j, -1, np.zeros(0), np.zeros((2, 7)), ["a"]]


@pytest.mark.parametrize("v", HOSTILE, ids=repr)
def test_retarget_to_tree_motion(small, v):
    ch = small.actor_skeleton(0)
    with pytest.raises(MotionError, match="^motion must be"):
        retarget_to_tree(v, ch)
    if v is not None:
        with pytest.raises(MotionError, match="^target must be"):
            retarget_to_tree(small.motion(0), ch, target=v)
