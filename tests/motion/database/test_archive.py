"""The database's file (repro.motion.database.archive): MotionDatabase.load on damaged, truncated
or foreign files; save is atomic (issue 9, item 6); a file's identity (issue 23, 5).

What is asserted: every bad file -- missing, a folder, empty, truncated, random bytes, a
valid ``.npz`` of another program, missing keys, wrong dtypes or shapes, object
(pickled) arrays, bad JSON, NaN, inconsistent offsets or indices, a member whose header
declares more than it holds, seeded byte flips -- raises :class:`DataError` naming the
file (never ``BadZipFile``, ``KeyError``, ``JSONDecodeError``, ``ValueError`` or a later
``IndexError``); a file that loads is equal to what was saved.  ``save`` replaces the
file atomically: saving over the file a database was loaded from works, and a failed
save leaves the previous file intact with no temporary file behind.  A file says what it
is (``identity``, inside its hashed content) and ``load(..., identity=...)`` refuses
another database put in its place.
"""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import pytest

from repro.errors import DataError, MotionError
from repro.motion.database.clips import MotionDatabase


@pytest.fixture(scope="module")
def small(synthetic_db):
    db = synthetic_db  # the session's synthetic database (tests/conftest.py), this module's copy
    punch = np.flatnonzero(db.semantics == "punch")[:2]
    kick = np.flatnonzero(db.semantics == "kick")[:2]
    return db.select(np.concatenate([punch, kick]))


@pytest.fixture(scope="module")
def saved(small, tmp_path_factory):
    p = small.save(tmp_path_factory.mktemp("db") / "db.npz")
    with zipfile.ZipFile(p) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    return p, p.read_bytes(), members


def npy(a, allow_pickle=False) -> bytes:
    b = io.BytesIO()
    np.lib.format.write_array(b, np.asanyarray(a), allow_pickle=allow_pickle)
    return b.getvalue()


def arrays_of(members) -> dict:
    return {n[:-4]: np.lib.format.read_array(io.BytesIO(v)) for n, v in members.items()}


def write_zip(path, members: dict) -> None:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for n, v in members.items():
            zf.writestr(n, v)


def variant(saved, tmp_path, **changes):
    """The saved archive with members replaced (an array or raw bytes) or removed (None)."""
    _, _, members = saved
    out = dict(members)
    for k, v in changes.items():
        name = k + ".npy"
        if v is None:
            out.pop(name)
        else:
            out[name] = v if isinstance(v, bytes) else npy(v)
    p = tmp_path / "bad.npz"
    write_zip(p, out)
    return p


def header_with(saved, **fields) -> np.ndarray:
    h = json.loads(str(arrays_of(saved[2])["header"]))
    h.update(fields)
    return np.array(json.dumps(h))


def assert_data_error(path, match=None):
    with pytest.raises(DataError, match=match) as e:
        MotionDatabase.load(path)
    assert str(path) in str(e.value)
    return str(e.value)


# ------------------------------------------------------------------- files
def test_round_trip_still_exact(small, saved):
    assert MotionDatabase.load(saved[0]).equals(small)


def test_missing_file_and_folder(tmp_path):
    assert_data_error(tmp_path / "nope.npz", "no such file")
    assert_data_error(tmp_path, "folder")


@pytest.mark.parametrize("cut", [0, 1, 4, 30, 0.25, 0.5, 0.9, -22, -1])
def test_truncated(saved, tmp_path, cut):
    raw = saved[1]
    n = int(len(raw) * cut) if isinstance(cut, float) else (cut if cut >= 0 else len(raw) + cut)
    p = tmp_path / "t.npz"
    p.write_bytes(raw[:n])
    assert_data_error(p)


