"""ASF/AMC reading: same skeleton and same joint positions as the staged CMU BVH of the
same take (the conversion convention of mocap/cmu/PROVENANCE.md), and malformed files."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from repro import data
from repro.errors import BVHError
from repro.motion import CMU_UNIT_M, read_amc, read_asf, read_asf_amc, read_bvh, write_bvh


def _source_text(rel: str) -> str:
    with data.open_file(rel) as fh:
        return fh.read().decode("utf-8")


@pytest.mark.data("cmu-bvh", "cmu-asfamc")
@pytest.mark.parametrize("take", ["135_04", "07_05"])
def test_asf_amc_gives_the_bvh_positions(take, tmp_path):
    subject = take.split("_")[0]
    amc = read_asf_amc(
        data.open_file(f"mocap/cmu/source/{subject}.asf"),
        data.open_file(f"mocap/cmu/source/{take}.amc"),
        unit_m=CMU_UNIT_M,
    )
    bvh = read_bvh(data.fetch(f"mocap/cmu/{take}.bvh"))
    assert amc.joint_names == bvh.joint_names
    assert amc.parents.tolist() == bvh.parents.tolist()
    assert amc.channels == bvh.channels
    assert amc.n_frames == bvh.n_frames
    assert amc.frame_time == pytest.approx(bvh.frame_time, rel=1e-4)
    np.testing.assert_allclose(amc.offsets, bvh.offsets, atol=1e-6)  # BVH prints 6 decimals
    assert amc.end_site_parents.tolist() == bvh.end_site_parents.tolist()
    np.testing.assert_allclose(amc.end_site_offsets, bvh.end_site_offsets, atol=1e-6)
    # all frames; the BVH channel values are rounded to 4 decimals
    np.testing.assert_allclose(amc.global_positions(), bvh.global_positions(), atol=1e-3)
    np.testing.assert_allclose(amc.end_site_positions(), bvh.end_site_positions(), atol=1e-3)
    np.testing.assert_allclose(amc.channel_values(), bvh.channel_values(), atol=5.1e-5)
    # and written out, it is the staged conversion again
    again = read_bvh(write_bvh(amc, tmp_path / f"{take}.bvh"))
    np.testing.assert_allclose(again.channel_values(), bvh.channel_values(), atol=5.1e-5)
    assert amc.to_metres().unit_m == 1.0


@pytest.mark.data("cmu-asfamc")
def test_asf_skeleton_fields_and_inputs():
    p = data.fetch("mocap/cmu/source/09.asf")  # the staged .gz file, read directly
    skel = read_asf(p)
    assert skel.length_unit == 0.45 and skel.angle_unit == "deg"
    assert skel.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ") and skel.root_axis == "XYZ"
    assert len(skel.bones) == 30 and skel.joint_names[:3] == ["root", "lhipjoint", "lfemur"]
    lfemur = skel.bones["lfemur"]
    assert lfemur.dofs == ("rx", "ry", "rz") and lfemur.axis_order == "XYZ"
    assert len(lfemur.limits) == 3 and lfemur.limits[0] == (-160.0, 20.0)
    assert skel.bones["ltibia"].dofs == ("rx",) and skel.bones["lhipjoint"].dofs == ()
    assert skel.children["thorax"] == ["lowerneck", "lclavicle", "rclavicle"]
    # path (gz), text stream and binary stream give the same motion
    amc_text = _source_text("mocap/cmu/source/09_06.amc")
    a = read_amc(io.StringIO(amc_text), skel)
    b = read_asf_amc(p, data.fetch("mocap/cmu/source/09_06.amc"))
    c = read_asf_amc(io.StringIO(_source_text("mocap/cmu/source/09.asf")), io.BytesIO(amc_text.encode()))
    for other in (b, c):
        np.testing.assert_array_equal(a.global_positions(), other.global_positions())
    assert a.n_frames == 141 and a.fps == pytest.approx(120)


# ------------------------------------------------------------- malformed ASF
@pytest.fixture(scope="module")
def asf_text():
    if data.missing_reason("cmu-asfamc"):
        pytest.skip(data.missing_reason("cmu-asfamc"))
    return _source_text("mocap/cmu/source/09.asf")


@pytest.fixture(scope="module")
def amc_text():
    """The first three frames of 09_06.amc."""
    if data.missing_reason("cmu-asfamc"):
        pytest.skip(data.missing_reason("cmu-asfamc"))
    text = _source_text("mocap/cmu/source/09_06.amc")
    return text[: text.index("\n4\n") + 1]


def _asf_raises(text: str, match: str = r"line \d+"):
    with pytest.raises(BVHError, match=match) as info:
        read_asf(io.StringIO(text))
    return info.value


@pytest.mark.data("cmu-asfamc")
def test_asf_truncations_raise(asf_text):
    lines = asf_text.splitlines(keepends=True)
    assert lines[-1].strip() == "end"
    for k in range(len(lines) - 1):  # every line boundary before the final 'end'
        with pytest.raises(BVHError, match=r"line \d+"):
            read_asf(io.StringIO("".join(lines[:k])))


@pytest.mark.data("cmu-asfamc")
def test_asf_mutations_raise_naming_the_line(asf_text):
    def sub(old, new, count=1):
        assert old in asf_text, old
        return asf_text.replace(old, new, count)

    lines = asf_text.splitlines()
    ln = next(i for i, s in enumerate(lines) if "name lfemur" in s) + 1
    cases = {
        "direction not numeric": (sub("direction 0.34202 -0.939693 0", "direction 0.34202 abc 0"), "not a number"),
        "direction nan": (sub("direction 0.34202 -0.939693 0", "direction 0.34202 nan 0"), "not a finite"),
        "direction short": (sub("direction 0.34202 -0.939693 0", "direction 0.34202 -0.939693"), "needs 3"),
        "length": (sub("length 7.54288", "length x"), "not a number"),
        "negative length": (sub("length 7.54288", "length -6.9"), "negative"),
        "axis order": (sub("axis 0 0 20  XYZ", "axis 0 0 20  XXY"), "permutation"),
        "axis missing order": (sub("axis 0 0 20  XYZ", "axis 0 0 20"), "axis needs"),
        "translation dof": (sub("dof rx ry rz", "dof rx ry tz"), "unsupported dof"),
        "repeated dof": (sub("dof rx ry rz", "dof rx rx rz"), "repeated dof"),
        "limits count": (sub("(-160.0 20.0)\n", "", 1), "limits"),
        "limit not numeric": (sub("(-160.0 20.0)", "(-160.0 abc)"), "not numeric"),
        "unknown field": (sub("name lfemur", "name lfemur\n     colour red"), "unknown bone field"),
        "no name": (sub("name lfemur\n", ""), "no 'name'"),
        "no length": (sub("length 7.54288", ""), "no 'length'"),
        "duplicate bone": (sub("name ltibia", "name lfemur"), "duplicate bone"),
        "bone called root": (sub("name lfemur", "name root"), "root"),
        "unknown child": (sub("lfemur ltibia", "lfemur lshin"), "unknown bone 'lshin'"),
        "unknown parent": (sub("lfemur ltibia", "lthigh ltibia"), "unknown parent"),
        "two parents": (sub("lfemur ltibia", "lfemur ltibia\n    rfemur ltibia"), "already has a parent"),
        "missing end": (sub("  end\n:hierarchy", "  begin\n:hierarchy"), r"line \d+"),
        "root order": (sub("order TX TY TZ RX RY RZ", "order TX TY TZ RX RY RQ"), "root order"),
        "root axis": (sub("   axis XYZ", "   axis XY"), "permutation"),
        "angle unit": (sub("angle deg", "angle grad"), "deg or rad"),
    }
    for label, (text, pattern) in cases.items():
        try:
            err = _asf_raises(text, match=pattern)
        except AssertionError as exc:  # pragma: no cover - failure reporting only
            raise AssertionError(f"case {label!r}: {exc}") from exc
        assert re.match(r"line \d+: ", str(err)), (label, str(err))
    # a bone left out of the hierarchy
    text = asf_text.replace("    lfoot ltoes\n", "")
    _asf_raises(text, match=r"line \d+: bones not connected to the root.*ltoes")
    # a cycle: two bones parenting each other, detached from the root
    cyc = sub("    ltibia lfoot\n", "    ltoes lfoot\n")
    _asf_raises(cyc, match=r"line \d+: bones not reachable from the root.*lfoot.*ltoes")
    _asf_raises(sub("length 0.45", "length zero"), match=r"line \d+: :units length")
    _asf_raises(sub("   order TX TY TZ RX RY RZ\n", ""), match=r"line \d+: the :root section needs")
    err = _asf_raises(sub("direction 0.34202 -0.939693 0", "direction 0.34202 abc 0"))
    assert f"line {ln + 1}" in str(err)


# ------------------------------------------------------------- malformed AMC
@pytest.mark.data("cmu-asfamc")
def test_amc_truncations(asf_text, amc_text):
    skel = read_asf(io.StringIO(asf_text))
    lines = amc_text.splitlines(keepends=True)
    frame_starts = {i for i, s in enumerate(lines) if s.strip().isdigit()}
    first = min(frame_starts)
    assert read_amc(io.StringIO(amc_text), skel).n_frames == 3
    for k in range(len(lines)):
        text = "".join(lines[:k])
        if k in frame_starts and k > first:
            # a cut between frames is a valid shorter take
            assert read_amc(io.StringIO(text), skel).n_frames == sum(1 for f in frame_starts if f < k)
        else:
            with pytest.raises(BVHError, match=r"line \d+"):
                read_amc(io.StringIO(text), skel)
    # a cut right after a bone name, in the last frame
    cut = amc_text.rindex("rfemur ") + len("rfemur ")
    with pytest.raises(BVHError, match=r"line \d+: bone 'rfemur' has 0 values, expected 3"):
        read_amc(io.StringIO(amc_text[:cut]), skel)


@pytest.mark.data("cmu-asfamc")
def test_amc_mutations_raise_naming_the_line(asf_text, amc_text):
    skel = read_asf(io.StringIO(asf_text))
    lines = amc_text.splitlines()
    ln = next(i for i, s in enumerate(lines) if s.startswith("lfemur")) + 1  # in frame 1
    lf = lines[ln - 1].split()

    def with_line(new):
        out = list(lines)
        if new is None:
            del out[ln - 1]
        else:
            out[ln - 1] = new
        return "\n".join(out) + "\n"

    cases = {
        "not numeric": (with_line(f"lfemur {lf[1]} abc {lf[3]}"), f"line {ln}: .*not a finite number"),
        "nan": (with_line(f"lfemur {lf[1]} nan {lf[3]}"), f"line {ln}: "),
        "inf": (with_line(f"lfemur {lf[1]} 1e999 {lf[3]}"), f"line {ln}: "),
        "too few": (with_line(f"lfemur {lf[1]} {lf[2]}"), f"line {ln}: bone 'lfemur' has 2 values, expected 3"),
        "too many": (with_line(" ".join(lf) + " 1"), f"line {ln}: bone 'lfemur' has 4 values"),
        "unknown bone": (with_line("lthigh 1 2 3"), f"line {ln}: unknown bone 'lthigh'"),
        "missing bone": (with_line(None), "lacks values for \\['lfemur'\\]"),
        "twice": (with_line(" ".join(lf) + "\n" + " ".join(lf)), f"line {ln + 1}: bone 'lfemur' appears twice"),
        "frame numbers": (amc_text.replace("\n2\n", "\n5\n"), "frame number 5 follows frame 1"),
        "no frames": (amc_text[: amc_text.index("\n1\n") + 1], "no frames"),
        "data before frame": (amc_text.replace("\n1\n", "\n"), "before the first frame number"),
        "header after frames": (amc_text + ":DEGREES\n", "header line"),
    }
    for label, (text, pattern) in cases.items():
        try:
            with pytest.raises(BVHError, match=pattern):
                read_amc(io.StringIO(text), skel)
        except AssertionError as exc:  # pragma: no cover - failure reporting only
            raise AssertionError(f"case {label!r}: {exc}") from exc
    with pytest.raises(BVHError, match="empty ASF"):
        read_asf(io.StringIO(""))


_CHARS = st.sampled_from(list("0123456789.-+e \t\n()#:abcXYZ") + ["nan", "inf", "begin", "end", "root", "lfemur", "\n1\n"])
_EDITS = st.lists(
    st.tuples(st.floats(0, 1), st.integers(0, 3), _CHARS, st.sampled_from(["replace", "insert", "delete"])),
    min_size=1,
    max_size=4,
)


def _mutate(text, edits):
    for frac, n, s, op in edits:
        pos = int(frac * len(text))
        if op == "replace":
            text = text[:pos] + s + text[pos + n :]
        elif op == "insert":
            text = text[:pos] + s + text[pos:]
        else:
            text = text[:pos] + text[pos + n + 1 :]
    return text


@pytest.mark.data("cmu-asfamc")
@settings(max_examples=40, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(asf_edits=_EDITS, amc_edits=_EDITS)
def test_random_asf_amc_mutations_raise_only_bvherror(asf_text, amc_text, asf_edits, amc_edits):
    skel = read_asf(io.StringIO(asf_text))
    for kind, text in (("asf", _mutate(asf_text, asf_edits)), ("amc", _mutate(amc_text, amc_edits))):
        try:
            if kind == "asf":
                read_asf(io.StringIO(text))
            else:
                assert np.all(np.isfinite(read_amc(io.StringIO(text), skel).global_positions()))
        except BVHError as exc:
            assert re.match(r"line \d+: ", str(exc)), str(exc)
