"""BVH reader/writer hardening (issue 9): overflow, bounded allocation, bare exceptions,
deep hierarchies, text after the frames, and hypothesis round trips with random layouts."""

from __future__ import annotations

import gzip
import io
import sys
import tracemalloc
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from repro.errors import BVHError, BVHWarning, ReproError
from repro.motion import Motion, read_bvh, write_bvh

ONE = """HIERARCHY
ROOT Hips
{
  OFFSET 0 @off@ 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0 @off@ 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 @end@ 0
    }
  }
}
MOTION
Frames: 2
Frame Time: @ft@
0 1 0 0 0 0 0 0 0
0 @pos@ 0 0 0 0 0 0 0
"""


def _text(off="1", pos="2", end="1", ft="0.01") -> str:
    return ONE.replace("@off@", off).replace("@pos@", pos).replace("@end@", end).replace("@ft@", ft)


def _read(text, **kw) -> Motion:
    return read_bvh(io.BytesIO(text.encode() if isinstance(text, str) else text), **kw)


def _chain(depth: int, frames: int = 2) -> str:
    """A chain of ``depth`` joints, one line per keyword, no indentation (linear size)."""
    head = ["HIERARCHY"]
    for j in range(depth):
        head += [f"{'ROOT' if j == 0 else 'JOINT'} j{j}", "{", "OFFSET 0 1 0", "CHANNELS 1 Zrotation"]
    head += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * depth
    rows = [" ".join(["1"] * depth)] * frames
    return "\n".join(head + ["MOTION", f"Frames: {frames}", "Frame Time: 0.1"] + rows) + "\n"


# ------------------------------------------------- item 1: finite in, infinite out
def test_finite_offsets_whose_positions_overflow_are_rejected():
    ok = _read(_text(off="1e300", pos="1e300"))  # large but representable
    assert np.isfinite(ok.global_positions()).all()
    with pytest.raises(BVHError, match=r"joint 'Spine', frame 1: world position overflows"):
        _read(_text(off="1.7e308", pos="1.7e308"))
    # only the End Site overflows
    with pytest.raises(BVHError, match=r"joint 'Spine', frame 1: End Site position overflows"):
        _read(_text(off="1", pos="1.7e308", end="1.7e308"))
    # the same check guards motions built from arrays
    m = _read(_text())
    with pytest.raises(BVHError, match="overflows"):
        Motion(**{**_fields(m), "offsets": np.full((2, 3), 1.5e308), "positions": np.full((2, 2, 3), 1.5e308)})


def _fields(m: Motion) -> dict:
    keys = ["joint_names", "parents", "offsets", "channels", "frame_time", "rotations", "positions",
            "end_site_parents", "end_site_offsets"]
    return {k: getattr(m, k) for k in keys}


@pytest.mark.parametrize("ft", ["1e-320", "4e-324", "1e-310"])
def test_frame_time_with_infinite_frame_rate_is_rejected(ft):
    with pytest.raises(BVHError, match=r"line 18: frame time .* infinite frame rate"):
        _read(_text(ft=ft))
    m = _read(_text())
    with pytest.raises(BVHError, match="frame rate"):
        Motion(**{**_fields(m), "frame_time": float(ft)})


def test_frame_time_with_infinite_duration_is_rejected():
    with pytest.raises(BVHError, match=r"line 18: .*infinite frame rate or duration"):
        _read(_text(ft="1e308"))
    assert _read(_text(ft="1e300")).duration == 2e300


# ----------------------------------------------- item 2: bounded allocation
def _no_channels(n_joints: int, frames: int, body: str = "") -> str:
    head = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 0"]
    for j in range(1, n_joints):
        head += [f"JOINT j{j}", "{", "OFFSET 0 1 0", "CHANNELS 0", "}"]
    head += ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.1"]
    return "\n".join(head) + "\n" + body


def _peak_mib(fn) -> float:
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak / 2**20


def test_channelless_header_cannot_claim_frames_the_file_lacks(tmp_path):
    text = _no_channels(40, 10_000_000)
    assert len(text) < 2000

    def read():
        with pytest.raises(BVHError, match=r"line 205: 'Frames: 10000000' declared but 0 frame lines present"):
            _read(text)

    assert _peak_mib(read) < 20  # was 11.9 GiB
    p = tmp_path / "bomb.bvh.gz"
    p.write_bytes(gzip.compress(text.encode()))
    with pytest.raises(BVHError, match="declared but 0 frame lines"):
        read_bvh(p)
    # a frame of joints without channels is one (empty) line: as many lines as frames is fine
    m = _read(_no_channels(3, 4, "\n\n\n\n"))
    assert m.n_frames == 4 and m.n_channels == 0
    with pytest.raises(BVHError, match="declared but 3 frame lines present"):
        _read(_no_channels(3, 4, "\n\n\n"))
    with pytest.raises(BVHError, match=r"line 21: frame 2 has 1 values, expected 0"):
        _read(_no_channels(3, 4, "\n1\n\n\n"))