def test_random_bytes_and_other_formats(tmp_path):
    rng = np.random.default_rng(0)
    for i, data in enumerate([rng.bytes(3000), b"PK\x03\x04" + rng.bytes(500), b"HIERARCHY\nROOT Hips\n",
                              json.dumps({"format": "repro.motion.database.clips/1"}).encode()]):
        p = tmp_path / f"r{i}.npz"
        p.write_bytes(data)
        assert_data_error(p)


def test_valid_npz_of_another_program(tmp_path):
    p = tmp_path / "other.npz"
    np.savez(p, x=np.arange(4), y=np.eye(3))
    assert_data_error(p, "header")
    np.savez(p)  # an empty archive
    assert_data_error(p)
    write_zip(p, {"readme.txt": b"hello"})
    assert_data_error(p)


def test_object_arrays_are_refused(saved, tmp_path):
    names = np.array(["a", "b", "c", "d"], dtype=object)
    p = variant(saved, tmp_path, names=npy(names, allow_pickle=True))
    assert_data_error(p, "objects")


def test_member_declaring_more_than_it_holds(saved, tmp_path):
    """A header declaring 8 TB is refused before anything is allocated."""
    b = io.BytesIO()
    np.lib.format.write_array_header_1_0(b, {"descr": "<f8", "fortran_order": False, "shape": (10**12, 3)})
    p = variant(saved, tmp_path, traj=b.getvalue() + b"\0" * 64)
    assert_data_error(p, "claims shape")
    b = io.BytesIO()
    np.lib.format.write_array_header_1_0(b, {"descr": "<f8", "fortran_order": False, "shape": (100,)})
    p = variant(saved, tmp_path, traj=b.getvalue() + b"\0" * 80)  # 80 of 800 bytes
    assert_data_error(p)


# ----------------------------------------------------------------- content
KEYS = ["header", "names", "semantics", "hit_frame", "n_frames", "traj", "traj_start", "pose_points", "pose_clip",
        "pose_start", "box_min", "actor0_offsets", "actor0_parents", "motion0_rotations", "motion0_positions"]


@pytest.mark.parametrize("key", KEYS)
def test_missing_key(saved, tmp_path, key):
    assert_data_error(variant(saved, tmp_path, **{key: None}), key)


