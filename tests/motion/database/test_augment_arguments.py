"""augment checks its arguments and what ``factor`` will allocate before allocating (issue 23, sections 3, 6).

What is asserted: ``factor=10**9`` or ``10**5`` (numpy asked for 67-99 GiB) is a
:class:`MotionError` naming ``factor`` and the memory budget, raised before anything is
allocated; a budget lowered through ``repro.checks.MEMORY_BUDGET`` refuses a factor the
default budget allows; ``factor``/``seed`` of the wrong type or range, NaN or reversed
ranges, a negative noise, a probability outside [0, 1] and a database that is not one
are each a :class:`MotionError` naming the argument (not ``ValueError``/``TypeError``,
nor a silently accepted ``seed=None``).
"""

from __future__ import annotations

import numpy as np
import pytest

import repro.checks
from repro.errors import MotionError
from repro.motion.database.augment import augment


@pytest.fixture(scope="module")
def base(synthetic_db):
    return synthetic_db.select(np.arange(2))


@pytest.mark.parametrize("factor", [10**9, 10**5, 10**30])
def test_huge_factor_is_refused_before_allocating(synthetic_db, factor):
    with pytest.raises(MotionError, match=rf"factor={factor} .* budget"):
        augment(synthetic_db, factor)  # 72 clips: 10**5 x would need about 250 GiB


def test_lowered_budget(base, monkeypatch):
    assert augment(base, 3).n_clips == 3 * base.n_clips
    monkeypatch.setattr(repro.checks, "MEMORY_BUDGET", 4096)
    with pytest.raises(MotionError, match="factor=3 .* budget"):
        augment(base, 3)


BAD = {
    "factor str": dict(factor="x"),
    "factor None": dict(factor=None),
    "factor nan": dict(factor=float("nan")),
    "factor float": dict(factor=2.0),
    "factor 0": dict(factor=0),
    "factor -1": dict(factor=-1),
    "factor complex": dict(factor=2j),
    "seed str": dict(seed="x"),
    "seed None": dict(seed=None),
    "seed -1": dict(seed=-1),
    "seed inf": dict(seed=float("inf")),
    "scale_range nan": dict(scale_range=(0.9, float("nan"))),
    "scale_range reversed": dict(scale_range=(1.1, 0.9)),
    "scale_range negative": dict(scale_range=(-1.0, 1.0)),
    "scale_range huge": dict(scale_range=(1.0, 1e300)),
    "scale_range str": dict(scale_range="ab"),
    "scale_range shape": dict(scale_range=(1.0, 1.1, 1.2)),
    "warp_range zero": dict(warp_range=(0.0, 1.0)),
    "warp_range None": dict(warp_range=None),
    "noise negative": dict(noise=-0.1),
    "noise nan": dict(noise=float("nan")),
    "noise str": dict(noise="0.01"),
    "mirror_probability 2": dict(mirror_probability=2.0),
    "mirror_probability None": dict(mirror_probability=None),
}


@pytest.mark.parametrize("kw", BAD.values(), ids=BAD.keys())
def test_bad_arguments(base, kw):
    kw = {"factor": 2, **kw}
    name = next(iter(k for k in kw if k != "factor"), "factor") if len(kw) > 1 else "factor"
    with pytest.raises(MotionError, match=rf"^{name}"):
        augment(base, **kw)


@pytest.mark.parametrize("db", ["db", None, 3, np.zeros(3)], ids=repr)
def test_not_a_database(db):
    with pytest.raises(MotionError, match="^db must be a MotionDatabase"):
        augment(db, 2)


def test_good_arguments_unchanged(base):
    a = augment(base, np.int64(3), seed=np.uint8(1), scale_range=[0.85, 1.15], warp_range=np.array([0.85, 1.15]))
    b = augment(base, 3, seed=1)
    assert a.equals(b) and a.n_clips == 3 * base.n_clips
    assert augment(base, 2, noise=0, mirror_probability=1).mirror[base.n_clips:].all()
