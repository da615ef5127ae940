"""Atomic output: nothing a user had is lost, and no half-written file is left.

Every file repro writes goes to a temporary file in the destination folder and
is moved into place with :func:`os.replace` only once it is complete.  Every
file repro reads goes through :func:`open_regular` (directly or through
:func:`read_bytes`), which opens regular files only (never a FIFO, a device or a
folder, so nothing hangs or streams forever), knows the size before reading and
caps what a file (or a gzip stream) may make the reader hold.  A path that a
file or a user names (a glTF buffer, a dataset entry, a cache member) goes
through :func:`inside` first, which keeps it inside its folder after ``..`` and
symlinks are resolved.
Read-modify-write of a shared file is serialised with :func:`file_lock`.
An ``.npz`` archive from outside the process (a cache, a saved database) is read
with :func:`read_npz`, which checks every member's ``.npy`` header against the
archive before allocating anything.
"""

from __future__ import annotations

import contextlib
import errno
import gzip
import math
import os
import stat
import struct
import tempfile
import tokenize
import zipfile
import zlib
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path

from repro.errors import DataError, ReproError

__all__ = [
    "atomic_path",
    "csv_text",
    "write_csv",
    "write_text",
    "save_figure",
    "read_bytes",
    "read_npz",
    "open_regular",
    "inside",
    "file_kind",
    "file_lock",
    "lock_path",
    "remove_stale_temporary",
    "publish_hooks",
    "MAX_READ_BYTES",
]

#: Default cap on the bytes one input file may make a reader hold (after gzip is undone): 2 GiB.
MAX_READ_BYTES = 2 << 30
_CHUNK = 1 << 20


def file_kind(mode: int) -> str:
    """How a file of this ``st_mode`` is named in messages ("is a folder", "is a FIFO (named pipe)" ...)."""
    for test, name in ((stat.S_ISDIR, "is a folder"), (stat.S_ISFIFO, "is a FIFO (named pipe)"),
                       (stat.S_ISCHR, "is a character device"), (stat.S_ISBLK, "is a block device"),
                       (stat.S_ISSOCK, "is a socket")):
        if test(mode):
            return name
    return "is not a regular file"


def open_regular(path, *, error: type[ReproError] = DataError, max_bytes: int | None = MAX_READ_BYTES):
    """``path`` opened for binary reading if it is a regular file of at most ``max_bytes``, else ``error``.

    The file is opened with ``O_NONBLOCK`` (so opening a FIFO never waits for a writer) and
    checked with ``fstat`` on that descriptor (so a symlink swapped in between cannot
    change what is checked): a FIFO, a device (``/dev/zero``), a socket or a folder is
    refused, and its size is known before a byte is read.  ``max_bytes=None`` skips the
    size check (the caller bounds what it reads).  Returns ``(binary file object, size)``.
    """
    try:
        p = os.fspath(path)
    except TypeError:
        raise error(f"expected a path, got {type(path).__name__}") from None
    if isinstance(p, bytes):
        p = os.fsdecode(p)
    if "\x00" in p:
        raise error(f"{p!r}: a path cannot hold a NUL character")
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except OSError as exc:
        raise _open_error(p, exc, error) from (None if isinstance(exc, _PLAIN_OPEN_ERRORS) else exc)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{p}: {file_kind(st.st_mode)}, not a file; only regular files are read")
        if max_bytes is not None and st.st_size > max_bytes:
            raise error(f"{p}: {st.st_size} bytes, more than the {max_bytes} allowed; refusing to read it")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        fh = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    return fh, st.st_size


def inside(folder, name, *, error: type[ReproError] = DataError, what: str = "file") -> Path:
    """``folder / name`` with ``..`` and symlinks resolved, if it stays inside ``folder``; else ``error``.

    ``name`` is a relative path that a file or a user gave (a glTF buffer ``uri`` after
    percent-decoding, a dataset entry, a cache member): an absolute path, a NUL byte, or a
    path that leaves the folder (``../../etc/passwd``, or a symlink pointing out) is refused,
    naming ``what``.  Existence and kind are not checked here (:func:`open_regular` does).
    """
    if not isinstance(name, (str, os.PathLike)):
        raise error(f"{what} must be a path, got {type(name).__name__}")
    n = os.fspath(name)
    if isinstance(n, bytes):
        n = os.fsdecode(n)
    if "\x00" in n:
        raise error(f"{what} {n[:60]!r}: a path cannot hold a NUL character")
    if os.path.isabs(n) or n.startswith(("/", "\\")):
        raise error(f"{what} {n[:60]!r} is an absolute path; only paths relative to {folder} are allowed")
    base = Path(os.path.realpath(folder))
    target = Path(os.path.realpath(base / n))
    if target != base and base not in target.parents:
        raise error(f"{what} {n[:60]!r} leads outside its folder {base} (to {target}); refusing to read it")
    return target


