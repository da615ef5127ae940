"""End Site lines as other exporters write them (issue 25): a name after ``End Site``, a number glued to it."""

from __future__ import annotations

import io

import numpy as np
import pytest

from repro.errors import BVHError
from repro.motion import read_bvh
from tests.motion.io.test_bvh import SMALL


@pytest.mark.parametrize("line", ["End Site Head_end", "End Site4", "End Site51", "End Site LeftToes_end"])
def test_named_and_numbered_end_sites_read_as_end_sites(line):
    plain = read_bvh(io.StringIO(SMALL))
    m = read_bvh(io.StringIO(SMALL.replace("    End Site\n", f"    {line}\n", 1)))
    assert m.joint_names == plain.joint_names
    np.testing.assert_array_equal(m.end_site_parents, plain.end_site_parents)
    np.testing.assert_array_equal(m.end_site_offsets, plain.end_site_offsets)
    np.testing.assert_array_equal(m.global_positions(), plain.global_positions())


@pytest.mark.parametrize("line", ["End Sight", "End Site x y", "End Sites", "End Site4a", "End"])
def test_other_end_lines_are_still_refused(line):
    with pytest.raises(BVHError):
        read_bvh(io.StringIO(SMALL.replace("    End Site\n", f"    {line}\n", 1)))
