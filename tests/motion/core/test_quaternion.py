"""quat_multiply's one-call path for few quaternions gives the component-wise formulas' numbers bit for bit.

Random quaternions of the shapes the one-pose paths multiply (one, a joint row, broadcast
against one), non-contiguous views, and the special values (signed zeros, inf, NaN), each
against the component-wise path (the one-call path switched off).
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.motion.core import quaternion as Q


def both(a, b, monkeypatch):
    fast = Q.quat_multiply(a, b)
    with monkeypatch.context() as mp:
        mp.setattr(Q, "_SMALL", -1)
        slow = Q.quat_multiply(a, b)
    return fast, slow


@pytest.mark.parametrize("sa,sb", [((4,), (4,)), ((1, 4), (1, 4)), ((1, 21, 4), (1, 21, 4)), ((1, 1, 4), (1, 54, 4)),
                                   ((3, 4), (1, 4)), ((2, 64, 4), (2, 64, 4)), ((4,), (5, 3, 4))])
def test_small_path_is_bit_identical(sa, sb, monkeypatch):
    rng = np.random.default_rng(sum(sa) + sum(sb))
    a, b = rng.normal(size=sa), rng.normal(size=sb)
    fast, slow = both(a, b, monkeypatch)
    assert fast.shape == slow.shape and fast.dtype == slow.dtype
    assert np.array_equal(fast, slow)
    big = rng.normal(size=(1, 60, 8))[..., ::2]  # a strided view
    fast, slow = both(big, big[:, ::-1], monkeypatch)
    assert np.array_equal(fast, slow)


def test_special_values(monkeypatch):
    v = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-300, 1e300])
    rng = np.random.default_rng(0)
    a = rng.choice(v, size=(40, 4))
    b = rng.choice(v, size=(40, 4))
    with np.errstate(all="ignore"):
        fast, slow = both(a, b, monkeypatch)
    same = (fast == slow) | (np.isnan(fast) & np.isnan(slow))
    assert same.all()
    finite = np.isfinite(slow)
    assert np.array_equal(np.signbit(fast[finite]), np.signbit(slow[finite]))


def test_other_dtypes_take_the_component_path():
    a = np.array([0, 0, 0, 1])
    assert Q.quat_multiply(a, a).dtype == np.result_type(a, a)
    np.testing.assert_array_equal(Q.quat_multiply(a, a), [0, 0, 0, 1])


def test_matrix_to_quat_refuses_degenerate_frames_with_a_motion_error():
    from repro.errors import MotionError
    from repro.motion.core.quaternion import matrix_to_quat

    good = np.stack([np.eye(3), np.diag([1.0, -1.0, -1.0])])
    np.testing.assert_allclose(np.abs(matrix_to_quat(good)), [[0, 0, 0, 1], [1, 0, 0, 0]], atol=1e-15)
    for bad in (np.zeros((3, 3)), np.diag([1.0, 1.0, -1.0]), np.full((2, 3, 3), np.nan)):
        with pytest.raises(MotionError, match="matrix_to_quat"):
            matrix_to_quat(bad)
