"""Tests of the ICT Face Model loader (repro.blendshapes.faces.ict).

The ``data("ict")`` tests use the staged ICT-FaceKit files and compare with the numbers in
``faces/ict/PROVENANCE.md``.  The full model is loaded once per module.
"""

from __future__ import annotations

import io
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro import data
from repro.blendshapes.faces import ict
from repro.blendshapes.faces.ict import (
    FACE_AREA,
    ICT_N_TRIANGLES,
    ICT_N_VERTICES,
    ICT_SHAPES,
    ICT_SLIDERS,
    load_ict,
)
from repro.errors import CacheWarning, DataError, ModelError


# ------------------------------------------ load_ict without the real files
def test_shape_names_are_checked_before_reading():
    with pytest.raises(ModelError, match="unknown ICT shapes"):
        load_ict(shapes=["browDown_L", "tongueOut"])
    with pytest.raises(ModelError, match="twice"):
        load_ict(shapes=["jawOpen", "jawOpen"])
    with pytest.raises(ModelError, match="at least one"):
        load_ict(shapes=[])


def test_ict_shapes_and_sliders_are_consistent():
    assert len(ICT_SHAPES) == 57 == len(set(ICT_SHAPES))
    for slider, combo in ICT_SLIDERS.items():
        assert set(combo) <= set(ICT_SHAPES), slider
    assert len(FACE_AREA) == 9409 and FACE_AREA[-1] == 9408


def _fake_reader(bad: str, how: str):
    """A stand-in for ``_read_shape``: a consistent tiny 'ICT' except shape ``bad``."""
    rng = np.random.default_rng(0)
    f0 = rng.normal(size=(ICT_N_VERTICES, 3))
    faces = np.array([[0, 1, 2], [2, 3, 0]])

    def read(stem):
        if stem != bad:
            return f0 + (stem != ict.ICT_NEUTRAL) * 0.1, faces
        if how == "vertices":
            return f0[:-1], faces
        return f0, faces[:, ::-1]

    return read


@pytest.mark.parametrize("how, words", [("vertices", "26718 vertices"), ("faces", "another face list")])
def test_inconsistent_shape_is_a_model_error(monkeypatch, how, words):
    monkeypatch.setattr(ict, "_read_shape", _fake_reader("jawOpen", how))
    with pytest.raises(ModelError, match=words):
        ict._build_arrays(("browDown_L", "jawOpen"))


def test_neutral_with_wrong_vertex_count_is_a_model_error(monkeypatch):
    monkeypatch.setattr(ict, "_read_shape", _fake_reader(ict.ICT_NEUTRAL, "vertices"))
    with pytest.raises(ModelError, match="expected 26719"):
        ict._build_arrays(("jawOpen",))


def test_cache_key_follows_the_registry_hashes(monkeypatch):
    key = ict._cache_key(("jawOpen",))
    assert key == ict._cache_key(("jawOpen",))
    assert key != ict._cache_key(("jawOpen", "browDown_L"))
    reg = dict(data.registry())
    rel = "faces/ict/jawOpen.obj"
    reg[rel] = data.DataFile(reg[rel].dataset, rel, "0" * 64, reg[rel].url)
    monkeypatch.setattr(data, "registry", lambda: reg)
    assert ict._cache_key(("jawOpen",)) != key


def test_cache_dir_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "c"))
    assert ict.cache_dir() == (tmp_path / "c").resolve()
    monkeypatch.delenv("REPRO_CACHE_DIR")
    assert ict.cache_dir().name == "derived"


# ------------------------------------------------------- with the real data
PROVENANCE_MAX_DISP = {  # cm, from the table in faces/ict/PROVENANCE.md
    "jawOpen": 4.1987,
    "browDown_L": 0.6488,
    "mouthSmile_L": 1.5758,
    "eyeSquint_L": 0.3722,
    "noseSneer_R": 1.0297,
    "PupilDilate_L": 0.4801,
}


