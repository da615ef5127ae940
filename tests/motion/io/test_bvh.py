"""BVH reading/writing: lossless round trips, the overwrite policy, and a malformed corpus."""

from __future__ import annotations

import dataclasses
import io
import os
import re
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from repro import data
from repro.errors import BVHError, BVHWarning
from repro.motion import Motion, read_bvh, write_bvh
from repro.motion.io.bvh import MAX_FRAMES

SMALL = """HIERARCHY
ROOT Hips
{
  OFFSET 0.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0.1 5.2 -0.3
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0.0 4.1 0.0
    }
  }
  JOINT LeftLeg
  {
    OFFSET 1.5 -0.5 0.0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0.0 -8.0 0.25
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
1.25 16.5 -39.125 -9.5 -18.625 8.25 4.75 -12.75 -41.25 5.5 13.75 42.5
1.5 16.25 -39.0 -9.25 -18.5 8.0 4.5 -12.5 -41.0 5.25 13.5 42.25
1.75 16.0 -38.875 -9.0 -18.375 7.75 4.25 -12.25 -40.75 5.0 13.25 42.0
"""


def _read(text: str) -> Motion:
    return read_bvh(io.StringIO(text))


def _raw_table(path) -> np.ndarray:
    """The frame block of a BVH file, parsed independently of repro (plain Python floats)."""
    text = open(path).read()
    rows = text[text.index("Frame Time") :].split("\n")[1:]
    return np.array([[float(v) for v in r.split()] for r in rows if r.strip()])


