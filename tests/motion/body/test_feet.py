"""repro.motion.body.feet: foot_contacts and foot_metrics check every argument at entry (issue 23, section 6).

Before, a string tolerance, an axis of 'x', None or 10**12, a skeleton or positions of the wrong type
raised TypeError, IndexError, AttributeError or ValueError from deep inside.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.body.feet import foot_contacts, foot_metrics


@pytest.fixture(scope="module")
def clip(synthetic_db):
    return synthetic_db.motion(0)


def test_valid_calls_still_agree(clip):
    c = foot_contacts(clip)
    assert c.shape == (clip.n_frames, 2) and c.dtype == bool
    same = foot_contacts(clip, global_positions=clip.global_positions(), up_axis=1)
    np.testing.assert_array_equal(c, same)
    assert set(foot_metrics(clip, c)) >= {"slide_speed", "min_toe_height"}


@pytest.mark.parametrize("kw", [
    {"height_tol": "x"}, {"height_tol": None}, {"height_tol": -0.1}, {"speed_tol": math.nan},
    {"up_axis": "x"}, {"up_axis": None}, {"up_axis": 3}, {"up_axis": 10**12}, {"up_axis": 1.0},
    {"skeleton": "x"}, {"skeleton": 0}, {"global_positions": "x"}, {"global_positions": np.zeros((2, 2))},
])
def test_foot_contacts_refuses_bad_arguments(clip, kw):
    with pytest.raises(MotionError, match=next(iter(kw))):
        foot_contacts(clip, **kw)


@pytest.mark.parametrize("bad", ["x", None, 1.0, object()])
def test_a_motion_is_required(bad, clip):
    with pytest.raises(MotionError, match="motion must be a Motion"):
        foot_contacts(bad)
    with pytest.raises(MotionError, match="motion must be a Motion"):
        foot_metrics(bad, np.zeros((clip.n_frames, 2), bool))


def test_foot_metrics_contacts_must_be_a_boolean_mask_of_the_frames(clip):
    F = clip.n_frames
    for bad in ("x", None, math.nan, np.ones((F, 2), int), np.zeros((F, 2), float)):
        with pytest.raises(MotionError, match="boolean array"):
            foot_metrics(clip, bad)
    with pytest.raises(MotionError, match=rf"contacts must be \({F}, 2\)"):
        foot_metrics(clip, np.zeros((F + 1, 2), bool))
    with pytest.raises(MotionError, match="up_axis"):
        foot_metrics(clip, np.zeros((F, 2), bool), up_axis="y")