@pytest.fixture(scope="module")
def full():
    return load_ict(face_only=False)


@pytest.fixture(scope="module")
def face():
    return load_ict(face_only=True)


@pytest.fixture(scope="module")
def landmarks():
    with data.open_file("faces/ict/vertex_indices.json") as fh:
        return json.load(fh)


@pytest.mark.data("ict")
def test_full_model_sizes_and_names(full, landmarks):
    assert full.name == "ict" and full.units == "cm"
    assert full.n_vertices == ICT_N_VERTICES == 26719
    assert full.n_shapes == 57
    assert full.faces.shape == (ICT_N_TRIANGLES, 3) == (52220, 3)
    assert full.names == ICT_SHAPES  # upstream order, documented in ICT_SHAPES
    files = {
        Path(f.path).name[: -len(".obj")]
        for f in data.files("ict")
        if f.path.endswith(".obj")
    }
    assert set(full.names) == files - {"generic_neutral_mesh"}
    assert list(full.names[:53]) == landmarks["expressions"]


@pytest.mark.data("ict")
def test_neutral_bounding_box_matches_provenance(full):
    lo, hi = full.f0.min(axis=0), full.f0.max(axis=0)
    np.testing.assert_allclose(lo[:2], [-12.42, -19.31], atol=0.01)
    np.testing.assert_allclose(hi[:2], [12.42, 14.50], atol=0.01)
    np.testing.assert_allclose([lo[2], hi[2]], [-9.23, 13.09], atol=0.01)
    # nose tip (vertex 4857, landmark 30) at z = 13.07: the face looks toward +z;
    # landmark 45 (the subject's left outer eye corner, vertex 3721) at x > 0
    assert full.f0[4857, 2] == pytest.approx(13.07, abs=0.01)
    assert full.f0[3721, 0] == pytest.approx(4.46, abs=0.01)


@pytest.mark.data("ict")
def test_face_only_model(full, face):
    assert face.n_vertices == 9409 == len(FACE_AREA)
    assert face.names == full.names
    np.testing.assert_array_equal(face.f0, full.f0[:9409])
    np.testing.assert_array_equal(face.D, full.D[: 3 * 9409])
    assert 0 < len(face.faces) < len(full.faces)
    assert face.faces.max() == 9408
    # every full triangle inside the face area is kept
    inside = (full.faces < 9409).all(axis=1)
    np.testing.assert_array_equal(face.faces, full.faces[inside])
    assert face.sliders == full.sliders
    for r, verts in full.regions.items():
        np.testing.assert_array_equal(face.regions[r], verts)


@pytest.mark.data("ict")
@pytest.mark.parametrize("shape", sorted(PROVENANCE_MAX_DISP))
def test_max_displacement_matches_provenance(full, shape):
    d = np.linalg.norm(full.displacement(full.weights({shape: 1.0})), axis=1)
    assert d.max() == pytest.approx(PROVENANCE_MAX_DISP[shape], abs=1e-3)


@pytest.mark.data("ict")
def test_left_shapes_move_the_plus_x_side(full):
    sided = [s for s in full.names if s.endswith(("_L", "_R"))]
    assert len(sided) == 44  # 57 minus 13 unsided jaw/mouth shapes
    for s in sided:
        d = np.linalg.norm(full.displacement(full.weights({s: 1.0})), axis=1)
        cx = (d * full.f0[:, 0]).sum() / d.sum()
        assert (cx > 1.0) if s.endswith("_L") else (cx < -1.0), (s, cx)


