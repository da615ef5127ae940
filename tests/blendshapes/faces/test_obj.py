"""Tests of the OBJ reader (repro.blendshapes.faces.obj), on small OBJ texts written here.

Also the defects found by fuzzing (issue 9, section 2): numbers with ``_`` (Python's
``float``/``int`` read ``1_0`` as 10) and path-named errors from :func:`repro.io.read_bytes`.
"""

from __future__ import annotations

import gzip
import io
from pathlib import Path

import numpy as np
import pytest

from repro.blendshapes.faces.obj import read_obj
from repro.errors import DataError, ModelError


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


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


# ----------------------------------------------------- found by fuzzing
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
