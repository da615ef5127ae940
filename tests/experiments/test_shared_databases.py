"""The figures' shared databases (repro.experiments.shared): built once, kept on disk by content hash, checked on load."""

from __future__ import annotations

import importlib
import warnings

import pytest

from repro.errors import CacheWarning
from repro.experiments import shared

augment_module = importlib.import_module("repro.motion.database.augment")  # (the package attribute is the function)


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
augment_module = importlib.import_module("repro.motion.database.augment")
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


# ------------------------------------------------------------------ issue 23: identity, special files, links, arguments
def _kept(factor):
    with shared.kept_on_disk():
        return shared.augmented_database("synthetic", factor, seed=0)


def _files(cache, factor):
    npz = next(cache.glob(f"synthetic-x{factor}-*.npz"))
    return npz, npz.with_suffix(".json")


def _rebuilt_with_warning(match, factor=2):
    with pytest.warns(CacheWarning, match=match):
        return _kept(factor)


def test_another_valid_cache_in_its_place_is_refused_even_with_its_sidecar_rewritten(cache):
    import json

    x2, x3 = _kept(2), _kept(3)
    npz2, side2 = _files(cache, 2)
    npz3, _ = _files(cache, 3)
    npz2.write_bytes(npz3.read_bytes())  # the x3 file for the x2, its sidecar made to match
    side2.write_text(json.dumps({"key": shared.database_key("synthetic", 2, 0), "sha256": shared._sha256(npz2)}))
    again = _rebuilt_with_warning("another database")
    assert again.equals(x2) and again.n_clips != x3.n_clips
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _kept(2).equals(x2)  # rewritten with its own identity


def test_a_cache_without_identity_is_not_trusted(cache):
    import json

    x2 = _kept(2)
    npz, side = _files(cache, 2)
    x2.save(npz)  # a layout-1 style archive: a valid database, no identity inside
    side.write_text(json.dumps({"key": shared.database_key("synthetic", 2, 0), "sha256": shared._sha256(npz)}))
    assert _rebuilt_with_warning("holds no identity").equals(x2)


def test_the_identity_names_every_input_and_the_layout_version():
    ident = shared.database_identity("synthetic", 2, 0)
    assert {"format", "base", "factor", "seed", "code", "numpy"} <= set(ident)
    assert ident["format"] == shared.FORMAT >= 2 and ident["factor"] == 2 and ident["seed"] == 0


def _finishes(fn, unblock):
    """``fn()`` in a thread, so that a regression (a read blocking on a FIFO) fails instead of hanging."""
    import threading

    out = {}
    t = threading.Thread(target=lambda: out.setdefault("v", fn()), daemon=True)
    t.start()
    t.join(120)
    if t.is_alive():
        unblock()
        pytest.fail("hangs on a FIFO in the cache")
    return out["v"]


@pytest.mark.parametrize("which", ["npz", "json"])
def test_a_fifo_in_place_of_a_cache_file_is_damage_not_a_hang(cache, which):
    import os

    x2 = _kept(2)
    npz, side = _files(cache, 2)
    target = npz if which == "npz" else side
    target.unlink()
    os.mkfifo(target)

    def unblock():
        os.close(os.open(target, os.O_WRONLY | os.O_NONBLOCK))

    with pytest.warns(CacheWarning, match="FIFO"):
        again = _finishes(lambda: _kept(2), unblock)
    assert again.equals(x2) and target.is_file()  # the FIFO replaced by the rebuilt file


def test_a_cache_linked_to_dev_zero_is_damage_not_an_endless_read(cache):
    x2 = _kept(2)
    npz, _ = _files(cache, 2)
    npz.unlink()
    npz.symlink_to("/dev/zero")
    with pytest.warns(CacheWarning, match="leads outside|character device"):
        again = _finishes(lambda: _kept(2), lambda: None)  # (before: the sha256 read never ended)
    assert again.equals(x2) and npz.is_file() and not npz.is_symlink()


