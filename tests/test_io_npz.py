"""repro.io.read_npz: a checked .npz reader (issue 9: a lying .npy header made np.load allocate GiBs;
zipfile / zlib / numpy errors escaped as bare exceptions)."""

from __future__ import annotations

import io
import re
import struct
import zipfile

import numpy as np
import pytest

from repro.errors import DataError, ModelError
from repro.io import read_npz


def _npz(path, compressed=False, **arrays):
    with open(path, "wb") as fh:
        (np.savez_compressed if compressed else np.savez)(fh, **arrays)
    return path


def _npy(a) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def _zip(path, members, method=zipfile.ZIP_STORED):
    with zipfile.ZipFile(path, "w", method) as z:
        for name, data in members:
            z.writestr(name, data)
    return path


GOOD = {
    "f": np.arange(12.0).reshape(3, 4),
    "fortran": np.asfortranarray(np.arange(6, dtype=np.int32).reshape(2, 3)),
    "big_endian": np.arange(5, dtype=">f8"),
    "text": np.array("hello"),
    "texts": np.array(["a", "bc"]),
    "empty": np.zeros((0, 7)),
    "scalar": np.array(3),
    "flags": np.array([True, False]),
    "z": np.array([1 + 2j]),
}


@pytest.mark.parametrize("compressed", [False, True])
def test_reads_what_numpy_writes_as_numpy_loads_it(tmp_path, compressed):
    p = _npz(tmp_path / "a.npz", compressed, **GOOD)
    got = read_npz(p)
    with np.load(p, allow_pickle=False) as z:
        assert list(got) == z.files
        for k in z.files:
            assert got[k].dtype == z[k].dtype and got[k].shape == z[k].shape, k
            np.testing.assert_array_equal(got[k], z[k], err_msg=k)
            assert got[k].flags.writeable, k
    with open(p, "rb") as fh:  # a stream too
        assert list(read_npz(fh)) == list(GOOD)


def test_allow_selects_and_checks_kinds_required_defaults_to_allow(tmp_path):
    p = _npz(tmp_path / "a.npz", **GOOD)
    assert list(read_npz(p, allow={"f": "f", "text": "U"})) == ["f", "text"]
    with pytest.raises(DataError, match=r"member 'text.npy': dtype <U5, expected kind 'f'"):
        read_npz(p, allow={"text": "f"})
    with pytest.raises(DataError, match=r"a\.npz: no \['nope'\] in the archive"):
        read_npz(p, allow={"f": "f", "nope": "f"})
    assert list(read_npz(p, allow={"f": "f", "nope": "f"}, required=())) == ["f"]
    with pytest.raises(ModelError, match="no \\['x'\\]"):  # the caller's error class
        read_npz(p, error=ModelError, required=["x"])


# the .npy header claims another size than the member holds: refused before any allocation
@pytest.mark.parametrize("shape", ["(10000000000,)", "(99999999999, 3)", "(4611686018427387904,)", "(2, 2)", "(0,)"])
def test_lying_npy_shape_header_is_refused_before_allocating(tmp_path, shape):
    lie = _npy_with_header(_npy(np.arange(10.0)), shape)
    p = _zip(tmp_path / "lie.npz", [("a.npy", lie)])
    with pytest.raises(DataError, match=r"lie\.npz, member 'a\.npy': the \.npy header claims shape .* the member holds 80 bytes"):
        read_npz(p)


def _npy_with_header(raw: bytes, shape: str) -> bytes:
    """``raw`` (a version 1.0 .npy) with its header's shape replaced, the header re-padded."""
    (hlen,) = struct.unpack("<H", raw[8:10])
    header = raw[10:10 + hlen].decode("latin1")
    header = re.sub(r"'shape': \([^)]*\)", f"'shape': {shape}", header).rstrip()
    header += " " * (-(10 + len(header) + 1) % 64) + "\n"
    return raw[:8] + struct.pack("<H", len(header)) + header.encode("latin1") + raw[10 + hlen:]


@pytest.mark.parametrize("shape", ["(-1,)", "(2.5,)", "('a',)"])
def test_bad_shapes_are_errors(tmp_path, shape):
    p = _zip(tmp_path / "s.npz", [("a.npy", _npy_with_header(_npy(np.arange(10.0)), shape))])
    with pytest.raises(DataError, match=r"s\.npz, member 'a\.npy'"):
        read_npz(p)


