"""Scoring with Eq. 1 and ``d`` (repro.motion.search.scoring), Pronost et al. Section 3.3.

What is asserted: Eq. 1 matters: a 1 m character aiming at a target at its own face height
retrieves a *high* punch, whereas without the rescaling a low punch would be chosen.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.motion.body.skeleton import scale_skeleton
from repro.motion.retargeting.morphology import retarget
from tests.motion.search.queries import frame_of


def test_eq1_changes_the_choice_for_a_small_character(db, retriever):
    """A 1 m fighter punching at its own face height needs a high punch of the 1.75 m actor."""
    j = next(i for i in range(db.n_clips) if db.names[i] == "actor2_punch_right_high")
    actor = db.actor_skeleton(j)
    assert actor.size == pytest.approx(1.75)
    small = scale_skeleton(actor, height=1.0)
    stance = frame_of(retarget(db.motion(j), small), 0)
    c = db.hit_position[j] * small.size / actor.size  # face height of the small fighter, at its reach
    with_eq1 = retriever.search(c, stance, small, "punch")
    without = retriever.search(c, stance, small, "punch", scale_target=False)
    assert db.levels[with_eq1.clip] == "high"
    assert with_eq1.d_cr < 0.05
    assert db.levels[without.clip] != "high"
    assert with_eq1.clip != without.clip
    # the unscaled target lies far below the high punch's trajectory
    assert np.min(np.linalg.norm(db.trajectory(with_eq1.clip) - c, axis=1)) > 0.3