def _bad_contents(saved):
    a = arrays_of(saved[2])
    C = a["n_frames"].size
    nan_pp = a["pose_points"].copy()
    nan_pp[3, 2, 1] = np.nan
    inf_traj = a["traj"].copy()
    inf_traj[-1, 0] = np.inf
    far = a["traj_start"].copy()
    far[-1] += 50  # clip offsets beyond the pose count
    swapped = a["pose_clip"].copy()
    swapped[[0, -1]] = swapped[[-1, 0]]
    box = a["box_min"].copy()
    box[0, 0] = a["box_max"][0, 0] + 1.0
    rot0 = a["motion0_rotations"]
    return {
        "string hit frames": dict(hit_frame=a["hit_frame"].astype(str)),
        "float hit frames": dict(hit_frame=a["hit_frame"] + 0.5),
        "complex scale": dict(scale=a["scale"].astype(complex)),
        "2-D box": dict(box_min=a["box_min"][:, :2]),
        "short n_frames": dict(n_frames=a["n_frames"][:-1]),
        "names not JSON": dict(names=np.array("[not json")),
        "names not strings": dict(names=np.array(json.dumps([1, 2, 3, 4]))),
        "names a number array": dict(names=np.arange(C)),
        "duplicate names": dict(names=np.array(json.dumps(["a", "a", "b", "c"]))),
        "semantics unknown": dict(semantics=np.array(json.dumps(["punch", "dance", "kick", "kick"]))),
        "hit segment unknown": dict(hit_roles=np.array(json.dumps(["nose"] * C))),
        "hit_where unknown": dict(hit_wheres=np.array(json.dumps(["elbow"] * C))),
        "header not JSON": dict(header=np.array("{bad")),
        "header deeply nested": dict(header=np.array("[" * 100_000 + "]" * 100_000)),
        "header a list": dict(header=np.array("[]")),
        "header format": dict(header=header_with(saved, format="something/2")),
        "header fps NaN": dict(header=header_with(saved, fps=float("nan"))),
        "header fps text": dict(header=header_with(saved, fps="30")),
        "header window 0": dict(header=header_with(saved, window=0)),
        "header window 2": dict(header=header_with(saved, window=2)),
        "header no actors": dict(header=header_with(saved, actors=[])),
        "header actor junk": dict(header=header_with(saved, actors=[3])),
        "header motions junk": dict(header=header_with(saved, motions={"a": 1})),
        "header motion clip 99": dict(header=header_with(saved, motions=[
            {**json.loads(str(a["header"]))["motions"][0], "clip": 99}])),
        "header no motions": dict(header=header_with(saved, motions=[])),
        "header meta list": dict(header=header_with(saved, meta=[1])),
        "header pose role unknown": dict(header=header_with(saved, pose_roles=["pelvis", "tail"])),
        "NaN pose point": dict(pose_points=nan_pp),
        "inf trajectory": dict(traj=inf_traj),
        "offsets beyond poses": dict(traj_start=far),
        "pose_start beyond poses": dict(pose_start=far),
        "pose_clip shuffled": dict(pose_clip=swapped),
        "pose_frame shifted": dict(pose_frame=a["pose_frame"] + 1),
        "hit frame beyond clip": dict(hit_frame=a["hit_frame"] + 10_000),
        "negative hit frame": dict(hit_frame=a["hit_frame"] * 0 - 1),
        "actor index beyond actors": dict(actor=a["actor"] + 5),
        "source clip beyond clips": dict(source_clip=a["source_clip"] + C),
        "zero size_a": dict(size_a=a["size_a"] * 0),
        "inverted box": dict(box_min=box),
        "pose_points wrong width": dict(pose_points=a["pose_points"][:, :5]),
        "motion rotations too few frames": dict(motion0_rotations=rot0[:-1]),
        "motion rotations zero": dict(motion0_rotations=rot0 * 0),
        "motion rotations not unit": dict(motion0_rotations=rot0 * 2),
        "motion positions NaN": dict(motion0_positions=a["motion0_positions"] * np.nan),
        "actor parents cyclic": dict(actor0_parents=np.roll(a["actor0_parents"], 1)),
        "actor parents float": dict(actor0_parents=a["actor0_parents"].astype(float)),
        "actor offsets short": dict(actor0_offsets=a["actor0_offsets"][:-1]),
        "end site offsets 2-D": dict(actor0_end_site_offsets=a["actor0_end_site_offsets"][:, :2]),
    }


@pytest.fixture(scope="module")
def bad_contents(saved):
    return _bad_contents(saved)


_IDS = ["string hit frames", "float hit frames", "complex scale", "2-D box", "short n_frames", "names not JSON",
        "names not strings", "names a number array", "duplicate names", "semantics unknown", "hit segment unknown",
        "hit_where unknown", "header not JSON", "header deeply nested", "header a list", "header format",
        "header fps NaN", "header fps text", "header window 0", "header window 2", "header no actors",
        "header actor junk", "header motions junk", "header motion clip 99", "header no motions",
        "header meta list", "header pose role unknown", "NaN pose point", "inf trajectory", "offsets beyond poses",
        "pose_start beyond poses", "pose_clip shuffled", "pose_frame shifted", "hit frame beyond clip",
        "negative hit frame", "actor index beyond actors", "source clip beyond clips", "zero size_a",
        "inverted box", "pose_points wrong width", "motion rotations too few frames", "motion rotations zero",
        "motion rotations not unit", "motion positions NaN", "actor parents cyclic", "actor parents float",
        "actor offsets short", "end site offsets 2-D"]


def test_case_table_is_complete(bad_contents):
    assert sorted(bad_contents) == sorted(_IDS)


