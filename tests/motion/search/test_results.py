"""The result of a retrieval (repro.motion.search.results), Pronost et al. Section 3.3, step 6.

What is asserted: the alignment puts the selected start pose onto the current pose, wherever
the character stands and whichever way it faces.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.motion.body.pose_frames import rotate_y
from repro.motion.search.retrieval import MotionRetriever
from tests.motion.search.queries import frame_of


@pytest.mark.parametrize("theta, shift", [(0.0, (0.0, 0.0)), (2.1, (3.0, -1.5)), (-0.8, (-4.0, 2.0))])
def test_alignment_places_the_start_pose_on_the_current_pose(db, retriever, theta, shift):
    i = 20
    m = db.motion(i)
    f = 5
    # the current pose: clip i's frame f, turned by theta and moved on the floor
    pose = frame_of(m, f)
    pos = np.array(pose.positions)
    pos[:, 0] = rotate_y(pos[:, 0], theta) + [shift[0], 0.0, shift[1]]
    qroot = np.array(pose.rotations)
    qy = np.array([0.0, np.sin(theta / 2), 0.0, np.cos(theta / 2)])
    from repro.motion.core.quaternion import quat_multiply

    qroot[:, 0] = quat_multiply(qy, qroot[:, 0])
    pose = dataclasses.replace(pose, positions=pos, rotations=qroot)
    actor = db.actor_skeleton(i)
    r = MotionRetriever(db, w_c=1e-9).search(db.hit_position[i], pose, actor, str(db.semantics[i]), prune=False)
    assert r.d_qr < 1e-6  # the same pose (or an identical one) is found
    start = db.motion(r.clip).global_positions()[r.start_frame]
    placed = r.place(start)
    np.testing.assert_allclose(placed, pose.global_positions()[0], atol=1e-5)
