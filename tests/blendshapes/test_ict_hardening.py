"""The OBJ reader and the ICT cache against the defects found by fuzzing (issue 9, section 2).

``read_obj``: numbers with ``_`` (Python's ``float``/``int`` read ``1_0`` as 10) and
path-named errors from :func:`repro.io.read_bytes` (item 3).  The derived ``.npz`` cache
of :func:`load_ict` (item 9): it records the source sha256s and a content hash, and any
damage -- a bad ``format``, rewritten arrays, missing or mistyped entries, a truncated
zip -- is rebuilt with a :class:`~repro.errors.CacheWarning`; a first build is silent.
"""

from __future__ import annotations

import gzip
import io
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from repro.blendshapes import ict
from repro.blendshapes.ict import load_ict, read_obj
from repro.errors import CacheWarning, DataError, ModelError

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


# ------------------------------------------------------------ read_obj
@pytest.mark.parametrize(
    "text, line, token",
    [
        ("v 1_0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 1, "1_0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1_000.5 0\nf 1 2 3\n", 3, "1_000.5"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0 1_0\nf 1 2 3\n", 3, "1_0"),  # the ignored w is checked too
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 0_3\n", 6, "0_3"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1_0/1 2 3\n", 4, "1/1_0/1"),
    ],
)
def test_underscore_numbers_are_a_model_error_naming_the_line(tmp_path, text, line, token):
    p = tmp_path / "u.obj"
    p.write_text(text)
    with pytest.raises(ModelError, match=rf"u.obj, line {line}: '{token}' is not an OBJ number"):
        read_obj(p)
    with pytest.raises(ModelError, match=rf"line {line}: '{token}'"):
        read_obj(io.BytesIO(text.encode()))


def test_underscores_outside_v_and_f_lines_are_fine():
    text = "mtllib my_mat.mtl\no generic_neutral_mesh\ng a_b\nusemtl skin_1\n# a_comment\n" + TRI
    V, F = read_obj(io.StringIO(text))
    assert V.shape == (3, 3) and F.tolist() == [[0, 1, 2]]


def test_unreadable_paths_are_data_errors_naming_the_path(tmp_path):
    with pytest.raises(DataError, match=r"absent.obj: no such file"):
        read_obj(tmp_path / "absent.obj")
    with pytest.raises(DataError, match=rf"{tmp_path.name}: is a folder"):
        read_obj(tmp_path)
    bad = tmp_path / "bad.obj.gz"
    bad.write_bytes(gzip.compress(TRI.encode())[:-12])  # cut inside the stream
    with pytest.raises(DataError, match=r"bad.obj.gz: corrupt gzip"):
        read_obj(bad)
    good = tmp_path / "good.obj.gz"
    good.write_bytes(gzip.compress(TRI.encode()))
    assert read_obj(good)[0].shape == (3, 3)


def test_stream_name_is_used():
    fh = io.BytesIO(b"v 0 0 0\nv nan 0 0\n")
    fh.name = "named.obj"
    with pytest.raises(ModelError, match=r"^named.obj, line 2"):
        read_obj(fh)
    with pytest.raises(ModelError, match=r"^<stream>: no vertices"):
        read_obj(io.BytesIO(b"f 1 2 3\n"))


# ------------------------------------------------------------ the cache
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