def read_bytes(src, *, error: type[ReproError] = DataError, max_bytes: int = MAX_READ_BYTES) -> tuple[bytes, str | None]:
    """Content of a path (``.gz`` undone, streamed with a cap) or of a stream, and its name.

    Every failure is raised as ``error`` naming the source: a missing file, a
    folder, a FIFO or device (only regular files are opened, see :func:`open_regular`),
    no permission, a corrupt gzip stream, or more than ``max_bytes`` of content (the
    file's size is checked before reading, and a gzip stream's while reading, so a
    gzip bomb never reaches memory).
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
    gz = p.suffix == ".gz"
    raw, _ = open_regular(p, error=error, max_bytes=None if gz else max_bytes)
    try:
        with (gzip.GzipFile(fileobj=raw, mode="rb") if gz else raw) as fh, raw:
            chunks, total = [], 0
            while chunk := fh.read(_CHUNK):
                total += len(chunk)
                if total > max_bytes:
                    raise error(f"{p}: more than {max_bytes} bytes of content; refusing to read it")
                chunks.append(chunk)
    except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise error(f"{p}: corrupt gzip stream ({exc})") from exc
    except OSError as exc:
        raise _open_error(p, exc, error) from (None if isinstance(exc, _PLAIN_OPEN_ERRORS) else exc)
    return b"".join(chunks), str(p)


_PLAIN_OPEN_ERRORS = (FileNotFoundError, IsADirectoryError, PermissionError)


def _open_error(p, exc: OSError, error: type[ReproError]) -> ReproError:
    """The caller's ``error`` for a file that cannot be opened or read, naming the path."""
    if isinstance(exc, FileNotFoundError):
        return error(f"{p}: no such file")
    if isinstance(exc, IsADirectoryError):
        return error(f"{p}: is a folder, not a file")
    if isinstance(exc, PermissionError):
        return error(f"{p}: permission denied")
    return error(f"{p} cannot be read: {exc}")


#: dtype kinds :func:`read_npz` returns when ``allow`` is not given (no objects, no structured records).
NPZ_KINDS = "biufcUS"
#: Largest expansion deflate can achieve (1032:1), plus slack for a member's framing.
_DEFLATE_RATIO = 1032
_DEFLATE_SLACK = 1 << 12
#: What zipfile, zlib and numpy's ``.npy`` header parser raise on a damaged archive.
_NPZ_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, zlib.error, struct.error,
               ValueError, TypeError, SyntaxError, KeyError, OverflowError, RecursionError,
               NotImplementedError, RuntimeError, tokenize.TokenError, UnicodeDecodeError)


def read_npz(
    src,
    *,
    error: type[ReproError] = DataError,
    allow: Mapping[str, str] | None = None,
    required: Iterable[str] | None = None,
    finite: bool = True,
    max_bytes: int = MAX_READ_BYTES,
) -> dict:
    """The arrays of an ``.npz`` archive (``numpy.savez`` / ``savez_compressed``), checked before allocating.

    A safe replacement for ``numpy.load(path, allow_pickle=False)`` on a file that
    may be damaged, truncated, foreign or hostile: nothing is allocated that the
    archive does not actually hold, and every failure is one ``error`` naming the
    file (and the member).

    Parameters
    ----------
    src : str, os.PathLike or binary file object
        The archive: a path, or a seekable binary stream (read from its start).
    error : ReproError subclass, default DataError
        The exception raised for every problem (e.g. ``MotionError``, ``ModelError``).
    allow : mapping of member name to dtype kinds, optional
        E.g. ``{"f0": "f", "faces": "iu", "names": "U"}`` (``numpy.dtype.kind`` codes:
        ``b`` bool, ``i``/``u`` integers, ``f`` float, ``c`` complex, ``U`` text, ``S``
        bytes).  Only these members are read (others are skipped unread), and a member
        of another kind is an error.  Default: every member, of any kind in
        :data:`NPZ_KINDS`.
    required : iterable of member names, optional
        Members that must be present.  Default: every name of ``allow`` (none when
        ``allow`` is not given); pass ``()`` to make them all optional.
    finite : bool, default True
        Float and complex members must hold no NaN or inf.
    max_bytes : int
        Cap on the sum of the members' decompressed sizes (default :data:`MAX_READ_BYTES`).

    Returns
    -------
    dict of str to numpy.ndarray
        Member names without ``.npy``, in archive order; fresh, writable arrays
        (not memory-mapped), in the byte order stored.

    Raises
    ------
    ``error``
        Naming the file (and member): no such file, a folder, no permission; not a
        zip archive, truncated, a bad CRC, an encrypted member or one compressed
        other than stored/deflate, duplicate names, a member that is not ``.npy``;
        a ``.npy`` header that is unreadable, of an unsupported version, an object
        (pickle) or structured dtype, or a shape whose size (``prod(shape) x
        itemsize``) is not what the member holds (checked before anything is
        allocated: a 200-byte lie claiming 10**10 items is refused); a member of a
        kind ``allow`` does not list, a missing ``required`` member, NaN/inf
        (``finite``), or more than ``max_bytes`` in all.

    Memory is bounded by what the archive holds (:func:`_npz_member`); cost: one pass over the
    decompressed bytes, as ``numpy.load``.
    """
    fh, own, where = _npz_source(src, error)
    try:
        out = _npz_arrays(fh, where, error, allow, finite, max_bytes)
    finally:
        if own:
            fh.close()
    need = list(allow or ()) if required is None else list(required)
    missing = [k for k in need if k not in out]
    if missing:
        raise error(f"{where}: no {missing} in the archive (it has {sorted(out) or 'no arrays'})")
    return out


