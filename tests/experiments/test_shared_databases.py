"""The figures' shared databases (repro.experiments.shared): built once, kept on disk by content hash, checked on load."""

from __future__ import annotations

import importlib
import warnings

import pytest

from repro.errors import CacheWarning
from repro.experiments import shared

augment_module = importlib.import_module("repro.motion.augment")  # (the package attribute is the function)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "motion"


def _no_build(monkeypatch):
    def fail(*a, **k):
        raise AssertionError("built again instead of read from the cache")

    monkeypatch.setattr(augment_module, "augment", fail)


def test_built_once_then_read_back_equal(cache, monkeypatch):
    shared.augmented_database("synthetic", 2, seed=0)
    assert not cache.exists(), "written only inside kept_on_disk (repro run / all)"
    with shared.kept_on_disk():
        first = shared.augmented_database("synthetic", 2, seed=0)
    files = sorted(p.suffix for p in cache.iterdir())
    assert files == [".json", ".npz"]
    assert shared.database_key("synthetic", 2, 0)[:20] in next(cache.glob("*.npz")).name
    with monkeypatch.context() as m:
        _no_build(m)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            again = shared.augmented_database("synthetic", 2, seed=0)
    assert again.equals(first) and again is not first
    assert again.equals(augment_module.augment(shared.augmented_database("synthetic", 1), 2, seed=0))


def test_the_key_names_every_input():
    keys = {shared.database_key("synthetic", 2, 0), shared.database_key("synthetic", 3, 0),
            shared.database_key("synthetic", 2, 1)}
    assert len(keys) == 3 and shared.database_key("synthetic", 2, 0) == shared.database_key("synthetic", 2, 0)


def test_a_damaged_cache_is_rebuilt_with_a_warning(cache):
    with shared.kept_on_disk():
        first = shared.augmented_database("synthetic", 2, seed=0)
    npz = next(cache.glob("*.npz"))
    raw = bytearray(npz.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    npz.write_bytes(bytes(raw))
    with pytest.warns(CacheWarning, match="sha256 is not the recorded one"), shared.kept_on_disk():
        again = shared.augmented_database("synthetic", 2, seed=0)
    assert again.equals(first)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert shared.augmented_database("synthetic", 2, seed=0).equals(first)  # rewritten whole


def test_an_unwritable_cache_folder_is_no_cache(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "file"))
    with shared.kept_on_disk():
        db = shared.augmented_database("synthetic", 2, seed=0)
    assert db.n_clips == 2 * shared.augmented_database("synthetic", 1).n_clips


def test_the_base_database_is_not_cached(cache):
    with shared.kept_on_disk():
        assert shared.augmented_database("synthetic", 1).n_clips > 0
    assert not cache.exists()


_BUILDER = """
import importlib, sys, time, warnings
from pathlib import Path
warnings.simplefilter("error")  # a half-replaced file seen as damaged would warn
from repro.experiments import shared
augment_module = importlib.import_module("repro.motion.augment")
real = augment_module.augment
def counted(*a, **k):
    Path(sys.argv[1], f"built-{sys.argv[2]}").write_text("")
    return real(*a, **k)
augment_module.augment = counted
Path(sys.argv[1], f"ready-{sys.argv[2]}").write_text("")
while not Path(sys.argv[1], "go").exists():
    time.sleep(0.005)
with shared.kept_on_disk():
    db = shared.augmented_database("synthetic", 3, seed=0)
print(db.n_clips)
"""


def test_two_processes_needing_one_database_build_it_once(cache, tmp_path):
    """``repro all --jobs`` workers (or two ``repro run``) asking for the same database at once: one builds
    and writes it, the other waits and reads it (the lock in :func:`shared.augmented_database`)."""
    import subprocess
    import sys
    import time

    procs = [subprocess.Popen([sys.executable, "-c", _BUILDER, str(tmp_path), tag], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for tag in "ab"]
    deadline = time.monotonic() + 120
    while not all((tmp_path / f"ready-{t}").exists() for t in "ab"):
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs), [p.communicate() for p in procs]
        time.sleep(0.01)
    (tmp_path / "go").write_text("")
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    assert outs[0][0] == outs[1][0]
    assert len(list(tmp_path.glob("built-*"))) == 1
    assert sorted(p.suffix for p in cache.iterdir()) == [".json", ".npz"]
