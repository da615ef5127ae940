"""Atomic output: nothing a user had is lost, and no half-written file is left.

Every file repro writes goes to a temporary file in the destination folder and
is moved into place with :func:`os.replace` only once it is complete.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

__all__ = ["atomic_path", "csv_text", "write_csv", "write_text", "save_figure"]


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