def test_object_arrays_and_records_are_refused(tmp_path):
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    p = _zip(tmp_path / "o.npz", [("o.npy", buf.getvalue())])
    with pytest.raises(DataError, match=r"member 'o\.npy': dtype object"):
        read_npz(p)
    p = _npz(tmp_path / "r.npz", r=np.zeros(2, dtype=[("x", "f8"), ("y", "i4")]))
    with pytest.raises(DataError, match=r"member 'r\.npy': dtype .*refused"):
        read_npz(p)


def test_nan_and_inf_are_refused_unless_allowed(tmp_path):
    p = _npz(tmp_path / "n.npz", a=np.array([[0.0, 1.0], [np.inf, 2.0]]))
    with pytest.raises(DataError, match=r"member 'a\.npy': NaN or inf at index \[1, 0\]"):
        read_npz(p)
    assert np.isinf(read_npz(p, finite=False)["a"][1, 0])


def test_a_lying_zip_size_is_refused_before_allocating(tmp_path):
    good = _npz(tmp_path / "g.npz", a=np.arange(100.0)).read_bytes()
    # a stored member whose central-directory size claims 1 GiB: patch file_size in both headers
    info = zipfile.ZipFile(io.BytesIO(good)).infolist()[0]
    size = struct.pack("<I", info.file_size)
    lie = good.replace(size, struct.pack("<I", 1 << 30))
    p = tmp_path / "z.npz"
    p.write_bytes(lie)
    with pytest.raises(DataError, match=r"z\.npz"):
        read_npz(p)
    # deflate cannot expand more than 1032:1
    comp = _npz(tmp_path / "c.npz", True, a=np.zeros(10)).read_bytes()
    info = zipfile.ZipFile(io.BytesIO(comp)).infolist()[0]
    lie = comp.replace(struct.pack("<I", info.file_size), struct.pack("<I", 2_000_000_000))
    p.write_bytes(lie)
    with pytest.raises(DataError, match=r"claims 2000000000 bytes from \d+ compressed|not a readable"):
        read_npz(p)


def test_damaged_archives_are_one_error_naming_the_file(tmp_path):
    good = _npz(tmp_path / "g.npz", **GOOD).read_bytes()
    p = tmp_path / "bad.npz"
    cases = {
        "not a zip": b"not a zip file",
        "empty": b"",
        "truncated": good[: len(good) // 2],
        "cut at the end": good[:-10],
        "flipped byte": good[:200] + bytes([good[200] ^ 0x40]) + good[201:],
    }
    for name, data in cases.items():
        p.write_bytes(data)
        with pytest.raises(DataError, match=r"bad\.npz"):
            read_npz(p)
    # a bzip2 member (zipfile's NotImplementedError / numpy never writes it), a foreign member, duplicates
    _zip(p, [("a.npy", _npy(np.zeros(3)))], zipfile.ZIP_BZIP2)
    with pytest.raises(DataError, match=r"compression method 12"):
        read_npz(p)
    _zip(p, [("readme.txt", b"hello")])
    with pytest.raises(DataError, match=r"'readme\.txt' is not an \.npy array"):
        read_npz(p)
    with pytest.warns(UserWarning, match="Duplicate name"):
        _zip(p, [("a.npy", _npy(np.zeros(3))), ("a.npy", _npy(np.ones(3)))])
    with pytest.raises(DataError, match=r"duplicate archive members \['a\.npy'\]"):
        read_npz(p)
    for bad in (b"\x93NUMPY\x09\x00", b"\x93NUMPY\x01\x00\xff\xff{'descr'", b"nonsense"):
        _zip(p, [("a.npy", bad)])
        with pytest.raises(DataError, match=r"bad\.npz, member 'a\.npy'"):
            read_npz(p)


def test_paths_that_are_not_files(tmp_path):
    with pytest.raises(DataError, match=r"missing\.npz: no such file"):
        read_npz(tmp_path / "missing.npz")
    with pytest.raises(DataError, match=r"is a folder"):
        read_npz(tmp_path)
    with pytest.raises(DataError, match="expected a path"):
        read_npz(3.5)


def test_total_size_cap(tmp_path):
    p = _npz(tmp_path / "a.npz", a=np.zeros(100), b=np.zeros(100))
    assert len(read_npz(p, max_bytes=2 * (800 + 128))) == 2  # data and .npy headers
    with pytest.raises(DataError, match="more than 1000 bytes"):
        read_npz(p, max_bytes=1000)
