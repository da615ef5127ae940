"""MotionDatabase.save/load ``identity`` (issue 23, 5): a file says what it is, inside its hashed content,
and ``load(..., identity=...)`` refuses another database put in its place."""

from __future__ import annotations

import math

import numpy as np
import pytest

from repro.errors import DataError, MotionError
from repro.motion.database.clips import MotionDatabase


@pytest.fixture(scope="module")
def small(synthetic_db):
    return synthetic_db.select(np.arange(3))


ID = {"base": "synthetic", "factor": 10, "seed": 0, "format": 2}


def test_identity_round_trip_and_mismatch(small, tmp_path):
    p = small.save(tmp_path / "a.npz", identity=ID)
    assert MotionDatabase.load(p, identity=ID).equals(small)
    assert MotionDatabase.load(p).equals(small)  # no identity asked: read as any database
    with pytest.raises(DataError, match=r"another database .*\['factor'\]"):
        MotionDatabase.load(p, identity=dict(ID, factor=20))
    q = small.save(tmp_path / "b.npz")  # saved without identity
    with pytest.raises(DataError, match="holds no identity"):
        MotionDatabase.load(q, identity=ID)
    assert MotionDatabase.load(q).equals(small)


@pytest.mark.parametrize("bad", [["x"], "factor=10", {"x": math.nan}, {"x": object()}])
def test_an_identity_that_is_not_a_json_object_is_refused(small, tmp_path, bad):
    with pytest.raises(MotionError, match="identity"):
        small.save(tmp_path / "a.npz", identity=bad)
    assert not (tmp_path / "a.npz").exists()


def test_load_checks_its_arguments(small, tmp_path):
    p = small.save(tmp_path / "a.npz")
    with pytest.raises(DataError, match="identity must be a mapping"):
        MotionDatabase.load(p, identity=["x"])
    for bad in ("10", None, -1, 1.5):
        with pytest.raises(DataError, match="max_bytes must be an integer"):
            MotionDatabase.load(p, max_bytes=bad)
