"""The motion database's file (Pronost et al., Section 3.2: "the motion database is so composed of
elements including the motion clip, the definition of the skeleton, the semantic information and
some necessary quantitative data"): one ``.npz`` archive without pickles.

Arrays are stored as they are; strings and structure (joint names, channels, roles, metadata)
as JSON strings.  :func:`save_database` writes atomically; :func:`load_database` checks
everything before use (the archive, each array's declared size, dtypes, shapes, finiteness, the
header and the consistency of the arrays) so that a damaged or foreign file is a
:class:`~repro.errors.DataError` naming it.  :meth:`MotionDatabase.save
<repro.motion.database.clips.MotionDatabase.save>` and :meth:`~repro.motion.database.clips.MotionDatabase.load`
are the entry points.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from repro.checks import as_int
from repro.errors import DataError, MotionError, ReproError
from repro.io import MAX_READ_BYTES, atomic_path, read_npz
from repro.motion.body.skeleton import Skeleton
from repro.motion.core.motion import Motion
from repro.motion.database.annotation import HIT_ROLES, SEMANTICS

__all__ = ["CLIP_NUM", "CLIP_STR", "DB_FORMAT", "POSE_NUM", "load_database", "save_database"]

#: The format name a database file carries in its header.
DB_FORMAT = "repro.motion.database.clips/1"

#: The per-clip string arrays, the other per-clip arrays and the per-pose (and trajectory) arrays.
CLIP_STR = ("names", "sources", "semantics", "kinds", "sides", "levels", "hit_roles", "hit_joints", "hit_wheres")
CLIP_NUM = ("hit_frame", "n_frames", "actor", "scale", "size_a", "source_clip", "source_time", "mirror", "warp",
            "noise", "box_min", "box_max", "hit_position", "traj_start", "pose_start")
POSE_NUM = ("traj", "pose_points", "pose_clip", "pose_frame", "pose_heading", "pose_origin")


def save_database(db, path, *, identity: Mapping | None = None) -> Path:
    """Write the database to ``path`` (``.npz``, no pickles), atomically.

    Arrays are stored as they are; strings and structure (joint names, channels,
    roles, metadata) as JSON strings.  :func:`load_database` gives back an equal
    database (:meth:`~repro.motion.database.clips.MotionDatabase.equals`).  The file is
    written to a temporary file beside ``path`` and moved into place only once complete
    (:func:`repro.io.atomic_path`), so saving over the file a database was loaded from is
    safe, and a failed save leaves the previous file as it was (a ``path`` that is a symlink is replaced by the file, the
    file it pointed to is left alone).

    ``identity``: a JSON object saying what the file is (for a cache: the inputs it was
    built from, e.g. base, factor, seed, code fingerprint, format); stored in the
    archive (member ``identity``, covered by the archive's CRCs and by any hash of the
    file) so that ``load_database(cls, path, identity=...)`` refuses a file that is another one,
    even a valid database put in its place.

    Raises
    ------
    repro.errors.MotionError
        :attr:`meta` or ``identity`` is not JSON-serialisable (``identity`` not an object).
    repro.errors.DataError
        ``path`` cannot be written (a folder, no permission, disk full ...).
    """
    try:
        path = Path(path)
    except TypeError:
        raise DataError(f"expected a path to save the database to, got {type(path).__name__}") from None
    out = _archive_arrays(db, identity)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    if path.is_dir():
        raise DataError(f"{path}: is a folder; cannot save the database there")
    try:
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **out)
    except OSError as exc:
        raise DataError(f"{path}: cannot write the database: {exc}") from exc
    return path


def _archive_arrays(db, identity: Mapping | None) -> dict[str, np.ndarray]:
    """The archive's members: the database's arrays, its actors' and stored motions' arrays, the JSON header."""
    out: dict[str, np.ndarray] = {}
    if identity is not None:
        if not isinstance(identity, Mapping):
            raise MotionError(f"identity must be a mapping (a JSON object), got {type(identity).__name__}")
        try:
            out["identity"] = np.array(json.dumps(dict(identity), sort_keys=True, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise MotionError(f"identity cannot be saved as JSON: {exc}") from None
    for k in CLIP_STR:
        out[k] = np.array(json.dumps(getattr(db, k).tolist()))
    for k in CLIP_NUM + POSE_NUM:
        out[k] = np.asarray(getattr(db, k))
    for a, sk in enumerate(db.actors):
        out[f"actor{a}_parents"] = np.asarray(sk.parents)
        out[f"actor{a}_offsets"] = np.asarray(sk.offsets)
        out[f"actor{a}_end_site_parents"] = np.asarray(sk.end_site_parents)
        out[f"actor{a}_end_site_offsets"] = np.asarray(sk.end_site_offsets)
    motions = db.stored_motions()
    motion_ids = sorted(motions)
    for i in motion_ids:
        m = motions[i]
        for f in ("parents", "offsets", "rotations", "positions", "end_site_parents", "end_site_offsets"):
            out[f"motion{i}_{f}"] = np.asarray(getattr(m, f))
    header = {
        "format": DB_FORMAT,
        "fps": db.fps,
        "pose_roles": list(db.pose_roles),
        "window": db.window,
        "step": db.step,
        "meta": db.meta,
        "actors": [{"joint_names": sk.joint_names, "channels": [list(c) for c in sk.channels or []],
                    "unit_m": sk.unit_m, "roles": dict(sk.roles)} for sk in db.actors],
        "motions": [{"clip": i, "joint_names": motions[i].joint_names,
                     "channels": [list(c) for c in motions[i].channels],
                     "frame_time": motions[i].frame_time, "unit_m": motions[i].unit_m,
                     "source": motions[i].source} for i in motion_ids],
    }
    try:
        out["header"] = np.array(json.dumps(header))
    except (TypeError, ValueError) as exc:
        raise MotionError(f"the database's meta (or an actor's roles) cannot be saved as JSON: {exc}") from None
    return out


def load_database(cls, path, *, max_bytes: int = MAX_READ_BYTES, identity: Mapping | None = None):
    """Read a database written by :func:`save_database` (``allow_pickle=False``), as a ``cls``.

    Everything is checked before use: the archive, every array's declared size
    against its bytes (before allocating), dtypes (no object arrays), shapes,
    finiteness, the JSON header and the consistency of the arrays (clip and pose
    offsets, frame indices, actors, stored motions), so that a damaged file fails
    here rather than later with an ``IndexError``.

    Parameters
    ----------
    path : path-like or binary stream
    max_bytes : int, default :data:`repro.io.MAX_READ_BYTES` (2 GiB)
        Cap on the file's bytes and on the decompressed arrays.
    identity : mapping, optional
        What the file must be: the archive's ``identity`` (written by ``save(...,
        identity=...)``) must equal it, else the file is refused (another database in
        its place, or one saved without an identity).

    Raises
    ------
    repro.errors.DataError
        A missing, unreadable, truncated, corrupt or foreign file, or one whose
        content is inconsistent, or whose identity is not ``identity``; the message
        names the file and what is wrong.
    """
    where = str(path) if not hasattr(path, "read") else str(getattr(path, "name", "<stream>"))
    max_bytes = as_int(max_bytes, "max_bytes", lo=0, error=DataError)
    if identity is not None and not isinstance(identity, Mapping):
        raise DataError(f"identity must be a mapping (a JSON object), got {type(identity).__name__}")
    # the archive, each array's declared size (before allocating) and dtypes: repro.io.read_npz;
    # finiteness and the schema: _Check below, with messages about the database
    arrays = read_npz(path, error=DataError, finite=False, max_bytes=max_bytes)
    if not arrays:
        raise DataError(f"{where}: not a motion database (the archive holds no .npy arrays)")
    if identity is not None:
        try:  # (compared as JSON: the form save wrote it in)
            want = json.loads(json.dumps(dict(identity), sort_keys=True, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise DataError(f"identity cannot be compared as JSON: {exc}") from None
        got = _Check(arrays, where).json("identity") if "identity" in arrays else None
        if got != want:
            differ = (sorted(k for k in set(got) | set(want) if got.get(k) != want.get(k))
                      if isinstance(got, dict) else None)
            raise DataError(f"{where}: " + ("holds no identity" if got is None else
                            f"is another database (its identity differs in {differ or 'its form'})")
                            + "; refusing it for the one requested")
    return _database_from_arrays(cls, arrays, where)


class _Check:
    """Schema checks of a loaded database, raising DataError naming the file."""

    def __init__(self, arrays: dict, where: str):
        self.arrays, self.where = arrays, where

    def fail(self, msg: str):
        raise DataError(f"{self.where}: {msg}")

    def array(self, key: str) -> np.ndarray:
        if key not in self.arrays:
            shown = ", ".join(sorted(self.arrays)[:8]) + (", ..." if len(self.arrays) > 8 else "")
            self.fail(f"no array {key!r}: not a complete motion database written by MotionDatabase.save "
                      f"(holds: {shown})")
        return self.arrays[key]

    def json(self, key: str):
        a = self.array(key)
        if a.shape != () or a.dtype.kind != "U":
            self.fail(f"{key!r} must be a JSON string, got a {a.dtype} array of shape {a.shape}")
        try:
            return json.loads(str(a))
        except (ValueError, RecursionError) as exc:
            self.fail(f"{key!r} is not valid JSON ({exc})")

    def strings(self, key: str, n: int | None) -> np.ndarray:
        v = self.json(key)
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(f"{key!r} must be a JSON list of strings")
        if n is not None and len(v) != n:
            self.fail(f"{key!r} has {len(v)} entries, expected {n} (one per clip)")
        return np.array(v, dtype=str) if v else np.zeros(0, dtype=str)

    def numbers(self, key: str, shape: tuple, kind: str, *, keep_float32: bool = False) -> np.ndarray:
        """``kind``: "int", "float" or "bool"; ``shape`` entries None match any length.

        Floats come back as float64, except float32 ones with ``keep_float32`` (the pose clouds
        of a database augmented with ``pose_dtype=float32`` reload as saved, not doubled in memory).
        """
        a = self.array(key)
        ok = {"int": "iu", "float": "iuf", "bool": "biu"}[kind]
        if a.dtype.kind not in ok:
            self.fail(f"array {key!r} has dtype {a.dtype}, expected {kind}")
        if a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape)):
            want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            self.fail(f"array {key!r} has shape {a.shape}, expected {want}")
        if kind == "float":
            a = a.astype(np.float32 if keep_float32 and a.dtype == np.float32 else float, copy=False)
            if not np.all(np.isfinite(a)):
                self.fail(f"array {key!r} contains NaN or inf")
        elif kind == "bool":
            if a.dtype.kind != "b" and not np.all((a == 0) | (a == 1)):
                self.fail(f"array {key!r} must hold booleans")
            a = a.astype(bool)
        else:
            a = a.astype(np.int64)
        return a

    def ensure(self, cond, msg: str) -> None:
        if not cond:
            self.fail(msg)


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_skeleton_header(ck: _Check, h, what: str) -> None:
    ck.ensure(isinstance(h, dict), f"{what} must be a JSON object")
    names = h.get("joint_names")
    ck.ensure(isinstance(names, list) and names and all(isinstance(n, str) for n in names),
              f"{what}: joint_names must be a non-empty list of strings")
    ch = h.get("channels")
    ck.ensure(isinstance(ch, list) and all(isinstance(c, list) and all(isinstance(x, str) for x in c) for c in ch),
              f"{what}: channels must be a list of lists of channel names")
    u = h.get("unit_m")
    ck.ensure(u is None or (_is_num(u) and u > 0), f"{what}: unit_m must be a finite number > 0 or null, got {u!r}")


def _database_from_arrays(cls, z: dict, where: str):
    """The database of the arrays ``z`` of a file (``where``), every part checked (:class:`_Check`)."""
    ck = _Check(z, where)
    fps, roles, window, step, meta, ah, mh = _header(ck)
    arrays = _clip_arrays(ck, len(ah))
    _pose_arrays(ck, arrays, window * len(roles))
    actors = _actors(ck, ah, roles, arrays)
    motions = _motions(ck, mh, fps, arrays["n_frames"])
    src = arrays["source_clip"]
    lacking = [i for i in range(src.size) if i not in motions and int(src[i]) not in motions]
    ck.ensure(not lacking, f"clips {lacking[:5]} have no stored motion, nor has their source clip")
    try:
        return cls(fps=fps, pose_roles=roles, window=window, step=step, actors=actors, motions=motions,
                   arrays=arrays, meta=meta)
    except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
        ck.fail(f"inconsistent database: {exc}")



def _header(ck: _Check) -> tuple:
    """``fps, pose_roles, window, step, meta, actor headers, motion headers`` of the JSON header."""
    header = ck.json("header")
    ck.ensure(isinstance(header, dict), "not a motion database (header is not a JSON object)")
    fmt = header.get("format")
    ck.ensure(fmt == DB_FORMAT, f"not a motion database file (format {fmt!r}, expected {DB_FORMAT!r})")
    fps = header.get("fps")
    ck.ensure(_is_num(fps) and fps > 0, f"fps must be a finite number > 0, got {fps!r}")
    roles = header.get("pose_roles")
    ck.ensure(isinstance(roles, list) and roles and all(isinstance(r, str) for r in roles),
              "pose_roles must be a non-empty list of role names")
    window, step = header.get("window"), header.get("step")
    ck.ensure(_is_int(window) and window >= 1 and _is_int(step) and step >= 1,
              f"window and step must be integers >= 1, got {window!r}, {step!r}")
    meta = header.get("meta")
    ck.ensure(isinstance(meta, dict), "meta must be a JSON object")
    ah, mh = header.get("actors"), header.get("motions")
    ck.ensure(isinstance(ah, list) and ah, "the header lists no actor")
    ck.ensure(isinstance(mh, list), "the header's motions must be a list")

    return fps, roles, window, step, meta, ah, mh


def _clip_arrays(ck: _Check, n_actors: int) -> dict[str, np.ndarray]:
    """The per-clip annotations and numbers, checked against each other and the ``n_actors`` actors."""
    names = ck.strings("names", None)
    C = names.size
    ck.ensure(C >= 1, "the database has no clip")
    ck.ensure(len(set(names.tolist())) == C, "clip names are not unique")
    arrays: dict[str, np.ndarray] = {"names": names}
    for k in CLIP_STR[1:]:
        arrays[k] = ck.strings(k, C)
    bad = sorted(set(arrays["semantics"].tolist()) - set(SEMANTICS))
    ck.ensure(not bad, f"unknown semantics {bad}; expected {list(SEMANTICS)}")
    bad = sorted(set(arrays["hit_roles"].tolist()) - set(HIT_ROLES))
    ck.ensure(not bad, f"unknown hit segments {bad}; expected {list(HIT_ROLES)}")
    bad = sorted(set(arrays["hit_wheres"].tolist()) - {"joint", "end_site"})
    ck.ensure(not bad, f"hit_wheres must be 'joint' or 'end_site', got {bad}")
    for k in ("hit_frame", "n_frames", "actor", "source_clip"):
        arrays[k] = ck.numbers(k, (C,), "int")
    for k in ("scale", "size_a", "source_time", "warp", "noise"):
        arrays[k] = ck.numbers(k, (C,), "float")
    arrays["mirror"] = ck.numbers("mirror", (C,), "bool")
    for k in ("box_min", "box_max", "hit_position"):
        arrays[k] = ck.numbers(k, (C, 3), "float")
    nf = arrays["n_frames"]
    ck.ensure(np.all(nf >= 1), "n_frames must be >= 1 for every clip")
    ck.ensure(np.all((arrays["hit_frame"] >= 0) & (arrays["hit_frame"] < nf)),
              "a hit frame lies outside its clip (hit_frame not in [0, n_frames))")
    ck.ensure(np.all((arrays["actor"] >= 0) & (arrays["actor"] < n_actors)),
              f"a clip's actor index is outside the {n_actors} stored actors")
    ck.ensure(np.all((arrays["source_clip"] >= 0) & (arrays["source_clip"] < C)),
              f"a source_clip index is outside [0, {C})")
    ck.ensure(np.all(arrays["scale"] > 0) and np.all(arrays["size_a"] > 0) and np.all(arrays["warp"] > 0),
              "scale, size_a and warp must be > 0")
    ck.ensure(np.all(arrays["noise"] >= 0), "noise must be >= 0")
    ck.ensure(np.all(arrays["box_min"] <= arrays["box_max"]), "a bounding box has box_min > box_max")

    return arrays


def _pose_arrays(ck: _Check, arrays: dict[str, np.ndarray], points: int) -> None:
    """Add the trajectories and the pose clouds (``points`` per pose) to ``arrays``, checked against the clips."""
    nf, C = arrays["n_frames"], arrays["names"].size
    for k in ("traj_start", "pose_start"):
        arrays[k] = ck.numbers(k, (C + 1,), "int")
    offsets = np.concatenate([[0], np.cumsum(nf)])
    for k in ("traj_start", "pose_start"):
        ck.ensure(np.array_equal(arrays[k], offsets),
                  f"{k} does not match the clips' frame counts (offsets must be 0 and the running sum of n_frames)")
    T = N = int(offsets[-1])
    arrays["traj"] = ck.numbers("traj", (T, 3), "float")
    arrays["pose_points"] = ck.numbers("pose_points", (N, points, 3), "float", keep_float32=True)
    arrays["pose_clip"] = ck.numbers("pose_clip", (N,), "int")
    arrays["pose_frame"] = ck.numbers("pose_frame", (N,), "int")
    arrays["pose_heading"] = ck.numbers("pose_heading", (N,), "float")
    arrays["pose_origin"] = ck.numbers("pose_origin", (N, 3), "float")
    pc = np.repeat(np.arange(C), nf)
    ck.ensure(np.array_equal(arrays["pose_clip"], pc), "pose_clip does not match the clips' frame counts")
    ck.ensure(np.array_equal(arrays["pose_frame"], np.arange(N) - offsets[pc]),
              "pose_frame does not number the frames of each clip from 0")



def _actors(ck: _Check, ah: list, roles: list, arrays: dict[str, np.ndarray]) -> list[Skeleton]:
    """The base actors of the header ``ah`` with their arrays; each has the pose ``roles`` and its clips' hit joints."""
    names = arrays["names"]
    actors = []
    for a, h in enumerate(ah):
        _check_skeleton_header(ck, h, f"actor {a}")
        ck.ensure(isinstance(h.get("roles"), dict) and all(isinstance(k, str) and isinstance(v, str)
                                                           for k, v in h["roles"].items()),
                  f"actor {a}: roles must map role names to joint names")
        J = len(h["joint_names"])
        try:
            sk = Skeleton(joint_names=h["joint_names"],
                          parents=ck.numbers(f"actor{a}_parents", (J,), "int"),
                          offsets=ck.numbers(f"actor{a}_offsets", (J, 3), "float"),
                          channels=[tuple(c) for c in h["channels"]] or None,
                          end_site_parents=ck.numbers(f"actor{a}_end_site_parents", (None,), "int"),
                          end_site_offsets=ck.numbers(f"actor{a}_end_site_offsets", (None, 3), "float"),
                          unit_m=h["unit_m"], roles=h["roles"])
        except DataError:
            raise
        except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
            ck.fail(f"actor {a} is unusable: {exc}")
        missing = [r for r in roles if r not in sk.roles]
        ck.ensure(not missing, f"actor {a} lacks the pose roles {missing}")
        actors.append(sk)
    for i in range(names.size):
        sk = actors[int(arrays["actor"][i])]
        if str(arrays["hit_joints"][i]) not in sk.joint_names:
            ck.fail(f"clip {i} ({names[i]}): hit joint {arrays['hit_joints'][i]!r} is not a joint of its actor")

    return actors


