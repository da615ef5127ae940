"""d(t) of Section 3.4.2 (repro.motion.adaptation.offset): 0 up to t0, d(tc) at tc, monotone in between
(smoothstep: zero slope at both ends), released back to 0 after tc when asked."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro.errors import MotionError
from repro.motion.adaptation import offset_curve


def test_offset_curve_endpoints_monotone_smooth():
    d_tc = np.array([0.1, -0.05, 0.02])
    d = offset_curve(10, 40, d_tc, 60)
    assert d.shape == (60, 3)
    assert np.all(d[:11] == 0.0)
    np.testing.assert_allclose(d[40], d_tc, atol=0)
    np.testing.assert_allclose(d[40:], np.broadcast_to(d_tc, (20, 3)))  # held by default
    # every d(t) is a multiple s(t) d_tc with s increasing from 0 to 1
    s = d[:, 0] / d_tc[0]
    np.testing.assert_allclose(d, s[:, None] * d_tc[None], atol=1e-15)
    assert np.all(np.diff(s[10:41]) > 0)
    # smoothstep: slope vanishes at both ends (first/last steps are the smallest)
    steps = np.diff(s[10:41])
    assert steps[0] < steps[15] / 10 and steps[-1] < steps[15] / 10
    assert steps.max() <= 1.5 / 30 + 1e-12  # max slope of 3u^2 - 2u^3 is 1.5


def test_offset_curve_linear_release_and_degenerate():
    d = offset_curve(0, 4, [1.0, 0, 0], 12, kind="linear", release=4)
    np.testing.assert_allclose(d[:, 0], [0, 0.25, 0.5, 0.75, 1, 0.75, 0.5, 0.25, 0, 0, 0, 0])
    d = offset_curve(3, 3, [0, 1.0, 0], 6)  # t0 == tc: a step at tc
    np.testing.assert_array_equal(d[:, 1], [0, 0, 0, 1, 1, 1])
    d = offset_curve(1, 3, [0, 0, 2.0], 6, release=0)
    np.testing.assert_array_equal(d[4:, 2], [0, 0])
    d = offset_curve(0, 10, [1.0, 0, 0], 11, kind="smootherstep")
    assert np.all(np.diff(d[:, 0]) > 0) and d[10, 0] == 1.0


@given(
    F=st.integers(2, 200),
    a=st.floats(0, 1),
    b=st.floats(0, 1),
    d=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
    kind=st.sampled_from(["linear", "smoothstep", "smootherstep"]),
    rel=st.one_of(st.none(), st.integers(0, 30)),
)
def test_offset_curve_properties(F, a, b, d, kind, rel):
    t0, tc = sorted((int(a * (F - 1)), int(b * (F - 1))))
    out = offset_curve(t0, tc, d, F, kind=kind, release=rel)
    assert np.all(out[: t0 + (tc > t0)] == 0.0) if tc > t0 else np.all(out[:tc] == 0.0)
    np.testing.assert_array_equal(out[tc], np.asarray(d, dtype=float))
    w = np.linalg.norm(out, axis=1)
    assert np.all(np.diff(w[t0: tc + 1]) >= -1e-12)  # grows monotonically to |d(tc)|
    assert np.all(w <= np.linalg.norm(d) + 1e-12)
    if rel is not None:
        assert np.all(np.diff(w[tc:]) <= 1e-12)  # then decreases back
        assert np.all(out[tc + rel + 1:] == 0.0) if rel > 0 else np.all(out[tc + 1:] == 0.0)


@pytest.mark.parametrize(
    "args, kw, match",
    [
        ((5, 3, [0, 0, 0], 10), {}, "after the contact"),
        ((0, 10, [0, 0, 0], 10), {}, "out of range"),
        ((-1, 3, [0, 0, 0], 10), {}, "out of range"),
        ((0, 3, [np.nan, 0, 0], 10), {}, "NaN"),
        ((0, 3, [0, 0], 10), {}, "3-vector"),
        ((0, 3, [0, 0, 0], 10), {"kind": "cubic"}, "kind"),
        ((0, 3, [0, 0, 0], 10), {"release": -1}, "release"),
        ((0.5, 3, [0, 0, 0], 10), {}, "integer"),
    ],
)
def test_offset_curve_bad_inputs(args, kw, match):
    with pytest.raises(MotionError, match=match):
        offset_curve(*args, **kw)
