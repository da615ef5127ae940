"""repro.bench.retarget.time_retarget: the retargeting's wall time per frame (no time asserted)."""

from __future__ import annotations

import pytest

from repro import data
from repro.bench.retarget import time_retarget
from repro.errors import MotionError
from repro.motion import CMU_UNIT_M, read_bvh
from repro.motion.body.skeleton import Skeleton
from repro.motion.database.synthetic import synthetic_clip


@pytest.mark.data("cmu-bvh")
def test_time_retarget_reports():
    front_kick = read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)
    t = time_retarget(front_kick, Skeleton.from_motion(front_kick), repeats=1)
    assert t["frames"] == 1316 and t["total_per_frame"] > 0  # measured, never asserted on


@pytest.mark.parametrize("repeats", [10**9, "5"])
def test_time_retarget_refuses_bad_repeats(repeats):
    m, _ = synthetic_clip("punch", "right", "middle", seed=0)
    with pytest.raises(MotionError, match="repeats"):
        time_retarget(m, Skeleton.from_motion(m), repeats=repeats)


@pytest.mark.parametrize("motion, target, match", [("m", None, "Motion"), (None, "sk", "target")])
def test_time_retarget_refuses_what_is_not_a_motion(motion, target, match):
    m, _ = synthetic_clip("punch", "right", "middle", seed=0)
    with pytest.raises(MotionError, match=match):
        time_retarget(m if motion is None else motion, Skeleton.from_motion(m) if target is None else target)