def _npz_source(src, error):
    """The archive as (binary file, whether it is ours to close, its name for messages)."""
    if hasattr(src, "read"):
        return src, False, str(getattr(src, "name", "<stream>"))
    try:
        p = Path(src)
    except TypeError:
        raise error(f"expected a path or a binary stream, got {type(src).__name__}") from None
    fh, _ = open_regular(p, error=error, max_bytes=None)  # (each member's size is bounded below)
    return fh, True, str(p)


def _npz_arrays(fh, where, error, allow, finite, max_bytes) -> dict:
    """The members ``allow`` names (every member without it), in archive order, within ``max_bytes`` in all;
    any failure of the zip or numpy readers as one ``error`` naming the file and member."""
    import numpy as np
    from numpy.lib import format as npy

    out: dict = {}
    member = None
    budget = max_bytes
    try:
        disk = fh.seek(0, os.SEEK_END)
        fh.seek(0)
        with zipfile.ZipFile(fh) as z:
            infos = z.infolist()
            dup = sorted(n for n, c in Counter(i.filename for i in infos).items() if c > 1)
            if dup:
                raise error(f"{where}: duplicate archive members {dup[:5]}")
            for info in infos:
                member = info.filename
                if not member.endswith(".npy"):
                    raise error(f"{where}: member {member!r} is not an .npy array (not a numpy .npz archive?)")
                key = member[:-4]
                if allow is not None and key not in allow:
                    continue
                budget -= info.file_size  # (checked before the member is read)
                if budget < 0:
                    raise error(f"{where}: more than {max_bytes} bytes of arrays; refusing to read it")
                out[key] = _npz_member(z, info, disk, where, error, allow, finite, np, npy)
            member = None
    except ReproError:
        raise
    except MemoryError:
        raise error(f"{where}{_in(member)}: not enough memory to read it") from None
    except _NPZ_ERRORS as exc:
        msg = str(exc)[:200] if not isinstance(exc, RecursionError) else "nested too deeply"
        raise error(f"{where}{_in(member)}: not a readable .npz archive ({type(exc).__name__}: {msg})") from None
    return out


def _in(member) -> str:
    return f", member {member!r}" if member else ""


