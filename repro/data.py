"""The data layer: every real dataset repro uses, known by public URL and sha256.

The registry (``repro/data_registry.csv``) lists each file by its path relative
to the data folder, the sha256 of its *uncompressed* content and the public URL
that serves that content.  The data folder is ``$REPRO_DATA_DIR`` (tests and CI
point it at the staged copy in ``../shared/data``), else pooch's per-user cache.

A file may sit in the data folder as itself or gzip-compressed beside it
(``name.gz``, as the staged copy stores it); either way its content is checked
against the registry's sha256 before use.  A missing file is downloaded with
:func:`pooch.retrieve` (which writes to a temporary file and moves it into place
only when the hash matches), unless downloads are off (``REPRO_OFFLINE=1``) or
the file has no public original.  A file that fails its check is never
overwritten: it is reported, and the user decides.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import io
import logging
import os
import stat
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from repro.checks import as_bool, as_names, as_path, as_str, describe
from repro.errors import DataError
from repro.io import MAX_READ_BYTES, file_kind, inside, open_regular

__all__ = [
    "DataFile",
    "DATASETS",
    "registry",
    "data_dir",
    "cache_dir",
    "locate",
    "cache_file",
    "cache_writable",
    "content_sha256",
    "fetch",
    "open_file",
    "status",
    "require",
    "missing_reason",
    "DATA_CHOICES",
    "DataChoice",
    "choose",
]

#: What each dataset is and where its licence and provenance live.
DATASETS: dict[str, str] = {
    "ict": "ICT Face Model (ICT-FaceKit, MIT): neutral + 57 expression shapes, 26,719 vertices",
    "cmu-bvh": "CMU mocap, subject 135 karate + walks of others, as BVH (converted from cmu-asfamc)",
    "cmu-asfamc": "CMU mocap originals (ASF skeletons, AMC motions) the BVH files were converted from",
    "bandai": "Bandai Namco Research Motiondataset (CC BY-NC 4.0): five clips, another skeleton",
}

_FOLDER = {
    "ict": "faces/ict",
    "cmu-bvh": "mocap/cmu",
    "cmu-asfamc": "mocap/cmu/source",
    "bandai": "mocap/bandai",
}


@dataclass(frozen=True)
class DataFile:
    """One registered file: where it lives, its content hash and its public URL."""

    dataset: str
    path: str  #: relative to the data folder, uncompressed name
    sha256: str  #: of the uncompressed content (what ``url`` serves)
    url: str  #: public original, or "" when there is none

    @property
    def how_to_get(self) -> str:
        """One sentence telling a user how to obtain this file."""
        if self.url:
            return (
                f"run `repro data fetch {self.dataset}` (downloads {self.url}), or set "
                f"REPRO_DATA_DIR to a folder holding {self.path} (or {self.path}.gz)"
            )
        return (
            f"{self.path} has no public original (it was converted from "
            f"{'cmu-asfamc' if self.dataset == 'cmu-bvh' else 'another dataset'}); set "
            f"REPRO_DATA_DIR to a folder holding the staged copy (see {_FOLDER[self.dataset]}/PROVENANCE.md)"
        )


@lru_cache(maxsize=1)
def registry() -> dict[str, DataFile]:
    """All registered files, keyed by relative path."""
    text = resources.files("repro").joinpath("data_registry.csv").read_text()
    rows = csv.DictReader(io.StringIO(text))
    return {r["path"]: DataFile(r["dataset"], r["path"], r["sha256"], r["url"]) for r in rows}


def files(dataset: str) -> list[DataFile]:
    """The registered files of one dataset."""
    as_str(dataset, "dataset", error=DataError)
    if dataset not in DATASETS:
        raise DataError(f"unknown dataset {dataset!r}; known: {sorted(DATASETS)}")
    return [f for f in registry().values() if f.dataset == dataset]


def data_dir() -> Path:
    """The data folder: ``$REPRO_DATA_DIR`` or pooch's per-user cache for repro."""
    env = os.environ.get("REPRO_DATA_DIR")
    if env:  # (realpath: a symlink loop is left as it is, and reported when a file is looked up)
        return Path(os.path.realpath(Path(env).expanduser()))
    import pooch

    return Path(pooch.os_cache("repro"))