@pytest.mark.data("ict")
def test_sliders_resolve(face):
    assert set(face.sliders) == {"Furrow", "SmirkLeft", "SmirkRight", "Wince", "SneerLeft", "SneerRight",
                                 "JawOpen", "MouthStretch", "Smile", "Blink", "BrowUp"}
    w = face.weights(Furrow=1)
    assert w[face.shape_index("browDown_L")] == 1.0 and w[face.shape_index("browDown_R")] == 1.0
    assert np.count_nonzero(w) == 2
    w = face.weights(Wince=0.7, SneerLeft=0.7, SneerRight=0.7, SmirkLeft=0.5)
    expected = {"eyeSquint_L": 0.7, "eyeSquint_R": 0.7, "noseSneer_L": 0.7, "noseSneer_R": 0.7, "mouthSmile_L": 0.5}
    assert {face.names[i]: w[i] for i in np.flatnonzero(w)} == pytest.approx(expected)
    np.testing.assert_array_equal(
        face.pose(face.weights(SmirkRight=0.3)), face.pose(face.weights(mouthSmile_R=0.3))
    )


@pytest.mark.data("ict")
def test_subset_of_shapes_keeps_order_sliders_and_regions(full, tmp_path, monkeypatch):
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path))
    sub = load_ict(shapes=["noseSneer_L", "browDown_R", "browDown_L"], face_only=False, cache=False)
    assert sub.names == ("noseSneer_L", "browDown_R", "browDown_L")
    assert set(sub.sliders) == {"Furrow", "SneerLeft"}
    for k, name in enumerate(sub.names):
        np.testing.assert_array_equal(sub.D[:, k], full.D[:, full.shape_index(name)])
    for r, verts in full.regions.items():
        np.testing.assert_array_equal(sub.regions[r], verts)
    assert not any(tmp_path.iterdir())  # cache=False writes nothing


@pytest.mark.data("ict")
def test_paper_regions(face, landmarks):
    R = face.regions
    lm = landmarks["idx_to_landmark_verts"]
    # Fig. 3a: two vertices between the eyebrows, mirror images across x = 0
    bm = R["brow_middle"]
    assert len(bm) == 2
    a, b = face.f0[bm]
    assert a[0] < 0 < b[0]
    np.testing.assert_allclose(a * [-1, 1, 1], b, atol=1e-3)
    assert abs(a[0]) < 0.5 and abs(a[1] - face.f0[lm[21], 1]) < 0.3
    furrow = face.displacement(face.weights(Furrow=1.0))
    assert (furrow[bm, 1] < -0.1).all()  # down by about 0.146 cm
    assert (furrow[R["brow_centers"], 1] < -0.3).all()
    # Fig. 4a: lip corners, Multi-PIE 48 (x < 0) and 54 (x > 0)
    mc = R["mouth_corners"]
    np.testing.assert_array_equal(mc, [lm[48], lm[54]])
    assert face.f0[mc[0], 0] < 0 < face.f0[mc[1], 0]
    smirk = face.displacement(face.weights(SmirkLeft=0.7, SmirkRight=0.7))
    assert (smirk[mc, 1] > 0.3).all()  # Fig. 4c: the corners move up markedly
    # Fig. 5a: six vertices below the subject's left eye, moved by Wince and SneerLeft
    ue = R["under_left_eye"]
    assert len(ue) == 6 == len(set(ue.tolist()))
    p = face.f0[ue]
    assert (p[:, 0] > 0).all()
    assert (p[:, 1] < min(face.f0[lm[46], 1], face.f0[lm[47], 1]) - 0.5).all()
    assert (p[:, 0] > face.f0[lm[42], 0]).all() and (p[:, 0] < face.f0[lm[45], 0]).all()
    for s, lo in [("eyeSquint_L", 0.2), ("noseSneer_L", 0.2)]:
        assert (np.linalg.norm(face.displacement(face.weights({s: 1})), axis=1)[ue] > lo).all(), s
    for s in ("eyeSquint_R", "noseSneer_R"):
        assert np.abs(face.displacement(face.weights({s: 1}))[ue]).max() < 0.01, s


