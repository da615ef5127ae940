"""ASF/AMC readers against the defects found by mutation fuzzing (issue 9, section 2).

Malformed integers (item 3), unreadable paths (item 3), bounded reads and allocation
(item 2) and deep hierarchies (item 8).  The files are generated here, so these tests
need no data.
"""

from __future__ import annotations

import gzip
import io
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from repro.errors import BVHError, ReproError
from repro.motion import read_amc, read_asf, read_asf_amc
from repro.motion.io import asf, asfamc


def chain_asf(n: int, *, dofs: bool = True, ids: bool = True) -> str:
    """An ASF whose n bones form one chain below the root (depth n)."""
    out = [
        ":version 1.10", ":name deep", ":units", "  mass 1.0", "  length 0.45", "  angle deg",
        ":root", "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0", "   orientation 0 0 0",
        ":bonedata",
    ]  # fmt: skip
    for i in range(n):
        out += ["  begin"] + ([f"     id {i + 1}"] if ids else []) + [
            f"     name b{i}", "     direction 0 1 0", "     length 1", "     axis 0 0 10 XYZ",
        ]  # fmt: skip
        if dofs:
            out += ["     dof rx ry rz", "     limits (-180 180)", "            (-180 180)", "            (-180 180)"]
        out += ["  end"]
    out += [":hierarchy", "  begin", "    root b0"] + [f"    b{i} b{i + 1}" for i in range(n - 1)] + ["  end"]
    return "\n".join(out) + "\n"


