"""Atomic output: nothing a user had is lost, and no half-written file is left.

Every file repro writes goes to a temporary file in the destination folder and
is moved into place with :func:`os.replace` only once it is complete.  Every
file repro reads goes through :func:`read_bytes`, which names the path in its
errors and caps what a file (or a gzip stream) may make the reader hold.
Read-modify-write of a shared file is serialised with :func:`file_lock`.
"""

from __future__ import annotations

import contextlib
import gzip
import os
import tempfile
import zlib
from pathlib import Path

from repro.errors import DataError, ReproError

__all__ = [
    "atomic_path",
    "csv_text",
    "write_csv",
    "write_text",
    "save_figure",
    "read_bytes",
    "file_lock",
    "MAX_READ_BYTES",
]

#: Default cap on the bytes one input file may make a reader hold (after gzip is undone): 2 GiB.
MAX_READ_BYTES = 2 << 30
_CHUNK = 1 << 20


def read_bytes(src, *, error: type[ReproError] = DataError, max_bytes: int = MAX_READ_BYTES) -> tuple[bytes, str | None]:
    """Content of a path (``.gz`` undone, streamed with a cap) or of a stream, and its name.

    Every failure is raised as ``error`` naming the source: a missing file, a
    folder, no permission, a corrupt gzip stream, or more than ``max_bytes`` of
    content (checked while reading, so a gzip bomb never reaches memory).
    """
    if hasattr(src, "read"):
        name = getattr(src, "name", None)
        name = str(name) if isinstance(name, (str, os.PathLike)) else None
        where = name or "<stream>"
        try:
            data = src.read(max_bytes + 1)
        except (OSError, EOFError, zlib.error) as exc:
            raise error(f"{where} cannot be read: {exc}") from exc
        if isinstance(data, str):
            data = data.encode("utf-8")
        if len(data) > max_bytes:
            raise error(f"{where}: more than {max_bytes} bytes of content; refusing to read it")
        return bytes(data), name
    try:
        p = Path(src)
    except TypeError:
        raise error(f"expected a path or a readable stream, got {type(src).__name__}") from None
    try:
        if p.suffix == ".gz":
            opener = gzip.open
        else:
            opener = open
        with opener(p, "rb") as fh:
            chunks, total = [], 0
            while chunk := fh.read(_CHUNK):
                total += len(chunk)
                if total > max_bytes:
                    raise error(f"{p}: more than {max_bytes} bytes of content; refusing to read it")
                chunks.append(chunk)
    except FileNotFoundError:
        raise error(f"{p}: no such file") from None
    except IsADirectoryError:
        raise error(f"{p}: is a folder, not a file") from None
    except PermissionError:
        raise error(f"{p}: permission denied") from None
    except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise error(f"{p}: corrupt gzip stream ({exc})") from exc
    except OSError as exc:
        raise error(f"{p} cannot be read: {exc}") from exc
    return b"".join(chunks), str(p)


@contextlib.contextmanager
def file_lock(path):
    """Hold an exclusive advisory lock (``fcntl.flock``) on ``path`` + ``.lock`` while inside.

    Used around read-modify-write of a file several processes share (the figure
    manifest), so that concurrent writers merge instead of losing entries.
    """
    import fcntl

    lock = Path(str(path) + ".lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path, *, mode: int = 0o644):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def csv_text(table) -> str:
    """The CSV text repro writes for a pandas DataFrame (no index, stable float format)."""
    return table.to_csv(index=False, float_format="%.10g", lineterminator="\n")


def write_csv(path, table) -> Path:
    """Write a pandas DataFrame to ``path`` atomically, as :func:`csv_text`."""
    return write_text(path, csv_text(table))


def save_figure(path, figure, **kw) -> Path:
    """Save a matplotlib figure to ``path`` atomically (format from the suffix)."""
    path = Path(path)
    kw.setdefault("dpi", 120)
    kw.setdefault("metadata", {"Software": None})  # no version string: stable bytes across runs
    with atomic_path(path) as tmp:
        figure.savefig(tmp, format=path.suffix.lstrip(".") or "png", **kw)
    return path