@pytest.mark.data("ict")
def test_broad_regions(face):
    R = face.regions
    f0 = face.f0
    for r in ("brow", "left_eye", "right_eye", "mouth", "nose"):
        assert 100 < len(R[r]) < 2000, (r, len(R[r]))
        assert (np.diff(R[r]) > 0).all()
    assert (f0[R["left_eye"], 0] > 0).all() and (f0[R["right_eye"], 0] < 0).all()
    # left and right eye are mirror images (x -> -x)
    left = f0[R["left_eye"]] * [-1, 1, 1]
    right = f0[R["right_eye"]]
    assert len(left) == len(right)
    dist = np.linalg.norm(left[:, None] - right[None], axis=2).min(axis=1)
    assert dist.max() < 0.01
    # vertical order: brow above eyes above nose tip above mouth
    y = {r: np.median(f0[R[r], 1]) for r in R}
    assert y["brow"] > y["left_eye"] > y["nose"] > y["mouth"]
    # the regions are where the paper's sliders act
    for slider, region in [("Furrow", "brow"), ("SmirkLeft", "mouth"), ("SneerLeft", "nose")]:
        d = np.linalg.norm(face.displacement(face.weights({slider: 1})), axis=1)
        assert d[R[region]].mean() > 2 * d.mean(), slider


# ----------------------------------------------------------------- caching
CACHE_SHAPES = ("browDown_L", "jawOpen")


def _arrays_of(m):
    return m.f0, m.D, m.faces