def cache_dir() -> Path:
    """Folder for derived caches (never the data folder): ``$REPRO_CACHE_DIR``, else
    ``pooch.os_cache("repro") / "derived"``.  The ICT arrays and the figures' shared databases live here."""
    env = os.environ.get("REPRO_CACHE_DIR")
    if env:  # (realpath: a symlink loop is left as it is: no cache, not an error)
        return Path(os.path.realpath(Path(env).expanduser()))
    import pooch

    return Path(pooch.os_cache("repro")) / "derived"


def cache_file(name) -> Path:
    """The path of cache member ``name`` (relative, e.g. ``"motion/x.npz"``) inside :func:`cache_dir`.

    The cache folder itself may be a symlink (the user chose it); inside it, ``..`` and
    symlinks are resolved and a member (or a sub-folder) that leads outside the folder is
    refused with :class:`~repro.errors.DataError`, so a cache is never read from, nor written
    through, a link to elsewhere.  Callers treat that as a damaged cache (a
    :class:`~repro.errors.CacheWarning`, built in memory; see :func:`cache_writable`).
    """
    return inside(cache_dir(), name, error=DataError, what="cache file")


def cache_writable(name) -> bool:
    """Whether cache member ``name`` may be (re)written: its folder stays inside :func:`cache_dir`.

    The member itself may be a symlink or a special file (an atomic write replaces the link
    or the FIFO with a regular file, never writes through it); a sub-folder that is a symlink
    leading outside the cache folder is never written into.
    """
    if not isinstance(name, (str, os.PathLike)):
        raise DataError(f"cache file must be a path, got {describe(name)}")
    parent = os.path.dirname(os.fsdecode(os.fspath(name))) or "."
    try:
        inside(cache_dir(), parent, error=DataError, what="cache folder")
    except DataError:
        return False
    return True


def _offline() -> bool:
    return os.environ.get("REPRO_OFFLINE", "").strip().lower() not in ("", "0", "false", "no")


def _entry(path: str) -> DataFile:
    as_str(path, "data file path", error=DataError)
    try:
        return registry()[path]
    except KeyError:
        raise DataError(f"{path!r} is not a registered data file") from None


def locate(path: str, root: Path | None = None) -> Path | None:
    """The file on disk for registered ``path`` (itself or ``path.gz``), or None.

    ``path`` is relative to the data folder (``root``, default :func:`data_dir`) and must
    stay inside it once ``..`` and symlinks are resolved (:func:`repro.io.inside`): a path
    leading out (``../../etc/passwd``, an absolute path, a symlink pointing elsewhere) is a
    :class:`~repro.errors.DataError`, as is something there that is not a regular file (a
    FIFO, a device, a folder).  Returns the resolved path.
    """
    as_str(path, "data file path", error=DataError)
    if root is None:
        root = data_dir()
    else:
        root = as_path(root, "root (the data folder)", error=DataError)
    for name in (path, path + ".gz"):
        candidate = inside(root, name, error=DataError, what="data file")
        try:
            mode = os.stat(candidate).st_mode
        except (FileNotFoundError, NotADirectoryError):  # absent (or below a file): missing
            continue
        except OSError as exc:
            raise DataError(f"{candidate} cannot be read: {exc}") from exc
        if not stat.S_ISREG(mode):
            raise DataError(f"{candidate}: {file_kind(mode)}, not a file; only regular files are read")
        return candidate
    return None


class _ClosingGzip(gzip.GzipFile):
    """A gzip reader that closes the file it reads from (``GzipFile(fileobj=...)`` leaves it open)."""

    def close(self) -> None:
        raw = self.fileobj
        try:
            super().close()
        finally:
            if raw is not None:
                raw.close()


def _open_raw(p: Path, *, max_bytes: int | None = MAX_READ_BYTES):
    """``p`` opened for reading (a regular file only, :func:`repro.io.open_regular`; ``.gz`` undone)
    and its size on disk.  ``max_bytes`` bounds the size on disk of a plain file (the caller bounds
    what it decompresses from a ``.gz``)."""
    gz = Path(p).suffix == ".gz"
    fh, size = open_regular(p, error=DataError, max_bytes=None if gz else max_bytes)
    fh.raw.name = str(p)  # (os.fdopen names the file by its descriptor; messages name the path)
    return (_ClosingGzip(fileobj=fh, mode="rb") if gz else fh), size


