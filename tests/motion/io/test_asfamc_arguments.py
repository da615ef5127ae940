"""read_amc / read_asf_amc check their arguments before reading (issue 23, section 6).

What is asserted: a skeleton that is not an :class:`AsfSkeleton` (a string, ``None``, a
number, an array) was an ``AttributeError`` and is a :class:`BVHError`; ``frame_time`` and
``unit_m`` that are not positive finite numbers are a :class:`BVHError`; ``read_bvh``'s
``strict`` must be a bool (an array raised numpy's ambiguous truth value).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from repro import data
from repro.errors import BVHError
from repro.motion import read_amc, read_asf, read_bvh

HOSTILE = ["x", None, math.nan, math.inf, -1, 0, 1j, np.zeros(0), np.zeros((2, 3)), "0.5"]


@pytest.mark.data("cmu-asfamc")
@pytest.mark.parametrize("v", HOSTILE, ids=repr)
def test_read_amc_arguments(v):
    sk = read_asf(data.fetch("mocap/cmu/source/09.asf"))
    amc = data.fetch("mocap/cmu/source/09_06.amc")
    with pytest.raises(BVHError, match="^skeleton must be an AsfSkeleton"):
        read_amc(amc, v)
    with pytest.raises(BVHError, match=r"^frame_time \(s\)"):
        read_amc(amc, sk, frame_time=v)
    if v is not None:
        with pytest.raises(BVHError, match=r"^unit_m"):
            read_amc(amc, sk, unit_m=v)


@pytest.mark.parametrize("v", [np.zeros(0), np.zeros((2, 3)), "x", None, 1], ids=repr)
def test_read_bvh_strict(synthetic_dir, v):
    f = sorted(synthetic_dir.glob("*.bvh"))[0]
    with pytest.raises(BVHError, match="^strict"):
        read_bvh(f, strict=v)
    assert read_bvh(f, strict=np.bool_(True)).n_frames > 0