@pytest.mark.data("ict")
def test_cache_round_trip_and_corruption(tmp_path, monkeypatch, full):
    cdir = tmp_path / "cache"
    monkeypatch.setenv("REPRO_CACHE_DIR", str(cdir))
    ict_folder = data.data_dir() / "faces" / "ict"
    before = sorted(p.name for p in ict_folder.iterdir())

    load_ict.cache_clear()
    cold = load_ict(shapes=CACHE_SHAPES, face_only=False)
    files = list(cdir.glob("ict-*.npz"))
    assert len(files) == 1 and not list(cdir.glob(".*tmp"))
    cache_file = files[0]
    assert cache_file.name == ict._cache_key(CACHE_SHAPES)
    with np.load(cache_file, allow_pickle=False) as z:
        assert tuple(z["names"].tolist()) == CACHE_SHAPES

    load_ict.cache_clear()
    warm = load_ict(shapes=CACHE_SHAPES, face_only=False)
    assert warm is not cold
    fresh = load_ict(shapes=CACHE_SHAPES, face_only=False, cache=False)
    for m in (warm, fresh):
        for x, y in zip(_arrays_of(m), _arrays_of(cold)):
            np.testing.assert_array_equal(x, y)
        assert m.names == cold.names and m.sliders == cold.sliders
    np.testing.assert_array_equal(cold.D[:, 1], full.D[:, full.shape_index("jawOpen")])
    # the in-process memo returns the same object
    assert load_ict(shapes=CACHE_SHAPES, face_only=False) is warm

    good = cache_file.read_bytes()
    corruptions = [
        b"not a zip file",  # garbage
        good[: len(good) // 2],  # truncated
        good[:200] + bytes([good[200] ^ 0xFF]) + good[201:],  # flipped byte in member data (CRC)
    ]
    # a valid npz whose content does not fit the request
    np.savez(buf := io.BytesIO(), f0=np.zeros((3, 3)), D=np.zeros((9, 2)), faces=np.zeros((1, 3), int),
             names=np.array(CACHE_SHAPES), landmarks=np.zeros(68, int), format=np.array(1))
    corruptions.append(buf.getvalue())
    for bad in corruptions:
        cache_file.write_bytes(bad)
        assert ict._load_cache(cache_file, CACHE_SHAPES) is None  # detected as unusable
        load_ict.cache_clear()
        with pytest.warns(CacheWarning, match="damaged"):  # rebuilt, and said so
            again = load_ict(shapes=CACHE_SHAPES, face_only=False)
        for x, y in zip(_arrays_of(again), _arrays_of(cold)):
            np.testing.assert_array_equal(x, y)
        # the damaged file was replaced by a good one
        assert ict._load_cache(cache_file, CACHE_SHAPES) is not None

    assert sorted(p.name for p in ict_folder.iterdir()) == before  # data folder untouched
    load_ict.cache_clear()


@pytest.mark.data("ict")
def test_unwritable_cache_folder_is_skipped(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("REPRO_CACHE_DIR", str(blocker / "cache"))  # cannot be created
    load_ict.cache_clear()
    m = load_ict(shapes=["browDown_L"], face_only=True)
    assert m.n_vertices == 9409 and m.names == ("browDown_L",)
    assert blocker.read_text() == "not a folder"
    assert not ict._save_cache(blocker / "cache" / "x.npz", {"a": np.zeros(1)})
    load_ict.cache_clear()


# ------------------------------------------ the cache against the defects found by fuzzing
# (issue 9, section 2, item 9): it records the source sha256s and a content hash, and any damage
# -- a bad ``format``, rewritten arrays, missing or mistyped entries, a truncated zip -- is rebuilt
# with a CacheWarning; a first build is silent.
SHAPES = ("jawOpen",)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The cache folder pointed at a fresh temporary folder, and the memo cleared."""
    folder = tmp_path / "derived"
    monkeypatch.setenv("REPRO_CACHE_DIR", str(folder))
    load_ict.cache_clear()
    yield folder
    load_ict.cache_clear()


def _load(**kw):
    load_ict.cache_clear()  # the in-process memo would hide the disk cache
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = load_ict(shapes=SHAPES, face_only=False, **kw)
    return m, [w for w in caught if issubclass(w.category, CacheWarning)]


def _entries(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _rewrite(path: Path, entries: dict) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **entries)


@pytest.mark.data("ict")
def test_first_build_is_silent_and_records_hashes(cache, capsys):
    m, caught = _load()
    assert caught == []
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    files = list(cache.iterdir())
    assert [f.name for f in files] == [ict._cache_key(SHAPES)]  # no temporary file left
    e = _entries(files[0])
    assert json.loads(str(e["sources"])) == ict._source_hashes(SHAPES)
    assert set(json.loads(str(e["sources"]))) == {
        "faces/ict/generic_neutral_mesh.obj", "faces/ict/vertex_indices.json", "faces/ict/jawOpen.obj",
    }  # fmt: skip
    assert str(e["content"]) == ict._content_hash({k: e[k] for k in ict._CACHE_ARRAYS})
    assert int(e["format"]) == ict._CACHE_FORMAT
    warm, caught = _load()
    assert caught == [] and capsys.readouterr().out == ""
    np.testing.assert_array_equal(warm.D, m.D)


def _damages(good: dict[str, np.ndarray]):
    """(name, entries or raw bytes) of damaged caches, starting from the good entries."""

    def edit(**changes):
        e = dict(good)
        for k, v in changes.items():
            if v is None:
                del e[k]
            else:
                e[k] = v
        return e

    yield "format abc", edit(format=np.array("abc"))
    yield "format 2-d", edit(format=np.array([[ict._CACHE_FORMAT]]))
    yield "format other", edit(format=np.array(ict._CACHE_FORMAT + 1))
    yield "D doubled", edit(D=good["D"] * 2.0)
    yield "one D entry changed", edit(D=np.where(np.arange(good["D"].size).reshape(good["D"].shape) == 7, 1.0, good["D"]))
    yield "f0 as float32", edit(f0=good["f0"].astype(np.float32))
    yield "faces as float", edit(faces=good["faces"].astype(float))
    yield "names as numbers", edit(names=np.arange(len(SHAPES)))
    yield "no content", edit(content=None)
    yield "no D", edit(D=None)
    yield "content not text", edit(content=np.zeros(3))
    yield "content wrong", edit(content=np.array("0" * 64))
    yield "sources not json", edit(sources=np.array("{not json"))
    yield "sources other sha", edit(
        sources=np.array(json.dumps({k: "0" * 64 for k in ict._source_hashes(SHAPES)}))
    )
    yield "landmarks as text", edit(landmarks=np.array(["a"] * 68))


def _write_damage(path: Path, good: dict, good_bytes: bytes, bad) -> None:
    if isinstance(bad, dict):
        _rewrite(path, bad)
    elif bad is None:  # a plain .npy, not an archive
        with open(path, "wb") as fh:
            np.save(fh, good["f0"])
    else:
        path.write_bytes(bad)


@pytest.fixture(scope="module")
def built():
    return ict._build_arrays(SHAPES)


@pytest.mark.data("ict")
def test_damaged_cache_is_rebuilt_with_a_cache_warning(cache, capsys, built, monkeypatch):
    # the cache layer itself, with the (slow, separately tested) build replaced by a copy
    builds = []
    monkeypatch.setattr(ict, "_build_arrays", lambda shapes: builds.append(shapes) or {k: v.copy() for k, v in built.items()})

    def arrays():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = ict._arrays(SHAPES, use_cache=True)
        return out, [w for w in caught if issubclass(w.category, CacheWarning)]

    first, caught = arrays()
    assert caught == [] and len(builds) == 1
    path = cache / ict._cache_key(SHAPES)
    good_bytes = path.read_bytes()
    good = _entries(path)
    _, caught = arrays()
    assert caught == [] and len(builds) == 1  # read from the cache
    cases = list(_damages(good)) + [
        ("truncated zip", good_bytes[: len(good_bytes) // 3]),
        ("cut at the end", good_bytes[:-30]),
        ("garbage", b"not a zip file at all"),
        ("empty file", b""),
        ("an .npy", None),
    ]
    for name, bad in cases:
        _write_damage(path, good, good_bytes, bad)
        n = len(builds)
        again, caught = arrays()
        assert len(caught) == 1 and len(builds) == n + 1, (name, caught)
        msg = str(caught[0].message)
        assert str(path) in msg and "damaged" in msg and "rebuilding" in msg, (name, msg)
        for k in ict._CACHE_ARRAYS:
            np.testing.assert_array_equal(again[k], built[k], err_msg=name)
        # the damaged file was replaced by a good one, which loads silently
        assert ict._load_cache(path, SHAPES) is not None, name
        _, caught = arrays()
        assert caught == [] and len(builds) == n + 1, name
    assert capsys.readouterr().out == ""
    assert sorted(p.name for p in cache.iterdir()) == [path.name]  # no temporary files left


@pytest.mark.data("ict")
@pytest.mark.parametrize("damage", ["format abc", "D doubled"])
def test_damaged_cache_end_to_end(cache, capsys, damage, built):
    _load()
    path = cache / ict._cache_key(SHAPES)
    e = _entries(path)
    if damage == "format abc":
        e["format"] = np.array("abc")
    else:  # well-formed, but not what the sources give
        e["D"] = e["D"] * 2.0
    _rewrite(path, e)
    again, caught = _load()
    assert [type(w.message) for w in caught] == [CacheWarning]
    np.testing.assert_array_equal(again.D, built["D"])
    np.testing.assert_array_equal(again.f0, built["f0"])
    assert capsys.readouterr().out == ""
    _, caught = _load()
    assert caught == []  # rebuilt for good


def test_unwritable_cache_is_not_a_warning(tmp_path, monkeypatch):
    # a cache folder that cannot exist (below a file) is "no cache", not a damaged one
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert ict._check_cache(blocker / "c" / "ict-x.npz", SHAPES) == (None, None)
    assert ict._check_cache(tmp_path / "absent.npz", SHAPES) == (None, None)
    assert not ict._save_cache(blocker / "c" / "x.npz", {"a": np.zeros(1)})


# --------------------------------------------------------- the cache file read through repro.io.read_npz
@pytest.fixture
def tiny_cache(tmp_path, monkeypatch):
    """A valid 6-vertex cache for two shapes (the ICT sizes patched to it): (path, shapes, arrays, write)."""
    monkeypatch.setattr(ict, "ICT_N_VERTICES", 6)
    monkeypatch.setattr(ict, "ICT_N_TRIANGLES", 3)
    shapes = tuple(ict.ICT_SHAPES[:2])
    rng = np.random.default_rng(0)
    arrays = {
        "f0": rng.normal(size=(6, 3)),
        "D": rng.normal(size=(18, 2)),
        "faces": np.array([[0, 1, 2], [0, 2, 3], [3, 4, 5]]),
        "names": np.array(shapes),
        "landmarks": rng.integers(0, 6, size=68),
        "format": np.array(ict._CACHE_FORMAT),
    }
    path = tmp_path / "ict-tiny.npz"

    def write(a):
        assert ict._save_cache(path, a, ict._source_hashes(shapes))

    write(arrays)
    return path, shapes, arrays, write


def test_read_cache_returns_a_good_cache_and_names_what_is_wrong(tiny_cache, tmp_path):
    path, shapes, arrays, _ = tiny_cache
    got = ict.read_cache(path, shapes)
    for k, v in arrays.items():
        np.testing.assert_array_equal(got[k], v)
    with pytest.raises(DataError, match=r"^ICT cache .*absent\.npz: no such file"):
        ict.read_cache(tmp_path / "absent.npz", shapes)
    with pytest.raises(DataError, match=r"other shapes or shape names"):
        ict.read_cache(path, shapes[::-1])


@pytest.mark.parametrize("key", ["f0", "D"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_nan_in_a_cache_with_a_matching_content_hash_is_damage(tiny_cache, key, value):
    # fuzz finding: NaN/inf in the cached arrays were used (the hash only says they were written so)
    path, shapes, arrays, write = tiny_cache
    bad = dict(arrays)
    bad[key] = arrays[key].copy()
    bad[key][1, 1] = value
    write(bad)
    got, damage = ict._check_cache(path, shapes)
    assert got is None and f"member '{key}.npy': NaN or inf at index [1, 1]" in damage
    with pytest.raises(DataError, match=rf"ICT cache .*: member '{key}\.npy': NaN or inf"):
        ict.read_cache(path, shapes)


def test_lying_npy_header_in_a_cache_is_damage_not_an_allocation(tiny_cache):
    # fuzz finding: a member whose .npy header claims shape (10000000000,) made np.load allocate (MemoryError)
    import re
    import zipfile

    path, shapes, _, _ = tiny_cache
    with zipfile.ZipFile(path) as z:
        members = [(i.filename, z.read(i)) for i in z.infolist()]
    members = [(n, re.sub(rb"'shape': \([^)]*\)", b"'shape': (10000000000,)", d, count=1) if n == "D.npy" else d)
               for n, d in members]
    with zipfile.ZipFile(path, "w") as z:
        for n, d in members:
            z.writestr(n, d)
    got, damage = ict._check_cache(path, shapes)
    assert got is None and "member 'D.npy': the .npy header claims shape (10000000000,)" in damage, damage


# --------------------------------------------------------- issue 23: special files, links, identity, arguments
@pytest.fixture
def tiny_build(tiny_cache, cache, monkeypatch):
    """``ict._arrays`` on the tiny arrays (no data files needed): (shapes, arrays, builds, run)."""
    _, shapes, arrays, _ = tiny_cache
    builds = []
    monkeypatch.setattr(ict, "_build_arrays", lambda s: builds.append(s) or {k: v.copy() for k, v in arrays.items()})

    def run(seconds=120):
        import threading

        out = {}

        def go():
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                out["arrays"] = ict._arrays(shapes, use_cache=True)
            out["warned"] = [str(w.message) for w in caught if issubclass(w.category, CacheWarning)]

        t = threading.Thread(target=go, daemon=True)  # a regression (a blocking read) fails, not hangs
        t.start()
        t.join(seconds)
        if t.is_alive():
            fifo = cache / ict._cache_key(shapes)
            import os

            with __import__("contextlib").suppress(OSError):
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            pytest.fail("the ICT cache read hangs")
        return out["arrays"], out["warned"]

    return shapes, arrays, builds, run


@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder"])
def test_a_special_file_in_place_of_the_cache_is_damage_not_a_hang(tiny_build, cache, kind):
    import os

    shapes, arrays, builds, run = tiny_build
    run()
    path = cache / ict._cache_key(shapes)
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()
    got, warned = run()
    assert len(builds) == 2 and len(warned) == 1 and "damaged" in warned[0], warned
    assert {"fifo": "FIFO", "dev-zero": "leads outside", "folder": "folder"}[kind] in warned[0]
    np.testing.assert_array_equal(got["D"], arrays["D"])
    if kind != "folder":  # (a folder is not replaced by a rename; the model is built each time)
        assert path.is_file() and not path.is_symlink()
        assert run()[1] == [] and len(builds) == 2  # the rebuilt file is read silently


def test_a_cache_linked_from_outside_the_cache_folder_is_refused_and_replaced(tiny_build, cache, tmp_path):
    import shutil

    shapes, arrays, builds, run = tiny_build
    run()
    path = cache / ict._cache_key(shapes)
    outside = tmp_path / "outside.npz"
    shutil.copy(path, outside)  # a valid cache, but outside the cache folder
    path.unlink()
    path.symlink_to(outside)
    before = outside.read_bytes()
    got, warned = run()
    assert len(builds) == 2 and len(warned) == 1 and "leads outside" in warned[0], warned
    assert path.is_file() and not path.is_symlink() and outside.read_bytes() == before


def test_another_valid_cache_in_its_place_is_refused(tiny_cache, tmp_path):
    """The identity (format, source sha256s, shape names) is inside the checked content."""
    path, shapes, arrays, _ = tiny_cache
    other = tmp_path / "other.npz"
    one = {k: v for k, v in arrays.items()}
    one["D"], one["names"] = arrays["D"][:, :1], arrays["names"][:1]
    assert ict._save_cache(other, one, ict._source_hashes(shapes[:1]))
    assert ict.read_cache(other, shapes[:1])["D"].shape == (18, 1)
    with pytest.raises(DataError, match="other source files|other shapes"):
        ict.read_cache(other, shapes)


@pytest.mark.parametrize("call, error, match", [
    (lambda: ict.read_cache(None), DataError, "expected a path"),
    (lambda: ict.read_cache(3.5), DataError, "expected a path"),
    (lambda: ict.read_cache("a\x00b"), DataError, "ICT cache"),
    (lambda: ict.read_cache("x" * 5000 + ".npz"), DataError, "ICT cache"),
    (lambda: load_ict(face_only="no"), ModelError, "face_only must be True or False"),
    (lambda: load_ict(cache=None), ModelError, "cache must be True or False"),
    (lambda: load_ict(shapes=5), ModelError, "shapes must be a sequence"),
    (lambda: load_ict(shapes=[None]), ModelError, "a shape name in shapes must be a string"),
    (lambda: ict.read_cache("x.npz", shapes=[1]), ModelError, "must be a string"),
])
def test_arguments_of_the_cache_and_loader_are_checked(cache, call, error, match):
    with pytest.raises(error, match=match):
        call()


def test_a_symlink_loop_in_place_of_the_cache_or_as_the_cache_folder_is_no_cache(tiny_build, cache, monkeypatch):
    shapes, arrays, builds, run = tiny_build
    run()
    path = cache / ict._cache_key(shapes)
    path.unlink()
    path.symlink_to(path.name)  # a link to itself
    got, _ = run()
    assert len(builds) == 2 and path.is_file() and not path.is_symlink()
    loop = cache.parent / "loop"
    loop.symlink_to("loop")
    monkeypatch.setenv("REPRO_CACHE_DIR", str(loop))
    got, warned = run()
    assert len(builds) == 3 and warned == []
    np.testing.assert_array_equal(got["D"], arrays["D"])
