"""Frame lines with a value lost or doubled (issue 25): repaired by interpolation with a BVHWarning when few,
an error when many, with ``strict=True``, or when a line is far from the channel count."""

from __future__ import annotations

import io
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro.errors import BVHError, BVHWarning
from repro.motion import read_bvh
from repro.motion.core.quaternion import slerp

HEADER = """HIERARCHY
ROOT Hips
{
  OFFSET 0 1 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0 1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: %d
Frame Time: 0.01
"""


def _frames(n: int) -> list[str]:
    """``n`` frames of a smooth motion: the root walks along x, both joints turn about z."""
    return [f"{0.01 * f} 1 0 {0.5 * f} 0 0 {0.25 * f} 0 0" for f in range(n)]


def _read(lines: list[str], **kw):
    return read_bvh(io.StringIO(HEADER % len(lines) + "\n".join(lines) + "\n"), **kw)


def test_a_short_line_is_interpolated_from_its_neighbours_with_a_warning():
    good = _read(_frames(200))
    lines = _frames(200)
    lines[50] = lines[50].rsplit(" ", 1)[0]  # 8 of 9 values
    lines[120] += " 7"  # 10 of 9 values
    with pytest.warns(BVHWarning, match=r"repaired 2 frame lines .*line 69 \(8 values\), line 139 \(10 values\)"
                                         r"; expected 9\): each such frame is interpolated"):
        m = _read(lines)
    assert m.n_frames == 200
    # the motion is linear in the channels, so the interpolated frames are the lost ones
    np.testing.assert_allclose(m.global_positions(), good.global_positions(), atol=1e-12)
    untouched = np.setdiff1d(np.arange(200), [50, 120])
    np.testing.assert_array_equal(m.rotations[untouched], good.rotations[untouched])


def test_interpolation_slerps_between_the_nearest_good_frames():
    lines = _frames(300)
    lines[100] = lines[100].rsplit(" ", 1)[0]
    lines[101] = lines[101].rsplit(" ", 1)[0]
    lines[0] = lines[0].rsplit(" ", 1)[0]  # at the start: the first good frame is copied
    with pytest.warns(BVHWarning, match="repaired 3 frame lines"):
        m = _read(lines)
    good = _read(_frames(300))
    for f, a in ((100, 1 / 3), (101, 2 / 3)):
        want = slerp(good.rotations[99], good.rotations[102], np.full((2, 1), a))
        np.testing.assert_allclose(m.rotations[f], want, atol=1e-12)
    np.testing.assert_array_equal(m.rotations[0], good.rotations[1])
    np.testing.assert_array_equal(m.positions[0], good.positions[1])


def test_many_bad_lines_far_counts_and_strict_are_errors():
    lines = _frames(200)
    for f in (10, 20, 30):  # 3 of 200 frames: over 1 %
        lines[f] = lines[f].rsplit(" ", 1)[0]
    with pytest.raises(BVHError, match=r"line 29: frame 11 has 8 values, expected 9 .*3 frame lines have the "
                                       r"wrong number of values, more than the 2 a read repairs"):
        _read(lines)
    lines = _frames(200)
    lines[10] = "1 2 3"  # far from 9 values: not a lost value
    with pytest.raises(BVHError, match=r"line 29: frame 11 has 3 values, expected 9"):
        _read(lines)
    lines = _frames(200)
    lines[10] = lines[10].rsplit(" ", 1)[0]
    with pytest.raises(BVHError, match=r"line 29: frame 11 has 8 values, expected 9"):
        _read(lines, strict=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _read(_frames(200))  # a sound file: no warning


def test_the_woosub_coda_file_reads_with_its_two_short_lines_repaired():
    """realrigs/woosub_coda02_woman.bvh: lines 327 and 328 hold 65 of 66 values (PROVENANCE.md)."""
    p = Path(os.environ.get("REPRO_DATA_DIR") or "/nonexistent") / "mocap/formats/realrigs/woosub_coda02_woman.bvh"
    if not p.is_file():
        if os.environ.get("REPRO_REQUIRE_DATA") == "1":
            pytest.fail(f"REPRO_REQUIRE_DATA=1 but {p} is not staged")
        pytest.skip(f"{p} not staged (set REPRO_DATA_DIR)")
    with pytest.warns(BVHWarning, match=r"repaired 2 frame lines .*line 327 \(65 values\), line 328 \(65 values\)"):
        m = read_bvh(p)
    assert m.n_frames == 947
    g = m.global_positions()
    step = np.linalg.norm(np.diff(g, axis=0), axis=-1).max(axis=1)  # the largest joint move per frame
    f = 327 - 138  # the first repaired frame, 0-based (line 138 holds frame 1)
    assert step[f - 2 : f + 2].max() <= 2 * np.median(step[f - 20 : f + 20])
    with pytest.raises(BVHError, match="line 327: frame 190 has 65 values, expected 66"):
        read_bvh(p, strict=True)
