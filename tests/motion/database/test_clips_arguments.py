"""MotionDatabase's clip accessors and ``select`` check their arguments (issue 23, sections 5-6).

What is asserted: ``motion``, ``clip``, ``trajectory``, ``poses_of`` and
``actor_skeleton`` take a clip index in ``0..C-1`` (numpy integers too) and refuse
with a :class:`MotionError` naming the argument everything else -- ``-1`` (which
silently answered the last clip), ``10**6`` (an ``IndexError``), floats, strings,
``None``, NaN, arrays; ``select`` takes a boolean mask of length C or distinct
indices in range, and refuses ``[0.5]`` (which silently selected clip 0), ``[-1]``,
``[10**6]``, a mask of another length, repeats, an empty selection and non-numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError
from repro.motion.database.clips import Clip


@pytest.fixture(scope="module")
def small(synthetic_db):
    punch = np.flatnonzero(synthetic_db.semantics == "punch")[:2]
    kick = np.flatnonzero(synthetic_db.semantics == "kick")[:2]
    return synthetic_db.select(np.concatenate([punch, kick]))


BAD_INDICES = [-1, -4, 4, 10**6, 10**30, 0.5, 1.0, float("nan"), float("inf"), "0", "x", None, 1j, True,
               np.zeros(0), np.array([0, 1]), [0], np.float64(2.0)]
ACCESSORS = ["motion", "clip", "trajectory", "poses_of", "actor_skeleton"]


@pytest.mark.parametrize("method", ACCESSORS)
@pytest.mark.parametrize("i", BAD_INDICES, ids=repr)
def test_bad_clip_index(small, method, i):
    with pytest.raises(MotionError, match=r"^i \(a clip index"):
        getattr(small, method)(i)


@pytest.mark.parametrize("method", ACCESSORS)
def test_good_clip_index(small, method):
    last = small.n_clips - 1
    a, b = getattr(small, method)(np.int64(last)), getattr(small, method)(last)
    if method == "motion":
        assert a is b and a.n_frames == small.n_frames[last]
    elif method == "clip":
        assert a.name == b.name == small.names[last]
    elif method in ("trajectory", "poses_of"):
        assert np.array_equal(a, b) and len(a) == small.n_frames[last]


BAD_MASKS = {
    "float index": [0.5],
    "negative index": [-1],
    "index too large": [10**6],
    "int64 overflow": [2**70],
    "repeated index": [1, 1],
    "empty list": [],
    "no clip": np.zeros(4, dtype=bool),
    "short mask": [True, False],
    "long mask": [True] * 5,
    "string": "01",
    "strings": ["a"],
    "None": None,
    "nan": [float("nan")],
    "scalar": 0,
    "2-D": [[0, 1]],
    "ragged": [[0], [1, 2]],
    "complex": [1j],
}


@pytest.mark.parametrize("mask", BAD_MASKS.values(), ids=BAD_MASKS.keys())
def test_bad_select(small, mask):
    with pytest.raises(MotionError, match=r"^mask"):
        small.select(mask)


def test_good_select(small):
    assert list(small.select([3, 1]).names) == [small.names[3], small.names[1]]  # the order given
    assert small.select(np.array([2], dtype=np.uint8)).names[0] == small.names[2]
    kicks = small.select(small.semantics == "kick")
    assert set(kicks.semantics) == {"kick"} and kicks.n_clips == int(np.sum(small.semantics == "kick"))
    assert small.select(np.arange(small.n_clips)).equals(small.select(np.ones(small.n_clips, dtype=bool)))


def test_manifest_fifo_does_not_hang(synthetic_dir, tmp_path):
    """A FIFO in place of the manifest is refused, not opened (open() waited for a writer forever)."""
    import os
    import shutil

    from repro.motion.database.sources import build_database
    from repro.motion.database.synthetic import read_manifest

    d = tmp_path / "db"
    shutil.copytree(synthetic_dir, d)
    (d / "manifest.csv").unlink()
    os.mkfifo(d / "manifest.csv")
    with pytest.raises(MotionError, match="manifest.csv"):
        build_database(d)
    with pytest.raises(MotionError, match="manifest.csv"):
        read_manifest(d / "manifest.csv")


def test_manifest_files_stay_in_their_folder(synthetic_dir, tmp_path):
    """A manifest row naming ../outside.bvh is refused (repro.io.inside), not read."""
    import shutil

    from repro.motion.database.sources import build_database

    d = tmp_path / "db"
    shutil.copytree(synthetic_dir, d)
    text = (d / "manifest.csv").read_text().splitlines()
    first = text[1].split(",")[0]
    shutil.copy(d / first, tmp_path / "outside.bvh")
    text[1] = text[1].replace(first, "../outside.bvh", 1)
    (d / "manifest.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(MotionError, match="leads outside"):
        build_database(d)


def test_clip_hit_segment_and_joint_names(small):
    m = small.motion(0)
    ok = dict(name="c", motion=m, semantics="punch", hit_role="right_fist", hit_joint=str(small.hit_joints[0]),
              hit_where="joint", hit_frame=1)
    Clip(**ok)
    for bad in (dict(hit_role="nose"), dict(hit_role=None), dict(hit_joint="NoSuchJoint"), dict(hit_joint=3),
                dict(side="middle"), dict(hit_frame=1.5), dict(hit_frame="1"), dict(name=""), dict(motion=None),
                dict(semantics=None)):
        with pytest.raises(MotionError):
            Clip(**{**ok, **bad})
