"""Work shared between figures, built once and kept on disk by content hash (issue 15, item 6).

The augmented databases (10x, 100x: :func:`repro.motion.database.augment.augment` of a base database)
are pure functions of their inputs, and the retrieval figure, ``repro bench retrieval`` and
the notebooks build the same ones.  :func:`augmented_database` builds each once and keeps it
in :func:`repro.data.cache_dir` ``/motion`` as ``.npz`` (:meth:`MotionDatabase.save`: no
pickles, written atomically), named after the sha256 of everything it depends on: the base
database (the code for ``"synthetic"``, the dataset's registry sha256s for ``"cmu"``), the
factor, the seed, the source of the ``repro`` package and numpy's version.  A ``.json``
beside it records that key and the archive's sha256, and the archive carries those inputs
itself (its ``identity``, :func:`database_identity`), so that another valid cache put in its
place (the x20 file for the x10, its ``.json`` rewritten) is refused: all are checked on load
(and :meth:`MotionDatabase.load` checks the archive's structure), so a damaged, foreign or stale
file is rebuilt, with a :class:`~repro.errors.CacheWarning` when it was damaged.  Only regular
files inside the cache folder are read (a FIFO, a device or a link leading outside is damage,
never a hang or a read elsewhere).  Writers hold
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
from functools import lru_cache
from pathlib import Path

__all__ = ["augmented_database", "code_fingerprint", "database_identity", "database_key", "estimated_bytes",
           "kept_on_disk"]

#: Version of the cache layout (part of every key and identity; 2: the identity inside the archive,
#: so caches of layout 1, which lack it, are rebuilt rather than trusted).
FORMAT = 2
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
    from repro.io import read_bytes

    root = Path(repro.__file__).parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*")):
        if f.suffix in (".py", ".csv") and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(root)).encode())
            h.update(read_bytes(f)[0])  # (regular files only, bounded: as every read of the library)
    return h.hexdigest()


#: :func:`source_fingerprint` once per process (the database cache keys on it)
code_fingerprint = lru_cache(maxsize=1)(source_fingerprint)


def database_identity(name: str, factor: int, seed: int) -> dict:
    """Everything ``augment(default_database(name), factor, seed=seed)`` depends on, as a JSON object.

    The cache's key is its sha256 (:func:`database_key`), and a cache file carries it inside
    its archive (:meth:`MotionDatabase.save` ``identity``), checked against the request on load.
    """
    import numpy as np

    from repro import data

    name, factor, seed = _checked(name, factor, seed)
    inputs = {"format": FORMAT, "base": name, "factor": factor, "seed": seed, "code": code_fingerprint(),
              "numpy": np.__version__}
    if name == "cmu":
        inputs["data"] = sorted(f"{f.path} {f.sha256}" for f in data.files("cmu-bvh"))
    return inputs


def database_key(name: str, factor: int, seed: int) -> str:
    """sha256 of everything ``augment(default_database(name), factor, seed=seed)`` depends on."""
    return hashlib.sha256(json.dumps(database_identity(name, factor, seed), sort_keys=True).encode()).hexdigest()


#: The bases :func:`augmented_database` knows (:func:`repro.motion.database.sources.default_database`).
BASES = ("synthetic", "cmu")
#: Largest seed accepted (numpy's generators take any int >= 0; the seed is part of a file name).
MAX_SEED = 2**63 - 1


def _checked(name, factor, seed) -> tuple[str, int, int]:
    from repro.checks import as_choice, as_int, as_str
    from repro.errors import RetrievalError

    as_str(name, "name (the base database)", error=RetrievalError)
    as_choice(name, "name (the base database)", BASES, error=RetrievalError)
    factor = as_int(factor, "factor", lo=1, error=RetrievalError)
    seed = as_int(seed, "seed", lo=0, hi=MAX_SEED, error=RetrievalError)
    return name, factor, seed


def _sha256(path: Path) -> str:
    """sha256 of a cache file: a regular file only (a FIFO or a link to /dev/zero is a DataError,
    never a hang), at most the size ``fstat`` gave when it was opened."""
    from repro import checks
    from repro.io import open_regular

    fh, size = open_regular(path, max_bytes=max(checks.MEMORY_BUDGET, 1))
    h = hashlib.sha256()
    with fh:
        left = size
        while left > 0 and (chunk := fh.read(min(1 << 22, left))):
            h.update(chunk)
            left -= len(chunk)
    return h.hexdigest()


def _load(npz: Path, side: Path, identity: dict, key: str):
    """The cached database, or None (absent); a damaged or mismatched file warns and gives None.

    ``npz`` and ``side`` are the archive and its ``.json`` as resolved inside the cache folder.
    Damaged: a sidecar or archive that is not a regular file (a FIFO, a device), a sidecar
    naming other inputs or another sha256, or an archive whose own identity is not the
    request's (another valid cache put in its place, its sidecar rewritten to match).
    """
    from repro import checks
    from repro.errors import DataError
    from repro.io import read_bytes
    from repro.motion.database.clips import MotionDatabase

    if not npz.exists() or not side.exists():
        return None
    try:
        rec = json.loads(read_bytes(side, max_bytes=1 << 16)[0])
        if not isinstance(rec, dict) or rec.get("key") != key:
            why = "made from other inputs"
        elif rec.get("sha256") != _sha256(npz):
            why = "its sha256 is not the recorded one"
        else:
            return MotionDatabase.load(npz, identity=identity, max_bytes=max(checks.MEMORY_BUDGET, 1))
    except (DataError, OSError, ValueError, RecursionError) as exc:
        why = str(exc)
    _warn(f"database cache {npz} is damaged ({why}); rebuilding it")
    return None


def _warn(message: str, stacklevel: int = 4) -> None:
    """A CacheWarning pointing at the caller of :func:`augmented_database` (from :func:`_load`: 4)."""
    import warnings

    from repro.errors import CacheWarning

    warnings.warn(message, CacheWarning, stacklevel=stacklevel)


def estimated_bytes(base, factor: int) -> int:
    """Bytes ``augment(base, factor)`` holds: the base's per-clip and per-pose arrays ``factor`` times,
    with the headroom of the longest time warp (``augment``'s buffers are sized for it)."""
    import numpy as np

    per_copy = sum(a.nbytes for a in vars(base).values() if isinstance(a, np.ndarray))
    return int(per_copy * factor * 1.15) + per_copy


def augmented_database(name: str = "synthetic", factor: int = 1, seed: int = 0, *, use_cache: bool = True):
    """``augment(default_database(name), factor, seed=seed)`` (the base itself for ``factor`` 1), from the cache.

    Read from the cache when it is there; else built, and saved to the cache inside
    :func:`kept_on_disk` (an unwritable cache folder only means no cache).
    ``use_cache=False`` builds without reading or writing it.  Each call returns its own
    database.

    Every argument is checked first (:class:`~repro.errors.RetrievalError`: ``name`` one of
    :data:`BASES`, ``factor`` an integer >= 1, ``seed`` an integer in 0..:data:`MAX_SEED`,
    ``use_cache`` a bool), and what the build will allocate (:func:`estimated_bytes`) against
    :data:`repro.checks.MEMORY_BUDGET` before building.

    The cache files live in :func:`repro.data.cache_dir` ``/motion``; a file (or the
    ``motion`` folder) that is a symlink leading outside the cache folder is refused
    (:func:`repro.data.cache_file`): a :class:`~repro.errors.CacheWarning`, and the database is
    built.  It is then written only where that stays inside the cache folder (a link in place
    of the file is replaced by the file; a ``motion`` folder linking outside is not written into).
    """
    from repro import data
    from repro.checks import as_bool, check_alloc
    from repro.errors import DataError, RetrievalError
    from repro.io import file_lock, write_text
    from repro.motion.database.augment import augment
    from repro.motion.database.sources import default_database

    name, factor, seed = _checked(name, factor, seed)
    use_cache = as_bool(use_cache, "use_cache", error=RetrievalError)
    if factor == 1:
        return default_database(name)

    def build():
        base = default_database(name)
        check_alloc(estimated_bytes(base, factor), f"augmented_database(factor={factor}) (the {name} database "
                    f"of {base.n_clips} clips, {factor} times)", error=RetrievalError)
        return augment(base, factor, seed=seed)

    if not use_cache:
        return build()
    identity = database_identity(name, factor, seed)
    key = database_key(name, factor, seed)
    stem = f"motion/{name}-x{factor}-seed{seed}-{key[:20]}"
    path = data.cache_dir() / f"{stem}.npz"  # where it is written (a link there is replaced, not followed)
    try:  # where it is read: inside the cache folder once `..` and symlinks are resolved
        npz, side = data.cache_file(f"{stem}.npz"), data.cache_file(f"{stem}.json")
    except DataError as exc:
        npz = side = None
        _warn(f"database cache {path} is refused ({exc}); building the database", stacklevel=3)
    with contextlib.ExitStack() as stack:
        if _WRITE[0]:  # writers (repro run / all, its --jobs workers, other processes) take turns per file:
            # the second waits for the first and reads what it wrote (no lock when the cache folder is a
            # symlink loop, which resolving raises RuntimeError for: then there is no cache either)
            with contextlib.suppress(OSError, RuntimeError):
                stack.enter_context(file_lock(_lock_path(path)))
        db = None if npz is None else _load(npz, side, identity, key)
        if db is not None:
            return db
        db = build()
        if not _WRITE[0] or not data.cache_writable(f"{stem}.npz"):
            return db
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            db.save(path, identity=identity)
            write_text(path.with_suffix(".json"), json.dumps({"key": key, "sha256": _sha256(path)}) + "\n")
        except (OSError, DataError):  # a cache folder that cannot be written: no cache
            pass
    return db


def _lock_path(path: Path) -> Path:
    """The lock of one cache file: in the temp folder, one per user and file (the cache folder holds only caches).

    Keyed on the cache folder and the file's name, never on what the file resolves to: a
    symlink (even a loop) in place of the cache file cannot change or break its lock.
    """
    from repro import data
    from repro.io import lock_path

    return lock_path(f"database-{path.stem}", data.cache_dir())