def _npz_member(z, info, disk, where, error, allow, finite, np, npy):
    """One ``.npy`` member of an open archive, every size checked before it is read.

    Memory is bounded by what the archive holds: the member's declared size is checked against
    its compressed size (deflate expands at most 1032:1; a stored member holds exactly its size),
    and data is read in chunks, so a lying ``ZipInfo.file_size`` ends in an error, not an allocation.
    """
    name = info.filename
    key = name[:-4]
    at = f"{where}, member {name!r}"
    if info.flag_bits & 0x1:
        raise error(f"{at}: encrypted")
    if info.compress_type == zipfile.ZIP_STORED:
        if info.file_size != info.compress_size:
            raise error(f"{at}: stored member of {info.file_size} bytes holds {info.compress_size}")
    elif info.compress_type == zipfile.ZIP_DEFLATED:
        if info.file_size > _DEFLATE_RATIO * info.compress_size + _DEFLATE_SLACK:
            raise error(f"{at}: claims {info.file_size} bytes from {info.compress_size} compressed (not possible)")
    else:
        raise error(f"{at}: compression method {info.compress_type} (expected stored or deflate, as numpy writes)")
    if info.header_offset + info.compress_size > disk:
        raise error(f"{at}: extends past the end of the file ({disk} bytes; truncated?)")
    with z.open(info) as fp:
        version = npy.read_magic(fp)
        if version == (1, 0):
            shape, fortran, dtype = npy.read_array_header_1_0(fp)
        elif version == (2, 0):
            shape, fortran, dtype = npy.read_array_header_2_0(fp)
        else:
            raise error(f"{at}: .npy format version {version} (expected 1.0 or 2.0)")
        if dtype.hasobject or dtype.fields is not None or dtype.subdtype is not None:
            raise error(f"{at}: dtype {dtype} (objects, records and sub-arrays are refused)")
        kinds = NPZ_KINDS if allow is None else allow[key]
        if dtype.kind not in kinds:
            raise error(f"{at}: dtype {dtype}, expected kind {' or '.join(repr(k) for k in kinds)}")
        if not all(isinstance(n, int) and n >= 0 for n in shape) or len(shape) > 32:
            raise error(f"{at}: bad shape {shape!r} in the .npy header")
        nbytes = math.prod(shape) * dtype.itemsize
        header = fp.tell()
        if header + nbytes != info.file_size:
            raise error(f"{at}: the .npy header claims shape {shape} of {dtype} ({nbytes} bytes), "
                        f"the member holds {info.file_size - header} bytes of data")
        buf = bytearray()
        while len(buf) < nbytes:
            chunk = fp.read(min(_CHUNK, nbytes - len(buf)))
            if not chunk:
                raise error(f"{at}: data ends after {len(buf)} of {nbytes} bytes (truncated?)")
            buf += chunk
        if fp.read(1):  # (also makes zipfile check the CRC)
            raise error(f"{at}: more data than its .npy header says")
    count = math.prod(shape)
    a = np.frombuffer(buf, dtype=dtype, count=count) if count else np.empty(0, dtype=dtype)
    a = a.reshape(shape[::-1]).T if fortran else a.reshape(shape)
    if finite and dtype.kind in "fc" and not np.isfinite(a).all():
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise error(f"{at}: NaN or inf at index {list(idx)} (value {a[idx]!r})")
    return a


def lock_path(kind: str, target) -> Path:
    """Where the lock (for :func:`file_lock`) of ``target`` lives: the temp folder, one per user,
    kind and resolved target (so that the folders the locks guard hold only their own files)."""
    import hashlib
    import tempfile

    key = hashlib.sha256(str(Path(target).resolve()).encode()).hexdigest()[:20]
    return Path(tempfile.gettempdir()) / f"repro-{os.getuid()}" / f"{kind}-{key}"


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


#: Called as ``hook(tmp, path)`` just before :func:`atomic_path` moves a finished temporary into place;
#: a hook may refuse by raising (the temporary is then removed).  The worker processes of ``repro run
#: --jobs`` install one that publishes nothing once their parent is gone (issue 23, section 1).
publish_hooks: list = []


@contextlib.contextmanager
def atomic_path(path, *, mode: int = 0o644, replace: bool = True):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically.

    With ``replace=False`` an existing ``path`` is never clobbered: the finished file is
    hard-linked into place, which fails atomically with :class:`FileExistsError` if the
    name exists (also when it appeared while the file was being written); on a
    filesystem without hard links it is moved into place after an existence check.
    The temporary is ``.NAME.XXXXXXXX.tmp``, locked (``flock``) while it is written, so that
    one left by a killed writer can be told from one being written (:func:`remove_stale_temporary`).
    """
    import fcntl

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            # still ours? (a cleaner may have taken it for stale between its creation and the lock)
            if os.path.samestat(os.fstat(fd), os.stat(tmp)):
                break
        except FileNotFoundError:
            pass
        except OSError:  # no flock here (some network filesystems): unlocked, as before
            break
        os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode)
        for hook in list(publish_hooks):
            hook(Path(tmp), path)
        if replace:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)  # atomic and never clobbers
            except FileExistsError:
                raise
            except OSError:  # a filesystem without hard links
                if path.exists():
                    raise FileExistsError(errno.EEXIST, "target exists", str(path)) from None
                os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.close(fd)  # (after the unlink: the lock is held until the name is gone)


def remove_stale_temporary(tmp) -> bool:
    """Remove ``tmp``, a temporary of :func:`atomic_path`, when no process is writing it; whether it was.

    Its writer holds an ``flock`` on it until it is moved into place: a free lock means the
    writer died (killed in the middle).  A temporary being written, a symlink or anything
    but a regular file is left alone.
    """
    import fcntl

    try:
        if not stat.S_ISREG(os.lstat(tmp).st_mode):  # (a device is not even opened)
            return False
        fd = os.open(tmp, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # being written (or no flock here: then it cannot be told, so kept)
            return False
        # (mkstemp's names are unique, so the name still is this file; a writer that created it but has
        # not locked it yet waits for this lock, then finds its name gone and makes another)
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        return True
    finally:
        os.close(fd)


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
