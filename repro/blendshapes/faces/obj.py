"""Wavefront OBJ meshes read with their vertex identity kept (the ICT Face Model's files).

A blendshape model needs vertex ``i`` of every expression to be vertex ``i`` of the
neutral (Lewis et al. 2005, Section 3).  General mesh loaders (e.g. ``trimesh.load``)
split vertices along UV seams and material groups (ICT's 26,719 become 27,081 or more),
which would break that correspondence, so :func:`read_obj` reads the ``v`` and ``f``
lines directly.
"""

from __future__ import annotations

import re

import numpy as np

from repro.errors import DataError, ModelError
from repro.io import read_bytes

__all__ = ["read_obj"]


def _err(source: str, line: int, what: str) -> ModelError:
    return ModelError(f"{source}, line {line}: {what}")


def read_obj(stream_or_path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of a Wavefront OBJ, keeping vertex identity.

    Only ``v`` and ``f`` statements are used; ``vt``, ``vn``, ``usemtl``,
    ``mtllib``, ``g``, ``o``, ``s``, comments and any other statement are
    ignored.  A face token ``v/vt/vn`` (or ``v//vn``, ``v/vt``) contributes its
    first index only, so vertices are never split along UV seams or material
    boundaries -- the property a blendshape model needs, since vertex ``i`` of
    every expression must be vertex ``i`` of the neutral (Lewis et al. 2005,
    Section 3).

    Parameters
    ----------
    stream_or_path : path-like or file object
        A file name (``.gz`` files are decompressed) or an open binary (or
        text) stream.

    Returns
    -------
    vertices : (n, 3) float64 array
        The ``v`` lines in file order (a fourth ``w`` or trailing vertex colours
        are ignored).
    faces : (F, 3) int64 array
        0-based triangles.  OBJ indices are 1-based; negative indices count back
        from the last vertex defined before the face; polygons with ``k > 3``
        corners are fan-triangulated from their first corner into ``k - 2``
        triangles ``(c0, c_j, c_{j+1})``, in file order.

    Raises
    ------
    ModelError
        The file has no vertices, a vertex with fewer than 3 (or non-numeric,
        NaN or infinite) coordinates, a number with ``_`` (Python reads ``1_0``
        as 10; OBJ does not), a face with fewer than 3 corners, a face
        index that is not an integer, is 0 or is out of range, or a line
        continuation (``\\``); the message names the source and the 1-based line
        number.
    DataError
        The file is missing, a folder, unreadable, a damaged gzip stream or
        holds more than :data:`repro.io.MAX_READ_BYTES`; the message names it.

    Notes
    -----
    Parsing is vectorised: lines are selected by their first token and all
    numbers of a kind are converted by one :func:`numpy.array` call; a
    line-by-line pass runs only to locate an error.  About 0.05-0.1 s for a
    2.5 MB ICT mesh.
    """
    # path-named DataError for a missing file, a folder, no permission, a damaged gzip
    # stream or more than repro.io.MAX_READ_BYTES of content (checked while reading)
    raw, name = read_bytes(stream_or_path, error=DataError)
    return _parse_obj(raw, name or "<stream>")


def _parse_obj(raw: bytes, source: str) -> tuple[np.ndarray, np.ndarray]:
    if b"\r" in raw:
        raw = raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"\t" in raw:
        raw = raw.replace(b"\t", b" ")
    lines = raw.split(b"\n")
    vi: list[int] = []
    fi: list[int] = []
    for i, line in enumerate(lines):
        if line[:1] == b" ":
            line = lines[i] = line.lstrip()
        head = line[:2]
        if head == b"v " or line == b"v":
            vi.append(i)
        elif head == b"f " or line == b"f":
            fi.append(i)
        else:
            continue
        if line.rstrip()[-1:] == b"\\":
            raise _err(source, i + 1, "line continuations ('\\') are not supported")
    if not vi:
        raise ModelError(f"{source}: no vertices ('v' lines)")
    vertices = _parse_vertices(lines, vi, source)
    faces = _parse_faces(lines, vi, fi, len(vertices), source)
    return vertices, faces


def _no_underscores(joined: bytes, bodies: list[bytes], index: list[int], source: str) -> None:
    """float() and int() read '1_0' as 10; OBJ numbers have no '_' (one scan of the joined lines)."""
    if b"_" in joined:
        k = next(k for k, b in enumerate(bodies) if b"_" in b)
        tok = next(t for t in bodies[k].split() if b"_" in t)
        raise _err(source, index[k] + 1, f"{tok.decode(errors='replace')[:40]!r} is not an OBJ number ('_' in it)")


def _parse_vertices(lines: list[bytes], vi: list[int], source: str) -> np.ndarray:
    bodies = [lines[i][1:] for i in vi]
    joined = b" ".join(bodies)
    _no_underscores(joined, bodies, vi, source)
    counts = np.fromiter((len(b.split()) for b in bodies), dtype=np.int64, count=len(bodies))
    V = None
    if (counts == 3).all():
        try:
            V = np.array(joined.split(), dtype=np.float64).reshape(-1, 3)
        except ValueError:
            V = None  # locate the bad line below
    if V is None:
        V = np.empty((len(vi), 3))
        for row, (i, body) in enumerate(zip(vi, bodies)):
            parts = body.split()
            if len(parts) not in (3, 4, 6, 7):
                raise _err(
                    source, i + 1,
                    f"a vertex needs 3 coordinates (x y z [w] [r g b]), got {len(parts)}",
                )
            for axis, tok in enumerate(parts[:3]):
                try:
                    V[row, axis] = float(tok)
                except ValueError:
                    raise _err(
                        source, i + 1, f"coordinate {'xyz'[axis]} {tok.decode(errors='replace')!r} is not a number"
                    ) from None
            for tok in parts[3:]:
                try:
                    float(tok)
                except ValueError:
                    raise _err(source, i + 1, f"field {tok.decode(errors='replace')!r} is not a number") from None
    bad = ~np.isfinite(V)
    if bad.any():
        row, axis = np.argwhere(bad)[0]
        raise _err(source, vi[row] + 1, f"coordinate {'xyz'[axis]} is {V[row, axis]} (NaN/inf)")
    return V


_SLASH_TAIL = re.compile(rb"/\S*")


def _parse_faces(lines: list[bytes], vi: list[int], fi: list[int], nv: int, source: str) -> np.ndarray:
    if not fi:
        return np.zeros((0, 3), dtype=np.int64)
    bodies = [lines[i][1:] for i in fi]
    counts = np.fromiter((len(b.split()) for b in bodies), dtype=np.int64, count=len(bodies))
    short = np.flatnonzero(counts < 3)
    if short.size:
        k = short[0]
        raise _err(source, fi[k] + 1, f"a face needs at least 3 vertices, got {counts[k]}")
    joined = b" ".join(bodies)
    _no_underscores(joined, bodies, fi, source)
    idx = None
    try:
        idx = np.array(_SLASH_TAIL.sub(b"", joined).split(), dtype=np.int64)
    except (ValueError, OverflowError):
        pass
    if idx is None or idx.size != counts.sum():
        for i, body in zip(fi, bodies):
            for tok in body.split():
                first = tok.split(b"/", 1)[0]
                try:
                    int(first)
                except ValueError:
                    raise _err(
                        source, i + 1, f"face index {tok.decode(errors='replace')!r} is not an integer"
                    ) from None
        raise ModelError(f"{source}: cannot parse the face lines")  # pragma: no cover
    # vertices defined before each face line, for negative (relative) indices
    before = np.repeat(np.searchsorted(np.asarray(vi), np.asarray(fi)), counts)
    resolved = np.where(idx > 0, idx - 1, before + idx)
    bad = (idx == 0) | (resolved < 0) | (resolved >= nv)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        poly = int(np.searchsorted(np.cumsum(counts), k, side="right"))
        raise _err(
            source, fi[poly] + 1,
            f"face index {idx[k]} is out of range (vertices are 1..{nv}, "
            f"or -1..-{before[k]} counting back from this line)",
        )
    starts = np.cumsum(counts) - counts
    ntri = counts - 2
    poly = np.repeat(np.arange(counts.size), ntri)
    j = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    first = starts[poly]
    return np.stack(
        [resolved[first], resolved[first + j], resolved[first + j + 1]], axis=1
    ).astype(np.int64)