def _motions(ck: _Check, mh: list, fps: float, nf: np.ndarray) -> dict[int, Motion]:
    """The stored motions of the header ``mh`` (clip index -> motion), ``nf[i]`` frames at ``fps`` each."""
    C = nf.size
    motions = {}
    for h in mh:
        _check_skeleton_header(ck, h, "a stored motion")
        i = h.get("clip")
        ck.ensure(_is_int(i) and 0 <= i < C, f"a stored motion names clip {i!r}, not in [0, {C})")
        ck.ensure(i not in motions, f"clip {i} has two stored motions")
        ft = h.get("frame_time")
        ck.ensure(_is_num(ft) and ft > 0 and abs(1.0 / ft - fps) <= 1e-6 * fps,
                  f"motion of clip {i}: frame_time {ft!r} does not match the database's {fps:g} fps")
        src = h.get("source")
        ck.ensure(src is None or isinstance(src, str), f"motion of clip {i}: source must be a string or null")
        J, F = len(h["joint_names"]), int(nf[i])
        rot = ck.numbers(f"motion{i}_rotations", (F, J, 4), "float")
        # the stored quaternions are unit already: kept bit for bit (Motion() would
        # re-normalise them, which may change their last bit); a zero one is Motion's to refuse
        norm = np.linalg.norm(rot, axis=-1)
        ck.ensure(np.all((norm < 1e-12) | (np.abs(norm - 1.0) < Motion.UNIT_TOLERANCE)),
                  f"motion of clip {i}: rotations are not unit quaternions")
        try:
            m = Motion.from_unit_rotations(
                joint_names=h["joint_names"], parents=ck.numbers(f"motion{i}_parents", (J,), "int"),
                offsets=ck.numbers(f"motion{i}_offsets", (J, 3), "float"),
                channels=[tuple(c) for c in h["channels"]], frame_time=ft, rotations=rot,
                positions=ck.numbers(f"motion{i}_positions", (F, J, 3), "float"),
                end_site_parents=ck.numbers(f"motion{i}_end_site_parents", (None,), "int"),
                end_site_offsets=ck.numbers(f"motion{i}_end_site_offsets", (None, 3), "float"),
                unit_m=h["unit_m"], source=src)
        except DataError:
            raise
        except (ReproError, ValueError, TypeError, KeyError, IndexError) as exc:
            ck.fail(f"the motion of clip {i} is unusable: {exc}")
        motions[i] = m
    return motions
