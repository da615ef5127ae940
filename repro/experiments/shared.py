"""Work shared between figures, built once and kept on disk by content hash (issue 15, item 6).

The augmented databases (10x, 100x: :func:`repro.motion.augment.augment` of a base database)
are pure functions of their inputs, and the retrieval figure, ``repro bench retrieval`` and
the notebooks build the same ones.  :func:`augmented_database` builds each once and keeps it
in :func:`repro.data.cache_dir` ``/motion`` as ``.npz`` (:meth:`MotionDatabase.save`: no
pickles, written atomically), named after the sha256 of everything it depends on: the base
database (the code for ``"synthetic"``, the dataset's registry sha256s for ``"cmu"``), the
factor, the seed, the source of the ``repro`` package and numpy's version.  A ``.json``
beside it records that key and the archive's sha256; both are checked on load (and
:meth:`MotionDatabase.load` checks the archive's structure), so a damaged, foreign or stale
file is rebuilt, with a :class:`~repro.errors.CacheWarning` when it was damaged.  Writers hold
a lock per file (:func:`repro.io.file_lock`) from reading to writing it, so two processes
needing the same database (``repro all --jobs``, two ``repro run``) build it once, and
neither sees the other's archive half-replaced beside an old ``.json``.

Writing costs about as much as building a 10x database (compressing it), so a cache file is
read wherever it exists but written only inside :func:`kept_on_disk` (``repro run`` / ``repro
all`` through :func:`repro.experiments.registry.run_many`): a figure computed from code or in
a notebook with an empty cache builds in memory and leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import warnings
from functools import lru_cache
from pathlib import Path

__all__ = ["augmented_database", "code_fingerprint", "database_key", "kept_on_disk"]

#: Version of the cache layout (part of every key).
FORMAT = 1
_WRITE = [False]


@contextlib.contextmanager
def kept_on_disk(on: bool = True):
    """Within: the databases :func:`augmented_database` builds are written to the cache too."""
    before, _WRITE[0] = _WRITE[0], bool(on)
    try:
        yield
    finally:
        _WRITE[0] = before


def source_fingerprint() -> str:
    """sha256 over every source file of the ``repro`` package (any code change invalidates)."""
    import repro

    root = Path(repro.__file__).parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*")):
        if f.suffix in (".py", ".csv") and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


#: :func:`source_fingerprint` once per process (the database cache keys on it)
code_fingerprint = lru_cache(maxsize=1)(source_fingerprint)


def database_key(name: str, factor: int, seed: int) -> str:
    """sha256 of everything ``augment(default_database(name), factor, seed=seed)`` depends on."""
    import numpy as np

    from repro import data

    inputs = {"format": FORMAT, "base": name, "factor": int(factor), "seed": int(seed), "code": code_fingerprint(),
              "numpy": np.__version__}
    if name == "cmu":
        inputs["data"] = sorted(f"{f.path} {f.sha256}" for f in data.files("cmu-bvh"))
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 22):
            h.update(chunk)
    return h.hexdigest()


def _load(path: Path, key: str):
    """The cached database, or None (absent); a damaged or mismatched file warns and gives None."""
    from repro.errors import CacheWarning, DataError
    from repro.io import read_bytes
    from repro.motion.database import MotionDatabase

    side = path.with_suffix(".json")
    if not path.exists() or not side.exists():
        return None
    try:
        rec = json.loads(read_bytes(side, max_bytes=1 << 16)[0])
        if not isinstance(rec, dict) or rec.get("key") != key:
            why = "made from other inputs"
        elif rec.get("sha256") != _sha256(path):
            why = "its sha256 is not the recorded one"
        else:
            return MotionDatabase.load(path)
    except (DataError, OSError, ValueError) as exc:
        why = str(exc)
    warnings.warn(f"database cache {path} is damaged ({why}); rebuilding it", CacheWarning, stacklevel=3)
    return None


def augmented_database(name: str = "synthetic", factor: int = 1, seed: int = 0, *, use_cache: bool = True):
    """``augment(default_database(name), factor, seed=seed)`` (the base itself for ``factor`` 1), from the cache.

    Read from the cache when it is there; else built, and saved to the cache inside
    :func:`kept_on_disk` (an unwritable cache folder only means no cache).
    ``use_cache=False`` builds without reading or writing it.  Each call returns its own
    database.
    """
    from repro.errors import DataError
    from repro.io import file_lock, write_text
    from repro.motion.augment import augment
    from repro.motion.sources import default_database

    if int(factor) == 1:
        return default_database(name)
    if not use_cache:
        return augment(default_database(name), factor, seed=seed)
    from repro import data

    key = database_key(name, factor, seed)
    path = data.cache_dir() / "motion" / f"{name}-x{int(factor)}-seed{int(seed)}-{key[:20]}.npz"
    with contextlib.ExitStack() as stack:
        if _WRITE[0]:  # writers (repro run / all, its --jobs workers, other processes) take turns per file:
            with contextlib.suppress(OSError):  # the second waits for the first and reads what it wrote
                stack.enter_context(file_lock(_lock_path(path)))
        db = _load(path, key)
        if db is not None:
            return db
        db = augment(default_database(name), factor, seed=seed)
        if not _WRITE[0]:
            return db
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            db.save(path)
            write_text(path.with_suffix(".json"), json.dumps({"key": key, "sha256": _sha256(path)}) + "\n")
        except (OSError, DataError):  # a cache folder that cannot be written: no cache
            pass
    return db


def _lock_path(path: Path) -> Path:
    """The lock of one cache file: in the temp folder, one per user and file (the cache folder holds only caches)."""
    from repro.io import lock_path

    return lock_path("database", path)
