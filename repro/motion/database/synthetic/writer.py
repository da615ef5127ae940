"""The synthetic database on disk: BVH clips plus ``manifest.csv`` (:func:`synthetic_database`)."""

from __future__ import annotations

import csv
import errno
import hashlib
import io
import os
import shutil
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

from repro.checks import as_bool, as_int
from repro.errors import MotionError
from repro.io import atomic_path, inside, open_regular, read_bytes
from repro.motion.io.bvh import write_bvh
from repro.motion.database.synthetic.choreography import synthetic_clip
from repro.motion.database.synthetic.moves import HIT_LEVELS, SIDES, STRIKE_KINDS
from repro.motion.database.synthetic.skeleton import DEFAULT_FPS, REFERENCE_HEIGHT_M

__all__ = [
    "MANIFEST_NAME",
    "MANIFEST_COLUMNS",
    "SyntheticDatabase",
    "database_actor_heights",
    "synthetic_database",
    "read_manifest",
]

#: File name of the database manifest.
MANIFEST_NAME = "manifest.csv"
#: Columns of the manifest, in order.  ``hit_frame`` is -1 and the ``hit_*`` fields are
#: empty for stance clips; ``hit_x_m``... is the hit point's world position at the hit
#: frame; ``clip_seed`` regenerates the clip with :func:`synthetic_clip`; ``unit_m`` is
#: the metres per BVH length unit (always 1).
MANIFEST_COLUMNS: tuple[str, ...] = (
    "file", "kind", "semantics", "side", "level", "hit_joint", "hit_frame",
    "actor_height_m", "frames", "frame_time", "sha256",
    "hit_point", "hit_x_m", "hit_y_m", "hit_z_m", "clip_seed", "unit_m",
)  # fmt: skip


# ---------------------------------------------------------------- public API: the database
class SyntheticDatabase(NamedTuple):
    """What :func:`synthetic_database` wrote.

    Attributes
    ----------
    paths : list of pathlib.Path
        The BVH files, in manifest order.
    manifest_path : pathlib.Path
        The ``manifest.csv``.
    records : list of dict
        The manifest rows, typed as by :func:`read_manifest`.
    """

    paths: list[Path]
    manifest_path: Path
    records: list[dict]


def database_actor_heights(n_actors: int) -> list[float]:
    """Actor heights of a database with ``n_actors`` actors: evenly spaced in [1.60, 1.90] m.

    One actor is 1.75 m; three are 1.60, 1.75 and 1.90 m.
    """
    n = _positive_int("n_actors", n_actors)
    if n == 1:
        return [REFERENCE_HEIGHT_M]
    return [round(float(h), 4) for h in np.linspace(1.60, 1.90, n)]


#: Most actors :func:`synthetic_database` writes (each adds 25 clips).
MAX_ACTORS: int = 1000


def _positive_int(name: str, value, minimum: int = 1) -> int:
    return as_int(value, name, minimum, MAX_ACTORS if name == "n_actors" else None, error=MotionError)


def _plan(n_actors: int, seed: int) -> list[dict]:
    """The clips of a database: per actor, every strike kind x side x level, plus one stance."""
    plan = []
    for a, height in enumerate(database_actor_heights(n_actors), start=1):
        combos = [(k, s, lv) for k in STRIKE_KINDS for s in SIDES for lv in HIT_LEVELS]
        combos.append(("stance", SIDES[(a - 1) % 2], "none"))
        for kind, side, level in combos:
            name = f"actor{a}_{kind}_{side}" + ("" if kind == "stance" else f"_{level}") + ".bvh"
            index = len(plan)
            clip_seed = int(np.random.SeedSequence([seed, index]).generate_state(1, np.uint32)[0])
            plan.append({"file": name, "kind": kind, "side": side, "level": level, "height": height, "seed": clip_seed})
    return plan


def _manifest_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(MANIFEST_COLUMNS)
    for r in rows:
        w.writerow([r[c] for c in MANIFEST_COLUMNS])
    return buf.getvalue()


def _sha256(path: Path) -> str:
    # a regular file only, its size known before reading (a FIFO or /dev/zero in its place never hangs)
    fh, size = open_regular(path, error=MotionError)
    with fh:
        return hashlib.sha256(fh.read(size)).hexdigest()


def synthetic_database(
    out_dir,
    n_actors: int = 3,
    seed: int = 0,
    *,
    fps: float = DEFAULT_FPS,
    overwrite: bool = False,
) -> SyntheticDatabase:
    """Write the synthetic motion database: BVH clips plus ``manifest.csv``.

    Per actor (heights :func:`database_actor_heights`): every strike kind
    (:data:`STRIKE_KINDS`) x side x level, i.e. 24 clips, plus one stance clip; the
    default three actors give 75 clips, the size of the paper's database (Section 3.2).
    Files are named ``actor{a}_{kind}_{side}_{level}.bvh`` (``actor{a}_stance_{side}.bvh``).
    Clip ``i`` is ``synthetic_clip(..., seed=SeedSequence([seed, i]))``, recorded as
    ``clip_seed`` in the manifest, so every file can be regenerated alone.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Folder to write into (created if missing).  Other files in it are left alone.
    n_actors : int, default 3
        Number of actor sizes.
    seed : int, default 0
        Master seed (>= 0).  The same arguments always give byte-identical files.
    fps : float, default 60
        Frame rate of every clip.
    overwrite : bool, default False
        Policy for existing files.  Every file is first generated in a temporary folder
        inside ``out_dir``; a target that already exists **with identical bytes** is kept
        (so re-running with the same arguments is a no-op); if any target exists with
        *different* content, nothing is written and :class:`FileExistsError` is raised,
        unless ``overwrite=True``, in which case those files are replaced.  Each file is
        moved into place atomically (:func:`repro.io.atomic_path`), the manifest last.

    Returns
    -------
    SyntheticDatabase
        ``(paths, manifest_path, records)``.

    Raises
    ------
    FileExistsError
        If ``out_dir`` holds a BVH file or manifest of the same name with other content
        and ``overwrite`` is False.
    repro.errors.MotionError
        For a bad ``n_actors``, ``seed`` or ``fps``.
    """
    n_actors = _positive_int("n_actors", n_actors)
    seed = _positive_int("seed", seed, minimum=0)
    out_dir = Path(out_dir)
    plan = _plan(n_actors, seed)
    clips = [synthetic_clip(p["kind"], p["side"], p["level"], p["height"], seed=p["seed"], fps=fps) for p in plan]
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".synthetic-", dir=out_dir))
    try:
        _stage(stage, plan, clips)
        _commit(stage, out_dir, [p["file"] for p in plan] + [MANIFEST_NAME], overwrite)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    manifest_path = out_dir / MANIFEST_NAME
    return SyntheticDatabase([out_dir / p["file"] for p in plan], manifest_path, read_manifest(manifest_path))