def chain_amc(n: int, frames: int = 2, *, dofs: bool = True) -> str:
    out = [":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(1, frames + 1):
        out += [str(f), f"root 0 {f} 0 0 0 0"]
        if dofs:
            out += [f"b{i} 1 2 {f}" for i in range(n)]
    return "\n".join(out) + "\n"


SMALL_ASF = chain_asf(3)
SMALL_AMC = chain_amc(3)


def _line_of(text: str, needle: str) -> int:
    return text.split("\n").index(needle) + 1


def test_small_chain_reads():
    m = read_asf_amc(io.StringIO(SMALL_ASF), io.StringIO(SMALL_AMC))
    assert m.joint_names == ["root", "b0", "b1", "b2"] and m.n_frames == 2
    assert np.isfinite(m.global_positions()).all()


# --------------------------------------------------------- item 3: integers
@pytest.mark.parametrize("value", ["+-5", "²", "\u0663", "1_0", "٣4", "-+1", "9" * 30, "9" * 5000, "0x1f", "1.0"])
def test_bad_asf_bone_id_is_a_bvherror_naming_line_and_value(value):
    text = SMALL_ASF.replace("     id 2\n", f"     id {value}\n")
    line = _line_of(text, f"     id {value}")
    with pytest.raises(BVHError, match=rf"^line {line}: bone id must be an integer") as exc:
        read_asf(io.StringIO(text))
    assert repr(value[:40]) in str(exc.value)


@pytest.mark.parametrize("value", ["+5", "-5", "007"])
def test_plain_asf_bone_ids_still_read(value):
    text = SMALL_ASF.replace("     id 2\n", f"     id {value}\n")
    assert read_asf(io.StringIO(text)).bones["b1"].id == int(value)


@pytest.mark.parametrize("value", ["²", "\u0661", "\u0662", "1_0", "2" * 5000, "-2", "²3"])
def test_bad_amc_frame_number_is_a_bvherror_naming_the_line(value):
    # the second frame's number; '\u0662' is an Arabic-Indic 2, which int() takes for 2
    lines = SMALL_AMC.split("\n")
    k = lines.index("2")
    lines[k] = value
    with pytest.raises(BVHError, match=rf"^line {k + 1}: frame number .* is not a plain integer"):
        read_amc(io.StringIO("\n".join(lines)), read_asf(io.StringIO(SMALL_ASF)))


def test_non_ascii_first_frame_number_is_rejected():
    text = SMALL_AMC.replace("\n1\n", "\n\u0661\n", 1)  # Arabic-Indic 1: int() gives 1
    with pytest.raises(BVHError, match=r"^line 3: frame number"):
        read_amc(io.StringIO(text), read_asf(io.StringIO(SMALL_ASF)))


@pytest.mark.parametrize("value", ["\u0663", "１", "1_0"])  # float() takes all three
def test_non_ascii_or_underscore_numbers_are_rejected(value):
    asf = SMALL_ASF.replace("     length 1\n", f"     length {value}\n", 1)
    with pytest.raises(BVHError, match=rf"^line {_line_of(asf, f'     length {value}')}: length value"):
        read_asf(io.StringIO(asf))
    asf = SMALL_ASF.replace("(-180 180)", f"(-180 {value})", 1)
    with pytest.raises(BVHError, match=r"^line \d+: limit"):
        read_asf(io.StringIO(asf))
    amc = SMALL_AMC.replace("b1 1 2 2", f"b1 1 {value} 2")
    with pytest.raises(BVHError, match=rf"^line {_line_of(amc, f'b1 1 {value} 2')}: bone 'b1' has a value"):
        read_amc(io.StringIO(amc), read_asf(io.StringIO(SMALL_ASF)))


def test_unknown_single_token_line_names_the_line():
    amc = SMALL_AMC.replace("b1 1 2 2", "nosuchbone")
    with pytest.raises(BVHError, match=rf"^line {_line_of(amc, 'nosuchbone')}: 'nosuchbone' is neither"):
        read_amc(io.StringIO(amc), read_asf(io.StringIO(SMALL_ASF)))


# ------------------------------------------------------------ item 3: paths
def test_missing_file_and_folder_are_bvherrors_naming_the_path(tmp_path):
    skel = read_asf(io.StringIO(SMALL_ASF))
    for reader in (read_asf, lambda p: read_amc(p, skel)):
        with pytest.raises(BVHError, match="absent.asf: no such file"):
            reader(tmp_path / "absent.asf")
        with pytest.raises(BVHError, match=f"{tmp_path.name}: is a folder"):
            reader(tmp_path)
    with pytest.raises(BVHError, match="corrupt gzip"):
        (tmp_path / "bad.amc.gz").write_bytes(b"\x1f\x8b\x08\x00garbage")
        read_amc(tmp_path / "bad.amc.gz", skel)


def test_non_utf8_names_the_source(tmp_path):
    p = tmp_path / "latin.asf"
    p.write_bytes(SMALL_ASF.replace(":name deep", ":name d\xe9ep").encode("latin-1"))
    with pytest.raises(BVHError, match=r"latin.asf, line 2: not valid UTF-8"):
        read_asf(p)


# ------------------------------------------------------ item 2: allocation
def test_reads_are_capped(tmp_path, monkeypatch):
    monkeypatch.setattr(asf, "MAX_ASF_BYTES", 1000)
    with pytest.raises(BVHError, match="more than 1000 bytes"):
        read_asf(io.StringIO(SMALL_ASF + "# padding\n" * 100))
    monkeypatch.setattr(asfamc, "MAX_AMC_BYTES", 5000)
    bomb = tmp_path / "bomb.amc.gz"
    bomb.write_bytes(gzip.compress(SMALL_AMC.encode() + b"#" * 100_000))  # ~100 KB from a few hundred bytes
    assert bomb.stat().st_size < 1000
    with pytest.raises(BVHError, match="bomb.amc.gz: more than 5000 bytes"):
        read_amc(bomb, read_asf(io.StringIO(SMALL_ASF)))


_LIMITED = textwrap.dedent(
    """
    import io, resource, sys
    resource.setrlimit(resource.RLIMIT_AS, (1 << 31, 1 << 31))  # 2 GiB address space
    sys.path.insert(0, sys.argv[1])
    from test_asfamc_malformed import chain_asf, chain_amc
    from repro.errors import ReproError
    from repro.motion import read_asf, read_amc
    skel = read_asf(io.StringIO(chain_asf(3000, dofs=False, ids=False)))
    amc = chain_amc(3000, frames=20000, dofs=False)  # 20,000 frames of one 'root' line: 0.5 MB
    try:
        read_amc(io.StringIO(amc), skel)
    except ReproError as exc:
        print("ReproError", exc)
    """
)


def test_many_bones_without_dofs_times_many_frames_is_refused_before_allocating():
    # 3,001 joints x 20,000 frames x 56 bytes = 3.4 GB of arrays from two files of < 1 MB
    root = str(Path(__file__).resolve().parents[2])  # this checkout's repro first
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]))
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")  # small address space
    run = subprocess.run(
        [sys.executable, "-c", _LIMITED, os.path.dirname(__file__)],
        capture_output=True, text=True, timeout=120, env=env,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.startswith("ReproError") and "20000 frames x 3001 joints" in run.stdout, run.stdout


def test_motion_size_bound_scales_with_the_file():
    # the same skeleton with dofs: every joint's values are in the file, so it reads
    skel = read_asf(io.StringIO(chain_asf(200)))
    m = read_amc(io.StringIO(chain_amc(200, frames=50)), skel)
    assert m.rotations.shape == (50, 201, 4)


# ---------------------------------------------------- item 8: deep chains
def test_deep_chain_reads():
    # an 8,000-deep chain reads without recursion; that the work is linear is checked by
    # counting operations (below), never by timing in a test
    n = 8000
    m = read_asf_amc(io.StringIO(chain_asf(n)), io.StringIO(chain_amc(n)))
    assert m.rotations.shape[1] == n + 1


@pytest.mark.parametrize("n", [10, 2000])
def test_rotations_are_vectorised_over_joints(n, monkeypatch):
    # one Euler conversion per distinct dof sequence / axis order, not one per joint
    calls = []
    real = asfamc.euler_to_quat
    for module in (asf, asfamc):  # the axis frames C (asf) and the motions M (asfamc)
        monkeypatch.setattr(module, "euler_to_quat", lambda *a, **k: calls.append(1) or real(*a, **k))
    read_asf_amc(io.StringIO(chain_asf(n)), io.StringIO(chain_amc(n)))
    assert len(calls) <= 4, len(calls)


def test_deep_asf_amc_to_motion_without_recursion_error():
    n = 8000  # far beyond the recursion limit
    asf, amc = chain_asf(n), chain_amc(n, frames=2)
    limit = sys.getrecursionlimit()
    assert n > 5 * limit
    skel = read_asf(io.StringIO(asf))
    assert len(skel.joint_names) == n + 1
    m = read_amc(io.StringIO(amc), skel)
    assert m.n_joints == n + 1 and m.parents[-1] == n - 1
    assert m.end_site_parents.tolist() == [n]
    # offsets: each joint one unit above its parent (the parent bone's direction x length)
    np.testing.assert_array_equal(m.offsets[2:], np.tile([0.0, 1.0, 0.0], (n - 1, 1)))
    # every bone the same local rotation C M C^-1, vectorised over joints
    np.testing.assert_allclose(m.rotations[1, 2:], np.broadcast_to(m.rotations[1, 1], (n - 1, 4)))
    assert not np.allclose(m.rotations[0, 1], m.rotations[1, 1])


def test_grouped_rotations_match_per_joint_formula():
    # a skeleton mixing dof sequences and axis orders: vectorising by group changes nothing
    asf = chain_asf(4)
    start = asf.index("     name b1\n")
    end = asf.index("  end", start)
    b1 = ["name b1", "direction 0 1 0", "length 1", "axis 5 -20 10 ZXY", "dof rz rx", "limits (-180 180)", "(-90 90)"]
    asf = asf[:start] + "".join(f"     {ln}\n" for ln in b1) + asf[end:]
    rng = np.random.default_rng(9)
    lines = [":DEGREES"]
    for f in range(1, 4):
        lines += [str(f), "root " + " ".join(f"{x:.3f}" for x in rng.uniform(-90, 90, 6))]
        for i in range(4):
            lines.append(f"b{i} " + " ".join(f"{x:.3f}" for x in rng.uniform(-90, 90, 2 if i == 1 else 3)))
    skel = read_asf(io.StringIO(asf))
    assert skel.bones["b1"].dofs == ("rz", "rx") and skel.bones["b1"].axis_order == "ZXY"
    m = read_amc(io.StringIO("\n".join(lines) + "\n"), skel)
    from repro.motion.core.quaternion import euler_to_quat, quat_multiply

    conj = np.array([-1.0, -1.0, -1.0, 1.0])
    for j, name in enumerate(skel.joint_names[1:], start=1):
        b = skel.bones[name]
        c = euler_to_quat(b.axis_order.lower(), b.axis)
        vals = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith(name + " ")])
        want = quat_multiply(quat_multiply(c, euler_to_quat("".join(d[1] for d in b.dofs), vals)), c * conj)
        np.testing.assert_allclose(m.rotations[:, j], want, atol=1e-12)
    np.testing.assert_allclose(skel.axis_quaternions()[2], euler_to_quat("zxy", [5, -20, 10]), atol=1e-12)


