"""Tests of the ICT Face Model loader (repro.blendshapes.ict).

The ``read_obj`` tests run on small OBJ texts written here; the ``data("ict")``
tests use the staged ICT-FaceKit files and compare with the numbers in
``faces/ict/PROVENANCE.md``.  The full model is loaded once per module.
"""

from __future__ import annotations

import gzip
import io
import json
from pathlib import Path

import numpy as np
import pytest

from repro import data
from repro.blendshapes import ict
from repro.blendshapes.ict import (
    FACE_AREA,
    ICT_N_TRIANGLES,
    ICT_N_VERTICES,
    ICT_SHAPES,
    ICT_SLIDERS,
    load_ict,
    read_obj,
)
from repro.errors import CacheWarning, DataError, ModelError


# --------------------------------------------------------------- read_obj
def _write(tmp_path: Path, text: str, name: str = "m.obj") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode())
    return p


SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def test_quad_and_polygon_are_fan_triangulated(tmp_path):
    text = SQUARE + "v 0.5 2 0\nf 1 2 3 4\nf 4 3 5\nf 1 2 3 5 4\n"
    V, F = read_obj(_write(tmp_path, text))
    assert V.shape == (5, 3) and V.dtype == np.float64
    assert F.dtype == np.int64
    np.testing.assert_array_equal(
        F,
        [[0, 1, 2], [0, 2, 3], [3, 2, 4], [0, 1, 2], [0, 2, 4], [0, 4, 3]],
    )


def test_v_vt_vn_tokens_use_the_vertex_index(tmp_path):
    text = (
        SQUARE
        + "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
        + "f 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 4//1\nf 2/2 3/3 4/1\n"
    )
    _, F = read_obj(_write(tmp_path, text))
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3], [1, 2, 3]])


def test_negative_indices_count_back_from_the_line(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4/1 -2 -1\nf 1 2 -1\n"
    V, F = read_obj(_write(tmp_path, text))
    assert len(V) == 4
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3], [0, 1, 3]])


def test_ignored_statements_crlf_tabs_and_streams(tmp_path):
    text = (
        "# comment\r\nmtllib x.mtl\r\no obj\r\ng grp\r\ns 1\r\nusemtl skin\r\n"
        "v\t0 0 0\r\n  v 1 0 0\r\nv 1 1 0 1.0\r\nvt 0.5 0.5\r\nvn 0 0 1\r\n\r\n"
        "l 1 2\r\nf 1 2 3\r\n"
    )
    expected_v = [[0, 0, 0], [1, 0, 0], [1, 1, 0]]  # the w of the third vertex is ignored
    for src in (
        _write(tmp_path, text),
        io.BytesIO(text.encode()),
        io.StringIO(text),
    ):
        V, F = read_obj(src)
        np.testing.assert_array_equal(V, expected_v)
        np.testing.assert_array_equal(F, [[0, 1, 2]])
    gz = tmp_path / "m.obj.gz"
    gz.write_bytes(gzip.compress(text.encode()))
    V, F = read_obj(gz)
    np.testing.assert_array_equal(V, expected_v)


def test_uv_seams_do_not_split_vertices(tmp_path):
    # a strip of two quads whose shared edge (vertices 2, 3) has two UVs each:
    # 6 positions, 8 texture coordinates; a UV-splitting loader would give 8
    text = (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
        + "".join(f"vt {i / 8} 0\n" for i in range(8))
        + "f 1/1 2/2 3/3 4/4\nf 2/5 5/6 6/7 3/8\n"
    )
    V, F = read_obj(_write(tmp_path, text))
    assert V.shape == (6, 3)
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    # both quads share vertices 1 and 2 (0-based): the edge is connected
    assert {1, 2} <= set(F[:2].ravel()) & set(F[2:].ravel())


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n", 2, "'x' is not a number"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n# c\nf 1 2 3\nf 1 2\n", 6, "at least 3"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf\n", 5, "at least 3"),
        ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", 2, "NaN/inf"),
        ("v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", 3, "NaN/inf"),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", 2, "3 coordinates"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2.5 3\n", 4, "not an integer"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 a/1 3\n", 4, "not an integer"),
        ("v 0 0 0\nv 1 0 0 \\\n 1\nv 0 1 0\n", 2, "continuation"),
    ],
)
def test_malformed_obj_names_the_line(tmp_path, text, line, words):
    with pytest.raises(ModelError) as exc:
        read_obj(_write(tmp_path, text))
    msg = str(exc.value)
    assert f"line {line}:" in msg, msg
    assert words in msg, msg
    assert "m.obj" in msg


def test_obj_without_vertices(tmp_path):
    with pytest.raises(ModelError, match="no vertices"):
        read_obj(_write(tmp_path, "# only a comment\nvt 0 0\n"))


def test_obj_without_faces_gives_empty_triangles(tmp_path):
    V, F = read_obj(_write(tmp_path, "v 1 2 3\n"))
    assert V.shape == (1, 3) and F.shape == (0, 3)


def test_missing_file_is_a_data_error(tmp_path):
    with pytest.raises(DataError):
        read_obj(tmp_path / "absent.obj")


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
