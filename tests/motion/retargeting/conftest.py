"""Fixtures of the retargeting tests: the real CMU front kick (135_04)."""

from __future__ import annotations

import pytest

from repro import data
from repro.motion import CMU_UNIT_M, read_bvh


@pytest.fixture(scope="module")
def front_kick():
    return read_bvh(data.fetch("mocap/cmu/135_04.bvh"), unit_m=CMU_UNIT_M)
