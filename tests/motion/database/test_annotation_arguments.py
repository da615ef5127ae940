"""The annotation functions check their arguments at the entry (issue 23, section 6).

What is asserted: ``detect_hits``, ``hit_frame_for``, ``check_semantics``,
``hit_point_trajectory`` and ``annotate`` given a non-motion, a non-skeleton, an
unknown side/semantics/role (``None``, a number, an array), a threshold that is a
string, NaN or infinite (or a negative time), a joint that is not a string, or
positions of the wrong shape, each raise a :class:`MotionError` (they raised
``KeyError``, ``TypeError``, ``AttributeError`` or numpy's ambiguous-truth
``ValueError``); good calls answer as before.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.database.annotation import check_semantics, detect_hits, hit_frame_for, hit_point_trajectory
from repro.motion.database.clips import annotate
from tests.helpers import refusal_failures


@pytest.fixture(scope="module")
def clip(synthetic_db):
    i = int(np.flatnonzero(synthetic_db.semantics == "punch")[0])
    return synthetic_db.clip(i)


HOSTILE = ["x", None, float("nan"), float("inf"), -1, 10**12, 1j, np.zeros(0), np.zeros((2, 7)), ["a"]]


def calls(c):
    m = c.motion
    out = []
    for v in HOSTILE:
        out += [
            ("detect_hits motion", lambda v=v: detect_hits(v)),
            ("hit_frame_for motion", lambda v=v: hit_frame_for(v, "right_fist")),
            ("hit_frame_for role", lambda v=v: hit_frame_for(m, v)),
            ("check_semantics", lambda v=v: check_semantics(v)),
            ("hit_point_trajectory motion", lambda v=v: hit_point_trajectory(v, c.hit_joint)),
            ("hit_point_trajectory joint", lambda v=v: hit_point_trajectory(m, v)),
            ("hit_point_trajectory where", lambda v=v: hit_point_trajectory(m, c.hit_joint, v)),
            ("annotate motion", lambda v=v: annotate(v, c.hit_frame, c.hit_role, "punch", name="n")),
            ("annotate hit_role", lambda v=v: annotate(m, c.hit_frame, v, "punch", name="n")),
            ("annotate semantics", lambda v=v: annotate(m, c.hit_frame, c.hit_role, v, name="n")),
            ("annotate hit_frame", lambda v=v: annotate(m, v, c.hit_role, "punch", name="n")),
        ]
        if v is not None:  # None: the default
            out += [
                ("detect_hits skeleton", lambda v=v: detect_hits(m, v)),
                ("detect_hits semantics", lambda v=v: detect_hits(m, semantics=v)),
                ("detect_hits side", lambda v=v: detect_hits(m, side=v)),
                ("hit_point_trajectory positions", lambda v=v: hit_point_trajectory(m, c.hit_joint, positions=v)),
            ]
        # a threshold may be any finite number, a time any finite number >= 0
        for kw in ("arm_extension", "arm_front", "kick_height", "leg_extension", "merge_gap", "min_duration",
                   "peak_tolerance")[0 if not isinstance(v, int) else 4 if v < 0 else 7:]:
            out.append((f"detect_hits {kw}", lambda v=v, kw=kw: detect_hits(m, **{kw: v})))
    return out


def test_hostile_arguments(clip):
    failures = refusal_failures(calls(clip), MotionError)
    assert not failures, "\n".join(failures)


def test_good_calls(clip):
    m = clip.motion
    assert hit_frame_for(m, clip.hit_role) == clip.hit_frame
    assert detect_hits(m, semantics=np.str_("punch"), side="right") == detect_hits(m, semantics="punch", side="right")
    g = m.global_positions()
    assert np.array_equal(hit_point_trajectory(m, clip.hit_joint, positions=g), hit_point_trajectory(m, clip.hit_joint))
    assert annotate(m, clip.hit_frame, clip.hit_role, "punch", name="n").hit_joint == clip.hit_joint
    assert check_semantics("kick") == "kick"