def test_every_error_is_a_repro_error():
    for bad in ("id +-5", "id ²"):
        with pytest.raises(ReproError):
            read_asf(io.StringIO(SMALL_ASF.replace("id 1", bad)))


@pytest.mark.parametrize("value", ["0_45", "\u0663"])
def test_length_unit_must_be_a_plain_number(value):
    asf = SMALL_ASF.replace("  length 0.45\n", f"  length {value}\n")
    with pytest.raises(BVHError, match=rf"^line 5: :units length must be a number > 0, got '{value}'"):
        read_asf(io.StringIO(asf))


# --------------------------------------------------------- finite input, infinite result (fuzz finding)
_NUMBER = __import__("re").compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


@pytest.mark.parametrize(
    "direction, length", [("0 1.7e308 0", "2"), ("0 2 0", "1.7e308"), ("1e200 0 0", "1e200")]
)
def test_bone_vector_that_overflows_is_a_bvherror_naming_the_bone(direction, length):
    # finite values whose product direction x length is inf (read_asf warned 'overflow encountered in multiply')
    asf = SMALL_ASF.replace(
        "     name b1\n     direction 0 1 0\n     length 1\n",
        f"     name b1\n     direction {direction}\n     length {length}\n",
        1,
    )
    assert asf != SMALL_ASF
    begin = asf.split("\n").index("     name b1") - 1  # 0-based index of 'name b1' - 2, plus 1: 'begin'
    with pytest.raises(BVHError, match=rf"^line {begin}: bone 'b1': direction x length overflows"):
        read_asf(io.StringIO(asf))


def test_every_huge_finite_value_is_loaded_finite_or_a_bvherror():
    """Each number of a small ASF and AMC in turn replaced by a huge finite value: never inf, never a warning.

    (RuntimeWarnings from repro are errors in this suite, pyproject ``filterwarnings``.)
    """
    cases = 0
    for which, text in (("asf", SMALL_ASF), ("amc", SMALL_AMC)):
        spans = [m.span() for m in _NUMBER.finditer(text)]
        for a, b in spans:
            for value in ("1.7e308", "-1.7e308", "1e200"):
                mutated = text[:a] + value + text[b:]
                asf, amc = (mutated, SMALL_AMC) if which == "asf" else (SMALL_ASF, mutated)
                try:
                    m = read_asf_amc(io.StringIO(asf), io.StringIO(amc))
                except BVHError:
                    continue
                finally:
                    cases += 1
                assert np.isfinite(m.global_positions()).all(), (which, a, value)
                assert np.isfinite(m.offsets).all() and np.isfinite(m.end_site_offsets).all()
    assert cases > 100