def test_a_cache_member_linking_outside_the_cache_folder_is_refused_and_replaced(cache, tmp_path):
    import shutil

    x2 = _kept(2)
    npz, side = _files(cache, 2)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    for f in (npz, side):  # a valid copy outside, linked in: still not read from there
        shutil.copy(f, outside / f.name)
        f.unlink()
        f.symlink_to(outside / f.name)
    before = {f.name: f.read_bytes() for f in outside.iterdir()}
    assert _rebuilt_with_warning("leads outside").equals(x2)
    assert not npz.is_symlink() and npz.is_file()  # the link replaced, the file it named left alone
    assert {f.name: f.read_bytes() for f in outside.iterdir()} == before


def test_a_cache_subfolder_linking_outside_is_never_written_into(cache, tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    cache.parent.mkdir(parents=True)
    cache.symlink_to(outside)  # <cache>/motion -> elsewhere
    db = _rebuilt_with_warning("leads outside")
    assert db.n_clips == 2 * shared.augmented_database("synthetic", 1).n_clips
    assert list(outside.iterdir()) == []


@pytest.mark.parametrize("args, kw, match", [
    (("synthetic", "x"), {}, "factor must be an integer"),
    (("synthetic", 2.0), {}, "factor must be an integer"),
    (("synthetic", True), {}, "factor must be an integer"),
    (("synthetic", -3), {}, "factor must be an integer in 1"),
    (("synthetic", 0), {}, "factor must be an integer in 1"),
    (("synthetic", 2), {"seed": "x"}, "seed must be an integer"),
    (("synthetic", 2), {"seed": -1}, "seed must be an integer in 0"),
    (("synthetic", 2), {"seed": None}, "seed must be an integer"),
    ((None, 2), {}, "name .* must be a string"),
    ((["synthetic"], 2), {}, "name .* must be a string"),
    (("nope", 2), {}, "must be one of 'synthetic', 'cmu'"),
    (("synthetic", 2), {"use_cache": "no"}, "use_cache must be True or False"),
])
def test_arguments_are_checked_at_the_entry(cache, args, kw, match):
    from repro.errors import RetrievalError

    with pytest.raises(RetrievalError, match=match):
        shared.augmented_database(*args, **kw)
    if "use_cache" not in kw:  # the key (and the cache file name) is made from the same checked arguments
        with pytest.raises(RetrievalError):
            shared.database_key(*(args + (kw.get("seed", 0),))[:3])


@pytest.mark.parametrize("use_cache", [True, False])
def test_a_factor_past_the_memory_budget_is_refused_before_building(cache, monkeypatch, use_cache):
    from repro.errors import RetrievalError

    _no_build(monkeypatch)  # (augment is never reached)
    with pytest.raises(RetrievalError, match=r"factor=10000000.*budget"):
        shared.augmented_database("synthetic", 10**7, use_cache=use_cache)
    base = shared.augmented_database("synthetic", 1)
    assert shared.estimated_bytes(base, 10) > 10 * shared.estimated_bytes(base, 1) / 2


def test_a_symlink_loop_in_place_of_the_cache_is_replaced_not_an_error(cache):
    x2 = _kept(2)
    npz, side = _files(cache, 2)
    for f in (npz, side):
        f.unlink()
        f.symlink_to(f.name)  # a link to itself: resolving it raised RuntimeError (in the lock's path)
    again = _kept(2)
    assert again.equals(x2) and npz.is_file() and not npz.is_symlink() and not side.is_symlink()


def test_a_cache_folder_that_is_a_symlink_loop_is_no_cache(tmp_path, monkeypatch):
    (tmp_path / "loop").symlink_to("loop")
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "loop"))
    with shared.kept_on_disk():
        db = shared.augmented_database("synthetic", 2, seed=0)
    assert db.n_clips == 2 * shared.augmented_database("synthetic", 1).n_clips