def _manifest_row(p: dict, motion, ann: dict, sha256: str) -> dict:
    hp = ann["hit_position"]
    return {
        "file": p["file"], "kind": ann["kind"], "semantics": ann["semantics"], "side": ann["side"],
        "level": ann["level"], "hit_joint": ann["hit_joint"], "hit_frame": ann["hit_frame"],
        "actor_height_m": f"{ann['actor_height_m']:.6g}", "frames": motion.n_frames,
        "frame_time": f"{motion.frame_time:.12g}", "sha256": sha256,
        "hit_point": ann["hit_point"],
        "hit_x_m": "" if hp is None else f"{hp[0]:.6f}",
        "hit_y_m": "" if hp is None else f"{hp[1]:.6f}",
        "hit_z_m": "" if hp is None else f"{hp[2]:.6f}",
        "clip_seed": p["seed"],
        "unit_m": "1",
    }  # fmt: skip


def _stage(stage: Path, plan: list[dict], clips) -> None:
    """Write every clip and the manifest into the staging folder."""
    rows = []
    for p, (motion, ann) in zip(plan, clips):
        staged = write_bvh(motion, stage / p["file"])
        rows.append(_manifest_row(p, motion, ann, _sha256(staged)))
    (stage / MANIFEST_NAME).write_text(_manifest_text(rows), encoding="utf-8", newline="")


def _commit(stage: Path, out_dir: Path, names: list[str], overwrite: bool) -> None:
    """Move the staged files into ``out_dir`` (identical ones kept; conflicts refused unless ``overwrite``)."""
    same, conflicts = set(), []
    for name in names:
        target = out_dir / name
        if target.is_file() and _sha256(target) == _sha256(stage / name):
            same.add(name)
        elif target.exists() or target.is_symlink():
            conflicts.append(name)
    if conflicts and not overwrite:
        raise FileExistsError(
            errno.EEXIST,
            f"{len(conflicts)} file(s) of the synthetic database already exist with other content "
            f"(e.g. {conflicts[0]!r}); nothing was written; pass overwrite=True to replace them",
            str(out_dir / conflicts[0]),
        )
    for name in names:  # the manifest last: it is complete only once every clip is in place
        if name not in same:
            with atomic_path(out_dir / name) as tmp:  # mode 0o644, moved into place atomically
                os.replace(stage / name, tmp)


_INT_COLUMNS = ("hit_frame", "frames", "clip_seed")
_FLOAT_COLUMNS = ("actor_height_m", "frame_time", "hit_x_m", "hit_y_m", "hit_z_m", "unit_m")


def read_manifest(path, *, verify: bool = False) -> list[dict]:
    """Read a ``manifest.csv`` written by :func:`synthetic_database`.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest.
    verify : bool, default False
        Also check the sha256 of every listed BVH file (in the manifest's folder).

    Returns
    -------
    list of dict
        One dict per clip with the :data:`MANIFEST_COLUMNS` as keys: ``hit_frame``,
        ``frames`` and ``clip_seed`` as int, ``actor_height_m``, ``frame_time``,
        ``unit_m`` and ``hit_x_m``/``hit_y_m``/``hit_z_m`` as float (None when empty, i.e. for stance
        clips), the rest as str.

    Raises
    ------
    repro.errors.MotionError
        If a column is missing or a value does not parse, or (``verify``) a file is
        missing or its sha256 differs.
    """
    verify = as_bool(verify, "verify", error=MotionError)
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise MotionError(f"path must be a manifest file path (str or os.PathLike), got {path!r}")
    path = Path(path)
    raw, _ = read_bytes(path, error=MotionError)  # a regular file, bounded (a FIFO would hang open())
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MotionError(f"{path}: a manifest is UTF-8 text ({exc})") from None
    with io.StringIO(text, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in MANIFEST_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise MotionError(f"{path}: manifest lacks column(s) {missing}")
        rows = []
        for lineno, raw in enumerate(reader, start=2):
            row = dict(raw)
            try:
                for c in _INT_COLUMNS:
                    row[c] = int(row[c])
                for c in _FLOAT_COLUMNS:
                    row[c] = None if row[c] in ("", None) else float(row[c])
            except (TypeError, ValueError) as e:
                raise MotionError(f"{path}, line {lineno}: {e}") from None
            rows.append(row)
    if verify:
        for row in rows:
            f = inside(path.parent, row["file"], error=MotionError, what=f"{path.name}: file")
            if not f.is_file():
                raise MotionError(f"{path}: listed file {row['file']!r} is missing")
            if _sha256(f) != row["sha256"]:
                raise MotionError(f"{path}: sha256 of {row['file']!r} differs from the manifest")
    return rows