@pytest.mark.parametrize("case", _IDS)
def test_bad_content(saved, tmp_path, bad_contents, case):
    assert_data_error(variant(saved, tmp_path, **bad_contents[case]))


def test_seeded_byte_flips(saved, small, tmp_path):
    """Flipped bytes anywhere: DataError, or (a flip in unused zip fields) an equal database."""
    raw = saved[1]
    rng = np.random.default_rng(9)
    p = tmp_path / "flip.npz"
    for _ in range(60):
        b = bytearray(raw)
        for pos in rng.integers(0, len(b), int(rng.integers(1, 4))):
            b[pos] ^= int(rng.integers(1, 256))
        p.write_bytes(bytes(b))
        try:
            back = MotionDatabase.load(p)
        except DataError as e:
            assert str(p) in str(e)
        else:
            assert back.equals(small)


def test_stream_and_size_cap(saved):
    with open(saved[0], "rb") as fh:
        assert MotionDatabase.load(fh).n_clips == 4
    with pytest.raises(DataError, match="more than"):
        MotionDatabase.load(saved[0], max_bytes=1000)


# -------------------------------------------------------------------- save
def test_save_over_the_loaded_file(small, tmp_path):
    p = small.save(tmp_path / "db.npz")
    back = MotionDatabase.load(p)
    back.save(p)
    assert MotionDatabase.load(p).equals(small)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["db.npz"]


def test_failed_save_keeps_the_previous_file(small, tmp_path, monkeypatch):
    p = small.save(tmp_path / "db.npz")
    before = p.read_bytes()

    def boom(fh, **kw):
        fh.write(b"PK partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", boom)
    with pytest.raises(DataError, match="cannot write"):
        small.save(p)
    monkeypatch.undo()
    assert p.read_bytes() == before
    assert sorted(x.name for x in tmp_path.iterdir()) == ["db.npz"]


def test_save_bad_targets_and_meta(small, tmp_path):
    (tmp_path / "dir.npz").mkdir()
    with pytest.raises(DataError, match="folder"):
        small.save(tmp_path / "dir.npz")
    with pytest.raises(DataError):
        small.save(None)
    p = small.save(tmp_path / "db.npz")
    before = p.read_bytes()
    odd = small.select(np.arange(small.n_clips))
    odd.meta["thing"] = object()
    with pytest.raises(MotionError, match="JSON"):
        odd.save(p)
    assert p.read_bytes() == before


ID = {"base": "synthetic", "factor": 10, "seed": 0, "format": 2}


def test_identity_round_trip_and_mismatch(small, tmp_path):
    p = small.save(tmp_path / "a.npz", identity=ID)
    assert MotionDatabase.load(p, identity=ID).equals(small)
    assert MotionDatabase.load(p).equals(small)  # no identity asked: read as any database
    with pytest.raises(DataError, match=r"another database .*\['factor'\]"):
        MotionDatabase.load(p, identity=dict(ID, factor=20))
    q = small.save(tmp_path / "b.npz")  # saved without identity
    with pytest.raises(DataError, match="holds no identity"):
        MotionDatabase.load(q, identity=ID)
    assert MotionDatabase.load(q).equals(small)


@pytest.mark.parametrize("bad", [["x"], "factor=10", {"x": math.nan}, {"x": object()}])
def test_an_identity_that_is_not_a_json_object_is_refused(small, tmp_path, bad):
    with pytest.raises(MotionError, match="identity"):
        small.save(tmp_path / "a.npz", identity=bad)
    assert not (tmp_path / "a.npz").exists()


def test_load_checks_its_arguments(small, tmp_path):
    p = small.save(tmp_path / "a.npz")
    with pytest.raises(DataError, match="identity must be a mapping"):
        MotionDatabase.load(p, identity=["x"])
    for bad in ("10", None, -1, 1.5):
        with pytest.raises(DataError, match="max_bytes must be an integer"):
            MotionDatabase.load(p, max_bytes=bad)