def test_channelless_motion_round_trips(tmp_path):
    m = _read(_no_channels(3, 5, "\n" * 5))
    back = read_bvh(write_bvh(m, tmp_path / "static.bvh"))
    assert back.n_frames == 5 and back.joint_names == m.joint_names
    np.testing.assert_array_equal(back.global_positions(), m.global_positions())


def test_pose_arrays_are_bounded_by_the_frame_data():
    # 3,000 joints, only the root has a channel: 2 bytes of text per frame would make
    # 3,000 joint poses (168 kB) per frame
    J, F = 3000, 2000
    head = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 1 Xposition"]
    for j in range(1, J):
        head += [f"JOINT j{j}", "{", "OFFSET 0 0 0", "CHANNELS 0", "}"]
    head = "\n".join(head + ["}", "MOTION"])
    text = head + f"\nFrames: {F}\nFrame Time: 0.1\n" + "0\n" * F

    def read():
        with pytest.raises(BVHError, match=r"2000 frames of 3000 joints would need 6000000 joint poses \(0.31 GiB\)"):
            _read(text)

    assert _peak_mib(read) < 60
    # the same skeleton with few frames is fine (under the 4 Mi joint-frame floor)
    assert _read(head + "\nFrames: 100\nFrame Time: 0.1\n" + "0\n" * 100).n_frames == 100


# ----------------------------------------------- item 3: no bare exceptions
def test_huge_numbers_of_digits_are_bvherrors():
    digits = "9" * 5000
    with pytest.raises(BVHError, match=r"line 17: frame count 9{40}\.\.\. is out of range"):
        _read(_text().replace("Frames: 2", f"Frames: {digits}"))
    # leading zeros are just zeros
    assert _read(_text().replace("Frames: 2", "Frames: " + "0" * 5000 + "2")).n_frames == 2
    with pytest.raises(BVHError, match="channel count .* out of range"):
        _read(_text().replace("CHANNELS 3", "CHANNELS " + "3" * 5000))


def test_unreadable_paths_are_bvherrors_naming_the_path(tmp_path):
    missing = tmp_path / "nope.bvh"
    with pytest.raises(BVHError, match=r"nope\.bvh: no such file") as info:
        read_bvh(missing)
    assert isinstance(info.value, ReproError)
    with pytest.raises(BVHError, match="is a folder"):
        read_bvh(tmp_path)
    bad = tmp_path / "bad.bvh.gz"
    bad.write_bytes(b"not gzip at all")
    with pytest.raises(BVHError, match=r"bad\.bvh\.gz: corrupt gzip"):
        read_bvh(bad)


# ----------------------------------------------- item 8: deep hierarchies
def test_deep_chain_round_trips_without_recursion(tmp_path):
    m = _read(_chain(1500))
    assert m.n_joints == 1500 and m.parents[-1] == 1498
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(200)  # nothing on the way may recurse per joint
    try:
        path = write_bvh(m, tmp_path / "deep.bvh")
        back = read_bvh(path)
        g = back.global_positions()
    finally:
        sys.setrecursionlimit(limit)
    assert back.parents.tolist() == m.parents.tolist()
    np.testing.assert_allclose(back.offsets, m.offsets)
    np.testing.assert_allclose(g, m.global_positions(), atol=1e-9)
    # the chain bends by 1 degree per joint: compare with a direct sum
    ang = np.radians(np.arange(1500))
    np.testing.assert_allclose(g[0, -1], [-np.sin(ang).sum(), np.cos(ang).sum(), 0], atol=1e-6)
    # indentation is capped, so the text grows linearly with the depth
    assert path.stat().st_size < 1500 * 400  # uncapped: 5.8 MB


def test_deep_chain_reads():
    # the reader was quadratic in the number of joints (a list lookup per name, and a token
    # list per line kept alive); a 20,000-deep chain now reads.  How the time grows is a
    # benchmark's business (timings are never asserted in tests).
    m = _read(_chain(20000, frames=1))
    assert m.parents.shape[0] >= 20000 and (m.parents[1:] == np.arange(m.parents.shape[0] - 1)).all()