@lru_cache(maxsize=512)
def _content_sha256(p: str, size: int, mtime_ns: int) -> str:
    # keyed on (path, size, mtime) so a file is hashed once per process unless it changes.
    # Only a regular file is opened (a FIFO or /dev/zero would never end), at most the size fstat
    # gave is read from a plain file, and at most MAX_READ_BYTES are decompressed from a .gz.
    h = hashlib.sha256()
    gz = Path(p).suffix == ".gz"
    fh, n = _open_raw(Path(p), max_bytes=MAX_READ_BYTES)
    left = MAX_READ_BYTES if gz else n
    try:
        with fh:
            while chunk := fh.read(min(1 << 20, left + 1)):
                left -= len(chunk)
                if left < 0:
                    raise DataError(f"{p}: more than {MAX_READ_BYTES if gz else n} bytes of content "
                                    f"({'decompressed' if gz else 'its size when opened'}); refusing to hash it")
                h.update(chunk)
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise DataError(f"{p} cannot be read: {exc}") from exc
    return h.hexdigest()


def content_sha256(p: Path) -> str:
    """sha256 of a file's content, decompressing ``.gz`` files.

    Regular files only (:func:`repro.io.open_regular`): a FIFO, a device or a folder is a
    :class:`~repro.errors.DataError`, as is a file that grows while read or a ``.gz`` holding
    more than :data:`repro.io.MAX_READ_BYTES`.
    """
    p = as_path(p, "the file to hash", error=DataError)
    try:
        st = p.stat()
    except OSError as exc:
        raise DataError(f"{p}: {'no such file' if isinstance(exc, FileNotFoundError) else exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise DataError(f"{p}: {file_kind(st.st_mode)}, not a file; only regular files are read")
    return _content_sha256(str(p), st.st_size, st.st_mtime_ns)


def _verified(entry: DataFile, p: Path) -> Path:
    got = content_sha256(p)
    if got != entry.sha256:
        raise DataError(
            f"{p} fails its sha256 check (expected {entry.sha256}, got {got}). "
            f"It was left untouched; delete it to download a fresh copy, or restore it."
        )
    return p


def fetch(path: str, *, download: bool | None = None, progressbar: bool = False) -> Path:
    """Path of the verified local copy of registered file ``path``.

    Looks in :func:`data_dir` for ``path`` or ``path.gz`` and checks its
    content hash.  When absent it downloads the public original with pooch
    (unless ``download`` is False or ``REPRO_OFFLINE`` is set); pooch writes to
    a temporary file and moves it into place only after the hash matched.

    Raises
    ------
    DataError
        The file is missing and cannot be downloaded (the message says how to
        get it), the download failed, or a file's hash does not match.
    """
    entry = _entry(path)
    if download is not None:
        download = as_bool(download, "download", error=DataError)
    progressbar = as_bool(progressbar, "progressbar", error=DataError)
    root = data_dir()
    found = locate(path, root)
    if found is not None:
        return _verified(entry, found)
    if download is None:
        download = not _offline()
    if not download or not entry.url:
        why = "downloads are off (REPRO_OFFLINE)" if entry.url and not download else "it is not there"
        raise DataError(f"{path} is missing from {root} and {why}: {entry.how_to_get}")
    return _download(entry, entry.url, root, progressbar=progressbar)


def _download(entry: DataFile, url: str, root: Path, *, progressbar: bool = False) -> Path:
    import pooch

    target = inside(root, entry.path, error=DataError, what="data file")  # (a registry row cannot write elsewhere)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with _quiet_pooch(not progressbar):
            got = pooch.retrieve(
                url,
                known_hash=f"sha256:{entry.sha256}",
                fname=target.name,
                path=target.parent,
                progressbar=_plain_bar() if progressbar else False,
            )
    except ValueError as exc:  # pooch's hash mismatch
        raise DataError(f"download of {entry.path} from {url} was rejected: {exc}") from exc
    except Exception as exc:  # network, HTTP status, permissions
        raise DataError(f"download of {entry.path} from {url} failed: {exc}") from exc
    return Path(got)


@contextmanager
def _quiet_pooch(quiet: bool):
    """pooch logs "Downloading data from ..." on stderr at INFO: silent unless progress was asked for.

    (A first-use download must not change what a notebook cell prints.)
    """
    if not quiet:
        yield
        return
    import pooch

    # a filter, not setLevel: pooch's logger lives outside logging's hierarchy, so a level
    # change would stick in its isEnabledFor cache after being undone
    def below_warning(record):
        return record.levelno >= logging.WARNING

    logger = pooch.get_logger()
    logger.addFilter(below_warning)
    try:
        yield
    finally:
        logger.removeFilter(below_warning)


def _plain_bar():
    """A plain tqdm byte counter on stderr for pooch (pooch's own would be a notebook widget in Jupyter)."""
    import sys

    from tqdm import tqdm

    return tqdm(total=1, ncols=79, ascii=True, unit="B", unit_scale=True, leave=True, file=sys.stderr)


def open_file(path: str):
    """A binary file object with the verified content of ``path`` (gzip undone; a regular file only)."""
    return _open_raw(fetch(path))[0]


def status(dataset: str) -> dict:
    """Presence and verification of a dataset's files (for ``repro data list``)."""
    entries = files(dataset)
    present = verified = 0
    problems: list[str] = []
    for e in entries:
        try:
            p = locate(e.path)
        except DataError as exc:  # something there, but refused (a link leading out, a FIFO ...)
            present += 1
            problems.append(str(exc))
            continue
        if p is None:
            continue
        present += 1
        try:
            _verified(e, p)
            verified += 1
        except DataError as exc:
            problems.append(str(exc))
    return {
        "dataset": dataset,
        "files": len(entries),
        "present": present,
        "verified": verified,
        "downloadable": all(e.url for e in entries),
        "problems": problems,
    }


def missing_reason(dataset: str) -> str | None:
    """None when every file of ``dataset`` is present, else why not and how to get it.

    Only presence is checked here (cheap); :func:`fetch` verifies hashes on use.
    """
    as_str(dataset, "dataset", error=DataError)
    if dataset in _switched_off:
        return (f"dataset {dataset!r} is switched off in this process (DATA = 'embedded', "
                f"repro.data.choose); choose('auto') uses it again")
    missing = [e for e in files(dataset) if locate(e.path) is None]
    if not missing:
        return None
    return (
        f"dataset {dataset!r} is not in {data_dir()} ({len(missing)} of {len(files(dataset))} "
        f"files missing, e.g. {missing[0].path}); {missing[0].how_to_get}"
    )


def require(dataset: str, *, download: bool | None = None, progressbar: bool = False) -> Path:
    """Fetch (verify or download) every file of ``dataset``; its folder in :func:`data_dir`."""
    entries = files(dataset)
    if download is not None:
        download = as_bool(download, "download", error=DataError)
    progressbar = as_bool(progressbar, "progressbar", error=DataError)
    it: Iterator[DataFile] = iter(entries)
    if progressbar:
        import sys

        from tqdm import tqdm  # plain, on stderr (the CLI's bar; never a notebook widget)

        it = tqdm(entries, desc=f"data {dataset}", unit="file", file=sys.stderr)
    for e in it:
        fetch(e.path, download=download)
    return data_dir() / _FOLDER[dataset]


# ------------------------------------------------------------------ what a notebook runs on
#: The values of a notebook's ``DATA`` parameter (see :func:`choose`).
DATA_CHOICES = ("auto", "embedded", "real")
#: The embedded stand-in for each real dataset a notebook may use.
EMBEDDED = {"ict": "the procedural 2,016-vertex face", "cmu-bvh": "the synthetic kung-fu database"}
#: Datasets switched off in this process by ``choose("embedded")`` (:func:`missing_reason` reports them absent).
_switched_off: set[str] = set()


@dataclass(frozen=True)
class DataChoice:
    """What a notebook runs on, as :func:`choose` resolved it."""

    requested: str  #: the ``DATA`` parameter: "auto", "embedded" or "real"
    real: tuple  #: the real datasets in use (present and not switched off)
    embedded: tuple  #: the datasets replaced by their embedded stand-in
    message: str  #: one line saying so, for the notebook to print

    @property
    def mode(self) -> str:
        """``"real"`` (every dataset asked for is real), ``"embedded"`` (none is) or ``"mixed"``."""
        return "embedded" if not self.real else "mixed" if self.embedded else "real"

    @property
    def face(self) -> str:
        """The face model to load: ``"ict"`` when its data is in use, else ``"procedural"``."""
        return "ict" if "ict" in self.real else "procedural"

    @property
    def database(self) -> str:
        """The motion database to build: ``"cmu"`` when its takes are in use, else ``"synthetic"``."""
        return "cmu" if "cmu-bvh" in self.real else "synthetic"

    def uses(self, dataset: str) -> bool:
        """Whether the real ``dataset`` is in use (the notebook shows its real-data sections)."""
        return dataset in self.real

    def __str__(self) -> str:
        return self.message


def choose(choice: str = "auto", needs=("ict", "cmu-bvh")) -> DataChoice:
    """Resolve a notebook's ``DATA`` parameter against what is in the data folder.

    ``needs``: the real datasets the notebook's real-data sections use.

    - ``"auto"``: each dataset of ``needs`` that is present is used, the others are
      replaced by their embedded stand-in (:data:`EMBEDDED`);
    - ``"embedded"``: the embedded data only, even where real data is present: the
      datasets of ``needs`` are switched off in this process, so that
      :func:`missing_reason` reports them absent and every figure computed afterwards
      runs on the embedded data alone;
    - ``"real"``: every dataset of ``needs`` must be present, else one :class:`DataError`
      saying what is missing and how to get it.

    Each call replaces the previous call's switch.  Raises :class:`DataError` for a value
    that is none of :data:`DATA_CHOICES`.
    """
    if not isinstance(choice, str) or choice.strip().lower() not in DATA_CHOICES:
        raise DataError(f"DATA = {choice!r} is not a known choice; expected one of "
                        f"{', '.join(repr(c) for c in DATA_CHOICES)}")
    choice = choice.strip().lower()
    needs = as_names(needs, "needs", error=DataError, nonempty=False, item="a dataset name")
    for name in needs:
        if name not in DATASETS:
            raise DataError(f"unknown dataset {name!r}; known: {sorted(DATASETS)}")
    _switched_off.clear()
    if choice == "embedded":
        real, embedded = (), needs
        _switched_off.update(needs)
    else:
        missing = {n: missing_reason(n) for n in needs}
        missing = {n: r for n, r in missing.items() if r is not None}
        if choice == "real" and missing:
            raise DataError(f"DATA = 'real' but {len(missing)} of the {len(needs)} datasets this notebook needs "
                            f"{'is' if len(missing) == 1 else 'are'} missing: " + "; ".join(missing.values())
                            + ". Use DATA = 'auto' or 'embedded' to run on the embedded data.")
        real = tuple(n for n in needs if n not in missing)
        embedded = tuple(n for n in needs if n in missing)
    return DataChoice(choice, real, embedded, _choice_message(choice, real, embedded))


def _choice_message(choice: str, real: tuple, embedded: tuple) -> str:
    if not real and not embedded:
        return "Data: this notebook uses only embedded data."
    parts = [f"real: {_SHORT.get(n, n)}" for n in real]
    parts += [f"embedded: {EMBEDDED.get(n, n)} instead of {_SHORT.get(n, n)}" for n in embedded]
    why = ""
    if embedded:
        why = (" (DATA = 'embedded')" if choice == "embedded" else
               " (not in the data folder; `repro data fetch` or REPRO_DATA_DIR brings it, and the real-data sections)")
    return "Data: " + "; ".join(parts) + why + "."


_SHORT = {"ict": "the ICT Face Model", "cmu-bvh": "the CMU karate takes (subject 135)",
          "cmu-asfamc": "the CMU ASF/AMC originals", "bandai": "the Bandai Namco clips"}