def assert_same_motion(a: Motion, b: Motion, tol: float = 1e-6) -> None:
    assert a.joint_names == b.joint_names
    assert a.parents.tolist() == b.parents.tolist()
    assert a.channels == b.channels
    assert a.n_frames == b.n_frames
    assert a.frame_time == pytest.approx(b.frame_time, rel=1e-9)
    np.testing.assert_allclose(a.offsets, b.offsets, atol=tol)
    assert a.end_site_parents.tolist() == b.end_site_parents.tolist()
    np.testing.assert_allclose(a.end_site_offsets, b.end_site_offsets, atol=tol)
    np.testing.assert_allclose(a.channel_values(), b.channel_values(), atol=tol)
    np.testing.assert_allclose(np.abs(np.sum(a.rotations * b.rotations, axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(a.global_positions(), b.global_positions(), atol=tol)
    np.testing.assert_allclose(a.end_site_positions(), b.end_site_positions(), atol=tol)


# --------------------------------------------------------------- round trips
def test_small_round_trip_and_channel_values(tmp_path):
    m = _read(SMALL)
    raw = np.array([[float(v) for v in ln.split()] for ln in SMALL.split("Frame Time: 0.0083333\n")[1].splitlines()])
    np.testing.assert_allclose(m.channel_values(), raw, atol=1e-12)
    out = write_bvh(m, tmp_path / "small.bvh")
    assert out == tmp_path / "small.bvh"
    back = read_bvh(out)
    assert_same_motion(m, back, tol=1e-9)
    # writing is idempotent: the text of write(read(write(m))) is the text of write(m)
    again = write_bvh(back, tmp_path / "again.bvh")
    assert again.read_text() == out.read_text()
    assert back.source == str(out)


def test_write_handles_partial_rotation_channels(tmp_path):
    text = SMALL.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 1 Xrotation")
    text = re.sub(r"(?m)^(.*) 5\.5 13\.75 42\.5$", r"\1 33.5", text)
    text = re.sub(r"(?m)^(.*) 5\.25 13\.5 42\.25$", r"\1 -170", text)
    text = re.sub(r"(?m)^(.*) 5\.0 13\.25 42\.0$", r"\1 0", text)
    m = _read(text)
    assert m.rotation_orders[2] == "X"
    back = read_bvh(write_bvh(m, tmp_path / "partial.bvh"))
    assert_same_motion(m, back, tol=1e-9)
    np.testing.assert_allclose(back.channel_values()[:, -1], [33.5, -170, 0], atol=1e-9)

    # a rotation a one-axis joint cannot express is refused before anything is written
    q = np.array(m.rotations)
    q[1, 2] = [0.0, 0.0, np.sin(0.3), np.cos(0.3)]  # about Z, but the joint only has Xrotation
    bad = dataclasses.replace(m, rotations=q)
    with pytest.raises(BVHError, match="LeftLeg.*frame 1"):
        write_bvh(bad, tmp_path / "bad.bvh")
    assert sorted(os.listdir(tmp_path)) == ["partial.bvh"]


@pytest.mark.data("cmu-bvh")
def test_cmu_round_trip_lossless(tmp_path):
    src = data.fetch("mocap/cmu/135_04.bvh")
    m = read_bvh(src)
    assert (m.n_joints, m.n_frames, m.n_channels) == (31, 1316, 96)
    assert m.fps == pytest.approx(120, rel=1e-4)
    # the structured pose gives back the file's own channel values
    np.testing.assert_allclose(m.channel_values(), _raw_table(src), atol=1e-9)
    back = read_bvh(write_bvh(m, tmp_path / "135_04.bvh"))
    assert_same_motion(m, back, tol=1e-6)
    np.testing.assert_allclose(back.channel_values(), _raw_table(src), atol=1e-6)


@pytest.mark.data("bandai")
def test_bandai_round_trip_lossless(tmp_path):
    src = data.fetch("mocap/bandai/dataset-1_punch_normal_001.bvh")
    m = read_bvh(src)
    assert (m.n_joints, m.n_frames, m.n_channels) == (22, 224, 132)
    np.testing.assert_allclose(m.channel_values(), _raw_table(src), atol=1e-9)
    back = read_bvh(write_bvh(m, tmp_path / "punch.bvh"))
    assert_same_motion(m, back, tol=1e-6)


# ------------------------------------------------------------ overwrite policy
def test_write_never_overwrites_unless_asked(tmp_path):
    m = _read(SMALL)
    target = tmp_path / "m.bvh"
    write_bvh(m, target)
    first = target.read_bytes()
    src = read_bvh(target)  # a motion read from ``target``
    with pytest.raises(FileExistsError, match="read from"):
        write_bvh(src, target)
    other = tmp_path / "other.txt"
    other.write_text("precious")
    with pytest.raises(FileExistsError):
        write_bvh(m, other)
    assert other.read_text() == "precious" and target.read_bytes() == first

    scaled = src.scaled(2.0)
    write_bvh(scaled, target, overwrite=True)
    np.testing.assert_allclose(read_bvh(target).offsets, 2 * m.offsets)
    # no temporary files left behind
    assert sorted(os.listdir(tmp_path)) == ["m.bvh", "other.txt"]


def test_write_rejects_unwritable_names_and_precision(tmp_path):
    m = _read(SMALL)
    with pytest.raises(BVHError, match="name"):
        write_bvh(dataclasses.replace(m, joint_names=["Hips", "Sp{ine", "LeftLeg"]), tmp_path / "x.bvh")
    with pytest.raises(BVHError, match="precision"):
        write_bvh(m, tmp_path / "x.bvh", precision=3)
    assert os.listdir(tmp_path) == []


# ------------------------------------------------------------ malformed corpus
def _raises(text: str | bytes, match: str = r"line \d+") -> BVHError:
    stream = io.BytesIO(text) if isinstance(text, bytes) else io.StringIO(text)
    with pytest.raises(BVHError, match=match) as info:
        read_bvh(stream)
    return info.value


def test_every_truncation_raises():
    # every cut before the start of the last value (cuts inside the last number can
    # leave a valid, shorter number: not detectable)
    # (every character offset: this covers every line boundary and every mid-line point)
    last_start = SMALL.rstrip().rfind(" ") + 1
    assert last_start > 600
    for cut in range(last_start):
        with pytest.raises(BVHError, match=r"line \d+"):
            read_bvh(io.StringIO(SMALL[:cut]))
    _read(SMALL.rstrip("\n"))  # the complete file without its final newline is fine


def _frame_line(k: int) -> int:
    return SMALL.splitlines().index("Frame Time: 0.0083333") + 2 + k


@pytest.mark.parametrize("bad", ["abc", "nan", "inf", "-inf", "1e999", "1.2.3", "--1", "0x10", "1_0", "1,5", "\x00"])
def test_bad_numbers_name_their_line(bad):
    lines = SMALL.splitlines()
    for k in range(3):  # frame k, channel 4
        mutated = list(lines)
        row = mutated[_frame_line(k) - 1].split()
        row[4] = bad
        mutated[_frame_line(k) - 1] = " ".join(row)
        err = _raises("\n".join(mutated) + "\n")
        assert f"line {_frame_line(k)}" in str(err), (bad, k, str(err))
    # and in OFFSET
    err = _raises(SMALL.replace("OFFSET 0.1 5.2 -0.3", f"OFFSET 0.1 {bad} -0.3"))
    assert "line 8" in str(err)


def test_channel_count_mismatches():
    lines = SMALL.splitlines()
    f0 = _frame_line(0) - 1
    cases = {
        "drop a value": lines[:f0] + [lines[f0].rsplit(" ", 1)[0]] + lines[f0 + 1 :],
        "extra value": lines[:f0] + [lines[f0] + " 1.0"] + lines[f0 + 1 :],
        "two frames on one line": lines[:f0] + [lines[f0] + " " + lines[f0 + 1]] + lines[f0 + 2 :],
        "frame split over two lines": lines[:f0] + lines[f0].split(" 4.75 ") + lines[f0 + 1 :],
    }
    for label, ls in cases.items():
        err = _raises("\n".join(ls) + "\n", match=r"line \d+: ")
        assert re.search(r"values, expected 12|frame lines present", str(err)), label
    # CHANNELS header whose count disagrees with its names
    _raises(SMALL.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 4 Zrotation Yrotation Xrotation"))
    _raises(SMALL.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS x Zrotation Yrotation Xrotation"))
    _raises(SMALL.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 7 A B C D E F G"))


@pytest.mark.parametrize(
    "frames, pattern",
    [
        ("-1", "out of range"),
        (str(MAX_FRAMES + 1), "out of range"),
        ("99999999999999999999", "out of range"),
        ("2", "3 frame lines present"),
        ("4", "3 frame lines present"),
        ("0", "3 frame lines present"),
        ("3.0", "not an integer"),
        ("three", "not an integer"),
    ],
)
def test_bad_frame_counts(frames, pattern):
    err = _raises(SMALL.replace("Frames: 3", f"Frames: {frames}"), match=pattern)
    assert "line" in str(err)


@pytest.mark.parametrize("ft", ["0", "-0.1", "nan", "inf", "-inf", "abc", ""])
def test_bad_frame_time(ft):
    ft_line = _frame_line(0) - 1
    assert SMALL.splitlines()[ft_line - 1].startswith("Frame Time")
    _raises(SMALL.replace("Frame Time: 0.0083333", f"Frame Time: {ft}"), match=f"line {ft_line}: ")


def test_structural_errors():
    cases = {
        "unknown channel": (SMALL.replace("Zrotation Xrotation Yrotation", "Zrotation Wrotation Yrotation"), "unknown channel"),
        "repeated channel": (SMALL.replace("Zrotation Xrotation Yrotation", "Zrotation Zrotation Yrotation"), "twice"),
        "missing }": (SMALL.replace("    }\n  }\n  JOINT LeftLeg", "    }\n  JOINT LeftLeg", 1), "missing '}'"),
        "extra }": (SMALL.replace("MOTION", "}\nMOTION"), "after the root joint was closed"),
        "missing {": (SMALL.replace("JOINT Spine\n  {\n", "JOINT Spine\n"), "expected '{'"),
        "stray {": (SMALL.replace("OFFSET 0.1 5.2 -0.3", "{\nOFFSET 0.1 5.2 -0.3"), "unexpected '{'"),
        "no OFFSET": (SMALL.replace("    OFFSET 0.1 5.2 -0.3\n", ""), "no OFFSET"),
        "no CHANNELS": (SMALL.replace("    CHANNELS 3 Zrotation Yrotation Xrotation\n", ""), "no CHANNELS"),
        "End Site without OFFSET": (SMALL.replace("      OFFSET 0.0 4.1 0.0\n", ""), "End Site.*no OFFSET"),
        "CHANNELS in End Site": (SMALL.replace("OFFSET 0.0 4.1 0.0", "OFFSET 0.0 4.1 0.0\nCHANNELS 0"), "End Site"),
        "two OFFSETs": (SMALL.replace("OFFSET 0.1 5.2 -0.3", "OFFSET 0.1 5.2 -0.3\nOFFSET 0 0 0"), "second OFFSET"),
        "OFFSET with 2 numbers": (SMALL.replace("OFFSET 0.1 5.2 -0.3", "OFFSET 0.1 5.2"), "3 numbers"),
        "duplicate name": (SMALL.replace("JOINT LeftLeg", "JOINT Spine"), "duplicate joint name 'Spine'"),
        "unnamed joint": (SMALL.replace("JOINT LeftLeg", "JOINT"), "without a name"),
        "second ROOT": (SMALL.replace("MOTION", "ROOT Other\n{\nOFFSET 0 0 0\nCHANNELS 0\n}\nMOTION"), "after the root"),
        "no HIERARCHY": (SMALL.replace("HIERARCHY\n", ""), "expected 'HIERARCHY'"),
        "garbage keyword": (SMALL.replace("JOINT LeftLeg", "JIONT LeftLeg"), "unexpected"),
        "no MOTION": (SMALL.split("MOTION")[0], "missing MOTION"),
        "empty hierarchy": ("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n", "empty hierarchy"),
        "empty file": ("", "empty file"),
        "blank file": ("\n\n  \n", "empty file"),
        "missing Frames": (SMALL.replace("Frames: 3\n", ""), "expected 'Frames"),
        "missing Frame Time": (SMALL.replace("Frame Time: 0.0083333\n", ""), "expected 'Frame Time"),
    }
    for label, (text, pattern) in cases.items():
        try:
            _raises(text, match=pattern)
        except AssertionError as exc:  # pragma: no cover - failure reporting only
            raise AssertionError(f"case {label!r}: {exc}") from exc
    _raises(SMALL.encode().replace(b"Spine", b"Sp\xffine"), match="UTF-8")
    # text after the frames is an error with strict=True (by default it is ignored with a
    # BVHWarning, issue 9 item 10: see tests/motion/io/test_bvh_malformed.py)
    with pytest.raises(BVHError, match=r"line 31: frame 4 has 2 values, expected 12"):
        read_bvh(io.StringIO(SMALL + "the end\n"), strict=True)


def test_errors_are_repro_errors_and_value_errors():
    err = _raises(SMALL.replace("Frames: 3", "Frames: -3"))
    assert isinstance(err, ValueError)
    from repro.errors import ReproError

    assert isinstance(err, ReproError)


_ALPHABET = st.sampled_from(list("0123456789.-+eE \t\n{}#:abcXYZnaif") + ["\r\n", "nan", "inf", "JOINT", "}", "{"])


@given(
    edits=st.lists(
        st.tuples(st.integers(0, len(SMALL)), st.integers(0, 3), _ALPHABET, st.sampled_from(["replace", "insert", "delete"])),
        min_size=1,
        max_size=4,
    )
)
def test_random_mutations_raise_only_bvherror(edits):
    text = SMALL
    for pos, n, s, op in edits:
        pos = min(pos, len(text))
        if op == "replace":
            text = text[:pos] + s + text[pos + n :]
        elif op == "insert":
            text = text[:pos] + s + text[pos:]
        else:
            text = text[:pos] + text[pos + n + 1 :]
    try:
        with warnings.catch_warnings():  # a mutation may leave text after the frames: read, with a warning
            warnings.simplefilter("ignore", BVHWarning)
            m = read_bvh(io.StringIO(text))
    except BVHError as exc:
        assert re.search(r"line \d+", str(exc)), str(exc)
    else:  # a mutation that still makes a valid file must give a consistent motion
        assert np.all(np.isfinite(m.global_positions()))


def test_reads_gzip_and_binary_streams(tmp_path):
    import gzip

    p = tmp_path / "small.bvh.gz"
    with gzip.open(p, "wt") as fh:
        fh.write(SMALL)
    a = read_bvh(p)
    b = read_bvh(io.BytesIO(SMALL.encode()))
    c = read_bvh(io.BytesIO(("\ufeff" + SMALL.replace("\n", "\r\n")).encode()))  # BOM + CRLF
    assert_same_motion(a, b, tol=0)
    assert_same_motion(a, c, tol=0)
    (tmp_path / "broken.bvh.gz").write_bytes(gzip.compress(SMALL.encode())[:-20])
    with pytest.raises(BVHError, match="gzip"):
        read_bvh(tmp_path / "broken.bvh.gz")


def _six_channel_child(values: str) -> Motion:
    """A root and one child with six channels, one frame: ``values`` are the child's Xposition Yposition
    Zposition after the root's six zeros and before its own three rotation zeros."""
    text = SMALL.replace("JOINT Spine\n  {\n    OFFSET 0.1 5.2 -0.3\n    CHANNELS 3 Zrotation Yrotation Xrotation",
                         "JOINT Spine\n  {\n    OFFSET 0.1 5.2 -0.3\n    CHANNELS 6 Xposition Yposition Zposition "
                         "Zrotation Yrotation Xrotation")
    head, _, _ = text.partition("Frames: 3")
    return _read(head + f"Frames: 1\nFrame Time: 0.0083333\n0 0 0 0 0 0 {values} 0 0 0 0 0 0\n")


def test_position_channels_below_the_root_equal_to_the_offset_replace_it():
    """Bandai Namco / mocopi / Blender: a joint's position channels are its whole local translation."""
    m = _six_channel_child("0.1 5.2 -0.3")
    np.testing.assert_allclose(m.positions[0, 1], [0.1, 5.2, -0.3])
    m = _six_channel_child("0.2 6.0 -0.3")  # a stretched spine: the channel, not offset + channel
    np.testing.assert_allclose(m.positions[0, 1], [0.2, 6.0, -0.3])


def test_position_channels_below_the_root_near_zero_are_displacements_from_the_offset(tmp_path):
    """MakeHuman's exporter writes, below the root, the displacement from OFFSET: zeros at rest.  Read as a
    replacement, the spine would have no length."""
    m = _six_channel_child("0.000001 0 -0.000002")
    np.testing.assert_allclose(m.positions[0, 1], [0.100001, 5.2, -0.300002])
    np.testing.assert_allclose(m.global_positions()[0, 1] - m.global_positions()[0, 0], [0.100001, 5.2, -0.300002])
    # written back, the positions are whole translations, read the same way again
    back = read_bvh(write_bvh(m, tmp_path / "again.bvh"))
    np.testing.assert_allclose(back.positions, m.positions, atol=1e-9)
