"""Planted feet pinned while decoding (repro.motion.retargeting.planted_feet).

What is asserted: a blend longer than any clip does not overflow (the whole clip).  The feet
pinned on a real clip are asserted in test_morphology (``retarget(..., fix_feet=True)``).
"""

from __future__ import annotations

import numpy as np

from repro.motion.retargeting.decoding import decode
from repro.motion.retargeting.representation import encode
from tests.motion.retargeting.mixamo_motions import random_motion, rest_skeleton


def test_a_blend_longer_than_any_clip_does_not_overflow():
    m = random_motion(0, F=4)
    a = decode(encode(m), rest_skeleton(), fix_feet=True, blend_time=1.7e308)  # used to overflow in round()
    b = decode(encode(m), rest_skeleton(), fix_feet=True, blend_time=1e6)
    np.testing.assert_array_equal(a.rotations, b.rotations)