def test_deep_chain_kinematics_do_not_loop_over_levels(monkeypatch):
    import repro.motion.core.kinematics as kin  # Motion.global_transforms' forward kinematics

    m = _read(_chain(20000, frames=2))
    calls, products = [], [0]
    real = kin.quat_multiply

    def counting(a, b):
        calls.append(1)
        products[0] += int(np.prod(np.broadcast_shapes(np.shape(a), np.shape(b))[:-1]))
        return real(a, b)

    monkeypatch.setattr(kin, "quat_multiply", counting)
    gq, gp = m.global_transforms()
    # pointer doubling: ceil(log2(20000)) = 15 vectorised rounds, not one per level
    assert len(calls) <= 16, len(calls)
    assert products[0] <= 16 * m.n_frames * m.n_joints
    ang = np.radians(np.arange(20001))  # joint k is turned by k + 1 degrees
    np.testing.assert_allclose(gp[0, -1], [-np.sin(ang[:-1]).sum(), np.cos(ang[:-1]).sum(), 0], atol=1e-6)
    np.testing.assert_allclose(m.end_site_positions()[0, 0], gp[0, -1] + [-np.sin(ang[-1]), np.cos(ang[-1]), 0], atol=1e-6)


def test_two_axis_rotations_beyond_90_degrees_are_written(tmp_path):
    # scipy's as_euler keeps the middle angle within +-90 deg: Rz(120) in "YZX" came out
    # as (180, 60, 180) and write_bvh refused a rotation its Y Z channels express
    text = _text().replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 2 Yrotation Zrotation")
    rows = text.splitlines()
    rows[-2:] = ["0 1 0 0 0 0 10 120", "0 2 0 0 0 0 -170 -135.5"]
    m = _read("\n".join(rows) + "\n")
    back = read_bvh(write_bvh(m, tmp_path / "yz.bvh"))
    np.testing.assert_allclose(np.abs(np.sum(back.rotations * m.rotations, axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(back.global_positions(), m.global_positions(), atol=1e-9)


# ----------------------------------------------- item 10: text after the frames
SL_APPENDIX = """
# keyframes
1 5 12
Created with QAvimator
"""


def test_text_after_the_frames_is_ignored_with_a_warning():
    plain = _read(_text())
    with pytest.warns(BVHWarning, match=r"ignored 3 lines of text after the 2 declared frames, from line 22"):
        m = _read(_text() + SL_APPENDIX)
    assert m.n_frames == 2
    np.testing.assert_array_equal(m.global_positions(), plain.global_positions())
    with pytest.raises(BVHError, match=r"line 22: frame 3 has 2 values, expected 9"):
        _read(_text() + SL_APPENDIX, strict=True)
    # without a final newline, and a single trailing word
    with pytest.warns(BVHWarning, match="ignored 1 line of text"):
        assert _read(_text() + "readme").n_frames == 2
    # the channel-less variant
    with pytest.warns(BVHWarning, match="ignored 1 line"):
        assert _read(_no_channels(2, 1, "\nthe end\n")).n_frames == 1
    with pytest.raises(BVHError, match="expected 0"):
        _read(_no_channels(2, 1, "\nthe end\n"), strict=True)


def test_declared_frames_are_still_checked():
    lines = _text().splitlines()
    short = "\n".join(lines[:-1] + [lines[-1].rsplit(" ", 1)[0]]) + "\n" + SL_APPENDIX
    with pytest.raises(BVHError, match=r"line 20: frame 2 has 8 values, expected 9"):
        _read(short)
    bad = "\n".join(lines[:-1] + [lines[-1].replace(" 2 ", " x ")]) + "\n" + SL_APPENDIX
    with pytest.raises(BVHError, match=r"line 20: value 'x' is not a number \(channel 2 of frame 2\)"):
        _read(bad)
    # one more complete frame than declared: the count is wrong, not an appendix
    extra = _text() + "0 0 0 0 0 0 0 0 0\n" + SL_APPENDIX
    with pytest.raises(BVHError, match=r"line 21: 'Frames: 2' declared but 3 frame lines present"):
        _read(extra)
    with pytest.raises(BVHError, match="declared but 1 frame lines present"):
        _read(_text().replace("Frames: 2", "Frames: 3").rsplit("\n", 2)[0] + "\n")


def test_trailing_text_warning_is_not_issued_for_clean_files():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _read(_text() + "\n\n  \n")


# ----------------------------------------------- hypothesis round trips (section 3)
ROT = ("Xrotation", "Yrotation", "Zrotation")
POS = ("Xposition", "Yposition", "Zposition")


@st.composite
def _layout(draw):
    """A random skeleton: parents, per-joint channel lists (any order, 0-6 channels)."""
    J = draw(st.integers(1, 7))
    parents = [-1] + [draw(st.integers(0, j - 1)) for j in range(1, J)]
    channels = []
    for _ in range(J):
        kind = draw(st.sampled_from(["rot3", "pos+rot3", "rot3+pos", "any"]))
        rot = list(draw(st.permutations(ROT)))
        if kind == "rot3":
            ch = rot
        elif kind == "pos+rot3":
            ch = list(draw(st.permutations(POS))) + rot
        elif kind == "rot3+pos":
            ch = rot + list(POS)
        else:  # unusual counts: any subset of the six channels, in any order
            ch = draw(st.permutations(ROT + POS))[: draw(st.integers(0, 6))]
        channels.append(tuple(ch))
    return parents, channels


def _num(draw, v: float) -> str:
    """``v`` (a multiple of 1/8) in a random but exact number format."""
    style = draw(st.sampled_from(["plain", "exp", "EXP", "plus", "noleading", "fixed"]))
    if style == "exp":
        return f"{v:.10e}"
    if style == "EXP":
        return f"{v:.12E}"
    if style == "plus":
        return f"{v:+}"
    if style == "fixed":
        return f"{v:.7f}"
    if style == "noleading" and 0 < abs(v) < 1:
        return f"{v}".replace("0.", ".", 1)
    return repr(v)


@st.composite
def _bvh(draw):
    parents, channels = draw(_layout())
    J = len(parents)
    F = draw(st.integers(0, 3))
    eighths = st.integers(-8 * 170, 8 * 170).map(lambda k: k / 8)
    offsets = [[draw(eighths) / 8 for _ in range(3)] for _ in range(J)]
    values = [[draw(eighths) for _ in range(sum(len(c) for c in channels))] for _ in range(F)]
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    sp = st.sampled_from([" ", "  ", "\t", " \t "])
    children = [[c for c in range(J) if parents[c] == j] for j in range(J)]
    order: list[int] = []

    def canon(x):
        return repr(float(x))

    def emit(fmt, join):
        out = ["HIERARCHY"]
        order.clear()
        stack = [(0, 0)]
        while stack:
            j, d = stack.pop()
            if j >= 0:
                order.append(j)
                out.append(join(["ROOT" if d == 0 else "JOINT", f"j{j}"]))
                out.append("{")
                out.append(join(["OFFSET"] + [fmt(v) for v in offsets[j]]))
                out.append(join(["CHANNELS", str(len(channels[j]))] + list(channels[j])))
                stack.append((~j, d))
                stack.extend((c, d + 1) for c in reversed(children[j]))
            else:
                if not children[~j]:
                    out += ["End Site", "{", join(["OFFSET", fmt(0.5), fmt(1), fmt(-0.25)]), "}"]
                out.append("}")
        out += ["MOTION", join(["Frames:", str(F)]), join(["Frame", "Time:", fmt(0.03125)])]
        return out

    # values in the file follow the depth-first order of the joints
    plain = emit(canon, " ".join)
    plain += [" ".join(canon(v) for v in row) for row in values]
    messy = emit(lambda v: _num(draw, v), lambda toks: draw(sp).join(toks) + draw(st.sampled_from(["", " ", "\t"])))
    messy += [draw(sp) + "".join(_num(draw, v) + draw(sp) for v in row) for row in values]
    return "\n".join(plain) + "\n", eol.join(messy) + draw(st.sampled_from(["", eol]))


@settings(max_examples=50, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_bvh())
def test_random_layouts_and_formats_round_trip(tmp_path_factory, texts):
    plain, messy = texts
    a, b = _read(plain), _read(messy)
    assert a.joint_names == b.joint_names and a.channels == b.channels
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    np.testing.assert_array_equal(a.global_positions(), b.global_positions())
    path = tmp_path_factory.mktemp("rt") / "m.bvh"
    back = read_bvh(write_bvh(a, path))
    assert back.joint_names == a.joint_names and back.channels == a.channels
    assert back.parents.tolist() == a.parents.tolist()
    assert back.n_frames == a.n_frames and back.frame_time == a.frame_time
    np.testing.assert_allclose(back.offsets, a.offsets, atol=1e-9)
    np.testing.assert_allclose(back.end_site_offsets, a.end_site_offsets, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(back.rotations * a.rotations, axis=-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(back.global_positions(), a.global_positions(), atol=1e-6)
    np.testing.assert_allclose(back.end_site_positions(), a.end_site_positions(), atol=1e-6)
