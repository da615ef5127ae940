"""repro.bench.adaptation.time_adaptation: the Section 3.4.2 solvers' wall time per frame (no time asserted)."""

from __future__ import annotations

import numpy as np
import pytest

from repro import data
from repro.bench.adaptation import time_adaptation
from repro.errors import MotionError
from repro.motion import CMU_UNIT_M, read_bvh
from repro.motion.database.synthetic import synthetic_clip


@pytest.mark.data("cmu-bvh")
def test_time_adaptation_reports():
    punch = read_bvh(data.fetch("mocap/cmu/135_09.bvh"), unit_m=CMU_UNIT_M).to_metres()
    t = time_adaptation(punch, "right_fist", frames=np.arange(290, 320), repeats=1)
    for k in ("limb_batch_per_frame", "limb_single_frame", "ccd_batch_per_frame"):
        assert np.isfinite(t[k]) and t[k] > 0
    assert t["frames"] == 30


def test_time_adaptation_refuses_huge_repeats():
    m, _ = synthetic_clip("punch", "right", "middle", seed=0)
    with pytest.raises(MotionError, match="repeats"):
        time_adaptation(m, "right_wrist", repeats=10**9)
