"""The argument fuzzer's runner catches what it must (:mod:`tests.fuzz.arguments`): a bare exception,
a NaN result, a memory blow-up, a hang and an invalid valid call are failures naming the case, the
parameter and the value; a ReproError and a finite result are not."""

from __future__ import annotations

import math
import time

import pytest

from tests.fuzz.arguments import Case, run

pytestmark = pytest.mark.fuzz


def _clean(x):
    from repro.checks import as_int
    from repro.errors import ModelError

    return as_int(x, "x", lo=0, hi=10, error=ModelError) * 1.0


def _bare(x):
    if x != 1:
        raise ValueError("bare")
    return 1.0


def _nan(x):
    return 1.0 if isinstance(x, int) and x == 1 else math.nan


def _alloc(x):
    if x is None:
        import numpy as np

        return np.ones(8 << 30, dtype=np.uint8)  # past RLIMIT_AS
    return 1.0


def _sleep(x):
    if x is None:
        time.sleep(60)
    return 1.0


def _invalid(x):
    from repro.errors import ModelError

    raise ModelError("always")


CASES = [
    Case("clean", lambda: (_clean, {"x": 1}), {"x": "int"}),
    Case("bare", lambda: (_bare, {"x": 1}), {"x": "int"}),
    Case("nan", lambda: (_nan, {"x": 1}), {"x": "int"}),
    Case("alloc", lambda: (_alloc, {"x": 1}), {"x": "any"}),
    Case("sleep", lambda: (_sleep, {"x": 1}), {"x": "any"}, time_limit=2.0),
    Case("invalid", lambda: (_invalid, {"x": 1}), {"x": "any"}),
]


def test_the_runner_reports_each_kind_of_failure(tmp_path):
    failures, n = run(__name__, str(tmp_path))
    text = "\n".join(failures)
    assert n == sum(1 + len(c.values("x")) for c in CASES)
    assert not [f for f in failures if f.startswith("clean(")], text
    assert "bare(x='x'): error ValueError: bare" in text
    assert "nan(x=-1): nonfinite" in text
    assert any(f.startswith("alloc(x=None): ") and ("MemoryError" in f or "crash" in f) for f in failures), text
    assert "sleep(x=None): timeout" in text
    assert "invalid((valid arguments)): repro_error ModelError" in text
    # only the None of alloc and sleep fail: the child came back after the crash and the timeout
    assert len([f for f in failures if f.startswith(("alloc(", "sleep("))]) == 2, text
