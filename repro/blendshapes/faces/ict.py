"""The real ICT Face Model as a delta blendshape model (Lewis et al. 2005, Section 3).

The ICT Face Model (ICT-FaceKit, USC Institute for Creative Technologies,
Vision and Graphics Lab, https://github.com/ICT-VGL/ICT-FaceKit, commit
``da5f95a6``) is a public, production-style face rig: a neutral mesh
``generic_neutral_mesh.obj`` (26,719 vertices, 26,384 quads and triangles) and
57 expression shapes (ARKit-style names such as ``browDown_L``, stored as full
meshes with the neutral's vertex order and polygons).  :func:`load_ict` turns it
into a :class:`~repro.blendshapes.model.BlendshapeModel` with
``D = [S_k - f0]``, the delta form of Section 3 of the paper, in centimetres
(+y up, the face looks toward +z, +x is the subject's own left, so ``_L``
shapes move the +x side).

Licence: MIT, "Copyright (c) 2020 USC Institute for Creative Technologies"; the
``LICENSE`` file travels with the staged data (``faces/ict/LICENSE`` in the data
folder).  Provenance (source commit, per-file sha256, the sub-mesh vertex
ranges, reference displacement statistics and the mapping of the paper's
sliders to ICT shapes) is in ``faces/ict/PROVENANCE.md`` beside the data.

Reading
-------
Each mesh is read by :func:`~repro.blendshapes.faces.obj.read_obj`, which keeps vertex
identity (general mesh loaders split vertices along UV seams).

Caching
-------
Parsing the 58 OBJs (about 150 MB of text) takes a few seconds, so the
assembled arrays are cached in an ``.npz`` file in ``$REPRO_CACHE_DIR`` (else
``pooch.os_cache("repro") / "derived"``), named after the registry sha256s of
the files used; the data folder itself is never written to.  The file records
those sha256s and a sha256 of its arrays, both checked when it is loaded; a
damaged cache is rebuilt with a :class:`~repro.errors.CacheWarning`.  A cache
file is read only as a regular file inside the cache folder (a FIFO, a device or a
link leading elsewhere in its place is damage, never a hang or a read elsewhere),
and its identity (format, source sha256s, shape names) is inside the checked
content, so another valid cache put in its place is refused.  The cache is
used only beside the data it came from: without the data files, a leftover
cache is ignored and loading fails as a first build would.  The model
is also kept in memory per process (see :func:`load_ict`).  :func:`read_cache`
reads and checks one cache file (through :func:`repro.io.read_npz`: no member is
allocated before its ``.npy`` header is checked against the archive) and says
what is wrong with a damaged one.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from repro import data
from repro.blendshapes.faces.obj import read_obj
from repro.blendshapes.model import BlendshapeModel
from repro.checks import as_bool, as_names, describe
from repro.errors import CacheWarning, DataError, ModelError
from repro.io import atomic_path, read_npz

__all__ = [
    "load_ict",
    "ict_regions",
    "cache_dir",
    "read_cache",
    "ICT_SHAPES",
    "ICT_SLIDERS",
    "ICT_NEUTRAL",
    "ICT_N_VERTICES",
    "ICT_N_TRIANGLES",
    "FACE_AREA",
    "SUBMESHES",
]

#: Name (file stem) of the neutral mesh.
ICT_NEUTRAL = "generic_neutral_mesh"

#: The 57 expression shapes, in upstream order: the 53 ``"expressions"`` of
#: ``vertex_indices.json`` in their order, then the four further shape files of
#: the same folder that list omits (``cheekRaiser_L/R``, ``PupilDilate_L/R``).
ICT_SHAPES: tuple[str, ...] = tuple(
    shape
    for stem in (
        "browDown_", "browInnerUp_", "browOuterUp_", "cheekPuff_", "cheekSquint_", "eyeBlink_", "eyeLookDown_",
        "eyeLookIn_", "eyeLookOut_", "eyeLookUp_", "eyeSquint_", "eyeWide_", "jawForward", "jawLeft", "jawOpen",
        "jawRight", "mouthClose", "mouthDimple_", "mouthFrown_", "mouthFunnel", "mouthLeft", "mouthLowerDown_",
        "mouthPress_", "mouthPucker", "mouthRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower",
        "mouthShrugUpper", "mouthSmile_", "mouthStretch_", "mouthUpperUp_", "noseSneer_", "cheekRaiser_", "PupilDilate_",
    )  # a stem ending in "_" is a pair of shapes, the subject's left (_L) then right (_R)
    for shape in ((stem + "L", stem + "R") if stem.endswith("_") else (stem,))
)  # fmt: skip

#: Vertex count of the neutral and of every shape.
ICT_N_VERTICES = 26719

#: Triangles of the full mesh after fan triangulation (25,836 quads + 548 triangles).
ICT_N_TRIANGLES = 52220

#: Sub-mesh vertex ranges from the upstream README, 0-based and *inclusive*.
SUBMESHES: dict[str, tuple[int, int]] = {
    "face": (0, 9408),
    "head_and_neck": (9409, 11247),
    "mouth_socket": (11248, 13293),
    "eye_sockets": (13294, 14061),
    "gums_and_tongue": (14062, 17038),
    "teeth": (17039, 21450),
    "eyeballs": (21451, 24590),
    "lacrimal_fluid_eye_blend_occlusion": (24591, 25350),
    "eyelashes": (25351, 26718),
}

#: The face area, vertices 0..9408 (9,409 vertices), as a ``range``.
FACE_AREA = range(SUBMESHES["face"][0], SUBMESHES["face"][1] + 1)

#: The paper's sliders (Lewis et al. 2005, Figs. 3-5) as combinations of ICT
#: shapes; see the mapping table in ``faces/ict/PROVENANCE.md``.
ICT_SLIDERS: dict[str, dict[str, float]] = {
    "Furrow": {"browDown_L": 1.0, "browDown_R": 1.0},  # brow lowerer, FACS AU4
    "SmirkLeft": {"mouthSmile_L": 1.0},  # lip-corner pull, AU12, subject's left
    "SmirkRight": {"mouthSmile_R": 1.0},
    "Wince": {"eyeSquint_L": 1.0, "eyeSquint_R": 1.0},  # lid tightener, AU7
    "SneerLeft": {"noseSneer_L": 1.0},  # nose wrinkler, AU9
    "SneerRight": {"noseSneer_R": 1.0},
    # names the procedural face also has, so the paper's scenarios run on either model
    "JawOpen": {"jawOpen": 1.0},
    "MouthStretch": {"mouthStretch_L": 1.0, "mouthStretch_R": 1.0},
    "Smile": {"mouthSmile_L": 1.0, "mouthSmile_R": 1.0},
    "Blink": {"eyeBlink_L": 1.0, "eyeBlink_R": 1.0},
    "BrowUp": {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0, "browOuterUp_L": 1.0, "browOuterUp_R": 1.0},
}

_FOLDER = "faces/ict"
_CACHE_FORMAT = 2  # bump when the cached arrays or their meaning change (2: source and content hashes)


# ------------------------------------------------------------------ regions
#: Multi-PIE 68-point landmark numbers (0-based) used by the region rules.  In
#: ``vertex_indices.json`` they are listed in the subject's frame: 17-21 the
#: subject's right brow (x < 0), 22-26 the left brow, 27-30 the nose bridge,
#: 31-35 the nose base, 36-41 the right eye, 42-47 the left eye (42 inner
#: corner, 45 outer corner, 46-47 lower lid), 48-59 the outer lip contour (48
#: right corner, 54 left corner), 60-67 the inner lip contour.
_LM = {
    "brow": list(range(17, 27)),
    "nose": list(range(27, 36)),
    "right_eye": [36, 37, 38, 39, 40, 41, 36],
    "left_eye": [42, 43, 44, 45, 46, 47, 42],
    "mouth_outer": [48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 48],
    "mouth_inner": [60, 61, 62, 63, 64, 65, 66, 67, 60],
}

#: Radii (cm) of the broad landmark-band regions, see :func:`ict_regions`.
_BAND_RADIUS = {"brow": 1.0, "left_eye": 0.8, "right_eye": 0.8, "mouth": 0.8, "nose": 0.8}

#: How far (cm, along -y) below the left lower-lid midpoint the
#: ``under_left_eye`` selection is centred, and how many vertices it has.
_UNDER_EYE_DROP = 1.0
_UNDER_EYE_COUNT = 6


def _distance_to_polyline(points: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """Euclidean distance of each point to the polyline through ``chain`` (k, 3)."""
    a, b = chain[:-1], chain[1:]
    ab = b - a
    t = np.einsum("pkc,kc->pk", points[:, None, :] - a[None], ab) / np.einsum("kc,kc->k", ab, ab)
    t = np.clip(t, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def ict_regions(f0: np.ndarray, landmarks: Sequence[int]) -> dict[str, np.ndarray]:
    """Named vertex sets of the ICT face, from the neutral and its landmarks.

    Every rule uses only the neutral positions ``f0`` (cm; +y up, +z forward,
    +x the subject's left) restricted to the face area (vertices 0..9408) and
    the Multi-PIE 68 landmark vertices ``landmarks`` (``idx_to_landmark_verts``
    of ``vertex_indices.json``; landmark numbers below are 0-based), so the
    regions do not depend on which shapes are loaded.  Vertex ids are the same
    in the full and in the face-only model (the face area is vertices
    0..9408).  Ties in distance are broken by the lower vertex id.

    Selections of the paper's figures (Lewis et al. 2005, Section 5):

    ``brow_middle`` (Fig. 3a: "two vertices whose motion is to be attenuated",
    at "the middle of the brow" that keeps moving down in Fig. 2c)
        The two vertices, one each side of the midline (x < 0 and x > 0),
        nearest to the midpoint of the inner brow ends, landmarks 21 and 22 --
        i.e. the glabella between the eyebrows.  On the ICT model these are
        vertices 2051 and 4247 (x = -/+0.30, y = 5.99), which ``Furrow``
        (``browDown_L + browDown_R``) moves 0.146 cm down and 0.05 cm inward.
        Note that ICT's ``browDown`` moves most (0.65 cm) at the middle of each
        eyebrow, not between them; those points are ``brow_centers``.
    ``brow_centers``
        The middle landmark of each eyebrow, landmarks 19 and 24 (vertices
        1914 and 4114), where ``Furrow`` moves about 0.65 cm.
    ``mouth_corners`` (Fig. 4a: "the corners of the mouth")
        The outer lip-corner landmarks 48 (the subject's right, x < 0) and 54
        (left, x > 0), in that order: vertices 5708 and 6213.
    ``under_left_eye`` (Fig. 5a: "Six vertices ... selected below the eye")
        The six vertices nearest to the point 1 cm below (-y) the midpoint of
        the subject's left lower-lid landmarks 46 and 47; on the upper cheek,
        where ``Wince`` (``eyeSquint``) and ``SneerLeft`` (``noseSneer_L``) both
        move the skin by about 0.35-0.5 cm.

    Broad regions (bands around landmark contours; 3D distance to the
    polyline through the landmarks, face area only):

    ``brow``: within 1.0 cm of the chain 17-18-...-26 (both brows and the
    glabella between them).  ``left_eye`` / ``right_eye``: within 0.8 cm of
    the closed eye contour 42-...-47 / 36-...-41 (lids and lid margins).
    ``mouth``: within 0.8 cm of the closed outer (48-59) or inner (60-67) lip
    contour.  ``nose``: within 0.8 cm, in the x-y (frontal) projection, of the
    convex hull of the nose landmarks 27-35 (bridge and base), which takes in
    the nostril wings.  The model is left-right symmetric, so ``left_eye`` and
    ``right_eye`` are mirror images.

    Parameters
    ----------
    f0 : (n, 3) array
        Neutral vertex positions with ``n >= 9409``.
    landmarks : sequence of 68 int
        Vertex ids of the Multi-PIE 68 landmarks.

    Returns
    -------
    dict of str to int64 array
        Sorted vertex ids, except ``mouth_corners`` and ``brow_centers`` and
        ``brow_middle`` (ordered right side first, then left).
    """
    f0 = np.asarray(f0, dtype=np.float64)
    lm = np.asarray(landmarks, dtype=np.int64)
    n_face = len(FACE_AREA)
    if f0.ndim != 2 or f0.shape[1] != 3 or f0.shape[0] < n_face:
        raise ModelError(f"ict_regions needs the ICT neutral (n >= {n_face}, 3), got {f0.shape}")
    if lm.shape != (68,) or lm.min() < 0 or lm.max() >= n_face:
        raise ModelError(f"expected 68 landmark vertex ids in the face area, got {lm.shape}")
    face = f0[:n_face]
    P = face[lm]
    regions = _figure_selections(face, lm, P)
    regions["brow"] = _band(face, P, [_LM["brow"]], _BAND_RADIUS["brow"])
    regions["left_eye"] = _band(face, P, [_LM["left_eye"]], _BAND_RADIUS["left_eye"])
    regions["right_eye"] = _band(face, P, [_LM["right_eye"]], _BAND_RADIUS["right_eye"])
    regions["mouth"] = _band(face, P, [_LM["mouth_outer"], _LM["mouth_inner"]], _BAND_RADIUS["mouth"])
    regions["nose"] = _nose(face, P)
    return regions


def _figure_selections(face: np.ndarray, lm: np.ndarray, P: np.ndarray) -> dict[str, np.ndarray]:
    """``brow_middle``, ``brow_centers``, ``mouth_corners``, ``under_left_eye``: the selections of Figs. 3-5."""
    ids = np.arange(len(face))

    def nearest(point, k=1, mask=None):
        d = np.linalg.norm(face - point, axis=1)
        cand = ids if mask is None else ids[mask]
        order = np.lexsort((cand, d[cand]))  # distance, then id
        return cand[order[:k]]

    mid = 0.5 * (P[21] + P[22])
    under = 0.5 * (P[46] + P[47]) - np.array([0.0, _UNDER_EYE_DROP, 0.0])
    return {
        "brow_middle": np.concatenate([nearest(mid, mask=face[:, 0] < 0), nearest(mid, mask=face[:, 0] > 0)]),
        "brow_centers": lm[[19, 24]],
        "mouth_corners": lm[[48, 54]],
        "under_left_eye": np.sort(nearest(under, k=_UNDER_EYE_COUNT)),
    }


def _band(face: np.ndarray, P: np.ndarray, chains: list[list[int]], radius: float) -> np.ndarray:
    """Face vertices within ``radius`` (3D) of the polyline through any of the landmark ``chains``."""
    d = np.min([_distance_to_polyline(face, P[c]) for c in chains], axis=0)
    return np.flatnonzero(d <= radius)


def _nose(face: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Face vertices within the nose radius, in x-y, of the convex hull of landmarks 27-35 (inside counts as 0)."""
    from scipy.spatial import ConvexHull, Delaunay

    hull_pts = P[27:36, :2]
    hull = ConvexHull(hull_pts)
    ring = np.column_stack([hull_pts[np.r_[hull.vertices, hull.vertices[0]]], np.zeros(len(hull.vertices) + 1)])
    flat = np.column_stack([face[:, :2], np.zeros(len(face))])
    d_nose = _distance_to_polyline(flat, ring)
    d_nose[Delaunay(hull_pts).find_simplex(face[:, :2]) >= 0] = 0.0
    return np.flatnonzero(d_nose <= _BAND_RADIUS["nose"])


# ------------------------------------------------------------------ loading
def cache_dir() -> Path:
    """Folder for derived caches: :func:`repro.data.cache_dir` (``$REPRO_CACHE_DIR``, else ``pooch.os_cache("repro") / "derived"``)."""
    return data.cache_dir()


def _relpath(stem: str) -> str:
    return f"{_FOLDER}/{stem}.obj"


def _used_files(shapes: tuple[str, ...]) -> list[str]:
    return [_relpath(ICT_NEUTRAL), f"{_FOLDER}/vertex_indices.json"] + [_relpath(s) for s in shapes]


def _source_hashes(shapes: tuple[str, ...]) -> dict[str, str]:
    """Registry sha256 of every file the arrays come from (``fetch`` checks the files against them)."""
    reg = data.registry()
    out = {}
    for rel in _used_files(shapes):
        try:
            out[rel] = reg[rel].sha256
        except KeyError:
            raise DataError(f"{rel!r} is not a registered data file") from None
    return out


def _cache_key(shapes: tuple[str, ...]) -> str:
    """Cache file name from the registry sha256s of every file the arrays come from."""
    h = hashlib.sha256(f"repro.blendshapes.ict cache format {_CACHE_FORMAT}\n".encode())
    for rel, sha in _source_hashes(shapes).items():
        h.update(f"{rel} {sha}\n".encode())
    return f"ict-{h.hexdigest()[:24]}.npz"


def _read_shape(stem: str) -> tuple[np.ndarray, np.ndarray]:
    return read_obj(data.fetch(_relpath(stem)))  # fetch verifies the sha256


def _read_landmarks() -> np.ndarray:
    rel = f"{_FOLDER}/vertex_indices.json"
    try:
        with data.open_file(rel) as fh:
            lm = json.load(fh)["idx_to_landmark_verts"]
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(f"{rel} has no usable 'idx_to_landmark_verts' list: {exc}") from exc
    lm = np.asarray(lm, dtype=np.int64)
    if lm.shape != (68,):
        raise DataError(f"{rel}: expected 68 landmark vertices, got shape {lm.shape}")
    return lm


def _build_arrays(shapes: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Parse the neutral and ``shapes``; check them; deltas ``D = S_k - f0``."""
    f0, faces = _read_shape(ICT_NEUTRAL)
    if f0.shape[0] != ICT_N_VERTICES:
        raise ModelError(
            f"{ICT_NEUTRAL}.obj has {f0.shape[0]} vertices, expected {ICT_N_VERTICES}"
        )
    D = np.empty((3 * f0.shape[0], len(shapes)))
    for k, stem in enumerate(shapes):
        S, F = _read_shape(stem)
        if S.shape != f0.shape:
            raise ModelError(
                f"shape {stem}.obj has {S.shape[0]} vertices, the neutral has {f0.shape[0]}"
            )
        if not np.array_equal(F, faces):
            diff = np.flatnonzero((F != faces).any(axis=1)) if F.shape == faces.shape else []
            where = f"first differing triangle {diff[0]}" if len(diff) else f"{len(F)} vs {len(faces)} triangles"
            raise ModelError(f"shape {stem}.obj has another face list than the neutral ({where})")
        D[:, k] = (S - f0).ravel()
    return {
        "f0": f0,
        "D": D,
        "faces": faces,
        "names": np.array(shapes, dtype=str),
        "landmarks": _read_landmarks(),
        "format": np.array(_CACHE_FORMAT),
    }


#: The arrays of a cache file, with their dtype kind (f: float, i: integer, U: text).
_CACHE_ARRAYS = {"f0": "f", "D": "f", "faces": "i", "names": "U", "landmarks": "i", "format": "i"}


def _content_hash(arrays: dict[str, np.ndarray]) -> str:
    """sha256 of the arrays' names, dtypes, shapes and bytes (about 0.05 s for all 57 shapes)."""
    h = hashlib.sha256()
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(f"{k} {a.dtype.str} {a.shape}\n".encode())
        h.update(memoryview(a).cast("B") if a.size else b"")
    return h.hexdigest()


def read_cache(path, shapes: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """The arrays of an ICT cache file, after every check :func:`load_ict` makes before using one.

    Parameters
    ----------
    path : path
        A cache file (:func:`cache_dir` holds them, named after the sources' sha256s).
    shapes : sequence of str, optional
        The expression shapes the cache must hold, in order (default all 57).

    Returns
    -------
    dict of str to numpy.ndarray
        ``f0`` (n, 3), ``D`` (3n, m), ``faces`` (T, 3), ``names`` (m,), ``landmarks`` (68,),
        ``format`` (the cache format, ``()``).

    Raises
    ------
    DataError
        ``"ICT cache <path>: <what is wrong>"`` for a missing file, and for any damage:
        not a readable ``.npz`` (not a zip, truncated, a bad member CRC, a lying ``.npy``
        header, an object dtype ... see :func:`repro.io.read_npz`), missing entries or
        entries of another kind or shape, NaN/inf, another cache format, source hashes
        other than the registry's, or arrays whose content hash is not the recorded
        one.  :func:`load_ict` rebuilds such a cache with a :class:`CacheWarning`.
    """
    try:
        path = Path(path)
    except TypeError:
        raise DataError(f"read_cache: expected a path to an ICT cache file, got {describe(path)}") from None
    arrays, damage = _check_cache(path, _normalise_shapes(shapes))
    if arrays is None:
        raise DataError(f"ICT cache {path}: {damage or 'no such file'}")
    return arrays


def _check_cache(path: Path, shapes: tuple[str, ...]) -> tuple[dict[str, np.ndarray] | None, str | None]:
    """The cached arrays and None, or None and what is wrong with the file (None if it is absent).

    Every kind of damage counts: not a zip, truncated, a bad member CRC, a lying
    ``.npy`` header, missing keys, wrong types or shapes, NaN/inf, another format,
    source hashes other than the registry's, or arrays whose content hash is not
    the recorded one.
    """
    try:
        there = path.exists()
    except (OSError, ValueError) as exc:  # a NUL byte, a name too long, a loop of links
        return None, f"cannot be looked up ({exc})"
    if not there:  # no cache yet (or no cache folder; also a cache folder below a file)
        return None, None
    allow = dict(_CACHE_ARRAYS, sources="U", content="U")
    allow.update(faces="iu", landmarks="iu", format="iu")
    try:
        z = read_npz(path, allow=allow)
    except DataError as exc:
        return None, str(exc).removeprefix(str(path)).lstrip(":, ")
    arrays = {k: z[k] for k in _CACHE_ARRAYS}
    sources, content = z["sources"], z["content"]
    for k in ("sources", "content"):
        if z[k].shape != ():
            return None, f"{k!r} is not a text entry"
    if arrays["format"].shape != () or int(arrays["format"]) != _CACHE_FORMAT:
        return None, f"format {arrays['format'].tolist()!r}, expected {_CACHE_FORMAT}"
    try:
        recorded = json.loads(str(sources))
    except (ValueError, RecursionError):
        recorded = None
    if recorded != _source_hashes(shapes):
        return None, "made from other source files (their sha256 differ from the registry's)"
    n = ICT_N_VERTICES
    shape_ok = (
        arrays["names"].shape == (len(shapes),)
        and tuple(arrays["names"].tolist()) == shapes
        and arrays["f0"].shape == (n, 3)
        and arrays["D"].shape == (3 * n, len(shapes))
        and arrays["faces"].shape == (ICT_N_TRIANGLES, 3)
        and arrays["landmarks"].shape == (68,)
    )
    if not shape_ok:
        return None, "arrays of other shapes or shape names than requested"
    if _content_hash(arrays) != str(content):
        return None, "content hash does not match (the arrays were changed)"
    return arrays, None


def _load_cache(path: Path, shapes: tuple[str, ...]) -> dict[str, np.ndarray] | None:
    """The cached arrays, or None when the file is absent, unreadable or inconsistent."""
    return _check_cache(path, shapes)[0]


def _save_cache(path: Path, arrays: dict[str, np.ndarray], sources: dict[str, str] | None = None) -> bool:
    """Write ``arrays`` with their source and content hashes atomically; False if not writable."""
    entries = dict(arrays)
    entries["sources"] = np.array(json.dumps(sources or {}, sort_keys=True))
    entries["content"] = np.array(_content_hash(arrays))
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:  # a file object: savez adds no suffix
            np.savez(fh, **entries)
        return True
    except OSError:
        return False


def _arrays(shapes: tuple[str, ...], use_cache: bool) -> dict[str, np.ndarray]:
    """The arrays for ``shapes``, from the cache file when it is good, else built (and cached).

    The cache file is read only as a regular file inside the cache folder
    (:func:`repro.data.cache_file`): a FIFO, a device or a symlink leading outside the folder in
    its place is damage (a :class:`CacheWarning`, rebuilt), and the rebuilt file replaces
    whatever was there (an atomic rename replaces a link, it never writes through it).
    """
    if not use_cache:
        return _build_arrays(shapes)
    name = _cache_key(shapes)
    path = cache_dir() / name  # where it is written
    try:
        arrays, damage = _check_cache(data.cache_file(name), shapes)
    except DataError as exc:  # a link leading outside the cache folder
        arrays, damage = None, str(exc)
    if arrays is None:
        if damage is not None:  # a first build is silent; only a damaged cache is reported
            warnings.warn(f"ICT cache {path} is damaged ({damage}); rebuilding it", CacheWarning, stacklevel=5)
        arrays = _build_arrays(shapes)
        _save_cache(path, arrays, _source_hashes(shapes))
    return arrays


def _require_sources(shapes: tuple[str, ...]) -> None:
    """Make sure the data files the arrays come from are in the data folder (presence only: cheap).

    The derived cache stands for the data beside it, never for absent data: a leftover cache
    after the data folder went away (or in a session without one) is not used.  A missing
    file is fetched (:func:`repro.data.fetch`: downloaded, or a :class:`DataError` saying how
    to get it), as on a first build.
    """
    root = data.data_dir()
    try:  # the folder's identity and modification time: a file removed or added changes it
        st = (root / _FOLDER).stat()
        stamp = (st.st_ino, st.st_mtime_ns)
    except OSError:
        stamp = None
    for rel in _missing_sources(str(root), stamp, shapes):
        data.fetch(rel)


@lru_cache(maxsize=8)
def _missing_sources(root: str, stamp, shapes: tuple[str, ...]) -> tuple[str, ...]:
    # (root, stamp) only key the memo: the 59 look-ups take about 10 ms, the folder's stat 10 us
    return tuple(rel for rel in _used_files(shapes) if data.locate(rel, Path(root)) is None)


def _normalise_shapes(shapes) -> tuple[str, ...]:
    if shapes is None:
        return ICT_SHAPES
    shapes = as_names(shapes, "shapes", error=ModelError, one=True, item="a shape name")
    unknown = [s for s in shapes if s not in ICT_SHAPES]
    if unknown:
        raise ModelError(f"unknown ICT shapes {unknown}; the 57 shapes are {list(ICT_SHAPES)}")
    if len(set(shapes)) != len(shapes):
        raise ModelError(f"shapes listed twice: {sorted({s for s in shapes if shapes.count(s) > 1})}")
    return shapes


def _make_model(arrays: dict[str, np.ndarray], face_only: bool) -> BlendshapeModel:
    names = tuple(arrays["names"].tolist())
    sliders = {k: v for k, v in ICT_SLIDERS.items() if all(s in names for s in v)}
    model = BlendshapeModel(
        f0=arrays["f0"],
        D=arrays["D"],
        names=names,
        faces=arrays["faces"],
        name="ict",
        units="cm",
        sliders=sliders,
        regions=ict_regions(arrays["f0"], arrays["landmarks"]),
    )
    return model.restrict(np.arange(len(FACE_AREA))) if face_only else model


@lru_cache(maxsize=2)
def _load_full(shapes: tuple[str, ...], data_root: str, cache_root: str) -> BlendshapeModel:
    # data_root and cache_root only key the memo: another folder is another model
    return _make_model(_arrays(shapes, use_cache=True), face_only=False)


@lru_cache(maxsize=2)
def _load_memo(face_only: bool, shapes: tuple[str, ...], data_root: str, cache_root: str) -> BlendshapeModel:
    full = _load_full(shapes, data_root, cache_root)
    return full.restrict(np.arange(len(FACE_AREA))) if face_only else full


def _cache_clear() -> None:
    _load_memo.cache_clear()
    _load_full.cache_clear()
    _missing_sources.cache_clear()


def load_ict(
    *, face_only: bool = True, shapes: Sequence[str] | None = None, cache: bool = True
) -> BlendshapeModel:
    """The ICT Face Model as a delta blendshape model ``f = f0 + D w`` (Section 3).

    Reads the neutral ``generic_neutral_mesh`` and the expression shapes from
    the data folder (:func:`repro.data.fetch`, which checks each file's sha256),
    verifies that every shape has the neutral's 26,719 vertices and exactly its
    face list, and forms ``D = [S_k - f0]`` (xyz packing, row ``3*v + axis``).

    Parameters
    ----------
    face_only : bool, default True
        Keep only the face area, vertices 0..9408 (9,409 vertices, the
        upstream README's "face" sub-mesh; 18,461 of the 52,220 triangles lie
        wholly inside it).  The expressions also move the mouth socket, gums,
        teeth, eyeballs, eye occlusion and eyelashes, which the paper's figures
        (Figs. 2-5, skin only) do not show and which would otherwise dominate
        coordinate counts such as the default ``alpha`` of Section 5 (the ratio
        of unselected to selected coordinates).  ``False`` gives all 26,719
        vertices.  Vertex ids of the face area are the same in both.
    shapes : sequence of str, optional
        Which expression shapes to load, in this order; default all 57 in the
        order of :data:`ICT_SHAPES` (the upstream ``expressions`` list of
        ``vertex_indices.json``, then ``cheekRaiser_L/R``, ``PupilDilate_L/R``).
    cache : bool, default True
        Use (and fill) the on-disk ``.npz`` cache in :func:`cache_dir` and the
        in-process memo.  ``False`` re-parses the OBJs and touches no cache.

    Returns
    -------
    BlendshapeModel
        ``name="ict"``, ``units="cm"``; shape names as the file stems; the
        paper's sliders of :data:`ICT_SLIDERS` (those whose shapes are loaded):
        ``Furrow``, ``SmirkLeft``, ``SmirkRight``, ``Wince``, ``SneerLeft``,
        ``SneerRight``; the regions of :func:`ict_regions` (``brow_middle``,
        ``brow_centers``, ``mouth_corners``, ``under_left_eye``, ``brow``,
        ``left_eye``, ``right_eye``, ``mouth``, ``nose``).

    Raises
    ------
    DataError
        A file is missing (the message says how to get it) or fails its sha256.
    ModelError
        An unknown or repeated shape name, a malformed OBJ, or a shape whose
        vertex count or face list differs from the neutral.

    Notes
    -----
    The on-disk cache file is named after the registry sha256s of the neutral,
    ``vertex_indices.json`` and the requested shapes, so changed data never
    reuses stale arrays.  The file also records those sha256s and a sha256 of
    its arrays' bytes, checked on every load (about 0.05 s); it is written
    atomically, and a damaged or inconsistent cache file (unreadable,
    truncated, missing or mistyped entries, another format, other source
    hashes, changed arrays) is rebuilt with a
    :class:`~repro.errors.CacheWarning`.  A first build prints and warns nothing.  When the cache folder is
    not writable the model is simply rebuilt each time.  The cache (and the
    in-process memo) is used only while the data files it came from are in the
    data folder (their presence is checked, not their sha256): a
    leftover cache does not stand in for absent data, which raise the
    :class:`DataError` of a first build.  Measured on the shared 2-core build machine (all
    57 shapes, face only): about 4 s cold (sha256 check and parse of 58 OBJs,
    about 0.06 s each), about 0.07 s from the 38 MB ``.npz`` cache (plus about
    0.3 s of imports in a new process), and nothing from the in-process memo
    (models are immutable, so the same object is returned).
    """
    face_only = as_bool(face_only, "face_only", error=ModelError)
    cache = as_bool(cache, "cache", error=ModelError)
    names = _normalise_shapes(shapes)
    if not cache:
        return _make_model(_arrays(names, use_cache=False), face_only)
    _require_sources(names)
    return _load_memo(face_only, names, str(data.data_dir()), str(cache_dir()))


#: Forget the in-process memo of :func:`load_ict` (the on-disk cache stays).
load_ict.cache_clear = _cache_clear  # type: ignore[attr-defined]
